"""Colliders: solid obstacles that particles stay outside of (woodstock §5.4, Eqs. 3-4).

A float64 table (k, COLLIDER_COLUMNS), one solid obstacle per row, unused columns 0; particles are
kept outside each at a clearance of their radius:

    PLANE     [0, px, py, pz, nx, ny, nz, 0, 0, 0]   a point, the unit normal (solid opposite n)
    BOX       [1, x0, y0, z0, x1, y1, z1, 0, 0, 0]   axis-aligned, min and max corners
    SPHERE    [2, cx, cy, cz, R,  0,  0,  0, 0, 0]   centre, radius
    CYLINDER  [3, ax, ay, az, bx, by, bz, R, 0, 0]   axis end points, radius; flat end caps

Each particle takes the implicit penalty step of Eq. 4 (the secant-compliance XPBD step of
:mod:`.capsules`) along the collider normal, with phi = particle_radius - sd (sd the signed
distance to the solid, :func:`collider_distance`) and W = w_p, one collider after the other.

Depenetration and restitution. A particle's correction may remove all the penetration made in this
substep and at most ``max_push`` (v_depenetration dt) of the penetration it started the substep
with (:func:`_allowed`). After the velocity update, every particle loses its outward normal
velocity at each collider it touched in the substep (:func:`collider_velocities`; restitution 0).

The kernels loop over particles, each writing only its own, so results are bit-identical for any
thread count. Each kernel's plain numpy twin ``*_reference`` is the version the tests compare
against.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .capsules import _dlambda
from .closest import _dot, _perp, _perp_reference

PLANE, BOX, SPHERE, CYLINDER = 0, 1, 2, 3
#: columns of a collider row: the kind, then up to 8 parameters (module docstring)
COLLIDER_COLUMNS = 10
#: parameters used by each kind
COLLIDER_PARAMS = {PLANE: 6, BOX: 6, SPHERE: 4, CYLINDER: 7}


def collider_row(kind: int, *params: float) -> np.ndarray:
    """One collider row (module docstring); a plane's normal is normalised."""
    if kind not in COLLIDER_PARAMS or len(params) != COLLIDER_PARAMS[kind]:
        raise ValueError(f"collider kind {kind} takes {COLLIDER_PARAMS.get(kind)} parameters, got {len(params)}")
    row = np.zeros(COLLIDER_COLUMNS)
    row[0] = kind
    row[1:1 + len(params)] = params
    if kind == PLANE:
        row[4:7] /= np.linalg.norm(row[4:7])
    return row


