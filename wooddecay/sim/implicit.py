"""A backward Euler step of the rods by Newton's method on the incremental potential
(docs/model.md §4; docs/decisions.md, "Implicit step").

The step of length h minimises

    Phi(x, q) = E(x, q) + sum_p m_p |x_p - x~_p|^2 / (2 h^2) + sum_e I_e |theta_e|^2 / (2 h^2),

E the potential of :mod:`~wooddecay.sim.equilibrium` (the energies XPBD converges to, Eq. 4
contact, gravity, loads), x~ = x + h v the predicted positions, theta_e the rotation from the
predicted orientation exp(h omega / 2) q_e to q_e, I_e = m_e inertia_factor_e its moment of inertia.
With h = inf the inertia drops out: the static equilibrium of wood an anchor holds.

Unknowns are the positions of the particles and a world rotation increment per element
(q <- exp(dtheta / 2) q); a small loose piece moves as one rigid body instead, a translation and a
rotation about its centre (:mod:`~wooddecay.sim.rigid`), its Newton system B^T (...) B. Each
Newton iteration solves (H + M / h^2) d = -grad Phi with the Gauss-Newton Hessian H = sum_c k_c J_c^T J_c of every constraint row c (C the constraint, J_c its
gradient, as in :mod:`~wooddecay.sim.equilibrium`; contact 2 k_col phi n n^T) plus the geometric
stiffness of stretched distances (projected Newton: positive semidefinite), exact where the
constraints are satisfied, by conjugate gradients with the two-level preconditioner of
:mod:`~wooddecay.sim.precondition`; a backtracking line search keeps Phi decreasing. It stops
when :func:`~wooddecay.sim.equilibrium.equilibrium_residual`, the inertia forces -M (x - x~) / h^2
included, is at most ``tol``, or, given ``stall``, as stalled when that many iterations have not
halved it. Anchored particles and elements stay.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..quaternion import conj_np, exp_np, mul_np, normalize_np, rotate_np
from ..wood import WoodModel
from . import break_order, equilibrium, failure, mechanics, precondition, rigid, sleep
from .contact.colliders import collider_distance_reference
from .mechanics import MechSetup, MechState, joint_stiffness

#: backtracking halvings before a Newton iteration gives up on decreasing Phi
LINE_SEARCH = 30
#: slip (m) up to which static friction holds as a spring (:class:`_Friction`)
STICK = 1e-5
#: Newton iterations between updates of the friction's contacts and normal forces
LAG = 4
#: relative tolerance and iteration cap of the Newton direction's conjugate gradients
LINEAR_TOL, LINEAR_CAP = 1e-2, 5000
#: rounds of failure in order per macro step at most
FAILURE_ROUNDS = 24
#: Newton iterations the static settling may take (from the rest shape, pressed into the ground)
SETTLE_NEWTON = 200
#: shortest step (s) of a bake's implicit macro step
STEP_FLOOR = 1.0
#: step (s) after a break within a macro step
BREAK_STEP = 0.01
#: seconds a day
DAY = 86400.0
#: Newton stops as stalled when STALL iterations have not halved its residual
STALL = 8
#: Newton iterations within which a macro step's first step doubles the next one's
EASY_NEWTON = 3


class StepReport(NamedTuple):
    """What one :func:`step` did."""

    newton: int  # Newton iterations
    residual: float  # equilibrium residual at the end (inertia forces included for finite h)
    converged: bool  # residual <= tol


class Blocks(NamedTuple):
    """sum_c k_c J_c^T J_c of constraint rows c, as the 3x3 blocks between their 3-DOF blocks."""

    values: np.ndarray  # (r, nb, nb, 3, 3) float64
    blocks: np.ndarray  # (r, nb) int64: particle p is block p, element e's rotation block P + e


def _summed(*terms: Blocks) -> Blocks:
    """The sum of terms over the same rows and blocks."""
    return Blocks(np.sum([t.values for t in terms], axis=0), terms[0].blocks)


def _rows(J: np.ndarray, blocks: np.ndarray, k: np.ndarray) -> Blocks:
    """:class:`Blocks` of constraint rows c with gradient blocks J (r, nb, 3) on ``blocks`` (r, nb)."""
    return Blocks(k[:, None, None, None, None] * J[:, :, None, :, None] * J[:, None, :, None, :], blocks)


def _matrix(parts: list[Blocks], n_blocks: int, free: np.ndarray | None = None) -> sp.bsr_matrix:
    """The sum of ``parts`` as a block sparse (3x3) matrix over the blocks where ``free`` (all if
    None), in block order: equal blocks summed by one sort of their (row, column) keys."""
    index = np.arange(n_blocks) if free is None else np.cumsum(free) - 1
    if free is not None:
        index[~free] = -1
    keys, vals = [], []
    for part in parts:
        b = index[part.blocks]
        keep = ((b[:, :, None] >= 0) & (b[:, None, :] >= 0)).ravel()
        keys.append((b[:, :, None] * n_blocks + b[:, None, :]).ravel()[keep])
        vals.append(part.values.reshape(-1, 9)[keep])
    n = n_blocks if free is None else int(free.sum())
    key, val = np.concatenate(keys), np.concatenate(vals)
    uniq, inv = np.unique(key, return_inverse=True)
    data = np.stack([np.bincount(inv, val[:, c], minlength=len(uniq)) for c in range(9)], axis=1)
    row, col = np.divmod(uniq, n_blocks)
    indptr = np.searchsorted(row, np.arange(n + 1))
    return sp.bsr_matrix((data.reshape(-1, 3, 3), col, indptr), shape=(3 * n, 3 * n))


def _tangents(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to the unit rows ``u`` and to each other."""
    t1 = np.cross(u, np.where(np.abs(u[:, :1]) < 0.9, np.eye(3)[0], np.eye(3)[1]))
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(u, t1)


