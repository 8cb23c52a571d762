"""Capsule contact between detached components (woodstock §5.4, Eqs. 3-4).

For elements i, j of different components (pairs of :func:`.broadphase.candidate_pairs`) with
closest points at parameters s on i and t on j, penetration phi_ij (Eq. 3,
:func:`.closest.capsule_contact`) and n_ij the unit direction from i to j:

    F_i = -k_col phi_ij^2 n_ij,   F_j = -F_i        (Eq. 4)

Implicit penalty. At dt = 0.01 s an explicit quadratic penalty is unstable, so Eq. 4 is applied as
an XPBD compliant constraint C = phi with the secant compliance alpha = 1 / (k_col phi). One XPBD
step from lambda = 0 gives

    dlambda = phi / (W + alpha / dt^2) = k_col phi^2 dt^2 / (1 + W k_col phi dt^2),
    W = sum_k w_k g_k^2,   g = (1 - s, s) on the particles of i, (1 - t, t) on those of j,

and moves particle k of i by -w_k g_k dlambda n_ij and particle k of j by +w_k g_k dlambda n_ij. The
constraint force dlambda / dt^2 tends to phi / alpha = k_col phi^2 at rest: the force of Eq. 4
(a particle resting on the ground settles at phi = sqrt(m g / k_col)). Pairs are projected together
(Jacobi): the corrections of each pair are computed independently, then every particle sums its
own in a fixed order (CSR of particle -> pair incidences by pair index) and divides by the number
of active contacts it takes part in (constraint averaging), so the result is bit-identical for any
thread count. Colliders take the same step (:mod:`.colliders`); friction follows all normal steps
(:mod:`.friction`).

Depenetration. A pair's correction is bounded only within its protected overlap (``protect`` of
:func:`project_contacts`): the overlap beyond phi_rest it had when its elements fell into different
components (shrinkage or a deformation had brought them closer than at rest), which shrinks by
max_push (v_depenetration dt) per projection whatever loads the pair, so capsules that overlap when
their connection breaks part gently, while a new or loaded penetration is resolved at once. A cap
on every pair's correction would also bound the force a resting pair carries, to
v_depenetration / (W dt), about 1 N, and heavy pieces would sink into each other
(docs/decisions.md, "Separation overlap"). After the velocity update, every pair touched in the
substep loses its separating normal velocity (:func:`contact_velocities`; restitution 0): the
position step that resolves a penetration would otherwise turn it into an outward velocity (a
bounce that grows with k_col).

Rest overlap. Capsules of neighbouring strands overlap in the intact wood (strands converge
between profiles: up to 1.5 r_s at rest spacing). That overlap is the wood's own volume, not an
interpenetration: when a crack separates the two elements, pushing it out would drive the pieces
apart against friction for ever (the capped push moves a piece by its contact particle's share of
its mass per substep, less than ground friction takes back), feeding a jitter that never
settles. So a pair's phi counts only beyond ``phi_rest``, its overlap at the rest positions
(:func:`pair_overlaps`, zero for elements that were apart): broken pieces fit back together as
they were, and every other contact is the plain Eq. 3.

Each kernel's plain numpy twin ``*_reference`` is the version the tests compare against.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .closest import _dot, capsule_contact, capsule_contact_reference


@nb.njit(cache=True, inline="always")
def _dlambda(phi, W, k_col, dt2):
    """XPBD multiplier of C = phi with compliance alpha = 1 / (k_col phi): phi / (W + alpha / dt^2)."""
    return k_col * phi * phi * dt2 / (1.0 + W * k_col * phi * dt2)


@nb.njit(parallel=True, cache=True)
def _pair_multipliers(x, w_p, first_particle, radius, pairs, phi_rest, protect, k_col, dt, max_push, pc, phi):
    """Per pair: penetration phi (Eq. 3) beyond the pair's rest overlap ``phi_rest`` and ``pc`` =
    (e, dlambda, s, t), e the correction per unit w_k g_k of j's particles (i's: -e): dlambda n_ij
    (dlambda 0, e 0 if inactive). The relative correction W dlambda is capped at max_push, or
    with ``protect`` (k,) (not (0,)) at phi - protect after lowering the pair's protected overlap
    to max(min(protect, phi) - max_push, 0) (written back)."""
    dt2 = dt * dt
    for q in nb.prange(len(pairs)):
        i, j = pairs[q, 0], pairs[q, 1]
        a, b = first_particle[i], first_particle[j]
        s, t, nx, ny, nz, ph = capsule_contact(x, a, a + 1, radius[i], b, b + 1, radius[j])
        ph -= phi_rest[q]
        W = (w_p[a] * (1.0 - s) * (1.0 - s) + w_p[a + 1] * s * s + w_p[b] * (1.0 - t) * (1.0 - t)
             + w_p[b + 1] * t * t)
        phi[q] = ph
        dl = _dlambda(ph, W, k_col, dt2) if ph > 0.0 and W > 0.0 else 0.0  # W = 0: both pinned
        cap = max_push
        if len(protect) > 0:
            protect[q] = max(min(protect[q], ph) - max_push, 0.0)
            cap = max(ph - protect[q], 0.0)
        if W * dl > cap:  # depenetration cap
            dl = cap / W
        pc[q, 0], pc[q, 1], pc[q, 2] = dl * nx, dl * ny, dl * nz
        pc[q, 3], pc[q, 4], pc[q, 5] = dl, s, t


@nb.njit(cache=True)
def _incidences(pairs, first_particle, active, indptr, inc):
    """CSR particle -> incidences q * 4 + slot of the ``active`` pairs, increasing q in each row
    (a counting sort; ``indptr`` (P + 1,) zeros on entry, ``inc`` (4 len(active),))."""
    for q in active:
        a, b = first_particle[pairs[q, 0]], first_particle[pairs[q, 1]]
        for p in (a, a + 1, b, b + 1):
            indptr[p] += 1
    for p in range(len(indptr) - 1):
        indptr[p + 1] += indptr[p]
    for u in range(len(active) - 1, -1, -1):  # indptr[p] ends as the first slot of row p
        q = active[u]
        a, b = first_particle[pairs[q, 0]], first_particle[pairs[q, 1]]
        parts = (a, a + 1, b, b + 1)
        for k in range(3, -1, -1):
            indptr[parts[k]] -= 1
            inc[indptr[parts[k]]] = q * 4 + k


@nb.njit(parallel=True, cache=True)
def _gather(x, w_p, force, indptr, inc, pc, dt):
    """Per particle, over its incidences (pair q, slot k) in CSR order: x += mean of the
    corrections -+ w g_k e_q (- on i's particles, slots 0-1; e_q = pc[q, :3]), force += sum of
    g_k dlambda_q / dt^2 (dlambda_q = pc[q, 3])."""
    dt2 = dt * dt
    for p in nb.prange(len(x)):
        lo, hi = indptr[p], indptr[p + 1]
        if hi == lo:
            continue
        ax = ay = az = f = 0.0
        for e in range(lo, hi):
            q, k = inc[e] // 4, inc[e] % 4
            u = pc[q, 4] if k < 2 else pc[q, 5]
            g = u if k % 2 else 1.0 - u
            c = (-1.0 if k < 2 else 1.0) * w_p[p] * g
            ax += c * pc[q, 0]
            ay += c * pc[q, 1]
            az += c * pc[q, 2]
            f += g * pc[q, 3] / dt2
        cnt = hi - lo
        x[p, 0] += ax / cnt
        x[p, 1] += ay / cnt
        x[p, 2] += az / cnt
        force[p] += f


def _rest(phi_rest, k: int) -> np.ndarray:
    return np.zeros(k) if phi_rest is None else np.ascontiguousarray(phi_rest, dtype=np.float64)


@nb.njit(parallel=True, cache=True)
def _overlaps(x, first_particle, radius, pairs, out):
    for q in nb.prange(len(pairs)):
        i, j = pairs[q, 0], pairs[q, 1]
        a, b = first_particle[i], first_particle[j]
        out[q] = capsule_contact(x, a, a + 1, radius[i], b, b + 1, radius[j])[5]


def pair_overlaps(x, first_particle, radius, pairs) -> np.ndarray:
    """(k,) overlap phi (Eq. 3) of each capsule pair of ``pairs`` at the positions ``x``."""
    out = np.empty(len(pairs))
    _overlaps(x, first_particle, radius, pairs, out)
    return out


def project_contacts(x, w_p, first_particle, radius, pairs, k_col, dt, force,
                     max_push: float = np.inf, touched=None, phi_rest=None, protect=None) -> tuple[int, float]:
    """One Jacobi XPBD projection of the capsule contacts of ``pairs`` (k, 2) (element pairs i, j
    as from :func:`.broadphase.candidate_pairs`; Eqs. 3-4, module docstring).

    Moves ``x`` (P, 3) in place (particles with w_p = 0 never move) and adds to ``force`` (P,) the
    normal force magnitude g_k dlambda / dt^2 each particle receives. ``max_push`` caps a pair's
    relative correction per projection (a depenetration speed times dt: capsules that overlap when
    their connection breaks, up to 1.5 r_s at rest spacing, part gently instead of exploding).
    Friction is not part of it (:func:`.friction.particle_friction`, after all normal steps).
    ``touched`` (k,) bool, if given, is or-ed with the pairs that had phi > 0 (for
    :func:`contact_velocities`).
    ``phi_rest`` (k,), if given, is each pair's overlap in the rest state (:func:`pair_overlaps`
    of the rest positions, module docstring "Rest overlap"); phi counts only beyond it.
    ``protect`` (k,), if given, replaces that cap: each pair's protected overlap beyond
    phi_rest (the overlap it had when its elements separated, module docstring "Depenetration"),
    first lowered in place to max(min(protect, phi) - max_push, 0), so that it shrinks by
    ``max_push`` per projection whatever loads the pair; the correction may remove all the
    penetration beyond it. Returns (number of pairs with phi > 0, largest phi), measured on the positions before the
    projection; k_col <= 0 means no contact: nothing changes and (0, 0.0) is returned."""
    if k_col <= 0.0 or len(pairs) == 0:
        return 0, 0.0
    pc, phi = np.empty((len(pairs), 6)), np.empty(len(pairs))
    prot = np.zeros(0) if protect is None else protect
    _pair_multipliers(x, w_p, first_particle, radius, pairs, _rest(phi_rest, len(pairs)), prot, float(k_col),
                      float(dt), float(max_push), pc, phi)
    if touched is not None:
        touched |= phi > 0.0
    active = np.flatnonzero(phi > 0.0)
    indptr, inc = np.zeros(len(x) + 1, dtype=np.int64), np.empty(4 * len(active), dtype=np.int64)
    _incidences(pairs, first_particle, active, indptr, inc)
    _gather(x, w_p, force, indptr, inc, pc, float(dt))
    return len(active), float(phi.max())


def _pair_geometry_reference(x, w_p, first_particle, radius, pairs):
    """Per pair: particles (k, 4), weights g (k, 4), inverse masses (k, 4), W, n, phi."""
    a, b = first_particle[pairs[:, 0]], first_particle[pairs[:, 1]]
    s, t, n, phi = capsule_contact_reference(x[a], x[a + 1], radius[pairs[:, 0]], x[b], x[b + 1], radius[pairs[:, 1]])
    parts = np.stack([a, a + 1, b, b + 1], axis=1)
    g = np.stack([1.0 - s, s, 1.0 - t, t], axis=1)
    w = w_p[parts]
    return parts, g, w, np.sum(w * g * g, axis=1), n, phi


def _jacobi_reference(y, parts, g, w, e, dl=None, force=None, dt=1.0):
    """Add to the rows of ``y`` the mean over each particle's pairs of -+ w g e (module
    docstring); ``force`` += sum of g dl / dt^2."""
    c = np.array([-1.0, -1.0, 1.0, 1.0]) * w * g
    acc = np.zeros_like(y)
    np.add.at(acc, parts.ravel(), (c[:, :, None] * e[:, None, :]).reshape(-1, 3))
    cnt = np.bincount(parts.ravel(), minlength=len(y))
    hit = cnt > 0
    y[hit] += acc[hit] / cnt[hit, None]
    if force is not None:
        fsum = np.zeros(len(y))
        np.add.at(fsum, parts.ravel(), (g * dl[:, None] / (dt * dt)).ravel())
        force[hit] += fsum[hit]


def _points_reference(y, parts, g):
    """Contact points' relative (j minus i) value of the rows of ``y``."""
    return np.einsum("kj,kjc->kc", g * [-1.0, -1.0, 1.0, 1.0], y[parts])


