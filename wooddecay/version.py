"""The package version (written into stages, glTF extras, summaries and error lines)."""

__version__ = "0.1.0"