def _distance(J: np.ndarray, blocks: np.ndarray, u: np.ndarray, k: np.ndarray, C: np.ndarray,
              L: np.ndarray) -> Blocks:
    """Hessian of 1/2 k (L - rest)^2 for L = |d|, d = sum_b w_b x_b: k J^T J (J the rows w_b u)
    plus, where stretched (C = L - rest > 0), the geometric part k C / L (I - u u^T) over the same
    weights (dropped where compressed, so the Hessian stays positive semidefinite)."""
    geo = k * np.maximum(C, 0.0) / np.maximum(L, 1e-300)
    w = np.einsum("rbc,rc->rb", J, u)  # the weights w_b
    t1, t2 = _tangents(u)
    return _summed(_rows(J, blocks, k), _rows(w[:, :, None] * t1[:, None, :], blocks, geo),
                   _rows(w[:, :, None] * t2[:, None, :], blocks, geo))


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x (k, 3, 3), row-wise: [v]x w = v x w."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return out


def _offset_rows(setup: MechSetup, ms: MechState, c: np.ndarray, k_conn: np.ndarray, particles: np.ndarray
                 ) -> Blocks:
    """J^T B J of the co-rotated offset delta = d - (u_i + u_j) / 2 of the REG edges ``c``
    (:func:`~wooddecay.sim.equilibrium.connection_targets`), B its stiffness
    (:func:`~wooddecay.sim.equilibrium.offset_tensor` of ``k_conn``), J's 3x3 blocks +-1/2 I on
    the centres' ``particles`` (i's two, then j's), 1/2 [u_i]x on theta_i and 1/2 [u_j]x on theta_j
    (d u_i = dtheta_i x u_i); B's own turn with theta_i adds terms in delta, zero where the offset
    holds."""
    ui, uj = equilibrium.connection_targets(setup, ms, c)
    J = np.empty((len(c), 6, 3, 3))
    J[:, :4] = np.array([-0.5, -0.5, 0.5, 0.5])[:, None, None] * np.eye(3)
    J[:, 4], J[:, 5] = 0.5 * _skew(ui), 0.5 * _skew(uj)
    B = equilibrium.offset_tensor(setup, ms, c, k_conn)
    values = J.transpose(0, 1, 3, 2)[:, :, None] @ (B[:, None] @ J)[:, None, :]
    return Blocks(values, np.concatenate([particles, setup.n_particles + setup.edges[c]], axis=1))


