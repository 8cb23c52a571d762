"""Closest points of segments and the penetration of two capsules (woodstock §5.4, Eq. 3).

Rod element i is a capsule of radius r_i around the segment from particle ``first_particle[i]`` to
``first_particle[i] + 1``. For elements i, j with closest points at parameters s on i and t on j,
dist(i, j) the distance of those points and n_ij the unit direction from i to j:

    phi_ij = max((r_i + r_j) - dist(i, j), 0)      (Eq. 3)

:func:`closest_segment_segment` finds (s, t) (Ericson, Real-Time Collision Detection §5.1.9) and
:func:`capsule_contact` adds n_ij and phi_ij. These numba helpers take a points array and row
indices (no array views inside the kernels) and are inlined into the kernels of the broad phase,
the capsule pairs and the colliders. Each has a vectorised numpy twin ``*_reference`` (rows are
points, segments or segment pairs) that the tests compare against.
"""
from __future__ import annotations

import numba as nb
import numpy as np

#: squared lengths (m^2) at or below this are degenerate (a point)
TINY = 1e-30
#: segments with sin^2(angle) at or below this are parallel
PARALLEL = 1e-12


@nb.njit(cache=True, inline="always")
def _clamp01(v):
    return min(max(v, 0.0), 1.0)


@nb.njit(cache=True, inline="always")
def _sub(X, i, j):
    """X[i] - X[j] as scalars (rows of a (m, 3) array: no views, no allocation)."""
    return X[i, 0] - X[j, 0], X[i, 1] - X[j, 1], X[i, 2] - X[j, 2]


@nb.njit(cache=True, inline="always")
def closest_point_segment(X, p, a, b):
    """Parameter t in [0, 1] of the point of segment X[a] X[b] closest to X[p] (rows of X; 0 for
    a degenerate segment)."""
    dx, dy, dz = _sub(X, b, a)
    dd = dx * dx + dy * dy + dz * dz
    if dd <= TINY:
        return 0.0
    vx, vy, vz = _sub(X, p, a)
    return _clamp01((vx * dx + vy * dy + vz * dz) / dd)


@nb.njit(cache=True, inline="always")
def closest_segment_segment(X, p1, q1, p2, q2):
    """Parameters (s, t) of the closest points X[p1] + s (X[q1] - X[p1]) and X[p2] + t (X[q2] - X[p2])
    (rows of X; Ericson, Real-Time Collision Detection §5.1.9). Degenerate segments reduce to
    point-segment; parallel ones (sin^2 of the angle <= PARALLEL) take s at the middle of the
    overlap of segment 2 projected on segment 1, so a contact along parallel capsules acts at its
    centre."""
    d1x, d1y, d1z = _sub(X, q1, p1)
    d2x, d2y, d2z = _sub(X, q2, p2)
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    if a <= TINY:
        return 0.0, closest_point_segment(X, p1, p2, q2)
    if e <= TINY:
        return closest_point_segment(X, p2, p1, q1), 0.0
    rx, ry, rz = _sub(X, p1, p2)
    b = d1x * d2x + d1y * d2y + d1z * d2z
    c = d1x * rx + d1y * ry + d1z * rz
    f = d2x * rx + d2y * ry + d2z * rz
    den = a * e - b * b
    if den <= PARALLEL * a * e:
        s0 = -c / a
        s1 = (b - c) / a
        s = _clamp01(0.5 * (max(min(s0, s1), 0.0) + min(max(s0, s1), 1.0)))
    else:
        s = _clamp01((b * f - c * e) / den)
    t = (b * s + f) / e
    if t < 0.0:
        return closest_point_segment(X, p2, p1, q1), 0.0
    if t > 1.0:
        return closest_point_segment(X, q2, p1, q1), 1.0
    return s, t


@nb.njit(cache=True, inline="always")
def _gap(X, p1, q1, p2, q2, s, t):
    """(X[p2] + t d2) - (X[p1] + s d1): from the point at s on segment 1 to the point at t on 2."""
    d1x, d1y, d1z = _sub(X, q1, p1)
    d2x, d2y, d2z = _sub(X, q2, p2)
    return (X[p2, 0] + t * d2x - (X[p1, 0] + s * d1x), X[p2, 1] + t * d2y - (X[p1, 1] + s * d1y),
            X[p2, 2] + t * d2z - (X[p1, 2] + s * d1z))


@nb.njit(cache=True, inline="always")
def _perp(ux, uy, uz):
    """A unit vector perpendicular to the non-zero u: u x e_k, e_k its least aligned axis."""
    ax, ay, az = abs(ux), abs(uy), abs(uz)
    if ax <= ay and ax <= az:
        vx, vy, vz = 0.0, uz, -uy
    elif ay <= az:
        vx, vy, vz = -uz, 0.0, ux
    else:
        vx, vy, vz = uy, -ux, 0.0
    m = np.sqrt(vx * vx + vy * vy + vz * vz)
    return vx / m, vy / m, vz / m


