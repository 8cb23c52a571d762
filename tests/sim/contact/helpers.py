"""Shared set-ups of the contact tests: random segment soups, capsule pairs with pinned particles,
a table of one collider of each kind, and positions displaced as by a substep."""
from __future__ import annotations

import numpy as np

from wooddecay.sim import contact as C

G = 9.81
DT = 0.01


def _segment_soup(seed, n_seg=600, n_comp=6):
    """Random segments in a unit box with parallel, collinear and degenerate ones mixed in:
    (x, first_particle, radius, component). Every segment owns its two particles."""
    rng = np.random.default_rng(seed)
    p = rng.random((n_seg, 3))
    d = rng.normal(size=(n_seg, 3)) * 0.04
    d[: n_seg // 4] = [0.05, 0.0, 0.0]  # parallel
    d[n_seg // 4: n_seg // 3, 1:] = 0.0  # parallel to x, different lengths
    d[n_seg // 3: n_seg // 3 + 20] = 0.0  # points
    p[:40, 1:] = 0.5  # collinear along x
    x = np.stack([p, p + d], axis=1).reshape(-1, 3)
    fp = np.arange(0, 2 * n_seg, 2, dtype=np.int64)
    return x, fp, rng.uniform(0.005, 0.03, n_seg), rng.integers(0, n_comp, n_seg).astype(np.int64)


def _rows(*pts):
    return np.array(pts, dtype=np.float64)


def _contact_setup(seed):
    x, fp, r, comp = _segment_soup(seed, n_seg=500)
    r = r * 2.0
    pairs = C.candidate_pairs(x, fp, r, comp, 0.0)
    w = np.random.default_rng(seed).uniform(0.5, 2.0, len(x))
    w[::7] = 0.0
    return x, w, fp, r, pairs


def _moved(x, seed):
    """x displaced as by a substep: the start-of-substep positions and the predicted ones."""
    x_prev = x.copy()
    return x_prev, x + np.random.default_rng(seed).normal(0.0, 2e-3, x.shape)


def _colliders():
    return np.stack([
        C.collider_row(C.PLANE, 0, 0, 0.1, 0.2, 0.1, 1.0),
        C.collider_row(C.BOX, 0.2, 0.2, 0.2, 0.5, 0.4, 0.6),
        C.collider_row(C.SPHERE, 0.7, 0.7, 0.5, 0.15),
        C.collider_row(C.CYLINDER, 0.3, 0.8, 0.2, 0.6, 0.8, 0.7, 0.1),
    ])
