"""Stage 1 as one direct solve per strand (Deul, Kugelstadt, Weiler and Bender 2018, "Direct
position-based solver for stiff rods"): the stretch, shear and bend-twist constraints of
:mod:`~wooddecay.sim.rods` along a strand, linearised at the current state, solved together.

Gauss-Seidel (:func:`rods.stretch_shear`, :func:`rods.bend_twist`) moves a correction one element
per sweep, so a strand of many stiff elements converges only over many sweeps and sags too far
(``benchmarks/cantilever.py --sweep``). Here the XPBD update of Eq. 1 for all of a strand's
constraints at once,

    (J W J^T + alpha~) dlambda = -(C + alpha~ lambda),

is solved exactly. Ordering the unknowns per element e as [stretch, shear_1, shear_2] of e and
[bend_1, bend_2, twist] of the joint (e, e + 1), each block of six couples only with its
neighbours' (they share a particle or a quaternion), so the matrix is block tridiagonal and a
block Thomas sweep solves it in O(n) per run. The gradients J are those the Gauss-Seidel
kernels apply (so both converge to the same state), W the inverse masses and inertias; a
failed element or joint, or one without a free particle or quaternion, is a row with dlambda = 0.
Runs (of different strands, or split by a failed element) share no particle or quaternion: one
thread per run, race-free and deterministic.
``solve_strands_reference`` assembles the same system densely per run and solves it with numpy.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..quaternion import mul, rotate

#: gradient slots of a row of element e: x_a (3), x_b (3), q_e (4), q_{e+1} (4)
SLOTS = 14


@nb.njit(cache=True)
def _rows(e, jt, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok, joint_rest,
          joint_length, kb, kt, lam_s, lam_sh, lam_j, dt, G, rhs, at, active):
    """Gradients ``G`` (6, SLOTS), right-hand sides, alpha~ and activity of element e's six rows
    (its stretch and shears, and the joint ``jt`` = (e, e + 1), or none if jt < 0)."""
    G[:] = 0.0
    rhs[:] = 0.0
    at[:] = 0.0
    active[:] = False
    a = fp[e]
    b = a + 1
    wa, wb, wq, l = w_p[a], w_p[b], w_q[e], rest_length[e]
    q0, q1, q2, q3 = q[e, 0], q[e, 1], q[e, 2], q[e, 3]
    if element_ok[e]:
        dx, dy, dz = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2]
        L = np.sqrt(dx * dx + dy * dy + dz * dz)
        k = k_stretch[e] / l
        if L > 0.0 and wa + wb > 0.0 and k > 0.0:
            active[0] = True
            n = (dx / L, dy / L, dz / L)
            for c in range(3):
                G[0, c] = -n[c]
                G[0, 3 + c] = n[c]
            at[0] = 1.0 / (k * dt * dt)
            rhs[0] = -(L - l) - at[0] * lam_s[e]
        k = k_shear[e] * l
        if (wa + wb) / (l * l) + 4.0 * wq > 0.0 and k > 0.0:
            d3 = rotate(q0, q1, q2, q3, 0.0, 0.0, 1.0)
            g = (dx / l - d3[0], dy / l - d3[1], dz / l - d3[2])
            for r in range(2):
                d = rotate(q0, q1, q2, q3, 1.0 if r == 0 else 0.0, 1.0 if r == 1 else 0.0, 0.0)
                active[1 + r] = True
                for c in range(3):
                    G[1 + r, c] = -d[c] / l
                    G[1 + r, 3 + c] = d[c] / l
                p = mul(0.0, d[0], d[1], d[2], q0, q1, q2, q3)
                u = mul(p[0], p[1], p[2], p[3], 0.0, 0.0, 0.0, -1.0)
                for c in range(4):
                    G[1 + r, 6 + c] = -2.0 * u[c]
                at[1 + r] = 1.0 / (k * dt * dt)
                rhs[1 + r] = -(g[0] * d[0] + g[1] * d[1] + g[2] * d[2]) - at[1 + r] * lam_sh[e, r]
    if jt >= 0 and w_q[e] + w_q[e + 1] > 0.0:
        b0, b1, b2, b3 = q[e + 1, 0], q[e + 1, 1], q[e + 1, 2], q[e + 1, 3]
        om = mul(q0, -q1, -q2, -q3, b0, b1, b2, b3)
        r0, r1, r2, r3 = joint_rest[jt, 0], joint_rest[jt, 1], joint_rest[jt, 2], joint_rest[jt, 3]
        s = 1.0 if om[0] * r0 + om[1] * r1 + om[2] * r2 + om[3] * r3 >= 0.0 else -1.0
        f = 2.0 / joint_length[jt]
        C = (f * (om[1] - s * r1), f * (om[2] - s * r2), f * (om[3] - s * r3))
        for m in range(3):
            k = (kt[jt] if m == 2 else kb[jt]) * joint_length[jt]
            if k <= 0.0:
                continue
            active[3 + m] = True
            e1, e2, e3 = 1.0 if m == 0 else 0.0, 1.0 if m == 1 else 0.0, 1.0 if m == 2 else 0.0
            ui = mul(b0, b1, b2, b3, 0.0, e1, e2, e3)
            uj = mul(q0, q1, q2, q3, 0.0, e1, e2, e3)
            for c in range(4):
                G[3 + m, 6 + c] = -f * ui[c]
                G[3 + m, 10 + c] = f * uj[c]
            at[3 + m] = 1.0 / (k * dt * dt)
            rhs[3 + m] = -C[m] - at[3 + m] * lam_j[jt, m]


@nb.njit(cache=True)
def _invert_spd(A, inv):
    """``inv`` = A^-1 for a symmetric positive definite 6 x 6 ``A`` (Cholesky A = L L^T, then
    L^-T L^-1); ``A`` is overwritten with L."""
    for j in range(6):
        d = A[j, j]
        for k in range(j):
            d -= A[j, k] * A[j, k]
        d = np.sqrt(d)
        A[j, j] = d
        for i in range(j + 1, 6):
            v = A[i, j]
            for k in range(j):
                v -= A[i, k] * A[j, k]
            A[i, j] = v / d
    for c in range(6):  # column c of L^-1, lower triangular, into inv[:, c]
        for i in range(6):
            v = 1.0 if i == c else 0.0
            for k in range(c, i):
                v -= A[i, k] * inv[k, c]
            inv[i, c] = v / A[i, i] if i >= c else 0.0
    for i in range(6):  # (L^-1)^T L^-1, symmetric
        for j in range(i + 1):
            v = 0.0
            for k in range(i, 6):
                v += inv[k, i] * inv[k, j]
            A[i, j] = v
    for i in range(6):
        for j in range(i + 1):
            inv[i, j] = A[i, j]
            inv[j, i] = A[i, j]


@nb.njit(cache=True)
def _diagonal_block(g, rhs, at, active, wa, wb, wq, wq1, D, y_e):
    """``D`` = J W J^T + alpha~ of one element's six rows (gradients ``g``; W: inverse masses
    ``wa``, ``wb`` of x_a, x_b, inertias ``wq``, ``wq1`` of q_e, q_{e+1}) and ``y_e`` their
    right-hand sides; an inactive row (no gradient) is 1 on the diagonal with right-hand side 0."""
    for r in range(6):
        for c in range(r + 1):
            v = 0.0
            if r < 3:  # element rows: x_a, x_b, q_e
                for k in range(3):
                    v += wa * g[r, k] * g[c, k] + wb * g[r, 3 + k] * g[c, 3 + k]
            if c < 3 or r >= 3:
                for k in range(6, 10):  # q_e
                    v += wq * g[r, k] * g[c, k]
            if c >= 3:
                for k in range(10, 14):  # q_{e+1}
                    v += wq1 * g[r, k] * g[c, k]
            D[r, c] = v
            D[c, r] = v
        D[r, r] = D[r, r] + at[r] if active[r] else 1.0
        y_e[r] = rhs[r] if active[r] else 0.0


@nb.njit(cache=True)
def _lower_block(g, h, wx, wq, Lo_e):
    """``Lo_e`` = J_e W J_{e-1}^T: the rows of e (gradients ``g``) against those of e - 1 (``h``),
    coupled through x_a(e) = x_b(e - 1) (inverse mass ``wx``) and q_e = q_{e+1} of e - 1 (``wq``)."""
    for r in range(6):
        for c in range(6):
            v = 0.0
            if r < 3 and c < 3:
                for k in range(3):
                    v += wx * g[r, k] * h[c, 3 + k]
            if c >= 3:
                for k in range(4):
                    v += wq * g[r, 6 + k] * h[c, 10 + k]
            Lo_e[r, c] = v


@nb.njit(cache=True)
def _eliminate(Lo_e, Minv_prev, y_prev, T, D, y_e):
    """Block Thomas elimination of e - 1 from the rows of e: with T = Lo_e M_{e-1}^-1,
    ``D`` -= T Lo_e^T and ``y_e`` -= T y_{e-1}."""
    for r in range(6):
        for c in range(6):
            v = 0.0
            for k in range(6):
                v += Lo_e[r, k] * Minv_prev[k, c]
            T[r, c] = v
    for r in range(6):
        for c in range(r + 1):
            v = 0.0
            for k in range(6):
                v += T[r, k] * Lo_e[c, k]
            D[r, c] -= v
            if c != r:
                D[c, r] -= v
        for c in range(6):
            y_e[r] -= T[r, c] * y_prev[c]


@nb.njit(cache=True)
def _forward_sweep(e0, e1, joint_of, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok, joint_rest,
                   joint_length, kb, kt, lam_s, lam_sh, lam_j, dt, G, Minv, Lo, y):
    """Forward sweep of the block Thomas solve of the run ``lo:hi`` = ``e0:e1``: per element its
    rows ``G[e]`` (:func:`_rows`), its lower block ``Lo[e]``, the inverse ``Minv[e]`` of its
    diagonal block less the elimination of e - 1, and its eliminated right-hand side ``y[e]``."""
    rhs, at = np.zeros(6), np.zeros(6)
    active = np.zeros(6, dtype=np.bool_)
    D, T = np.zeros((6, 6)), np.zeros((6, 6))
    for e in range(e0, e1):
        g = G[e]
        _rows(e, joint_of[e], fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok, joint_rest,
              joint_length, kb, kt, lam_s, lam_sh, lam_j, dt, g, rhs, at, active)
        wa, wb, wq = w_p[fp[e]], w_p[fp[e] + 1], w_q[e]
        wq1 = w_q[e + 1] if joint_of[e] >= 0 else 0.0
        _diagonal_block(g, rhs, at, active, wa, wb, wq, wq1, D, y[e])
        if e > e0:
            _lower_block(g, G[e - 1], w_p[fp[e]], wq, Lo[e])
            _eliminate(Lo[e], Minv[e - 1], y[e - 1], T, D, y[e])
        _invert_spd(D, Minv[e])


@nb.njit(cache=True)
def _apply_step(e, g, dl, joint_of, fp, x, q, w_p, w_q, lam_s, lam_sh, lam_j):
    """Element e's ``dl`` (its six dlambda) added to the multipliers, and W J_e^T dl (gradients
    ``g``) to x_a, x_b, q_e and, with a joint, q_{e+1}."""
    lam_s[e] += dl[0]
    lam_sh[e, 0] += dl[1]
    lam_sh[e, 1] += dl[2]
    wa, wb, wq = w_p[fp[e]], w_p[fp[e] + 1], w_q[e]
    for k in range(3):
        sa = sb = 0.0
        for r in range(3):
            sa += g[r, k] * dl[r]
            sb += g[r, 3 + k] * dl[r]
        x[fp[e], k] += wa * sa
        x[fp[e] + 1, k] += wb * sb
    for k in range(4):
        v = 0.0
        for r in range(6):
            v += g[r, 6 + k] * dl[r]
        q[e, k] += wq * v
    jt = joint_of[e]
    if jt >= 0:
        for m in range(3):
            lam_j[jt, m] += dl[3 + m]
        for k in range(4):
            v = 0.0
            for r in range(3, 6):
                v += g[r, 10 + k] * dl[r]
            q[e + 1, k] += w_q[e + 1] * v


@nb.njit(cache=True)
def _back_substitution(e0, e1, joint_of, fp, x, q, w_p, w_q, lam_s, lam_sh, lam_j, G, Minv, Lo, y):
    """Backward sweep of the block Thomas solve of the run ``e0:e1``: from the last element on,
    dlambda_e = M_e^-1 (y_e - Lo_{e+1}^T dlambda_{e+1}), applied (:func:`_apply_step`)."""
    z, dl = np.zeros(6), np.zeros(6)
    for e in range(e1 - 1, e0 - 1, -1):
        for r in range(6):
            z[r] = y[e, r]
            if e + 1 < e1:
                for k in range(6):
                    z[r] -= Lo[e + 1, k, r] * dl[k]
        for r in range(6):
            v = 0.0
            for k in range(6):
                v += Minv[e, r, k] * z[k]
            dl[r] = v
        _apply_step(e, G[e], dl, joint_of, fp, x, q, w_p, w_q, lam_s, lam_sh, lam_j)


@nb.njit(cache=True)
def _normalise_run(e0, e1, w_q, q):
    """The moving quaternions of the run ``e0:e1`` scaled back to unit length."""
    for e in range(e0, e1):
        if w_q[e] > 0.0:  # a still quaternion keeps its bits
            norm = np.sqrt(q[e, 0] ** 2 + q[e, 1] ** 2 + q[e, 2] ** 2 + q[e, 3] ** 2)
            for c in range(4):
                q[e, c] /= norm


@nb.njit(parallel=True, cache=True)
def solve_strands(lo, hi, joint_of, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok,
                  joint_rest, joint_length, kb, kt, lam_s, lam_sh, lam_j, dt):
    """One direct solve of the constraints of each run of elements ``lo[t]:hi[t]`` (whole strands,
    or the unbroken pieces of them, :func:`~wooddecay.sim.mechanics.stage1_plan`; module
    docstring); updates ``x``, ``q`` and the multipliers. ``joint_of[e]``: the joint
    (e, e + 1) or -1 at a strand's last element. Element rows (0-2) touch slots 0-9, joint rows
    (3-5) slots 6-13, so a block couples its neighbour's only through x_a (element rows) and q_e."""
    n = len(rest_length)
    G = np.empty((n, 6, SLOTS))  # every entry is written before it is read
    Minv = np.empty((n, 6, 6))
    Lo = np.empty((n, 6, 6))
    y = np.empty((n, 6))
    for s in nb.prange(len(lo)):
        _forward_sweep(lo[s], hi[s], joint_of, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok,
                       joint_rest, joint_length, kb, kt, lam_s, lam_sh, lam_j, dt, G, Minv, Lo, y)
        _back_substitution(lo[s], hi[s], joint_of, fp, x, q, w_p, w_q, lam_s, lam_sh, lam_j, G, Minv, Lo, y)
        _normalise_run(lo[s], hi[s], w_q, q)


