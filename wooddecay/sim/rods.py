"""XPBD projections of the rod constraints (woodstock §5.1-5.2, Eqs. 1-2; Kugelstadt and Schoemer
2016, "Position and orientation based Cosserat rods").

Every constraint is projected with the XPBD multiplier update of Eq. 1,

    dlambda = (-C - alpha~ lambda) / (grad C^T M^-1 grad C + alpha~),   alpha~ = alpha / dt^2,

per scalar component, the compliance alpha from the strand's stiffness so that XPBD converges to
the elastic energy 1/2 k C^2 (per length where C is a strain):

* stretch (distance constraint) C = |p_b - p_a| - l_r, alpha = l_r / (E A);
* shear (the d1, d2 components of Kugelstadt's stretch-shear constraint)
  C_k = ((p_b - p_a) / l_r - d3(q)) . d_k, alpha = 1 / (G A l_r). Its d3 component is the stretch,
  which the distance constraint already carries, so it is not projected twice;
* bend-twist between two quaternions C = (2 / l) (Im(conj(q_i) q_j) - s Im(Omega_0)), s = +-1 the
  sign that picks the nearer of +-Omega_0 (Kugelstadt §4.2), alpha = 1 / (k l) with
  k = (E I, E I, G J); used along each strand (consecutive elements) and on REG pairs with their
  rest Darboux vector (Stage 2);
* connection (Eq. 2) on element centres C = |c_j - c_i| - dp, alpha = 1 / k_conn, k_conn the
  pair's stiffness times its integrity I_ij (Eq. 21).

The multipliers start at zero every substep (plain XPBD). Kernels run over one colour class at a time (a set of
constraints that share no particle or quaternion), in parallel: race-free and deterministic.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..quaternion import conj_np, mul, mul_np, normalize_np, pure_np, rotate, rotate_np


@nb.njit(inline="always", cache=True)
def _xpbd(C, lam, W, k, dt):
    """Eq. 1 for one scalar component; k the stiffness (0: inactive). Returns dlambda."""
    if k <= 0.0:
        return 0.0
    at = 1.0 / (k * dt * dt)
    return (-C - at * lam) / (W + at)


@nb.njit(parallel=True, cache=True)
def stretch_shear(elems, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok,
                  lam_s, lam_sh, dt):
    """Distance (stretch) and shear constraints of the elements ``elems`` (one parity class)."""
    for t in nb.prange(len(elems)):
        e = elems[t]
        if not element_ok[e]:
            continue
        a = fp[e]
        b = a + 1
        wa, wb, wq, l = w_p[a], w_p[b], w_q[e], rest_length[e]
        # stretch: C = |p_b - p_a| - l, alpha = l / (E A)
        dx, dy, dz = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2]
        L = math.sqrt(dx * dx + dy * dy + dz * dz)
        if L > 0.0 and wa + wb > 0.0:
            dl = _xpbd(L - l, lam_s[e], wa + wb, k_stretch[e] / l, dt)
            lam_s[e] += dl
            nx, ny, nz = dx / L, dy / L, dz / L
            x[a, 0] -= wa * nx * dl
            x[a, 1] -= wa * ny * dl
            x[a, 2] -= wa * nz * dl
            x[b, 0] += wb * nx * dl
            x[b, 1] += wb * ny * dl
            x[b, 2] += wb * nz * dl
        # shear: C_k = ((p_b - p_a) / l - d3) . d_k, k = 1, 2; alpha = 1 / (G A l)
        q0, q1, q2, q3 = q[e, 0], q[e, 1], q[e, 2], q[e, 3]
        W = (wa + wb) / (l * l) + 4.0 * wq
        if W <= 0.0:
            continue
        gx = (x[b, 0] - x[a, 0]) / l
        gy = (x[b, 1] - x[a, 1]) / l
        gz = (x[b, 2] - x[a, 2]) / l
        d3 = rotate(q0, q1, q2, q3, 0.0, 0.0, 1.0)
        gx, gy, gz = gx - d3[0], gy - d3[1], gz - d3[2]
        d1 = rotate(q0, q1, q2, q3, 1.0, 0.0, 0.0)
        d2 = rotate(q0, q1, q2, q3, 0.0, 1.0, 0.0)
        ks = k_shear[e] * l
        dl1 = _xpbd(gx * d1[0] + gy * d1[1] + gz * d1[2], lam_sh[e, 0], W, ks, dt)
        dl2 = _xpbd(gx * d2[0] + gy * d2[1] + gz * d2[2], lam_sh[e, 1], W, ks, dt)
        lam_sh[e, 0] += dl1
        lam_sh[e, 1] += dl2
        vx = dl1 * d1[0] + dl2 * d2[0]
        vy = dl1 * d1[1] + dl2 * d2[1]
        vz = dl1 * d1[2] + dl2 * d2[2]
        x[a, 0] -= wa * vx / l
        x[a, 1] -= wa * vy / l
        x[a, 2] -= wa * vz / l
        x[b, 0] += wb * vx / l
        x[b, 1] += wb * vy / l
        x[b, 2] += wb * vz / l
        if wq > 0.0:
            # dq = -2 w_q (v q conj(e3)), conj(e3) = (0, 0, 0, -1)
            p = mul(0.0, vx, vy, vz, q0, q1, q2, q3)
            r = mul(p[0], p[1], p[2], p[3], 0.0, 0.0, 0.0, -1.0)
            n0, n1, n2, n3 = q0 - 2 * wq * r[0], q1 - 2 * wq * r[1], q2 - 2 * wq * r[2], q3 - 2 * wq * r[3]
            s = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
            q[e, 0], q[e, 1], q[e, 2], q[e, 3] = n0 * s, n1 * s, n2 * s, n3 * s


@nb.njit(inline="always", cache=True)
def _bend_twist_one(i, j, q, w_q, rest, length, kb, kt, lam, k, dt):
    """Bend-twist constraint between the quaternions of elements i and j (row k of rest / lam)."""
    wi, wj = w_q[i], w_q[j]
    if wi + wj <= 0.0:
        return
    a0, a1, a2, a3 = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    b0, b1, b2, b3 = q[j, 0], q[j, 1], q[j, 2], q[j, 3]
    om = mul(a0, -a1, -a2, -a3, b0, b1, b2, b3)
    r0, r1, r2, r3 = rest[k, 0], rest[k, 1], rest[k, 2], rest[k, 3]
    s = 1.0 if om[0] * r0 + om[1] * r1 + om[2] * r2 + om[3] * r3 >= 0.0 else -1.0
    f = 2.0 / length
    W = f * f * (wi + wj)
    dl0 = _xpbd(f * (om[1] - s * r1), lam[k, 0], W, kb * length, dt)
    dl1 = _xpbd(f * (om[2] - s * r2), lam[k, 1], W, kb * length, dt)
    dl2 = _xpbd(f * (om[3] - s * r3), lam[k, 2], W, kt * length, dt)
    lam[k, 0] += dl0
    lam[k, 1] += dl1
    lam[k, 2] += dl2
    # dq_j = w_j f q_i u, dq_i = -w_i f q_j u, u = (0, dlambda)
    uj = mul(a0, a1, a2, a3, 0.0, dl0, dl1, dl2)
    ui = mul(b0, b1, b2, b3, 0.0, dl0, dl1, dl2)
    # a quaternion of weight 0 (anchored, asleep, held) keeps its bits: renormalising it would
    # move it by an ulp
    if wj > 0.0:
        n0, n1, n2, n3 = b0 + wj * f * uj[0], b1 + wj * f * uj[1], b2 + wj * f * uj[2], b3 + wj * f * uj[3]
        t = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
        q[j, 0], q[j, 1], q[j, 2], q[j, 3] = n0 * t, n1 * t, n2 * t, n3 * t
    if wi > 0.0:
        n0, n1, n2, n3 = a0 - wi * f * ui[0], a1 - wi * f * ui[1], a2 - wi * f * ui[2], a3 - wi * f * ui[3]
        t = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
        q[i, 0], q[i, 1], q[i, 2], q[i, 3] = n0 * t, n1 * t, n2 * t, n3 * t


@nb.njit(parallel=True, cache=True)
def bend_twist(pairs, idx, q, w_q, rest, length, k_bend, k_twist, lam, dt):
    """Bend-twist constraints of ``pairs[idx]`` (one colour class); stiffness 0 disables one."""
    for t in nb.prange(len(idx)):
        k = idx[t]
        _bend_twist_one(pairs[k, 0], pairs[k, 1], q, w_q, rest, length[k], k_bend[k], k_twist[k],
                        lam, k, dt)


#: a colour class of fewer REG edges than this is swept on the calling thread: a parallel
#: region costs about 2 us to start, more than such a class's work (docs/decisions.md, "Small
#: classes on one thread")
PARALLEL_MIN = 96


@nb.njit(parallel=True, cache=True)
def reg_pass(edges, ptr, active, fp, x, q, w_p, w_q, rest_offset, k_conn, rest, length, k_bend, k_twist,
             lam_c, lam_bt, dt, fresh=False):
    """Stage 2, one sweep over the REG edges colour class after colour class: class c is the
    edges ``active[ptr[c]:ptr[c + 1]]`` (positions in colour order, no shared particle,
    :func:`color_edges`), those with a connection, bend or twist stiffness left; on each the
    connection constraint of Eq. 2 on element centres, then the pair's bend-twist coupling where
    it holds. One call per sweep: a call per class (41 per substep on the log) cost 9% of Stage 2;
    a failed edge costs nothing (docs/decisions.md, "One call per Stage 2 sweep"). Classes under
    ``PARALLEL_MIN`` edges run serially: the edges of a class are independent, so the bits are the
    same. ``fresh``: each swept edge's multipliers are set to zero before its projection (the
    substep's first sweep: ``lam_c`` and ``lam_bt`` need not be zeroed beforehand, which
    cost 4.5% of the tree's substep; docs/decisions.md, "Multipliers written, not zeroed")."""
    for c in range(len(ptr) - 1):
        if ptr[c + 1] - ptr[c] < PARALLEL_MIN:
            for t in range(ptr[c], ptr[c + 1]):
                _reg_edge(active[t], edges, fp, x, q, w_p, w_q, rest_offset, k_conn, rest, length, k_bend, k_twist,
                          lam_c, lam_bt, dt, fresh)
        else:
            for t in nb.prange(ptr[c], ptr[c + 1]):
                _reg_edge(active[t], edges, fp, x, q, w_p, w_q, rest_offset, k_conn, rest, length, k_bend, k_twist,
                          lam_c, lam_bt, dt, fresh)


