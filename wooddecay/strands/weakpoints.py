"""Weak-point field W(x) in [0, 1]: Perlin noise in wood-local coordinates.

Woodstock §6 (opening), Fig. 5, Table 3: W is a 3D Perlin noise evaluated in the local wood frame
that modulates transport and growth (docs/model.md §3: rates scale by 1 + k_W (2W - 1)). Here the noise is
evaluated at the element's cross-section position (u, v) and its arc length s, with s divided
by ``stretch`` so features are elongated along the grain, summed over ``octaves`` (fractal
Brownian motion), mapped to [0, 1], and raised near branch junctions by
``junction_boost * exp(-(d / junction_radius)^2)`` (d = distance to the nearest fork node).

W lives with the wood model (it is a fixed property of the specimen), so it is computed at build
time; see docs/decisions.md.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .. import fmath as fm


def _fade(t: np.ndarray) -> np.ndarray:
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def perlin3(p: np.ndarray, perm: np.ndarray) -> np.ndarray:
    """Improved Perlin noise (Perlin 2002) at points (n, 3); values in about [-1, 1].

    ``perm`` is a permutation of 0..255 (seeded); the 12 edge-midpoint gradients are used.
    """
    grads = np.array([[1, 1, 0], [-1, 1, 0], [1, -1, 0], [-1, -1, 0], [1, 0, 1], [-1, 0, 1],
                      [1, 0, -1], [-1, 0, -1], [0, 1, 1], [0, -1, 1], [0, 1, -1], [0, -1, -1]],
                     dtype=np.float64)
    P = np.concatenate([perm, perm])
    cell = np.floor(p)
    f = p - cell
    ci = cell.astype(np.int64) & 255
    u = _fade(f)
    out = np.zeros(len(p))
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                h = P[P[P[ci[:, 0] + dx] + ci[:, 1] + dy] + ci[:, 2] + dz] % 12
                g = np.einsum("nk,nk->n", grads[h], f - (dx, dy, dz))
                w = ((u[:, 0] if dx else 1 - u[:, 0]) * (u[:, 1] if dy else 1 - u[:, 1])
                     * (u[:, 2] if dz else 1 - u[:, 2]))
                out += w * g
    return out


def weak_point_field(
    uv: np.ndarray,
    s: np.ndarray,
    centers: np.ndarray,
    junctions: np.ndarray,
    *,
    scale: float,
    stretch: float,
    octaves: int,
    junction_boost: float,
    junction_radius: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """W per element (see module docstring)."""
    perm = rng.permutation(256)
    q = np.stack([uv[:, 0] / scale, uv[:, 1] / scale, s / (scale * stretch)], axis=1)
    total = np.zeros(len(q))
    norm = 0.0
    for o in range(octaves):
        amp = 0.5 ** o
        total += amp * perlin3(q * 2.0 ** o + 17.0 * o, perm)
        norm += amp
    W = 0.5 + 0.5 * total / norm
    if len(junctions):
        d, _ = cKDTree(junctions).query(centers)
        W = W + junction_boost * fm.exp(-((d / junction_radius) ** 2))
    return np.clip(W, 0.0, 1.0)