@nb.njit(cache=True, inline="always")
def capsule_contact(X, p1, q1, r1, p2, q2, r2):
    """(s, t, nx, ny, nz, phi) of the capsules of radii r1, r2 around segments X[p1] X[q1] and
    X[p2] X[q2]: closest parameters, unit normal from 1 to 2 and penetration phi (Eq. 3). When the
    axes touch (distance <= 1e-12 (r1 + r2)) the normal is d1 x d2, or perpendicular to the axes
    when they are parallel, turned towards centre 2."""
    s, t = closest_segment_segment(X, p1, q1, p2, q2)
    nx, ny, nz = _gap(X, p1, q1, p2, q2, s, t)
    dist = np.sqrt(nx * nx + ny * ny + nz * nz)
    if dist > 1e-12 * (r1 + r2):
        return s, t, nx / dist, ny / dist, nz / dist, max(r1 + r2 - dist, 0.0)
    d1x, d1y, d1z = _sub(X, q1, p1)
    d2x, d2y, d2z = _sub(X, q2, p2)
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    cx, cy, cz = d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x
    cc = cx * cx + cy * cy + cz * cz
    if cc > PARALLEL * a * e and a > TINY and e > TINY:
        m = np.sqrt(cc)
        nx, ny, nz = cx / m, cy / m, cz / m
    elif a > TINY:
        nx, ny, nz = _perp(d1x, d1y, d1z)
    elif e > TINY:
        nx, ny, nz = _perp(d2x, d2y, d2z)
    else:
        nx, ny, nz = 0.0, 0.0, 1.0
    ox, oy, oz = _sub(X, p2, p1)
    qx, qy, qz = _sub(X, q2, q1)
    if nx * (ox + qx) + ny * (oy + qy) + nz * (oz + qz) < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    return s, t, nx, ny, nz, max(r1 + r2 - dist, 0.0)


def _clamp01_ref(v):
    return np.clip(v, 0.0, 1.0)


def _dot(u, v):
    return u[:, 0] * v[:, 0] + u[:, 1] * v[:, 1] + u[:, 2] * v[:, 2]


def closest_point_segment_reference(p, a, b):
    """Vectorised :func:`closest_point_segment` (rows are points and segments)."""
    d = b - a
    dd = _dot(d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(dd <= TINY, 0.0, _clamp01_ref(_dot(p - a, d) / dd))


def closest_segment_segment_reference(p1, q1, p2, q2):
    """Vectorised :func:`closest_segment_segment` (rows are segment pairs)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b, c, f = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2), _dot(d1, r), _dot(d2, r)
    den = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s0, s1 = -c / a, (b - c) / a
        s_par = _clamp01_ref(0.5 * (np.maximum(np.minimum(s0, s1), 0.0) + np.minimum(np.maximum(s0, s1), 1.0)))
        s = np.where(den <= PARALLEL * a * e, s_par, _clamp01_ref((b * f - c * e) / den))
        t = (b * s + f) / e
    s = np.where(t < 0.0, closest_point_segment_reference(p2, p1, q1),
                 np.where(t > 1.0, closest_point_segment_reference(q2, p1, q1), s))
    t = _clamp01_ref(t)
    s_deg1 = np.where(e <= TINY, closest_point_segment_reference(p2, p1, q1), s)
    t = np.where(e <= TINY, 0.0, t)
    s = np.where(a <= TINY, 0.0, s_deg1)
    t = np.where(a <= TINY, closest_point_segment_reference(p1, p2, q2), t)
    return s, t


def _perp_reference(u):
    k = np.argmin(np.abs(u), axis=1)
    axis = np.eye(3)[k]
    v = np.cross(u, axis)
    return v / np.linalg.norm(v, axis=1)[:, None]


def capsule_contact_reference(p1, q1, r1, p2, q2, r2):
    """Vectorised :func:`capsule_contact`: (s, t, n (m, 3), phi)."""
    s, t = closest_segment_segment_reference(p1, q1, p2, q2)
    d1, d2 = q1 - p1, q2 - p2
    diff = (p2 + t[:, None] * d2) - (p1 + s[:, None] * d1)
    dist = np.sqrt(_dot(diff, diff))
    a, e = _dot(d1, d1), _dot(d2, d2)
    cr = np.cross(d1, d2)
    cc = _dot(cr, cr)
    with np.errstate(divide="ignore", invalid="ignore"):
        fall = np.where((cc > PARALLEL * a * e)[:, None] & (a > TINY)[:, None] & (e > TINY)[:, None],
                        cr / np.sqrt(cc)[:, None],
                        np.where((a > TINY)[:, None], _perp_reference(d1),
                                 np.where((e > TINY)[:, None], _perp_reference(d2), [0.0, 0.0, 1.0])))
        o = (p2 - p1) + (q2 - q1)
        fall = np.where((_dot(fall, o) < 0.0)[:, None], -fall, fall)
        n = np.where((dist > 1e-12 * (r1 + r2))[:, None], diff / dist[:, None], fall)
    return s, t, n, np.maximum(r1 + r2 - dist, 0.0)
