"""What a piece's time samples hold: its rigid motion apart from its shape, and a value only where
it changed past a tolerance (docs/architecture.md "USD stage", format 2).

The wood's vertices are grouped by piece, each piece's vertices contiguous (``start``, the
offsets of the K pieces' runs, ``start[K] = V``).

* :func:`rigid_fit`: per piece the rotation R and translation c that carry its written local
  points L closest to the frame's points X in the least-squares sense (Kabsch; Arun, Huang and
  Blostein 1987: R = V diag(1, 1, det(V U^T)) U^T from the SVD U S V^T of the covariance
  sum (L - mean L)(X - mean X)^T), and the largest distance |R L + c - X| left;
* :class:`PoseTrack`: a piece's written local points and pose. A frame whose points the rigid fit
  meets within ``tol`` changes the pose only (when it moved a point by more than ``tol``);
  otherwise the points are written again in the pose they have;
* :func:`changed`: which pieces' values moved by more than a tolerance since they were written.

Plain numpy: K small 3x3 SVDs in one batched call.
"""
from __future__ import annotations

import numpy as np


def piece_max(values: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Largest of ``values`` (V,) over each piece's run (K,); -inf for an empty piece."""
    out = np.full(len(start) - 1, -np.inf)
    full = start[1:] > start[:-1]
    if len(values):
        out[full] = np.maximum.reduceat(values, start[:-1][full])
    return out


def rigid_fit(L: np.ndarray, X: np.ndarray, start: np.ndarray):
    """(R (K, 3, 3), c (K, 3), residual (K,)): per piece the proper rotation and translation
    minimising sum |R L + c - X|^2 over its vertices (module docstring) and the largest
    |R L + c - X| after it."""
    K = len(start) - 1
    counts = np.diff(start)
    piece = np.repeat(np.arange(K), counts)
    n = np.maximum(counts, 1)[:, None]
    mL = np.stack([np.bincount(piece, L[:, k], minlength=K) for k in range(3)], 1) / n
    mX = np.stack([np.bincount(piece, X[:, k], minlength=K) for k in range(3)], 1) / n
    A, B = L - mL[piece], X - mX[piece]
    H = np.stack([np.bincount(piece, A[:, i] * B[:, j], minlength=K) for i in range(3) for j in range(3)],
                 1).reshape(K, 3, 3)
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, 1, 2)
    d = np.sign(np.linalg.det(V @ np.swapaxes(U, 1, 2)))
    d[d == 0] = 1.0
    V[:, :, 2] *= d[:, None]
    R = V @ np.swapaxes(U, 1, 2)
    c = mX - np.einsum("kij,kj->ki", R, mL)
    gap = np.linalg.norm(np.einsum("vij,vj->vi", R[piece], L) + c[piece] - X, axis=1)
    return R, c, piece_max(gap, start)


class PoseTrack:
    """The written local points ``L`` (V, 3) and pose (``R`` (K, 3, 3), ``c`` (K, 3)) of every
    piece: world = R L + c. Starts with R = I, c = the centre of each piece's bounding box at the
    first frame."""

    def __init__(self, X: np.ndarray, start: np.ndarray):
        K = len(start) - 1
        c = np.stack([0.5 * (piece_max(X[:, k], start) - piece_max(-X[:, k], start)) for k in range(3)], 1)
        self.start = start
        self.piece = np.repeat(np.arange(K), np.diff(start))
        self.R = np.repeat(np.eye(3)[None], K, axis=0)
        self.c = c
        self.L = X - c[self.piece]

    def world(self) -> np.ndarray:
        """The written points in the world."""
        return np.einsum("vij,vj->vi", self.R[self.piece], self.L) + self.c[self.piece]

    def update(self, X: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
        """Follow the frame's points ``X``: returns (pieces whose pose changed, pieces whose
        points changed) as boolean (K,) arrays, with ``R``, ``c`` and ``L`` updated. A piece whose
        written state lies within ``tol`` of ``X`` keeps it; one that its rigid fit meets within
        ``tol`` gets the fit's pose; any other gets its points again, in the pose it has. Every
        point of the written state lies within ``tol`` of ``X`` afterwards (up to rounding)."""
        keep = piece_max(np.linalg.norm(self.world() - X, axis=1), self.start) <= tol
        R, c, gap = rigid_fit(self.L, X, self.start)
        pose = ~keep & (gap <= tol)
        shape = ~keep & ~pose
        self.R[pose], self.c[pose] = R[pose], c[pose]
        v = shape[self.piece]
        if v.any():
            p = self.piece[v]
            self.L[v] = np.einsum("vji,vj->vi", self.R[p], X[v] - self.c[p])
        return pose, shape


def changed(new: np.ndarray, old: np.ndarray, start: np.ndarray, tol) -> np.ndarray:
    """(K, n) bool: piece k's column j moved by more than ``tol`` (scalar or (n,)) anywhere, for
    per-vertex values ``new`` and ``old`` (V, n)."""
    d = np.abs(new - old) > np.asarray(tol, dtype=float)
    return np.stack([piece_max(d[:, j].astype(np.float64), start) > 0 for j in range(d.shape[1])], 1)
