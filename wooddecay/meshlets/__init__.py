"""Meshlets: kinetic Delaunay triangulation and kinetic alpha shape of branch cross-sections (woodstock §8.1, Fig. 10; SPEC §5)."""
