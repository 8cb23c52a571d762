"""How far the rods are from static equilibrium: one measure for every solver (docs/model.md §4).

The forces are those of the energies XPBD converges to (:mod:`~wooddecay.sim.rods`), evaluated on
a returned state, never the solver's own multipliers, so XPBD at any number of sweeps and an
implicit solve are judged alike:

* stretch E = 1/2 (E A / l_r) (|p_b - p_a| - l_r)^2;
* shear E = 1/2 G A l_r sum_k C_k^2, C_k = ((p_b - p_a) / l_r) . d_k(q), k = 1, 2;
* bend-twist of strand joints and REG pairs E = 1/2 sum_c k_c l C_c^2,
  C = (2 / l) (Im(conj(q_i) q_j) - s Im(Omega_0)), k = (E I, E I, G J) (times I_ij on the REG);
* REG connection (Eq. 2) E = 1/2 c k_conn (|c_j - c_i| - dp)^2 on element centres, plus, with
  offset shares s_a > 0 (implicit solver only), 1/2 sum_a s_a k_conn ((c_j - c_i - (u_i + u_j) / 2) . e_a)^2,
  u_i the pair's rest offset carried by i's rotation (:func:`connection_targets`);
* contact of colliders and of capsule pairs (Eqs. 3-4) F = k_col phi^2 n, phi beyond the pair's
  rest overlap, i.e. E = k_col phi^3 / 3;
* gravity, the ``[[load]]`` forces and the studies' torques.

A world rotation increment dtheta of element j turns q_j into exp(dtheta / 2) q_j and changes
Im(conj(q_i) q_j) = v (w its real part) by 1/2 (w I - [v]x) R_i^T dtheta (the increment of i by
minus that), so the pair's torque on j is -1/2 R_i (w g + v x g) with g = dE / dIm; the shear's
on its element is -G A l_r sum_k C_k (d_k x (p_b - p_a) / l_r).

:func:`equilibrium_residual` is the net force on each particle and the net torque over the
length of each element of the bound wood (the components held by an anchor or within contact
reach of a collider or another piece; a piece falling clear is judged by its motion, not by
this), summed as
norms, over a normaliser that is never zero for a loaded or shrinking body: each particle's weight
and load plus the force its stretch and REG connections' rest changes would cause if it were held.
At a contact, static friction may take up to mu_f times the contact's normal force of the
tangential remainder. Anchored particles and elements carry reactions and are left out of both
sums. Plain numpy, one pass over the constraints: a frame of the log costs a few milliseconds.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..quaternion import conj_np, mul_np, rotate_np
from . import rigid
from .contact.closest import capsule_contact_reference
from .contact.colliders import collider_distance_reference
from .mechanics import CONTACT_MARGIN, MechSetup, MechState, joint_stiffness


class Forces(NamedTuple):
    """Generalised forces of the rods' potential on a state (module docstring)."""

    f: np.ndarray  # (P, 3) float64, N: net force on each particle, contact included
    tau: np.ndarray  # (n, 3) float64, N m: net world torque on each element
    contact: np.ndarray  # (P, 3) float64, N: the colliders' and pairs' normal forces in ``f``
    scale: np.ndarray  # (P,) float64, N: weight, load and rest-change force (the normaliser)
    energy: float  # J: the potential (elastic, contact, gravity, loads)


def _scatter(index: np.ndarray, values: np.ndarray, size: int) -> np.ndarray:
    """Sums of the rows ``values`` (k, 3) into ``size`` rows at ``index``, in index order."""
    return np.stack([np.bincount(index, values[:, c], minlength=size) for c in range(3)], axis=1)


def _darboux(q: np.ndarray, pairs: np.ndarray, rest: np.ndarray, length: np.ndarray, kb: np.ndarray,
             kt: np.ndarray) -> tuple[np.ndarray, float]:
    """Torques (n, 3) and energy of the bend-twist constraints of element ``pairs`` (module
    docstring), with s picking the nearer of +-Omega_0 as the projection does."""
    i, j = pairs[:, 0], pairs[:, 1]
    om = mul_np(conj_np(q[i]), q[j])
    s = np.where((om * rest).sum(axis=1) >= 0.0, 1.0, -1.0)
    f = 2.0 / length
    C = f[:, None] * (om[:, 1:] - s[:, None] * rest[:, 1:])
    k = np.stack([kb, kb, kt], axis=1) * length[:, None]
    g = k * C * f[:, None]
    t = rotate_np(q[i], 0.5 * (om[:, :1] * g + np.cross(om[:, 1:], g)))
    n = len(q)
    return _scatter(i, t, n) - _scatter(j, t, n), float(0.5 * (k * C * C).sum())