@nb.njit(inline="always", cache=True)
def _reg_edge(k, edges, fp, x, q, w_p, w_q, rest_offset, k_conn, rest, length, k_bend, k_twist, lam_c, lam_bt, dt,
              fresh):
    """:func:`reg_pass` on the edge at colour position ``k``."""
    i, j = edges[k, 0], edges[k, 1]
    ai, aj = fp[i], fp[j]
    bi, bj = ai + 1, aj + 1
    W = 0.25 * (w_p[ai] + w_p[bi] + w_p[aj] + w_p[bj])
    if fresh:  # the substep's first sweep: this edge's multipliers start at zero
        lam_c[k] = lam_bt[k, 0] = lam_bt[k, 1] = lam_bt[k, 2] = 0.0
    if k_conn[k] > 0.0 and W > 0.0:
        dx = 0.5 * (x[aj, 0] + x[bj, 0] - x[ai, 0] - x[bi, 0])
        dy = 0.5 * (x[aj, 1] + x[bj, 1] - x[ai, 1] - x[bi, 1])
        dz = 0.5 * (x[aj, 2] + x[bj, 2] - x[ai, 2] - x[bi, 2])
        L = math.sqrt(dx * dx + dy * dy + dz * dz)
        if L > 0.0:
            dl = _xpbd(L - rest_offset[k], lam_c[k], W, k_conn[k], dt)
            lam_c[k] += dl
            h = 0.5 * dl / L
            for cc, dc in ((0, dx), (1, dy), (2, dz)):
                x[ai, cc] -= w_p[ai] * h * dc
                x[bi, cc] -= w_p[bi] * h * dc
                x[aj, cc] += w_p[aj] * h * dc
                x[bj, cc] += w_p[bj] * h * dc
    if k_bend[k] > 0.0 or k_twist[k] > 0.0:
        _bend_twist_one(i, j, q, w_q, rest, length[k], k_bend[k], k_twist[k], lam_bt, k, dt)


