"""Writers of baked results (USD, glTF) and debug views of the wood model."""
