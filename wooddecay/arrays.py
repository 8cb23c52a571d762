"""Small array utilities shared by the model build and the solvers."""
from __future__ import annotations

import numpy as np


def group_rows(keys: np.ndarray, n: int) -> list[np.ndarray]:
    """Row indices grouped by integer key 0..n-1 (one stable sort, no per-row Python work)."""
    order = np.argsort(keys, kind="stable")
    bounds = np.searchsorted(keys[order], np.arange(n + 1))
    return [order[bounds[i]:bounds[i + 1]] for i in range(n)]


def best_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R (3 x 3, on column vectors) of the least-squares rigid motion of the points
    ``a`` (k, 3) onto ``b`` (Kabsch 1976): b - mean(b) ~ (a - mean(a)) R^T."""
    a0, b0 = a - a.mean(axis=0), b - b.mean(axis=0)
    u, _, vt = np.linalg.svd(a0.T @ b0)
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])
    return (u @ flip @ vt).T