def project_contacts_reference(x, w_p, first_particle, radius, pairs, k_col, dt, force,
                               max_push: float = np.inf, touched=None, phi_rest=None,
                               protect=None) -> tuple[int, float]:
    """numpy version of :func:`project_contacts`."""
    if k_col <= 0.0 or len(pairs) == 0:
        return 0, 0.0
    parts, g, w, W, n, phi = _pair_geometry_reference(x, w_p, first_particle, radius, pairs)
    rest = _rest(phi_rest, len(pairs))
    phi = phi - rest
    if touched is not None:
        touched |= phi > 0.0
    act = phi > 0.0
    if protect is not None:
        protect[:] = np.maximum(np.minimum(protect, phi) - max_push, 0.0)
    parts, g, w, W, n, ph = parts[act], g[act], w[act], W[act], n[act], phi[act]
    dt2 = dt * dt
    dl = np.where(W > 0.0, k_col * ph * ph * dt2 / (1.0 + W * k_col * ph * dt2), 0.0)  # W = 0: both pinned
    cap = np.full(len(dl), float(max_push))
    if protect is not None:
        cap = np.maximum(ph - protect[act], 0.0)
    over = W * dl > cap
    dl[over] = cap[over] / W[over]
    _jacobi_reference(x, parts, g, w, dl[:, None] * n, dl, force, dt)
    return int(act.sum()), float(phi.max())