def reg_stiffness(setup: MechSetup, ms: MechState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Connection, pair bend and pair twist stiffness per REG edge id: those of
    :meth:`~wooddecay.sim.mechanics.RegSweep.arrays`, taken out of colour order."""
    kreg, order = setup.sweep.arrays(ms), setup.sweep.order
    out = []
    for k in (kreg.k_conn, kreg.k_bend, kreg.k_twist):
        by_id = np.empty(len(order))
        by_id[order] = k
        out.append(by_id)
    return out[0], out[1], out[2]


def _strands(setup: MechSetup, ms: MechState, f: np.ndarray, tau: np.ndarray, scale: np.ndarray) -> float:
    """Stretch and shear of the intact elements into ``f``, ``tau``, ``scale``; their energy."""
    e = np.flatnonzero(ms.element_ok)
    a, b = setup.fp[e], setup.fp[e] + 1
    l = ms.rest_length[e]
    d = ms.x[b] - ms.x[a]
    L = np.linalg.norm(d, axis=1)
    ks = setup.k_stretch[e] / l
    fs = (ks * (L - l) / np.where(L > 0.0, L, 1.0))[:, None] * d  # on a, minus on b
    q = ms.q[e]
    g = d / l[:, None]
    dk = [rotate_np(q, np.broadcast_to(axis, g.shape)) for axis in (np.eye(3)[0], np.eye(3)[1])]
    Ck = [np.einsum("ij,ij->i", g, dd) for dd in dk]
    ksh = setup.k_shear[e] * l
    fsh = -(ksh / l)[:, None] * (Ck[0][:, None] * dk[0] + Ck[1][:, None] * dk[1])  # on b, minus on a
    P, n = len(f), len(tau)
    f += _scatter(a, fs - fsh, P) + _scatter(b, fsh - fs, P)
    tau -= _scatter(e, ksh[:, None] * (Ck[0][:, None] * np.cross(dk[0], g) + Ck[1][:, None] * np.cross(dk[1], g)), n)
    rest = np.abs(ks * (l - setup.rest_length0[e]))
    scale += np.bincount(a, rest, minlength=P) + np.bincount(b, rest, minlength=P)
    return float(0.5 * (ks * (L - l) ** 2).sum() + 0.5 * (ksh * (Ck[0] ** 2 + Ck[1] ** 2)).sum())


def connection_targets(setup: MechSetup, ms: MechState, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """u_i, u_j (k, 3): the rest offset c_j - c_i of the REG edges ``k`` carried by i's and by j's
    rotation from rest, scaled to the current rest offset dp (Eq. 16)."""
    i, j, d0 = setup.edges[k, 0], setup.edges[k, 1], setup.offset0[k]
    f = (ms.rest_offset[k] / np.where(d0 > 0.0, d0, 1.0))[:, None]
    return f * rotate_np(ms.q[i], setup.edge_body[k, 0]), f * rotate_np(ms.q[j], setup.edge_body[k, 1])


def offset_tensor(setup: MechSetup, ms: MechState, k: np.ndarray, k_conn: np.ndarray) -> np.ndarray:
    """B (k, 3, 3): the co-rotated offset's stiffness of the REG edges ``k`` in the world, sum_a
    s_a k_conn e_a e_a^T over the pair's axes e_a (``setup.edge_axes`` turned by i's rotation) and
    their shares s_a (``setup.offset_share``); ``k_conn`` of the edges ``k``."""
    i = setup.edges[k, 0]
    axes = np.stack([rotate_np(ms.q[i], setup.edge_axes[k, a]) for a in range(3)], axis=1)  # rows e_a
    return np.einsum("ka,kai,kaj->kij", setup.offset_share[k] * k_conn[:, None], axes, axes)


def _connections(setup: MechSetup, ms: MechState, k_conn: np.ndarray, f: np.ndarray, tau: np.ndarray,
                 scale: np.ndarray) -> float:
    """REG connections into ``f``, ``tau`` and ``scale``; their energy: the central spring (Eq. 2)
    with ``setup.central_share`` of k_conn and, where ``setup.offset_share`` is not zero, the
    co-rotated offset 1/2 delta^T B delta, delta = d - (u_i + u_j) / 2 (:func:`connection_targets`,
    :func:`offset_tensor`), whose torque on i is 1/2 u_i x g + delta x g (the second from B turning
    with i) and on j 1/2 u_j x g, g = B delta."""
    k = np.flatnonzero(k_conn > 0.0)
    ai, aj = setup.fp[setup.edges[k, 0]], setup.fp[setup.edges[k, 1]]
    d = 0.5 * (ms.x[aj] + ms.x[aj + 1] - ms.x[ai] - ms.x[ai + 1])
    L = np.linalg.norm(d, axis=1)
    c = setup.central_share[k]
    kc, dp = k_conn[k], ms.rest_offset[k]
    half = (0.5 * c * kc * (L - dp) / np.where(L > 0.0, L, 1.0))[:, None] * d  # on each of i's particles
    energy = 0.5 * (c * kc * (L - dp) ** 2).sum()
    off = setup.offset_share[k].any(axis=1)
    if off.any():
        o = k[off]
        ui, uj = connection_targets(setup, ms, o)
        delta = d[off] - 0.5 * (ui + uj)
        g = np.einsum("kij,kj->ki", offset_tensor(setup, ms, o, kc[off]), delta)
        half[off] += 0.5 * g
        n = len(tau)
        tau += (_scatter(setup.edges[o, 0], 0.5 * np.cross(ui, g) + np.cross(delta, g), n)
                + _scatter(setup.edges[o, 1], 0.5 * np.cross(uj, g), n))
        energy += 0.5 * (g * delta).sum()
    P = len(f)
    for p, sign in ((ai, 1.0), (ai + 1, 1.0), (aj, -1.0), (aj + 1, -1.0)):
        f += _scatter(p, sign * half, P)
        scale += np.bincount(p, 0.5 * kc * np.abs(dp - setup.offset0[k]), minlength=P)
    return float(energy)


class PairContacts(NamedTuple):
    """The capsule pairs of ``ms.pairs`` at their closest points (Eq. 3)."""

    elements: np.ndarray  # (k, 2) int64: i, j
    blocks: np.ndarray  # (k, 4) int64: the particles of i, then of j
    w: np.ndarray  # (k, 4) float64: their weights in j's closest point minus i's
    normal: np.ndarray  # (k, 3) float64: unit direction from i to j
    phi: np.ndarray  # (k,) float64, m: penetration beyond the pair's rest and protected overlap (negative: a gap)


def pair_contacts(setup: MechSetup, ms: MechState) -> PairContacts:
    """:class:`PairContacts` of ``ms.pairs`` (the Verlet list of :func:`mechanics.refresh_pairs`).
    Neither the rest overlap nor the protected one a pair had when its elements separated is a
    force: pieces born overlapping their old neighbours are not pushed apart by that overlap
    (XPBD lets it out at v_depenetration, the implicit step as the pieces part:
    :func:`wooddecay.sim.implicit.step`)."""
    i, j = ms.pairs[:, 0], ms.pairs[:, 1]
    a, b = setup.fp[i], setup.fp[j]
    s, t, normal, phi = capsule_contact_reference(ms.x[a], ms.x[a + 1], ms.radius[i], ms.x[b], ms.x[b + 1],
                                                  ms.radius[j])
    rest = ms.pairs_rest if len(ms.pairs_rest) == len(ms.pairs) else np.zeros(len(ms.pairs))
    if len(ms.pairs_protect) == len(ms.pairs):
        rest = rest + ms.pairs_protect
    return PairContacts(ms.pairs, np.stack([a, a + 1, b, b + 1], axis=1), np.stack([s - 1.0, -s, 1.0 - t, t], axis=1),
                        normal, phi - rest)


def _contacts(setup: MechSetup, ms: MechState) -> tuple[np.ndarray, float, np.ndarray]:
    """Normal contact forces (P, 3) of colliders and pairs (Eq. 4), their energy and the
    elements within contact reach (bool, (n,)): a gap under CONTACT_MARGIN radii, so a piece that
    rests or has bounced a little is judged, and one that falls clear is not."""
    P, n = setup.n_particles, setup.n_elements
    fc, energy, touching = np.zeros((P, 3)), 0.0, np.zeros(n, dtype=bool)
    if setup.k_col <= 0.0:
        return fc, energy, touching
    hit = np.zeros(P, dtype=bool)
    for row in setup.colliders:
        sd, normal = collider_distance_reference(row, ms.x)
        phi = np.maximum(ms.radius_p - sd, 0.0)
        fc += (setup.k_col * phi * phi)[:, None] * normal
        energy += float(setup.k_col * (phi ** 3).sum() / 3.0)
        hit |= ms.radius_p - sd > -CONTACT_MARGIN * ms.radius_p
    touching |= hit[setup.fp] | hit[setup.fp + 1]
    if len(ms.pairs):
        pc = pair_contacts(setup, ms)
        i, j = pc.elements[:, 0], pc.elements[:, 1]
        near = pc.phi > -CONTACT_MARGIN * np.minimum(ms.radius[i], ms.radius[j])
        phi = np.maximum(pc.phi, 0.0)
        F = (setup.k_col * phi * phi)[:, None] * pc.normal
        fc += _scatter(pc.blocks.ravel(), (pc.w[:, :, None] * F[:, None, :]).reshape(-1, 3), P)
        energy += float(setup.k_col * (phi ** 3).sum() / 3.0)
        touching[i[near]] = touching[j[near]] = True
    return fc, energy, touching


def forces(setup: MechSetup, ms: MechState) -> tuple[Forces, np.ndarray]:
    """The :class:`Forces` of the rods' potential on ``ms`` and the elements in contact."""
    P, n = setup.n_particles, setup.n_elements
    f, tau, scale = np.zeros((P, 3)), np.zeros((n, 3)), np.zeros(P)
    energy = _strands(setup, ms, f, tau, scale)
    kb, kt = joint_stiffness(setup, ms)
    t, e = _darboux(ms.q, setup.joints, setup.joint_rest, setup.joint_length, kb, kt)
    tau += t
    energy += e
    k_conn, k_pb, k_pt = reg_stiffness(setup, ms)
    energy += _connections(setup, ms, k_conn, f, tau, scale)
    t, e = _darboux(ms.q, setup.edges, setup.edge_rest, setup.edge_length, k_pb, k_pt)
    tau += t
    energy += e
    fc, e, touching = _contacts(setup, ms)
    weight = ms.mass_p[:, None] * setup.gravity[None, :]
    f += fc + weight + ms.force
    tau += ms.torque
    scale += np.linalg.norm(weight, axis=1) + np.linalg.norm(ms.force, axis=1)
    energy += e - float((weight * ms.x).sum() + (ms.force * ms.x).sum())
    return Forces(f, tau, fc, scale, energy), touching


