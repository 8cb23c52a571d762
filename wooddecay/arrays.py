"""Small array utilities shared by the model build and the solvers."""
from __future__ import annotations

import numpy as np


def group_rows(keys: np.ndarray, n: int) -> list[np.ndarray]:
    """Row indices grouped by integer key 0..n-1 (one stable sort, no per-row Python work)."""
    order = np.argsort(keys, kind="stable")
    bounds = np.searchsorted(keys[order], np.arange(n + 1))
    return [order[bounds[i]:bounds[i + 1]] for i in range(n)]