@nb.njit(parallel=True, cache=True)
def _pair_separation(x, v, w_p, first_particle, radius, pairs, touched, pc, sep):
    """Per touched pair, at the positions ``x``: ``pc`` = (n_ij, -v_n / W, s, t) and sep = True
    where the pair separates at v_n = n_ij . (v_j(t) - v_i(s)) > 0."""
    for q in nb.prange(len(pairs)):
        sep[q] = False
        if not touched[q]:
            continue
        i, j = pairs[q, 0], pairs[q, 1]
        a, b = first_particle[i], first_particle[j]
        s, t, nx, ny, nz, _ = capsule_contact(x, a, a + 1, radius[i], b, b + 1, radius[j])
        W = (w_p[a] * (1.0 - s) * (1.0 - s) + w_p[a + 1] * s * s + w_p[b] * (1.0 - t) * (1.0 - t)
             + w_p[b + 1] * t * t)
        vn = 0.0
        for k, c in ((0, nx), (1, ny), (2, nz)):
            vn += c * ((1.0 - t) * v[b, k] + t * v[b + 1, k] - (1.0 - s) * v[a, k] - s * v[a + 1, k])
        if vn > 0.0 and W > 0.0:
            sep[q] = True
            pc[q, 0], pc[q, 1], pc[q, 2] = -vn / W * nx, -vn / W * ny, -vn / W * nz
            pc[q, 3], pc[q, 4], pc[q, 5] = 0.0, s, t


