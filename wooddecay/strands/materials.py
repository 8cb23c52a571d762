"""Material parameters resolved per tissue (docs/model.md §1-2: any parameter of ``[fungi]``,
``[moisture]``, ``[mechanics]``, ``[transport]`` or ``[wood]`` may be overridden per tissue).

:class:`Materials` is the one lookup every solver uses: the value of a parameter in each tissue
(:data:`~wooddecay.strands.rings.TISSUES` order), as a per-tissue table or gathered per element.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Materials:
    """``values[name]`` holds the value of ``name`` in each tissue; ``tissue`` the tissue index
    of each element."""

    values: Mapping[str, tuple]
    tissue: np.ndarray

    def per_tissue(self, name: str) -> tuple:
        """The value of ``name`` in each tissue (any type: numbers, keyframe lists)."""
        return self.values[name]

    def table(self, names: Sequence[str]) -> np.ndarray:
        """(n_tissues, len(names)) float64 values, a row per tissue."""
        return np.array([[self.values[k][t] for k in names] for t in range(len(self.values[names[0]]))],
                        dtype=np.float64)

    def per_element(self, name: str) -> np.ndarray:
        """(n,) float64 value of ``name`` at every element (its tissue's value)."""
        return np.array(self.values[name], dtype=np.float64)[self.tissue]