def active_edges(ptr: np.ndarray, k_conn: np.ndarray, k_bend: np.ndarray, k_twist: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The colour-ordered positions with any stiffness left and the class pointers into them
    (:func:`reg_pass`'s ``active`` and ``ptr``): the classes are contiguous, so class c keeps
    the active positions within ``ptr[c]:ptr[c + 1]``."""
    active = np.flatnonzero((k_conn > 0.0) | (k_bend > 0.0) | (k_twist > 0.0))
    return active, np.searchsorted(active, ptr).astype(np.int64)


def color_edges(edges: np.ndarray, fp: np.ndarray, n_particles: int) -> tuple[np.ndarray, np.ndarray]:
    """Greedy colouring of the REG edges so that no two edges of a colour share a particle
    (each element owns particles fp and fp + 1). Returns (colour_ptr, edge order): the edges of
    colour c are ``order[ptr[c]:ptr[c + 1]]``, in increasing id. Deterministic (edge order)."""
    edges = np.ascontiguousarray(edges, dtype=np.int64)
    fp = fp.astype(np.int64)
    parts = np.stack([fp[edges[:, 0]], fp[edges[:, 0]] + 1, fp[edges[:, 1]], fp[edges[:, 1]] + 1], axis=1)
    touching = np.bincount(parts.ravel(), minlength=n_particles)
    # an edge meets at most this many others at its four particles, so greedy needs one colour more
    meets = int((touching[parts].sum(axis=1) - 4).max(initial=0))
    color = _greedy_colors(edges, fp, n_particles, meets // 64 + 1)
    order = np.argsort(color, kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(color, minlength=color.max(initial=-1) + 1))])
    return ptr.astype(np.int64), order.astype(np.int64)


@nb.njit(cache=True)
def _greedy_colors(edges, fp, n_particles, words):
    m = len(edges)
    color = np.empty(m, dtype=np.int64)
    # colours used at each particle, as a bit set over 64 * words colours
    used = np.zeros((n_particles, words), dtype=np.uint64)
    for k in range(m):
        i, j = edges[k, 0], edges[k, 1]
        parts = (fp[i], fp[i] + 1, fp[j], fp[j] + 1)
        c = -1
        for w in range(words):
            taken = used[parts[0], w] | used[parts[1], w] | used[parts[2], w] | used[parts[3], w]
            if taken != np.uint64(0xFFFFFFFFFFFFFFFF):
                b = 0
                while (taken >> np.uint64(b)) & np.uint64(1):
                    b += 1
                c = 64 * w + b
                break
        color[k] = c
        bit = np.uint64(1) << np.uint64(c % 64)
        for p in parts:
            used[p, c // 64] |= bit
    return color


# ------------------------------------------------------------------ plain-numpy references
# The same projections, vectorised over one colour class (its constraints are independent).

def _xpbd_np(C, lam, W, k, dt):
    with np.errstate(divide="ignore", invalid="ignore"):
        at = 1.0 / (k * dt * dt)
        return np.where(k > 0.0, (-C - at * lam) / (W + at), 0.0)


def stretch_shear_reference(elems, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok,
                            lam_s, lam_sh, dt):
    e = elems[element_ok[elems]]
    a, b = fp[e], fp[e] + 1
    wa, wb, wq, l = w_p[a], w_p[b], w_q[e], rest_length[e]
    d = x[b] - x[a]
    L = np.linalg.norm(d, axis=1)
    dl = np.where((L > 0) & (wa + wb > 0), _xpbd_np(L - l, lam_s[e], wa + wb, k_stretch[e] / l, dt), 0.0)
    lam_s[e] += dl
    n = d / np.where(L > 0, L, 1.0)[:, None]
    x[a] -= (wa * dl)[:, None] * n
    x[b] += (wb * dl)[:, None] * n
    W = (wa + wb) / l**2 + 4 * wq
    ok = W > 0
    g = (x[b] - x[a]) / l[:, None] - rotate_np(q[e], np.array([0.0, 0.0, 1.0]))
    d1 = rotate_np(q[e], np.array([1.0, 0.0, 0.0]))
    d2 = rotate_np(q[e], np.array([0.0, 1.0, 0.0]))
    ks = np.where(ok, k_shear[e] * l, 0.0)
    dl1 = _xpbd_np(np.sum(g * d1, axis=1), lam_sh[e, 0], W, ks, dt)
    dl2 = _xpbd_np(np.sum(g * d2, axis=1), lam_sh[e, 1], W, ks, dt)
    lam_sh[e, 0] += dl1
    lam_sh[e, 1] += dl2
    v = dl1[:, None] * d1 + dl2[:, None] * d2
    x[a] -= (wa / l)[:, None] * v
    x[b] += (wb / l)[:, None] * v
    r = mul_np(mul_np(pure_np(v), q[e]), np.array([0.0, 0.0, 0.0, -1.0]))
    rot = ok & (wq > 0)
    q[e[rot]] = normalize_np(q[e] - 2 * wq[:, None] * r)[rot]


def bend_twist_reference(pairs, idx, q, w_q, rest, length, k_bend, k_twist, lam, dt):
    i, j = pairs[idx, 0], pairs[idx, 1]
    wi, wj = w_q[i], w_q[j]
    act = wi + wj > 0
    idx, i, j, wi, wj = idx[act], i[act], j[act], wi[act], wj[act]
    qi, qj = q[i].copy(), q[j].copy()
    om = mul_np(conj_np(qi), qj)
    r = rest[idx]
    s = np.where(np.sum(om * r, axis=1) >= 0, 1.0, -1.0)
    f = 2.0 / length[idx]
    W = f * f * (wi + wj)
    C = f[:, None] * (om[:, 1:] - s[:, None] * r[:, 1:])
    k = np.stack([k_bend[idx], k_bend[idx], k_twist[idx]], axis=1) * length[idx][:, None]
    dl = _xpbd_np(C, lam[idx], W[:, None], k, dt)
    lam[idx] += dl
    u = pure_np(dl)
    q[j[wj > 0]] = normalize_np(qj + (wj * f)[:, None] * mul_np(qi, u))[wj > 0]
    q[i[wi > 0]] = normalize_np(qi - (wi * f)[:, None] * mul_np(qj, u))[wi > 0]


def reg_pass_reference(edges, ptr, active, fp, x, q, w_p, w_q, rest_offset, k_conn, rest, length, k_bend, k_twist,
                       lam_c, lam_bt, dt):
    for c in range(len(ptr) - 1):
        idx = active[ptr[c]:ptr[c + 1]]
        i, j = edges[idx, 0], edges[idx, 1]
        ai, aj = fp[i], fp[j]
        bi, bj = ai + 1, aj + 1
        W = 0.25 * (w_p[ai] + w_p[bi] + w_p[aj] + w_p[bj])
        d = 0.5 * (x[aj] + x[bj] - x[ai] - x[bi])
        L = np.linalg.norm(d, axis=1)
        act = (k_conn[idx] > 0) & (W > 0) & (L > 0)
        dl = np.where(act, _xpbd_np(L - rest_offset[idx], lam_c[idx], W, np.where(act, k_conn[idx], 0.0), dt), 0.0)
        lam_c[idx] += dl
        h = (0.5 * dl / np.where(L > 0, L, 1.0))[:, None] * d
        x[ai] -= w_p[ai][:, None] * h
        x[bi] -= w_p[bi][:, None] * h
        x[aj] += w_p[aj][:, None] * h
        x[bj] += w_p[bj][:, None] * h
        bt = idx[(k_bend[idx] > 0) | (k_twist[idx] > 0)]
        bend_twist_reference(edges, bt, q, w_q, rest, length, k_bend, k_twist, lam_bt, dt)
