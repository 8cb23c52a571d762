"""Unit quaternions (w, x, y, z) for the Cosserat rods (Kugelstadt and Schoemer 2016).

Scalar numba helpers (inlined into the kernels of :mod:`wooddecay.sim.mechanics`) and their
vectorised numpy twins for the reference solver. ``q`` maps the material frame (d1, d2, d3) to
the world: ``d_k = q e_k conj(q)``; d3 runs along the segment.
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(inline="always", cache=True)
def mul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product a b."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@nb.njit(inline="always", cache=True)
def rotate(q0, q1, q2, q3, x, y, z):
    """q v conj(q) for a 3-vector v."""
    tx = 2.0 * (q2 * z - q3 * y)
    ty = 2.0 * (q3 * x - q1 * z)
    tz = 2.0 * (q1 * y - q2 * x)
    return (x + q0 * tx + q2 * tz - q3 * ty,
            y + q0 * ty + q3 * tx - q1 * tz,
            z + q0 * tz + q1 * ty - q2 * tx)


def mul_np(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamilton product of (..., 4) arrays."""
    a0, a1, a2, a3 = np.moveaxis(a, -1, 0)
    b0, b1, b2, b3 = np.moveaxis(b, -1, 0)
    return np.stack([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                     a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0], axis=-1)


def conj_np(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def pure_np(v: np.ndarray) -> np.ndarray:
    """(..., 3) vectors as pure quaternions (..., 4)."""
    return np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)


def rotate_np(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """q v conj(q), row-wise."""
    return mul_np(mul_np(q, pure_np(v)), conj_np(q))[..., 1:]


def normalize_np(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def exp_np(theta: np.ndarray) -> np.ndarray:
    """The unit quaternions exp(theta / 2) of the rotation vectors ``theta`` (k, 3), row-wise."""
    angle = np.linalg.norm(theta, axis=1)
    half = 0.5 * angle
    axis = theta / np.where(angle > 0.0, angle, 1.0)[:, None]
    return np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], axis=1)
