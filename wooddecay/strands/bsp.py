"""BSP prepartition in wood-local coordinates and the boundary indicator theta_ij.

Woodstock §7.1, Figs. 9 and 11, Table 2; docs/model.md §2. Each branch starts as one cell of its elements
in wood-local coordinates scaled to physical length, X = (r, r phi, s / elongation): a larger
``elongation`` makes cells longer along the grain (Fig. 11b). The cell whose longest axis is the
longest of all is split across that axis, at the middle of its extent moved by a jitter of up to
``jitter`` times the extent (so cells are near-cubic but not a lattice); a split that would leave
one side empty falls back to the median. Splitting stops when ``cells`` leaves exist. Leaves are
numbered in creation order, which with the seeded jitter makes the partition deterministic.
``cells = 0`` disables the partition (one leaf, theta = 0 everywhere). With fewer ``cells``
than branches each branch is one leaf (recorded in decisions.md).

theta_ij = 1 when elements i and j lie in different leaves (§7.1).
"""
from __future__ import annotations

import heapq

import numpy as np

from ..arrays import group_rows


def bsp_coordinates(wood_coords: np.ndarray, elongation: float) -> np.ndarray:
    """X = (r, r phi, s / elongation) from wood-local (r, phi, s)."""
    r, phi, s = wood_coords[:, 0], wood_coords[:, 1], wood_coords[:, 2]
    return np.stack([r, r * phi, s / elongation], axis=1)


def _split(X: np.ndarray, idx: np.ndarray, jitter: float, rng: np.random.Generator):
    """Split cell ``idx`` across its longest axis; None if it cannot be split."""
    pts = X[idx]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    axis = int(np.argmax(hi - lo))
    cut = 0.5 * (lo[axis] + hi[axis]) + jitter * rng.uniform(-1.0, 1.0) * (hi[axis] - lo[axis])
    left = pts[:, axis] < cut
    if left.all() or not left.any():
        cut = np.median(pts[:, axis])
        left = pts[:, axis] < cut
        if left.all() or not left.any():
            return None
    return idx[left], idx[~left]


def _extent(X: np.ndarray, idx: np.ndarray) -> float:
    pts = X[idx]
    return float(np.max(pts.max(axis=0) - pts.min(axis=0)))


def bsp_leaves(
    wood_coords: np.ndarray,
    branch: np.ndarray,
    cells: int,
    elongation: float,
    jitter: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Leaf index (groupID) of every element: ``max(cells, branches)`` leaves, or a single leaf
    when ``cells`` = 0."""
    X = bsp_coordinates(wood_coords, elongation)
    leaf = np.zeros(len(X), dtype=np.int64)
    if cells == 0:  # disabled: one leaf, theta = 0 everywhere
        return leaf
    members = [g for g in group_rows(branch, int(branch.max()) + 1) if len(g)]
    if cells <= len(members):
        for k, idx in enumerate(members):
            leaf[idx] = k
        return leaf
    heap: list[tuple[float, int, np.ndarray]] = []
    counter = 0
    for idx in members:
        heapq.heappush(heap, (-_extent(X, idx), counter, idx))
        counter += 1
    done: list[np.ndarray] = []
    while heap and len(heap) + len(done) < cells:
        _, _, idx = heapq.heappop(heap)
        parts = _split(X, idx, jitter, rng) if len(idx) > 1 else None
        if parts is None:
            done.append(idx)
            continue
        for part in parts:
            heapq.heappush(heap, (-_extent(X, part), counter, part))
            counter += 1
    # leaves numbered by their creation counter: deterministic and independent of heap layout
    final = sorted(heap, key=lambda h: h[1])
    for k, idx in enumerate(done + [h[2] for h in final]):
        leaf[idx] = k
    return leaf


def theta(leaf: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """theta_ij = 1 if the edge crosses a BSP cell boundary (§7.1), as float64 (m,)."""
    return (leaf[edges[:, 0]] != leaf[edges[:, 1]]).astype(np.float64)
