"""Friction of contacts on positions, after all normal steps (woodstock §5.4, Eqs. 5-7).

Eq. 7 scales the velocity by 1 - min(1, mu_f |dF| dt / (m max(|v|, eps))). Multiplied by dt it acts
on the displacement of the substep. The substep (:func:`wooddecay.sim.mechanics.substep`) applies
it per particle after all normal steps of a projection, colliders and pairs
(:func:`particle_friction`): a particle that they moved by push takes back

    d_t <- d_t - min(1, mu_f |push| / max(|d_t|, eps dt)) d_t

of the part d_t of its displacement since the start of the substep normal to push. |push| stands
for |dF| dt^2 / m, the normal force of the particle's contacts rather than the particle-capsule
force of Eqs. 5-6: once Eq. 3 is resolved a particle of i lies at r_i + r_j from the axis of j,
so phi_ikj = max(r_j - dist(p_ik, j), 0) of Eq. 5 vanishes and resting contacts would slide
freely. Friction is static below the cone (a particle on an incline with tan(angle) < mu_f stays,
and so does a capsule lying across two others) and kinetic above it (it slides with
g (sin - mu_f cos)); both are tested. Applied after the normal steps, it sees the tangential part
of every push of the Jacobi projection (docs/decisions.md, "Contact"). Per particle, so race-free
and bit-identical for any thread count; :func:`particle_friction_reference` is the numpy version
the tests compare against.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .closest import _dot


@nb.njit(cache=True, inline="always")
def _friction_step(dx, dy, dz, nx, ny, nz, normal, mu, floor):
    """Eq. 7 on a displacement: the tangential part d_t of (dx, dy, dz) (normal n) times
    min(1, mu normal / max(|d_t|, floor)), the part friction takes back."""
    dn = dx * nx + dy * ny + dz * nz
    tx, ty, tz = dx - dn * nx, dy - dn * ny, dz - dn * nz
    mag = np.sqrt(tx * tx + ty * ty + tz * tz)
    if mag <= 0.0:
        return 0.0, 0.0, 0.0
    c = min(1.0, mu * normal / max(mag, floor))
    return c * tx, c * ty, c * tz


@nb.njit(parallel=True, cache=True)
def _particle_friction(x, x_start, x_prev, mu, floor):
    for p in nb.prange(len(x)):
        px, py, pz = x[p, 0] - x_start[p, 0], x[p, 1] - x_start[p, 1], x[p, 2] - x_start[p, 2]
        push = np.sqrt(px * px + py * py + pz * pz)
        if push <= 0.0:
            continue
        fx, fy, fz = _friction_step(x[p, 0] - x_prev[p, 0], x[p, 1] - x_prev[p, 1], x[p, 2] - x_prev[p, 2],
                                    px / push, py / push, pz / push, push, mu, floor)
        x[p, 0] -= fx
        x[p, 1] -= fy
        x[p, 2] -= fz


def particle_friction(x, x_start, x_prev, mu: float, floor: float) -> None:
    """Friction of Eq. 7 on positions, after all normal contact steps of a projection (module
    docstring "Friction"): every particle that the normal steps moved, by push = x - ``x_start``
    (colliders and capsule pairs together), takes back min(1, mu |push| / max(|d_t|, ``floor``))
    of the part d_t of its displacement since ``x_prev`` (the start of the substep) normal to
    push. Changes ``x`` (P, 3) in place; per particle, so race-free and deterministic."""
    if mu > 0.0 and len(x):
        _particle_friction(x, x_start, x_prev, float(mu), float(floor))


def _friction_reference(d, n, normal, mu, floor):
    """Vectorised :func:`_friction_step` (rows)."""
    tang = d - _dot(d, n)[:, None] * n
    mag = np.sqrt(_dot(tang, tang))
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(mag > 0.0, np.minimum(1.0, mu * normal / np.maximum(mag, floor)), 0.0)
    return c[:, None] * tang


def particle_friction_reference(x, x_start, x_prev, mu: float, floor: float) -> None:
    """numpy version of :func:`particle_friction`."""
    if not (mu > 0.0 and len(x)):
        return
    push = x - x_start
    mag = np.sqrt(_dot(push, push))
    on = mag > 0.0
    n = push[on] / mag[on, None]
    x[on] -= _friction_reference(x[on] - x_prev[on], n, mag[on], mu, floor)