def contact_velocities(v, x, w_p, first_particle, radius, pairs, touched) -> int:
    """Inelastic capsule contacts (restitution 0, module docstring "Depenetration"): for every
    pair with ``touched`` (k,) set (phi > 0 in a projection of this substep), the separating
    relative normal velocity v_n = n_ij . (v_j(t) - v_i(s)) > 0 at the end positions ``x`` is
    removed by the velocity step -+ w_k g_k (v_n / W) n_ij, Jacobi-averaged per particle like the
    position step. Changes ``v`` (P, 3) in place; returns the number of pairs changed."""
    if len(pairs) == 0 or not touched.any():
        return 0
    pc, sep = np.empty((len(pairs), 6)), np.empty(len(pairs), dtype=np.bool_)
    _pair_separation(x, v, w_p, first_particle, radius, pairs, touched, pc, sep)
    active = np.flatnonzero(sep)
    indptr, inc = np.zeros(len(x) + 1, dtype=np.int64), np.empty(4 * len(active), dtype=np.int64)
    _incidences(pairs, first_particle, active, indptr, inc)
    _gather(v, w_p, np.zeros(len(x)), indptr, inc, pc, 1.0)
    return len(active)


def contact_velocities_reference(v, x, w_p, first_particle, radius, pairs, touched) -> int:
    """numpy version of :func:`contact_velocities`."""
    if len(pairs) == 0 or not touched.any():
        return 0
    parts, g, w, W, n, _ = _pair_geometry_reference(x, w_p, first_particle, radius, pairs)
    vn = _dot(_points_reference(v, parts, g), n)
    sep = touched & (vn > 0.0) & (W > 0.0)
    _jacobi_reference(v, parts[sep], g[sep], w[sep], (-vn[sep] / W[sep])[:, None] * n[sep])
    return int(sep.sum())