def solve_strands_reference(lo, hi, joint_of, fp, x, q, w_p, w_q, rest_length, k_stretch, k_shear, element_ok,
                            joint_rest, joint_length, kb, kt, lam_s, lam_sh, lam_j, dt):
    """Plain-numpy twin of :func:`solve_strands`: each strand's system assembled densely from
    the same rows and solved with ``numpy.linalg.solve``."""
    x0, q0 = x.copy(), q.copy()
    for e0, e1 in zip(lo.tolist(), hi.tolist()):
        m = e1 - e0
        J = np.zeros((6 * m, 3 * (m + 1) + 4 * m))
        wts = np.zeros(J.shape[1])
        b = np.zeros(6 * m)
        alpha = np.zeros(6 * m)
        on = np.zeros(6 * m, dtype=bool)
        for t, e in enumerate(range(e0, e1)):
            G, rhs, at, act = np.zeros((6, SLOTS)), np.zeros(6), np.zeros(6), np.zeros(6, dtype=bool)
            _rows(e, joint_of[e], fp, x0, q0, w_p, w_q, rest_length, k_stretch, k_shear, element_ok, joint_rest,
                  joint_length, kb, kt, lam_s, lam_sh, lam_j, dt, G, rhs, at, act)
            rows = slice(6 * t, 6 * t + 6)
            xa, qe = 3 * t, 3 * (m + 1) + 4 * t
            J[rows, xa:xa + 6] = G[:, :6]
            J[rows, qe:qe + 4] = G[:, 6:10]
            if t + 1 < m:
                J[rows, qe + 4:qe + 8] = G[:, 10:]
            wts[xa:xa + 3], wts[xa + 3:xa + 6] = w_p[fp[e]], w_p[fp[e] + 1]
            wts[qe:qe + 4] = w_q[e]
            b[rows], alpha[rows], on[rows] = rhs, at, act
        A = (J * wts) @ J.T + np.diag(alpha)
        A[~on] = 0.0
        A[:, ~on] = 0.0
        A[~on, ~on] = 1.0
        dl = np.linalg.solve(A, np.where(on, b, 0.0))
        step = wts * (J.T @ dl)
        for t, e in enumerate(range(e0, e1)):
            lam_s[e] += dl[6 * t]
            lam_sh[e] += dl[6 * t + 1:6 * t + 3]
            if joint_of[e] >= 0:
                lam_j[joint_of[e]] += dl[6 * t + 3:6 * t + 6]
            q[e] += step[3 * (m + 1) + 4 * t:3 * (m + 1) + 4 * t + 4]
        x[fp[e0]:fp[e0] + m + 1] += step[:3 * (m + 1)].reshape(-1, 3)
        moves = w_q[e0:e1] > 0.0
        q[e0:e1][moves] /= np.linalg.norm(q[e0:e1][moves], axis=1)[:, None]