@nb.njit(cache=True)
def collider_distance(colliders, c, px, py, pz):
    """(sd, nx, ny, nz): signed distance of point p to the solid of collider row c (negative
    inside) and the unit outward normal of the closest surface point. Inside a box the nearest
    face wins (ties: x before y before z, min side first)."""
    kind = int(colliders[c, 0])
    ax, ay, az = colliders[c, 1], colliders[c, 2], colliders[c, 3]  # point, min corner, centre, end
    bx, by, bz = colliders[c, 4], colliders[c, 5], colliders[c, 6]  # normal, max corner, end
    if kind == PLANE:
        return (px - ax) * bx + (py - ay) * by + (pz - az) * bz, bx, by, bz
    if kind == BOX:
        dx, dy, dz = px - min(max(px, ax), bx), py - min(max(py, ay), by), pz - min(max(pz, az), bz)
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > 0.0:
            return d, dx / d, dy / d, dz / d
        depth = (px - ax, bx - px, py - ay, by - py, pz - az, bz - pz)
        f = 0
        for k in range(1, 6):
            if depth[k] < depth[f]:
                f = k
        sgn = 1.0 if f % 2 else -1.0
        return -depth[f], sgn * (f // 2 == 0), sgn * (f // 2 == 1), sgn * (f // 2 == 2)
    if kind == SPHERE:
        dx, dy, dz = px - ax, py - ay, pz - az
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > 0.0:
            return d - bx, dx / d, dy / d, dz / d
        return -bx, 0.0, 0.0, 1.0
    # CYLINDER from a to b: axial coordinate t along u, radial distance rho
    ux, uy, uz = bx - ax, by - ay, bz - az
    h = np.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / h, uy / h, uz / h
    vx, vy, vz = px - ax, py - ay, pz - az
    t = vx * ux + vy * uy + vz * uz
    rx, ry, rz = vx - t * ux, vy - t * uy, vz - t * uz
    rho = np.sqrt(rx * rx + ry * ry + rz * rz)
    if rho > 0.0:
        ex, ey, ez = rx / rho, ry / rho, rz / rho
    else:
        ex, ey, ez = _perp(ux, uy, uz)
    dr = rho - colliders[c, 7]
    if t < 0.5 * h:
        dz, cx, cy, cz = -t, -ux, -uy, -uz
    else:
        dz, cx, cy, cz = t - h, ux, uy, uz
    if dr > 0.0 or dz > 0.0:
        a, b = max(dr, 0.0), max(dz, 0.0)
        d = np.sqrt(a * a + b * b)
        return d, (a * ex + b * cx) / d, (a * ey + b * cy) / d, (a * ez + b * cz) / d
    if dr > dz:
        return dr, ex, ey, ez
    return dz, cx, cy, cz


@nb.njit(cache=True, inline="always")
def _allowed(ph, ph_prev, max_push):
    """Largest correction of a penetration ph that had been ph_prev at the start of the substep:
    all the penetration made in this substep, and at most max_push of the one it started with."""
    return max(ph - max(ph_prev - max_push, 0.0), 0.0)


@nb.njit(parallel=True, cache=True)
def _colliders_kernel(x, x_prev, w_p, particle_radius, colliders, k_col, dt, max_push, force, n_active, pen,
                      touched):
    """Per particle, collider after collider: the XPBD step of phi = particle_radius - sd, its
    correction capped at max_push, or at :func:`_allowed` with the start-of-substep positions
    ``x_prev`` ((0, 3): none); ``touched`` (P, k) (or (0, k)) set where phi > 0."""
    dt2 = dt * dt
    for p in nb.prange(len(x)):
        na = 0
        mp = 0.0
        for c in range(len(colliders)):
            sd, nx, ny, nz = collider_distance(colliders, c, x[p, 0], x[p, 1], x[p, 2])
            ph = particle_radius[p] - sd
            if ph <= 0.0:
                continue
            na += 1
            mp = max(mp, ph)
            if len(touched) > 0:
                touched[p, c] = True
            dl = _dlambda(ph, w_p[p], k_col, dt2)
            cap = max_push
            if len(x_prev) > 0:
                sd0 = collider_distance(colliders, c, x_prev[p, 0], x_prev[p, 1], x_prev[p, 2])[0]
                cap = _allowed(ph, particle_radius[p] - sd0, max_push)
            if w_p[p] * dl > cap:
                dl = cap / w_p[p]
            x[p, 0] += w_p[p] * dl * nx
            x[p, 1] += w_p[p] * dl * ny
            x[p, 2] += w_p[p] * dl * nz
            force[p] += dl / dt2
        n_active[p] = na
        pen[p] = mp


@nb.njit(parallel=True, cache=True)
def _collider_separation(x, v, w_p, colliders, touched, changed):
    """Per particle and touched collider: remove the outward normal velocity at the end position."""
    for p in nb.prange(len(x)):
        changed[p] = False
        if w_p[p] == 0.0:
            continue
        for c in range(len(colliders)):
            if not touched[p, c]:
                continue
            _, nx, ny, nz = collider_distance(colliders, c, x[p, 0], x[p, 1], x[p, 2])
            vn = v[p, 0] * nx + v[p, 1] * ny + v[p, 2] * nz
            if vn > 0.0:
                v[p, 0] -= vn * nx
                v[p, 1] -= vn * ny
                v[p, 2] -= vn * nz
                changed[p] = True


def check_colliders(colliders) -> None:
    """Raise ValueError unless ``colliders`` are collider rows: shape, kinds, unit plane normals and
    cylinders of positive length."""
    if colliders.ndim != 2 or colliders.shape[1] != COLLIDER_COLUMNS:
        raise ValueError(f"colliders must be (k, {COLLIDER_COLUMNS}), got {colliders.shape}")
    kind = colliders[:, 0]
    if not np.isin(kind, list(COLLIDER_PARAMS)).all():
        raise ValueError(f"collider kinds must be in {sorted(COLLIDER_PARAMS)}")
    if not np.allclose(np.linalg.norm(colliders[kind == PLANE, 4:7], axis=1), 1.0, atol=1e-9):
        raise ValueError("plane normals must be unit vectors")
    cyl = colliders[kind == CYLINDER]
    if not (np.linalg.norm(cyl[:, 4:7] - cyl[:, 1:4], axis=1) > 0.0).all():
        raise ValueError("cylinder end points must differ")


def _rows(x_prev) -> np.ndarray:
    return np.zeros((0, 3)) if x_prev is None else x_prev


def project_colliders(x, w_p, particle_radius, colliders, k_col, dt, force, max_push: float = np.inf,
                      x_prev=None, touched=None, checked: bool = False) -> tuple[int, float]:
    """Keep each particle outside every collider at clearance ``particle_radius`` (P,): per
    particle, one collider after the other, phi = particle_radius - sd and the secant-compliance
    XPBD step along the collider normal with W = w_p (module docstring). Moves ``x`` in place,
    adds the normal force dlambda / dt^2 to ``force``. ``max_push`` caps each correction; with the
    start-of-substep positions ``x_prev`` (P, 3) it caps only the removal of the penetration the
    particle had there; friction follows all normal steps
    (:func:`.friction.particle_friction`). ``touched`` (P, k) bool, if given, is set where phi > 0 (for
    :func:`collider_velocities`). Returns (number of particle-collider contacts with phi > 0,
    largest phi); k_col <= 0 or no colliders: nothing, (0, 0.0). ``checked``: the rows passed
    :func:`check_colliders` already (the mechanics setup checks its own once, not every substep:
    the check cost 6% of a log bake)."""
    if k_col <= 0.0 or len(colliders) == 0 or len(x) == 0:
        return 0, 0.0
    if not checked:
        check_colliders(colliders)
    n_active, pen = np.empty(len(x), dtype=np.int64), np.empty(len(x))
    hit = np.zeros((0, len(colliders)), dtype=np.bool_) if touched is None else touched
    _colliders_kernel(x, _rows(x_prev), w_p, particle_radius, colliders, float(k_col), float(dt), float(max_push),
                      force, n_active, pen, hit)
    return int(n_active.sum()), float(pen.max())


def collider_velocities(v, x, w_p, colliders, touched) -> int:
    """Inelastic collider contacts (restitution 0): every free particle removes the outward
    normal velocity max(v . n, 0) n of each collider it ``touched`` (P, k) in this substep, the
    normal taken at its end position ``x``, collider after collider. Changes ``v`` in place;
    returns the number of particles changed."""
    if len(colliders) == 0 or len(x) == 0 or not touched.any():
        return 0
    changed = np.empty(len(x), dtype=np.bool_)
    _collider_separation(x, v, w_p, colliders, touched, changed)
    return int(changed.sum())


def collider_velocities_reference(v, x, w_p, colliders, touched) -> int:
    """numpy version of :func:`collider_velocities`."""
    if len(colliders) == 0 or len(x) == 0 or not touched.any():
        return 0
    changed = np.zeros(len(x), dtype=bool)
    for c, row in enumerate(colliders):
        _, n = collider_distance_reference(row, x)
        vn = _dot(v, n)
        sel = touched[:, c] & (w_p > 0.0) & (vn > 0.0)
        v[sel] -= vn[sel, None] * n[sel]
        changed |= sel
    return int(changed.sum())


def collider_distance_reference(row, p):
    """Vectorised :func:`collider_distance`: (sd (m,), n (m, 3))."""
    kind = int(row[0])
    if kind == PLANE:
        n = np.broadcast_to(row[4:7], p.shape)
        return _dot(p - row[1:4], n), n
    if kind == BOX:
        d = p - np.clip(p, row[1:4], row[4:7])
        dist = np.sqrt(_dot(d, d))
        depth = np.concatenate([p - row[1:4], row[4:7] - p], axis=1)[:, [0, 3, 1, 4, 2, 5]]
        f = np.argmin(depth, axis=1)
        n_in = np.zeros_like(p)
        n_in[np.arange(len(p)), f // 2] = np.where(f % 2 == 1, 1.0, -1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = dist > 0.0
            return np.where(out, dist, -depth.min(axis=1)), np.where(out[:, None], d / dist[:, None], n_in)
    if kind == SPHERE:
        d = p - row[1:4]
        dist = np.sqrt(_dot(d, d))
        with np.errstate(divide="ignore", invalid="ignore"):
            return dist - row[4], np.where((dist > 0.0)[:, None], d / dist[:, None], [0.0, 0.0, 1.0])
    u = row[4:7] - row[1:4]
    h = np.sqrt(u @ u)
    u = u / h
    v = p - row[1:4]
    t = v[:, 0] * u[0] + v[:, 1] * u[1] + v[:, 2] * u[2]
    r = v - t[:, None] * u
    rho = np.sqrt(_dot(r, r))
    with np.errstate(divide="ignore", invalid="ignore"):
        er = np.where((rho > 0.0)[:, None], r / rho[:, None], _perp_reference(u[None])[0])
        dr = rho - row[7]
        low = t < 0.5 * h
        dz = np.where(low, -t, t - h)
        ec = np.where(low[:, None], -u, u)
        a, b = np.maximum(dr, 0.0), np.maximum(dz, 0.0)
        d = np.sqrt(a * a + b * b)
        n_out = (a[:, None] * er + b[:, None] * ec) / d[:, None]
    outside = (dr > 0.0) | (dz > 0.0)
    sd = np.where(outside, d, np.maximum(dr, dz))
    n = np.where(outside[:, None], n_out, np.where((dr > dz)[:, None], er, ec))
    return sd, n


def project_colliders_reference(x, w_p, particle_radius, colliders, k_col, dt, force, max_push: float = np.inf,
                                x_prev=None, touched=None) -> tuple[int, float]:
    """numpy version of :func:`project_colliders`."""
    if k_col <= 0.0 or len(colliders) == 0 or len(x) == 0:
        return 0, 0.0
    check_colliders(colliders)
    dt2 = dt * dt
    n_active, pen = 0, 0.0
    for c, row in enumerate(colliders):
        sd, n = collider_distance_reference(row, x)
        ph = particle_radius - sd
        act = ph > 0.0
        if not act.any():
            continue
        if touched is not None:
            touched[act, c] = True
        n_active += int(act.sum())
        pen = max(pen, float(ph[act].max()))
        w, ph, n = w_p[act], ph[act], n[act]
        dl = k_col * ph * ph * dt2 / (1.0 + w * k_col * ph * dt2)
        cap = np.full(len(dl), float(max_push))
        if x_prev is not None:
            prev = particle_radius[act] - collider_distance_reference(row, x_prev[act])[0]
            cap = np.maximum(ph - np.maximum(prev - max_push, 0.0), 0.0)
        over = w * dl > cap
        dl[over] = cap[over] / w[over]
        x[act] += (w * dl)[:, None] * n
        force[act] += dl / dt2
    return n_active, pen