def _darboux_rows(q, pairs, rest, length, kb, kt, P) -> Blocks:
    """Bend-twist rows: J on theta_j = (2 / l) A, on theta_i minus that, A = 1/2 (w I - [v]x) R_i^T;
    their blocks B = A^T diag(k) A on (j, j) and (i, i), -B on (i, j) and (j, i)."""
    on = (kb > 0.0) | (kt > 0.0)
    pairs, rest, length, kb, kt = pairs[on], rest[on], length[on], kb[on], kt[on]
    i, j = pairs[:, 0], pairs[:, 1]
    om = mul_np(conj_np(q[i]), q[j])
    w, v = om[:, 0], om[:, 1:]
    Rt = np.stack([rotate_np(conj_np(q[i]), np.broadcast_to(np.eye(3)[c], v.shape)) for c in range(3)], axis=2)
    A = 0.5 * (w[:, None, None] * np.eye(3) - _skew(v)) @ Rt * (2.0 / length)[:, None, None]
    k = np.stack([kb, kb, kt], axis=1) * length[:, None]
    B = np.einsum("rci,rc,rcj->rij", A, k, A)
    sign = np.array([[1.0, -1.0], [-1.0, 1.0]])
    return Blocks(sign[None, :, :, None, None] * B[:, None, None], np.stack([P + i, P + j], axis=1))


def hessian(setup: MechSetup, ms: MechState) -> sp.csr_matrix:
    """The Gauss-Newton Hessian of the potential E over [x (P, 3), theta (n, 3)] (module docstring)."""
    return _matrix(_hessian_rows(setup, ms), setup.n_particles + setup.n_elements).tocsr()


def _hessian_rows(setup: MechSetup, ms: MechState) -> list[Blocks]:
    """:func:`hessian` as :class:`Blocks`, term by term."""
    P = setup.n_particles
    e = np.flatnonzero(ms.element_ok)
    a, b, l = setup.fp[e], setup.fp[e] + 1, ms.rest_length[e]
    d = ms.x[b] - ms.x[a]
    L = np.linalg.norm(d, axis=1)
    u = d / np.maximum(L, 1e-300)[:, None]
    parts = [_distance(np.stack([-u, u], axis=1), np.stack([a, b], axis=1), u, setup.k_stretch[e] / l, L - l, L)]
    g = d / l[:, None]
    shear = []
    for axis in np.eye(3)[:2]:
        dk = rotate_np(ms.q[e], np.broadcast_to(axis, g.shape))
        J = np.stack([-dk / l[:, None], dk / l[:, None], np.cross(dk, g)], axis=1)
        shear.append(_rows(J, np.stack([a, b, P + e], axis=1), setup.k_shear[e] * l))
    parts.append(_summed(*shear))
    kb, kt = joint_stiffness(setup, ms)
    parts.append(_darboux_rows(ms.q, setup.joints, setup.joint_rest, setup.joint_length, kb, kt, P))
    k_conn, k_pb, k_pt = equilibrium.reg_stiffness(setup, ms)
    c = np.flatnonzero(k_conn > 0.0)
    ai, aj = setup.fp[setup.edges[c, 0]], setup.fp[setup.edges[c, 1]]
    d = 0.5 * (ms.x[aj] + ms.x[aj + 1] - ms.x[ai] - ms.x[ai + 1])
    L = np.linalg.norm(d, axis=1)
    u = d / np.maximum(L, 1e-300)[:, None]
    blocks = np.stack([ai, ai + 1, aj, aj + 1], axis=1)
    parts.append(_distance(0.5 * np.stack([-u, -u, u, u], axis=1), blocks, u, setup.central_share[c] * k_conn[c],
                           L - ms.rest_offset[c], L))
    off = setup.offset_share[c].any(axis=1)
    if off.any():
        parts.append(_offset_rows(setup, ms, c[off], k_conn[c[off]], blocks[off]))
    parts.append(_darboux_rows(ms.q, setup.edges, setup.edge_rest, setup.edge_length, k_pb, k_pt, P))
    for row in setup.colliders:
        sd, normal = collider_distance_reference(row, ms.x)
        phi = ms.radius_p - sd
        p = np.flatnonzero(phi > 0.0)
        parts.append(_rows(normal[p][:, None, :], p[:, None], 2.0 * setup.k_col * phi[p]))
    if len(ms.pairs):
        parts.append(_pair_rows(setup, ms))
    return parts


