"""Meshlets (woodstock §8.1, §8.3, Fig. 10; docs/model.md §5): the kinetic Voronoi sweep of the strand sites
into per-element closed shells, their blend skinning per frame and crack-face visibility."""
