"""The gallery: woodstock's figures as shipped scenes (``samples/gallery/``), each baked, rendered
through the add-on and measured against the paper's claim (``wooddecay gallery``; docs/gallery.md).

:mod:`.figures` holds what each figure varies, claims and tests, :mod:`.measures` the figure
statistics, :mod:`.run` the bakes, renders and ``signatures.json``.
"""
from .figures import FIGURES, Figure, Variant
from .run import run_gallery

__all__ = ["FIGURES", "Figure", "Variant", "run_gallery"]