def _pair_rows(setup: MechSetup, ms: MechState) -> Blocks:
    """2 k_col phi J^T J of the capsule pairs in contact (Eq. 4), J the closest points' weights
    times the normal."""
    pc = equilibrium.pair_contacts(setup, ms)
    on = pc.phi > 0.0
    return _rows(pc.w[on][:, :, None] * pc.normal[on][:, None, :], pc.blocks[on], 2.0 * setup.k_col * pc.phi[on])


def _rotation_from(q: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """The world rotation vector theta with q = exp(theta / 2) q_ref (row-wise)."""
    r = mul_np(q, conj_np(q_ref))
    r = r * np.where(r[:, :1] < 0.0, -1.0, 1.0)
    s = np.linalg.norm(r[:, 1:], axis=1)
    return r[:, 1:] * np.where(s > 0.0, 2.0 * np.arctan2(s, r[:, 0]) / np.where(s > 0.0, s, 1.0), 2.0)[:, None]


def _turned(q: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """exp(theta / 2) q, row-wise."""
    return normalize_np(mul_np(exp_np(theta), q))


class _Friction(NamedTuple):
    """Lagged static friction at the contacts of the step's start, colliders and capsule pairs:
    contact k's point r = sum_b w_b x_b (a particle against a collider; the closest points of a
    pair, j's minus i's) resists its tangential slip u = (I - n n^T)(r - r0) from r0 at the
    step's start with the force -mu N u / max(|u|, STICK) (shared by w_b): a stiff spring up to
    STICK of slip, Coulomb's mu N beyond it."""

    blocks: np.ndarray  # (k, 4) int64: the contact's particles
    w: np.ndarray  # (k, 4) float64: their weights in r
    n: np.ndarray  # (k, 3) float64: contact normals
    r0: np.ndarray  # (k, 3) float64, m: r at the step's start
    muN: np.ndarray  # (k,) float64, N: mu_f times the normal force (Eq. 4)

    def slip(self, x: np.ndarray) -> np.ndarray:
        d = np.einsum("kb,kbc->kc", self.w, x[self.blocks]) - self.r0
        return d - np.einsum("ij,ij->i", d, self.n)[:, None] * self.n

    def energy(self, x: np.ndarray) -> float:
        u = np.linalg.norm(self.slip(x), axis=1)
        return float(np.where(u <= STICK, 0.5 * self.muN * u * u / STICK, self.muN * (u - 0.5 * STICK)).sum())

    def forces(self, x: np.ndarray) -> np.ndarray:
        u = self.slip(x)
        f = -(self.muN / np.maximum(np.linalg.norm(u, axis=1), STICK))[:, None] * u
        per = (self.w[:, :, None] * f[:, None, :]).reshape(-1, 3)
        return np.stack([np.bincount(self.blocks.ravel(), per[:, c], minlength=len(x)) for c in range(3)], axis=1)

    def rows(self, x: np.ndarray) -> Blocks:
        """(mu N / max(|u|, STICK)) (I - n n^T) per contact, as the two tangent rows."""
        k = self.muN / np.maximum(np.linalg.norm(self.slip(x), axis=1), STICK)
        t1, t2 = _tangents(self.n)
        return _summed(_rows(self.w[:, :, None] * t1[:, None, :], self.blocks, k),
                       _rows(self.w[:, :, None] * t2[:, None, :], self.blocks, k))


def _friction(setup: MechSetup, ms: MechState, x0: np.ndarray) -> _Friction:
    """The :class:`_Friction` of the contacts of ``ms`` (colliders, then ``ms.pairs``), slip
    measured from ``x0`` (P, 3)."""
    parts = []
    one = np.array([1.0, 0.0, 0.0, 0.0])
    for row in setup.colliders:
        sd, normal = collider_distance_reference(row, ms.x)
        phi = ms.radius_p - sd
        p = np.flatnonzero(phi > 0.0)
        parts.append((np.repeat(p[:, None], 4, axis=1), np.tile(one, (len(p), 1)), normal[p],
                      setup.mu_f * setup.k_col * phi[p] ** 2))
    if len(ms.pairs):
        pc = equilibrium.pair_contacts(setup, ms)
        on = pc.phi > 0.0
        parts.append((pc.blocks[on], pc.w[on], pc.normal[on], setup.mu_f * setup.k_col * pc.phi[on] ** 2))
    if not parts:
        return _Friction(np.zeros((0, 4), np.int64), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    blocks, w, n, muN = (np.concatenate(c) for c in zip(*parts))
    return _Friction(blocks, w, n, np.einsum("kb,kbc->kc", w, x0[blocks]), muN)


class _Inertia(NamedTuple):
    x_pred: np.ndarray
    q_pred: np.ndarray
    m: np.ndarray  # (P,) particle masses over h^2
    I: np.ndarray  # (n,) element moments of inertia over h^2

    def energy(self, ms: MechState) -> float:
        th = _rotation_from(ms.q, self.q_pred)
        return float(0.5 * (self.m * ((ms.x - self.x_pred) ** 2).sum(axis=1)).sum()
                     + 0.5 * (self.I * (th * th).sum(axis=1)).sum())

    def forces(self, ms: MechState) -> tuple[np.ndarray, np.ndarray]:
        return -self.m[:, None] * (ms.x - self.x_pred), -self.I[:, None] * _rotation_from(ms.q, self.q_pred)


def _inertia(setup: MechSetup, ms: MechState, h: float) -> _Inertia:
    w = 0.0 if np.isinf(h) else 1.0 / (h * h)
    hh = 0.0 if np.isinf(h) else h
    return _Inertia(ms.x + hh * ms.v, _turned(ms.q, rotate_np(ms.q, hh * ms.omega)), w * ms.mass_p,
                    w * ms.mass_e * setup.inertia_factor)


class Layout(NamedTuple):
    """What a step's Newton systems share: the free unknowns, the inertia's blocks and the
    preconditioner's structure (:mod:`~wooddecay.sim.precondition`) over the reduced blocks: the
    free blocks that are not in a rigid piece (:mod:`~wooddecay.sim.rigid`), then two per rigid
    piece (its translation, its rotation)."""

    free_blocks: np.ndarray  # (P + n,) bool: particles, then element rotations, not anchored
    mass: Blocks  # M / h^2 on the diagonal blocks
    strand: np.ndarray  # (reduced blocks,) int64: the strand of each (a rigid piece its own)
    position: np.ndarray  # (reduced blocks,) float64: its place along the strand
    modes: sp.csr_matrix  # (reduced DOFs, 6 k): the aggregates' rigid modes, each rigid piece's own

    @property
    def free(self) -> np.ndarray:
        return np.repeat(self.free_blocks, 3)


def layout(setup: MechSetup, ms: MechState, inertia: _Inertia) -> Layout:
    """The :class:`Layout` of a step from ``ms`` with the :class:`_Inertia` ``inertia``."""
    free_blocks = np.concatenate([~setup.anchored_p, ~setup.anchored_e])
    mass = Blocks(np.concatenate([inertia.m, inertia.I])[:, None, None, None, None] * np.eye(3),
                  np.arange(len(free_blocks))[:, None])
    rb = rigid.bodies(setup, ms)
    kept, k = free_blocks & ~rb.blocks, rb.n_pieces
    strand, position = precondition.strand_of_blocks(setup)
    strand = np.concatenate([strand[kept], int(strand.max()) + 1 + np.repeat(np.arange(k), 2)])
    position = np.concatenate([position[kept], np.tile([0.0, 1.0], k)])
    modes = precondition.rigid_modes(setup, ms, precondition.aggregates(setup, ms))[np.repeat(kept, 3)]
    modes = sp.block_diag([modes, sp.identity(6 * k)], format="csr")
    return Layout(free_blocks, mass, strand, position, modes)


def scaled(H: sp.spmatrix, modes: sp.csr_matrix) -> tuple[sp.csr_matrix, np.ndarray, sp.csr_matrix]:
    """H diagonally scaled to a unit diagonal (translation and rotation stiffnesses differ by
    orders of magnitude), the scale, and ``modes`` in the scaled unknowns. Unknowns without
    stiffness or inertia (a failed element's rotation in a static solve) get a unit row and a
    zero scale: they stay."""
    diag = H.diagonal()
    live = diag > 0.0
    scale = np.where(live, 1.0 / np.sqrt(np.where(live, diag, 1.0)), 0.0)
    A = (sp.diags(scale) @ H.tocsr() @ sp.diags(scale) + sp.diags((~live).astype(float))).tocsr()
    return A, scale, (sp.diags(np.where(live, np.sqrt(np.where(live, diag, 1.0)), 0.0)) @ modes).tocsr()


def _solve(H: sp.spmatrix, b: np.ndarray, lay: Layout) -> np.ndarray:
    """H^-1 b by conjugate gradients to LINEAR_TOL of |b| (an inexact Newton direction) on the
    :func:`scaled` system, preconditioned by :func:`~wooddecay.sim.precondition.two_level`."""
    A, scale, modes = scaled(H, lay.modes)
    y, _ = spla.cg(A, b * scale, rtol=LINEAR_TOL, maxiter=LINEAR_CAP,
                   M=precondition.two_level(A, lay.strand, lay.position, modes))
    return y * scale


def newton_system(setup: MechSetup, ms: MechState, inertia: _Inertia, friction: _Friction, lay: Layout
                  ) -> tuple[sp.bsr_matrix, np.ndarray, float]:
    """The Newton system of the incremental potential at ``ms``: the Hessian over the free
    blocks, the gradient over all unknowns, and Phi."""
    F, _ = equilibrium.forces(setup, ms)
    fi, ti = inertia.forces(ms)
    grad = -np.concatenate([(F.f + fi + friction.forces(ms.x)).ravel(), (F.tau + ti).ravel()])
    phi = F.energy + inertia.energy(ms) + friction.energy(ms.x)
    H = _matrix(_hessian_rows(setup, ms) + [friction.rows(ms.x), lay.mass], len(lay.free_blocks), lay.free_blocks)
    return H, grad, phi


def first_system(setup: MechSetup, ms: MechState, h: float) -> tuple[sp.csr_matrix, np.ndarray, Layout, sp.csr_matrix]:
    """The first Newton system :func:`step` solves for a step of ``h`` from ``ms``, reduced to the
    rigid pieces' unknowns and :func:`scaled`: the matrix, the right-hand side, the layout and the
    coarse modes (for benchmarks)."""
    inertia = _inertia(setup, ms, h)
    lay = layout(setup, ms, inertia)
    H, grad, _ = newton_system(setup, ms, inertia, _friction(setup, ms, ms.x), lay)
    B = rigid.basis(setup, ms, rigid.bodies(setup, ms), lay.free_blocks)
    A, scale, modes = scaled(B.T @ H @ B, lay.modes)
    return A, -(B.T @ grad[lay.free]) * scale, lay, modes


def step(setup: MechSetup, ms: MechState, h: float = np.inf, tol: float = 1e-3, max_newton: int = 30,
         stall: int = 0) -> StepReport:
    """One backward Euler step of length ``h`` (inf: the static equilibrium) of ``ms`` in place,
    to an equilibrium residual of ``tol`` (module docstring); velocities from the step."""
    P, n = setup.n_particles, setup.n_elements
    inertia, friction = _inertia(setup, ms, h), _friction(setup, ms, ms.x)
    x0, q0 = ms.x.copy(), ms.q.copy()
    lay = layout(setup, ms, inertia)
    free = lay.free
    moving = MechState.copy(ms)
    res = equilibrium.equilibrium_residual(setup, moving, inertia.forces(moving))
    history = [res]
    it = 0
    for it in range(1, max_newton + 1):
        if _refreshed(setup, moving) or it % LAG == 0:  # the contacts and their normal forces where the solve has got to
            friction = _friction(setup, moving, moving.x if np.isinf(h) else x0)
        H, grad, phi0 = newton_system(setup, moving, inertia, friction, lay)
        rb = rigid.bodies(setup, moving)
        B = rigid.basis(setup, moving, rb, lay.free_blocks)
        reduced = _solve(B.T @ H @ B, -(B.T @ grad[free]), lay)
        d = np.zeros(3 * (P + n))
        d[free] = B @ reduced
        t, omega = rigid.motions(rb, reduced)
        slope = float(grad @ d)
        alpha, trial = 1.0, moving
        for _ in range(LINE_SEARCH):
            trial = MechState.copy(moving)
            trial.x = rigid.moved(moving.x + alpha * d[:3 * P].reshape(P, 3), moving.x, rb, alpha * t, alpha * omega)
            trial.q = _turned(moving.q, alpha * d[3 * P:].reshape(n, 3))
            if (equilibrium.forces(setup, trial)[0].energy + inertia.energy(trial) + friction.energy(trial.x)
                    <= phi0 + 1e-4 * alpha * slope):
                break
            alpha *= 0.5
        moving = trial
        res = equilibrium.equilibrium_residual(setup, moving, inertia.forces(moving))
        history.append(res)
        if res <= tol or (0 < stall < it and res > 0.5 * history[-1 - stall]):
            break
    ms.x, ms.q = moving.x, moving.q
    ms.pairs, ms.pairs_x, ms.pairs_rest, ms.pairs_protect, ms.pairs_sep = (
        moving.pairs, moving.pairs_x, moving.pairs_rest, moving.pairs_protect, moving.pairs_sep)
    _part(setup, ms)
    if not np.isinf(h):
        ms.v = (ms.x - x0) / h
        ms.omega = rotate_np(conj_np(ms.q), _rotation_from(ms.q, q0)) / h
    return StepReport(it, res, res <= tol)


def _refreshed(setup: MechSetup, ms: MechState) -> bool:
    """Rebuild the contact list of ``ms`` where the iterates have carried a particle half its
    margin (:func:`~wooddecay.sim.mechanics.refresh_pairs`): a list kept over a whole step lets
    pieces that were apart at its start pass into each other unseen. Whether it was rebuilt."""
    before = ms.pairs_x
    mechanics.refresh_pairs(setup, ms)
    return ms.pairs_x is not before


def _part(setup: MechSetup, ms: MechState) -> None:
    """Shrink each pair's protected overlap (:func:`~wooddecay.sim.equilibrium.pair_contacts`) to
    what is left of it, so pieces that parted cannot sink back into it; it never grows."""
    if len(ms.pairs) and len(ms.pairs_protect) == len(ms.pairs):
        ms.pairs_protect = np.maximum(ms.pairs_protect + np.minimum(equilibrium.pair_contacts(setup, ms).phi, 0.0), 0.0)
        mechanics.keep_overlaps(ms.pairs_sep, ms.pairs_rest, ms.pairs_protect, ms.sep_overlap)


def span(setup: MechSetup, n_sub: int) -> float:
    """The step of :func:`macro_step` for ``n_sub`` substeps: their span, at least STEP_FLOOR
    (shorter backward Euler steps only add inertia to wood that drifts through slow rest
    changes)."""
    return max(n_sub * setup.dt, STEP_FLOOR)


def next_step(report: StepReport, h: float, longest: float) -> float:
    """The step the next macro step starts with after a first step of ``h`` (of at most
    ``longest``) that did ``report``; 0 for the whole span: BREAK_STEP after a stall, twice ``h``
    after at most EASY_NEWTON iterations, else ``h``. Wood that a break set moving (a bit swinging
    on its last connection) stalls long steps, whose Newton iterates slide it off its arc; short
    ones follow it in a few iterations, and the steps grow back as it comes to rest."""
    if not report.converged:
        return BREAK_STEP
    grown = 2.0 * h if report.newton <= EASY_NEWTON else h
    return 0.0 if grown >= longest else grown


def macro_step(model: WoodModel, state, n_sub: int) -> int:
    """Algorithm 1 lines 4-8 with ``mechanics.solver = "implicit"``: one backward Euler step of
    :func:`span`, or shorter as :func:`next_step` set, under the loads of the day (a stalled one
    goes on in a step of BREAK_STEP), then
    failure in order (:mod:`~wooddecay.sim.break_order`): while anything is over its limit, the
    round's breaks, each furthest over its limit within its neighbourhood, and a step of
    BREAK_STEP from there (what a break frees moves, and the inertia of short steps keeps Newton
    well-posed); the last of FAILURE_ROUNDS rounds breaks all that is over. The first step's
    displacement of the bound wood is creep through the rest data's change since the last macro
    step (:func:`creep`). Returns the new failures; ``ms.resolves`` counts the steps after
    breaks."""
    setup, ms = model.mech, state.mech
    ms.force = mechanics.external_forces(setup, state.t_days)
    longest = span(setup, n_sub)
    h = min(longest, ms.h_next[0]) if ms.h_next[0] > 0.0 else longest
    elapsed = (state.t_days - ms.stepped_day[0]) * DAY
    ms.stepped_day[0] = state.t_days
    new = 0
    for round_ in range(FAILURE_ROUNDS):
        ms.pairs_x = None
        mechanics.refresh_pairs(setup, ms)
        report = step(setup, ms, h, tol=setup.residual_tolerance, stall=STALL)
        ms.t_seconds += h
        if round_ == 0:
            ms.h_next[0] = next_step(report, h, longest)
        last_h = h
        if not report.converged and h > BREAK_STEP:  # a stalled long step: on in short ones
            report = step(setup, ms, BREAK_STEP, tol=setup.residual_tolerance)
            last_h = BREAK_STEP
            ms.t_seconds += BREAK_STEP
        rb = rigid.bodies(setup, ms)
        if round_ == 0:
            creep(ms, rb, last_h, elapsed)
        ms.unconverged[0] += not report.converged
        ms.resolves[0] += round_ > 0
        last = round_ == FAILURE_ROUNDS - 1
        rigid.freeze_strains(setup, ms, rb)
        count = failure.update(setup, ms, tested=None if last else break_order.select(setup, ms))
        new += count
        if not count:
            break
        h = BREAK_STEP
    return new


def creep(ms: MechState, rb: rigid.Bodies, h: float, elapsed: float) -> None:
    """The velocities after a macro step's first step of ``h`` that answered rest data changed over
    ``elapsed`` seconds of biology: the bound wood (every piece not among the rigid ``rb``,
    :mod:`~wooddecay.sim.rigid`) moved there through the change, so its displacement is spread
    over ``elapsed`` (v = dx / elapsed), not momentum gained in ``h``; rigid pieces keep
    theirs (they fall). Why (docs/decisions.md, "Creep between macro steps"): with dx / h the
    log's wood left every first step of 0.01 s moving at 2.4 cm/s (median), the next step
    started 16x further from equilibrium, and the schedule found it moving at every macro step."""
    if elapsed <= h:
        return
    ms.v[rb.particle < 0] *= h / elapsed
    ms.omega[rb.element < 0] *= h / elapsed


def settle(model: WoodModel, state) -> None:
    """The rods' static equilibrium under gravity with infinite limits (only decayed connections
    and crumbled elements fail), its strains the reference of :func:`failure.update`, as
    :func:`wooddecay.sim.mechanics.settle` does by settling in time. Wood that nothing can hold
    (no anchor, no collider) has no static equilibrium: it falls, in steps of BREAK_STEP over
    ``time.settle`` seconds, as XPBD's settling lets it."""
    setup, ms = model.mech, state.mech
    limits = ms.limit_elem, ms.limit_edge
    ms.limit_elem, ms.limit_edge = np.full_like(limits[0], np.inf), np.full_like(limits[1], np.inf)
    ms.force = np.zeros((setup.n_particles, 3))
    failure.update(setup, ms)
    mechanics.refresh_pairs(setup, ms)
    if setup.anchored_p.any() or len(setup.colliders):
        ms.unconverged[0] += not step(setup, ms, np.inf, tol=setup.residual_tolerance, max_newton=SETTLE_NEWTON).converged
    else:
        for _ in range(int(np.ceil(model.time.settle / BREAK_STEP - 1e-9))):
            ms.unconverged[0] += not step(setup, ms, BREAK_STEP, tol=setup.residual_tolerance).converged
    ms.limit_elem, ms.limit_edge = limits
    ms.strain_ref_elem, ms.strain_ref_edge = failure.strains(setup, ms)
    ms.v[:] = 0.0
    ms.omega[:] = 0.0
    sleep.wake_all(setup, ms)