def bound(setup: MechSetup, ms: MechState, touching: np.ndarray) -> np.ndarray:
    """The elements of the components held by an anchor or touching a collider or another piece."""
    held = np.unique(ms.component[setup.anchored_e | touching])
    return np.isin(ms.component, held)


def _friction(f: np.ndarray, contact: np.ndarray, mu: float) -> np.ndarray:
    """``f`` (P, 3) less what static friction can take at a contact: up to mu |N| of its part
    across the contact force N."""
    N = np.linalg.norm(contact, axis=1)
    nhat = contact / np.where(N > 0.0, N, 1.0)[:, None]
    fn = np.einsum("ij,ij->i", f, nhat)[:, None] * nhat
    ft = f - fn
    T = np.linalg.norm(ft, axis=1)
    keep = np.maximum(T - mu * N, 0.0) / np.where(T > 0.0, T, 1.0)
    return fn + keep[:, None] * ft


def equilibrium_residual(setup: MechSetup, ms: MechState,
                         inertia: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """Net force and torque on the bound wood over its normaliser (module docstring): 0 in
    equilibrium, 1 for wood that carries its loads with no deformation at all. ``inertia``: the
    forces (P, 3) and torques (n, 3) of a time step's inertia term, added to the net. A rigid
    piece (:mod:`~wooddecay.sim.rigid`) is judged as one body: :func:`_rigid_remainder`."""
    F, touching = forces(setup, ms)
    if inertia is not None:
        F = F._replace(f=F.f + inertia[0], tau=F.tau + inertia[1])
    elems = bound(setup, ms, touching)
    parts = np.zeros(setup.n_particles, dtype=bool)
    parts[setup.fp[elems]] = parts[setup.fp[elems] + 1] = True
    parts &= ~setup.anchored_p
    den = float(F.scale[parts].sum())
    if den <= 0.0:
        return 0.0
    rb = rigid.bodies(setup, ms)
    own = parts & (rb.particle < 0)
    rest = _friction(F.f[own], F.contact[own], setup.mu_f)
    turn = elems & ~setup.anchored_e & (rb.element < 0)
    num = np.linalg.norm(rest, axis=1).sum() + (np.linalg.norm(F.tau[turn], axis=1) / ms.rest_length[turn]).sum()
    judged = np.zeros(rb.n_pieces, dtype=bool)
    judged[rb.element[elems & (rb.element >= 0)]] = True
    return float((num + _rigid_remainder(setup, ms, F, rb)[judged].sum()) / den)


#: projected gradient iterations of the rigid pieces' static friction (:func:`_rigid_remainder`)
FRICTION_ITERATIONS = 100


def _rigid_remainder(setup: MechSetup, ms: MechState, F: Forces, rb: rigid.Bodies) -> np.ndarray:
    """Per rigid piece, |a| + |b| / rho with a and b its net force and its net torque about its
    centre (its own elastic forces cancel in both) plus the static friction phi_p at its contacts
    that minimises |a|^2 + |b|^2 / rho^2, each phi_p across its contact's normal force N_p and at
    most mu_f |N_p| (projected gradient, FRICTION_ITERATIONS steps of 1 / Lipschitz from zero);
    rho the piece's radius of gyration."""
    p = np.flatnonzero(rb.particle >= 0)
    k, size = rb.particle[p], rb.n_pieces
    r = ms.x[p] - rb.centre[k]
    e = np.flatnonzero(rb.element >= 0)
    net = _scatter(k, F.f[p], size)
    torque = _scatter(k, np.cross(r, F.f[p]), size) + _scatter(rb.element[e], F.tau[e], size)
    m = np.bincount(k, ms.mass_p[p], minlength=size)
    gyration = np.sqrt(np.bincount(k, ms.mass_p[p] * (r * r).sum(axis=1), minlength=size) / np.where(m > 0.0, m, 1.0))
    rho2 = np.where(gyration > 0.0, gyration, 1.0) ** 2
    N = np.linalg.norm(F.contact[p], axis=1)
    c = np.flatnonzero(N > 0.0)
    kc, rc, cap = k[c], r[c], setup.mu_f * N[c]
    n = F.contact[p][c] / N[c, None]
    lipschitz = np.bincount(kc, 1.0 + (rc * rc).sum(axis=1) / rho2[kc], minlength=size)
    step = 1.0 / np.where(lipschitz > 0.0, lipschitz, 1.0)[kc]
    phi = np.zeros_like(rc)
    a, b = net, torque
    for _ in range(FRICTION_ITERATIONS if len(c) else 0):
        g = a[kc] + np.cross(b[kc], rc) / rho2[kc, None]
        phi = phi - step[:, None] * g
        phi -= np.einsum("ij,ij->i", phi, n)[:, None] * n
        size_phi = np.linalg.norm(phi, axis=1)
        phi *= (np.minimum(size_phi, cap) / np.where(size_phi > 0.0, size_phi, 1.0))[:, None]
        a = net + _scatter(kc, phi, size)
        b = torque + _scatter(kc, np.cross(rc, phi), size)
    return np.linalg.norm(a, axis=1) + np.linalg.norm(b, axis=1) / np.sqrt(rho2)
