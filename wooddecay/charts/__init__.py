"""Charts of the studies the paper validates against (matplotlib, written to files)."""
