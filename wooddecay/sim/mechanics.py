"""Mechanics: XPBD Cosserat strands coupled on the REG (woodstock §5, Eqs. 1-2; Algorithm 1
lines 4-8).

One substep of length dt (``substep``):

1. external forces (gravity, ``[[load]]`` forces), viscous damping, prediction of particle
   positions and element quaternions (angular velocity in the body frame);
2. ``iterations`` sweeps (:mod:`wooddecay.sim.rods`) of: Stage 1 per strand (stretch and shear of
   even then odd elements, bend-twist of even then odd joints: a red-black order along each chain;
   the runs of a strand that no intact REG edge ties to another strand, a lone strand or a stick
   broken free, all at once by :mod:`~wooddecay.sim.strand_solve`, :func:`stage1_plan`),
   Stage 2 on the REG one colour class at a time (connection of Eq. 2 scaled by I_ij, pair
   bend-twist by the rest Darboux vector), colliders and capsule contact
   (:mod:`wooddecay.sim.contact`, Eqs. 3-4, with the particle friction of Eq. 7 applied to the
   displacements of the substep after all normal contact steps);
3. velocities from the positions; contacts touched in this substep keep no separating normal
   velocity (restitution 0);
4. failure against the limits L(M) and recomputed components (:mod:`wooddecay.sim.failure`).

Anchored elements (a stump) have zero inverse mass and inertia. Stiffnesses come from the strand's
E A, G A, E I, G J (``[mechanics] E, G``, radius r_s); a REG connection has stiffness
G A_c / dp_0 with A_c = 2 r_s l the strands' contact area, and its pair bend-twist coupling the
strand's E I, G J over dp_0. The kernels of :mod:`~wooddecay.sim.rods` and
:mod:`~wooddecay.sim.contact` each have a plain-numpy ``*_reference`` twin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from typing import NamedTuple, cast

import numba as nb
import numpy as np

from ..wood import WoodModel
from ..quaternion import conj_np, mul, mul_np, rotate, rotate_np
from ..wood import Load, MechConfig
from . import contact, failure, rods, sleep, strand_solve

#: contact candidate pairs are searched with this margin (in r_s) and rebuilt once a particle
#: has moved half of it (a Verlet list)
CONTACT_MARGIN = 2.0
#: seconds of settling between two checks of the strain drift (:func:`settle` with ``tol``)
SETTLE_CHUNK = 0.05
#: a [[load]] may move a particle by at most this fraction of its element's rest length in one
#: substep (dt^2 w_p |f_p|); beyond it the substeps are split (:func:`load_split`)
LOAD_JUMP = 0.25
#: largest :func:`strain_excess` a bake accepts without a warning: a clamped strand then sags
#: within about 3% of beam theory
STRAIN_EXCESS_TOLERANCE = 0.03
#: iterations a substep that bring a bundle of strands within about 0.02 of its law (Fig. 6's
#: section: 0.94 at 16, 0.058 at 128, 0.020 at 256; docs/decisions.md, "Fig. 6: a converged
#: section"), for the remedy the bake prints
CONVERGED_ITERATIONS = 256


@dataclass(frozen=True, eq=False)
class RegSweep:
    """Stage 2's static per-edge data in colour order (:func:`rods.color_edges`): colour c is
    the block ``ptr[c]:ptr[c + 1]``, its edges in increasing id, and ``order`` maps a position
    to its REG edge id. A colour class then reads its edges' data as one contiguous block
    instead of one cache line per edge (docs/decisions.md, "Stage 2 in colour order")."""

    ptr: np.ndarray  # (colours + 1,)
    order: np.ndarray  # (m,) edge id at each position
    edges: np.ndarray  # (m, 2)
    rest: np.ndarray  # (m, 4) rest Darboux
    length: np.ndarray  # (m,) lever of the pair bend-twist
    k_conn0: np.ndarray  # (m,) connection stiffness at I = 1
    k_pb0: np.ndarray  # (m,)
    k_pt0: np.ndarray  # (m,)

    @classmethod
    def of(cls, ptr: np.ndarray, order: np.ndarray, edges, rest, length, k_conn0, k_pb0, k_pt0) -> "RegSweep":
        return cls(ptr, order, *(np.ascontiguousarray(a[order]) for a in (edges, rest, length, k_conn0, k_pb0, k_pt0)))

    def arrays(self, ms: "MechState") -> "RegStiffness":
        """dp, connection, pair bend and pair twist stiffness (base times I_ij, zero where
        failed) of the current state, in colour order, and the edges that keep any
        (:func:`rods.active_edges`)."""
        out = cast("tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]",
                   tuple(np.empty(len(self.order)) for _ in range(4)))
        _sweep_arrays(self.order, ms.edge_ok, ms.integrity, ms.rest_offset, self.k_conn0, self.k_pb0, self.k_pt0,
                      *out)
        return RegStiffness(*out, *rods.active_edges(self.ptr, *out[1:]))


class RegStiffness(NamedTuple):
    """Stage 2's per-state data (:meth:`RegSweep.arrays`), in colour order."""

    offset: np.ndarray
    k_conn: np.ndarray
    k_bend: np.ndarray
    k_twist: np.ndarray
    active: np.ndarray  # positions with any stiffness left, class by class
    ptr: np.ndarray  # class c is active[ptr[c]:ptr[c + 1]]


@nb.njit(parallel=True, cache=True)
def _sweep_arrays(order, edge_ok, integrity, rest_offset, k_conn0, k_pb0, k_pt0, offset, k_conn, k_bend, k_twist):
    """:meth:`RegSweep.arrays`, one gather (numpy fancy indexing of the (m, 3) flags took 17 ms
    per substep on the tree)."""
    for t in nb.prange(len(order)):
        k = order[t]
        offset[t] = rest_offset[k]
        k_conn[t] = integrity[k] * k_conn0[t] if edge_ok[k, 0] else 0.0
        k_bend[t] = integrity[k] * k_pb0[t] if edge_ok[k, 1] else 0.0
        k_twist[t] = integrity[k] * k_pt0[t] if edge_ok[k, 2] else 0.0


@dataclass(frozen=True, eq=False)
class MechSetup:
    """Static data of the rod system, built once with the model (``model.mech``)."""

    fp: np.ndarray  # (n,) first particle of each element (the second is fp + 1)
    n_particles: int
    elems: tuple  # (even, odd) element ids: the two colour classes of Stage 1 stretch-shear
    joints: np.ndarray  # (J, 2) consecutive elements (e, e + 1) of a strand
    joint_sets: tuple  # (even, odd) joint ids
    strand_offsets: np.ndarray  # (strands + 1,) element ranges of the strands
    joint_of: np.ndarray  # (n,) the joint (e, e + 1) of element e, -1 at a strand's last element
    joint_rest: np.ndarray  # (J, 4) rest Darboux quaternion conj(q_e) q_{e+1}
    joint_length: np.ndarray  # (J,) mean rest length of the two elements
    joint_kb: np.ndarray  # (J,) E I
    joint_kt: np.ndarray  # (J,) G J
    rest_length0: np.ndarray  # (n,) l_r0
    radius: np.ndarray
    k_stretch: np.ndarray  # (n,) E A
    k_shear: np.ndarray  # (n,) G A
    inertia_factor: np.ndarray  # (n,) I_rot / m = inertia_scale (r^2 / 4 + l^2 / 12)
    dry_mass: np.ndarray  # (n,) rho_dry pi r^2 l_r0 (element mass = dry_mass (1 + M))
    anchored_p: np.ndarray  # (P,) pinned particles
    anchored_e: np.ndarray  # (n,) elements without rotation
    x_rest: np.ndarray  # (P, 3) rest particle positions (the rest overlap of contact pairs)
    inner: np.ndarray  # (n,) elements with a neighbour on both sides in their strand
    edges: np.ndarray  # (m, 2) REG
    edge_rest: np.ndarray  # (m, 4) rest Darboux
    offset0: np.ndarray  # (m,) dp_0
    edge_length: np.ndarray  # (m,) max(dp_0, r_s): the lever of the pair bend-twist
    sweep: RegSweep  # Stage 2 data in colour order
    gravity: np.ndarray
    damping: float
    dt: float
    iterations: int
    strand_solver: str  # "auto", "direct" or "gauss-seidel" (:func:`stage1_plan`)
    solver: str  # "xpbd" or "implicit" (:mod:`~wooddecay.sim.implicit`)
    residual_tolerance: float  # the equilibrium residual each implicit step is solved to
    central_share: np.ndarray  # (m,) share of k_conn on the central spring (:mod:`~wooddecay.sim.equilibrium`)
    offset_share: np.ndarray  # (m, 3) share of k_conn on the co-rotated offset along the pair's R, T, L
    edge_body: np.ndarray  # (m, 2, 3) rest offset c_j - c_i in i's and in j's body frame
    edge_axes: np.ndarray  # (m, 3, 3) rows: element i's wood axes e_R, e_T, e_L at rest in its body frame
    colliders: np.ndarray  # (k, contact.COLLIDER_COLUMNS)
    k_col: float
    v_depenetration: float
    mu_f: float
    epsilon: float
    loads: tuple  # of (day0, day1, (P, 3) particle forces)
    I_fail_elem: np.ndarray | None = None  # (n,) integrity below which the strand link e, e + 1 fails
    I_fail_edge: np.ndarray | None = None  # (m,) integrity below which a REG connection fails
    sleep_speed: float = 0.0  # :mod:`~wooddecay.sim.sleep` (0: never)
    sleep_time: float = 0.2

    @property
    def n_elements(self) -> int:
        return len(self.fp)

    @cached_property
    def all_elements(self) -> np.ndarray:
        """Every element id (:func:`failure.update` tests these by default)."""
        return np.arange(len(self.fp))

    @cached_property
    def all_edges(self) -> np.ndarray:
        """Every REG edge id."""
        return np.arange(len(self.edges))


@dataclass(eq=False)
class MechState:
    """The mechanical part of the SimState (docs/architecture.md: positions, velocities, quaternions,
    angular velocities, current rest data, I_ij, failure flags, component labels)."""

    x: np.ndarray  # (P, 3) particle positions
    v: np.ndarray  # (P, 3)
    q: np.ndarray  # (n, 4) element orientations (w, x, y, z)
    omega: np.ndarray  # (n, 3) angular velocities, body frame
    w_p: np.ndarray  # (P,) inverse masses
    mass_p: np.ndarray  # (P,)
    w_q: np.ndarray  # (n,) inverse quaternion inertia 1 / (4 I_rot)
    mass_e: np.ndarray  # (n,) element masses
    rest_length: np.ndarray  # (n,) l_r (Eq. 17)
    rest_offset: np.ndarray  # (m,) dp (Eq. 16)
    radius: np.ndarray  # (n,) contact radius: r_s shrunk by brown rot (:mod:`~wooddecay.sim.coupling`)
    radius_p: np.ndarray  # (P,) particle radius (collider clearance)
    integrity: np.ndarray  # (m,) I_ij (Eq. 21)
    link_integrity: np.ndarray  # (n,) I of the strand link e, e + 1 (Eq. 21; 1 at a strand end)
    crumbled: np.ndarray  # (n,) bool: remaining mass below m_crumble (:mod:`~wooddecay.sim.coupling`)
    limit_elem: np.ndarray  # (n, 2) stretch, shear limits L(M) (Eq. 18)
    limit_edge: np.ndarray  # (m, 3) bundle, bend, twist limits
    element_ok: np.ndarray  # (n,) bool: stretch / shear intact
    edge_ok: np.ndarray  # (m, 3) bool: connection, bend, twist intact
    component: np.ndarray  # (n,) int64 connected-component label
    strain_ref_elem: np.ndarray  # (n, 2) settled stretch, shear strain (failure measures from it)
    strain_ref_edge: np.ndarray  # (m, 3) settled bundle, bend, twist strain
    asleep: np.ndarray  # (n,) bool: the element's piece sleeps (:mod:`~wooddecay.sim.sleep`)
    held: np.ndarray  # (n,) bool: the element's piece is held still in this solve (:mod:`~wooddecay.sim.schedule`)
    sleep_x: np.ndarray  # (P, 3) positions at the start of the sleep window
    sleep_t: np.ndarray  # (1,) seconds at the start of the sleep window
    force: np.ndarray  # (P, 3) external forces: the [[load]]s of the day (:func:`macro_step`)
    torque: np.ndarray  # (n, 3) external world torques per element (zero but in studies)
    t_seconds: float = 0.0
    failures: int = 0  # failure events so far (elements + edge flags)
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))  # contact list
    pairs_x: np.ndarray | None = None  # positions when ``pairs`` was built
    pairs_rest: np.ndarray = field(default_factory=lambda: np.zeros(0))  # rest overlap per pair
    pairs_protect: np.ndarray = field(default_factory=lambda: np.zeros(0))  # protected overlap per pair
    pairs_sep: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # row in sep_*, or -1
    #: element pairs i < j (keys i n + j, sorted) that overlapped when they fell into different
    #: components (:func:`failure.record_separations`), and their overlap beyond which contact
    #: resolves penetration at once: the overlap then, lowered by v_depenetration dt per substep
    #: (docs/decisions.md, "Separation overlap"; checkpointed)
    sep_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    sep_overlap: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: the rest data, integrity and masses of the last mechanics solve, its day and whether it
    #: ended quiet (:mod:`~wooddecay.sim.schedule`; checkpointed)
    solved_rest_length: np.ndarray = field(default_factory=lambda: np.zeros(0))
    solved_rest_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))
    solved_integrity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    solved_mass: np.ndarray = field(default_factory=lambda: np.zeros(0))
    solved_day: np.ndarray = field(default_factory=lambda: np.zeros(1))
    quiet: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=bool))
    #: implicit steps that stopped at their Newton cap above their tolerance (checkpointed)
    unconverged: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    #: implicit steps re-solved after a round of breaks (:mod:`~wooddecay.sim.break_order`; checkpointed)
    resolves: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    #: the step (s) the next implicit macro step starts with, 0 for its whole span
    #: (:func:`wooddecay.sim.implicit.macro_step`; checkpointed)
    h_next: np.ndarray = field(default_factory=lambda: np.zeros(1))
    #: the day of the last implicit macro step: the rest data it answers changed since
    #: (:func:`wooddecay.sim.implicit.macro_step`, creep; checkpointed)
    stepped_day: np.ndarray = field(default_factory=lambda: np.zeros(1))
    #: the last exact failure test of every REG edge within this :func:`_advance`
    #: (:class:`failure.Epoch`; not checkpointed: each call starts with an exact test)
    fail_epoch: failure.Epoch | None = None

    def copy(self) -> "MechState":
        return MechState(**{f.name: (getattr(self, f.name).copy() if isinstance(getattr(self, f.name), np.ndarray)
                                     else getattr(self, f.name)) for f in fields(self)})

    def restore(self, arrays: dict[str, np.ndarray], t_seconds: float, failures: int) -> None:
        """Take the state saved as :meth:`arrays` and the clock and failure count."""
        for k in self.arrays():
            setattr(self, k, arrays[k])
        self.t_seconds, self.failures = t_seconds, failures

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays a checkpoint needs (the contact list is rebuilt from them, the forces
        from the loads of the day)."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if isinstance(getattr(self, f.name), np.ndarray)
                and f.name not in ("pairs", "pairs_x", "pairs_rest", "pairs_protect", "pairs_sep", "force", "torque")}


def _joint_length(l0: np.ndarray, anchored: np.ndarray, je: np.ndarray) -> np.ndarray:
    """Length over which a joint's curvature is integrated: half of each adjoining element, but
    only of free ones, so the clamp joint spans half the first free element (the anchored one is
    part of the wall); a full length there would bend the strand as if clamped half an element
    further out (2 / n too much tip deflection)."""
    free = ~anchored
    half = 0.5 * (l0[je] * free[je] + l0[je + 1] * free[je + 1])
    return np.where(half > 0.0, half, 0.5 * (l0[je] + l0[je + 1]))


def _per_particle_max(fp: np.ndarray, values: np.ndarray, P: int) -> np.ndarray:
    """The largest of ``values`` (per element) over the elements at each of the P particles."""
    out = np.zeros(P)
    np.maximum.at(out, fp, values)
    np.maximum.at(out, fp + 1, values)
    return out


def _particle_mass(setup: "MechSetup", mass_e: np.ndarray) -> np.ndarray:
    """Particle masses: half of each element's mass ``mass_e`` to each of its particles."""
    mass_p = np.zeros(setup.n_particles)
    np.add.at(mass_p, setup.fp, 0.5 * mass_e)
    np.add.at(mass_p, setup.fp + 1, 0.5 * mass_e)
    return mass_p


def _inner(element_offsets: np.ndarray, n: int) -> np.ndarray:
    """Elements that are neither the first nor the last of their strand."""
    inner = np.ones(n, dtype=bool)
    inner[element_offsets[:-1]] = False
    inner[element_offsets[1:] - 1] = False
    return inner


def _joint_of(je: np.ndarray, n: int) -> np.ndarray:
    """(n,) joint index of each element's joint (e, e + 1); -1 at a strand's last element."""
    out = np.full(n, -1, dtype=np.int64)
    out[je] = np.arange(len(je))
    return out


def _parity_sets(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (np.ascontiguousarray(ids[ids % 2 == 0]), np.ascontiguousarray(ids[ids % 2 == 1]))


def prepare(model: WoodModel, config: MechConfig, colliders: np.ndarray, loads: tuple[Load, ...]) -> MechSetup:
    """Stiffnesses (from the tissues' E, G, rho_dry in ``model.materials``), colour classes, rest
    data, ``colliders`` (rows of :func:`contact.collider_row`) and the particle forces of
    ``loads`` (each shared over its elements' particles in proportion to their dry mass)."""
    contact.check_colliders(colliders)
    n = model.n_elements
    mech = config
    per_element = model.materials.per_element
    fp = model.first_particle.astype(np.int64)
    P = len(model.particles)
    r, l0 = model.radius, model.rest_length
    A = np.pi * r**2
    je = _joint_elements(model)
    joints = np.stack([je, je + 1], axis=1)
    ij = model.reg_edges.astype(np.int64)
    k = base_stiffness(model, per_element("E"), per_element("G"), mech.reg_moduli, mech.connection_shear)
    rho = per_element("rho_dry")
    I_fail = per_element("I_fail")
    anchored_p = np.zeros(P, dtype=bool)
    anchored_p[fp[model.anchored]] = True
    anchored_p[fp[model.anchored] + 1] = True
    dry = rho * A * l0
    load_forces = []
    for ld in loads:
        mask = ld.mask
        pm = np.zeros(P)
        np.add.at(pm, fp[mask], 0.5 * dry[mask])
        np.add.at(pm, fp[mask] + 1, 0.5 * dry[mask])
        pm[anchored_p] = 0.0
        share = pm / pm.sum() if pm.sum() > 0 else pm
        load_forces.append((ld.day0, ld.day1, share[:, None] * np.asarray(ld.force)[None, :]))
    return MechSetup(
        fp=fp, n_particles=P, elems=_parity_sets(np.arange(n)), joints=joints,
        joint_sets=_parity_sets(np.arange(len(joints))),
        strand_offsets=model.element_offsets.astype(np.int64), joint_of=_joint_of(je, n),
        joint_rest=_conj_mul(model.rest_quat[je], model.rest_quat[je + 1]),
        joint_length=_joint_length(l0, model.anchored, je), joint_kb=k.joint_kb, joint_kt=k.joint_kt,
        rest_length0=l0.copy(), radius=r.copy(), k_stretch=k.k_stretch, k_shear=k.k_shear,
        inertia_factor=mech.inertia_scale * (r**2 / 4.0 + l0**2 / 12.0), dry_mass=dry, anchored_p=anchored_p,
        anchored_e=model.anchored.copy(), x_rest=model.particles.astype(np.float64),
        inner=_inner(model.element_offsets, n), edges=ij, edge_rest=model.reg_rest_darboux.copy(),
        offset0=model.reg_rest_offset.copy(), edge_length=k.edge_length,
        sweep=RegSweep.of(*rods.color_edges(ij, fp, P), ij, model.reg_rest_darboux, k.edge_length,
                          k_conn0=k.k_conn0, k_pb0=k.k_pb0, k_pt0=k.k_pt0),
        gravity=np.asarray(mech.gravity, dtype=np.float64), damping=float(mech.damping),
        dt=float(mech.dt_mech), iterations=int(mech.iterations), strand_solver=str(mech.strand_solver),
        solver=str(mech.solver), residual_tolerance=float(mech.residual_tolerance),
        central_share=k.central_share, offset_share=k.offset_share, edge_body=_edge_body(model, fp, ij),
        edge_axes=_edge_axes(model, ij),
        colliders=colliders, k_col=float(mech.k_col),
        v_depenetration=float(mech.v_depenetration), mu_f=float(mech.mu_f), epsilon=float(mech.epsilon),
        loads=tuple(load_forces),
        sleep_speed=float(mech.sleep_speed), sleep_time=float(mech.sleep_time),
        I_fail_elem=I_fail, I_fail_edge=0.5 * (I_fail[ij[:, 0]] + I_fail[ij[:, 1]]),
    )


class BaseStiffness(NamedTuple):
    """The rods' stiffnesses (:func:`base_stiffness`): per element, per strand joint and per REG edge
    (edge order)."""

    k_stretch: np.ndarray  # (n,) E A
    k_shear: np.ndarray  # (n,) G A
    joint_kb: np.ndarray  # (J,) E I
    joint_kt: np.ndarray  # (J,) G J
    edge_length: np.ndarray  # (m,) lever of the pair bend-twist: max(|dp_0|, r_s)
    k_conn0: np.ndarray  # (m,) connection stiffness at I = 1
    k_pb0: np.ndarray  # (m,)
    k_pt0: np.ndarray  # (m,)
    central_share: np.ndarray  # (m,) share of k_conn0 on the central spring
    offset_share: np.ndarray  # (m, 3) share of k_conn0 on the co-rotated offset along R, T, L


def base_stiffness(model: WoodModel, E: np.ndarray, G: np.ndarray, reg: tuple | None = None,
                   connection_shear: float = 0.0) -> BaseStiffness:
    """Stiffnesses from the strands' moduli ``E``, ``G`` (n,) (docs/model.md §4): stretch and shear
    E A, G A, joint bend and twist E I, G J (pair means), REG pair bend and twist E pi r_s^4 / 4,
    G pi r_s^4 / 2, and the connection (Eq. 2) k_conn = 2 r_s l / |dp_0| G (pair means; |dp_0| at
    least r_s), a share s = ``connection_shear`` of it on the co-rotated offset along every axis
    and 1 - s on the central spring. With ``reg`` = (a_R, a_T, a_L, b_R, b_T, b_L)
    (:class:`~wooddecay.species.RodModuli`, a species' rods) the central spring has 2 r_s l /
    |dp_0| (a_R n_r^2 + a_T n_t^2 + a_L n_l^2), n its rest direction in the wood frame, and the
    offset along the pair's R, T and L axes 2 r_s l / |dp_0| (b_R, b_T, b_L); k_conn0 is the
    central stiffness plus the offset's mean."""
    r = model.radius
    A, I_b = np.pi * r**2, np.pi * (r * r) * (r * r) / 4.0  # products, not numpy's power (wooddecay.fmath)
    je = _joint_elements(model)
    ij = model.reg_edges.astype(np.int64)
    r_s, l0 = model.r_s, model.rest_length
    edge_length = np.maximum(model.reg_rest_offset, r_s)
    Em, Gm = 0.5 * (E[ij[:, 0]] + E[ij[:, 1]]), 0.5 * (G[ij[:, 0]] + G[ij[:, 1]])
    lm = 0.5 * (l0[ij[:, 0]] + l0[ij[:, 1]])
    m = len(ij)
    if reg is None:
        k_conn0 = Gm * 2.0 * r_s * lm / edge_length
        central_share, offset_share = np.full(m, 1.0 - connection_shear), np.full((m, 3), float(connection_shear))
    else:
        lever = 2.0 * r_s * lm / edge_length
        central = lever * (model.reg_dir_weights @ np.asarray(reg[:3], dtype=np.float64))
        offset = lever[:, None] * np.asarray(reg[3:], dtype=np.float64)[None, :]
        k_conn0 = central + offset.mean(axis=1)
        live = k_conn0 > 0.0
        central_share = np.divide(central, k_conn0, out=np.zeros(m), where=live)
        offset_share = np.divide(offset, k_conn0[:, None], out=np.zeros((m, 3)), where=live[:, None])
    return BaseStiffness(k_stretch=E * A, k_shear=G * A, joint_kb=0.5 * (E[je] + E[je + 1]) * I_b[je],
                         joint_kt=0.5 * (G[je] + G[je + 1]) * 2 * I_b[je], edge_length=edge_length,
                         k_conn0=k_conn0, k_pb0=Em * np.pi * r_s**4 / 4.0, k_pt0=Gm * np.pi * r_s**4 / 2.0,
                         central_share=central_share, offset_share=offset_share)


def _edge_body(model: WoodModel, fp: np.ndarray, ij: np.ndarray) -> np.ndarray:
    """The rest offset c_j - c_i of each REG pair in the body frame of its element i and of j
    (the co-rotated offset of :func:`wooddecay.sim.equilibrium.connection_targets`)."""
    x = model.particles.astype(np.float64)
    c = 0.5 * (x[fp] + x[fp + 1])
    d = c[ij[:, 1]] - c[ij[:, 0]]
    q = model.rest_quat
    return np.stack([rotate_np(conj_np(q[ij[:, 0]]), d), rotate_np(conj_np(q[ij[:, 1]]), d)], axis=1)


def _joint_elements(model: WoodModel) -> np.ndarray:
    """The first element of each strand joint: every element but its strand's last."""
    last = np.zeros(model.n_elements, dtype=bool)
    last[model.element_offsets[1:] - 1] = True
    return np.flatnonzero(~last)


def _edge_axes(model: WoodModel, ij: np.ndarray) -> np.ndarray:
    """Element i's wood axes (rows e_r, e_t, e_l of ``model.frames``) in its body frame at rest,
    for each REG pair (i, j): the axes of its co-rotated offset."""
    body = conj_np(model.rest_quat[ij[:, 0]])
    return np.stack([rotate_np(body, model.frames[ij[:, 0], a]) for a in range(3)], axis=1)


def _conj_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return mul_np(conj_np(a), b)


def initial_state(model: WoodModel) -> MechState:
    """Rest configuration, at rest, no external forces; masses and limits are set by
    :func:`coupling.step`."""
    setup = model.mech
    n, m, P = setup.n_elements, len(setup.edges), setup.n_particles
    ms = MechState(
        x=model.particles.astype(np.float64).copy(), v=np.zeros((P, 3)), q=model.rest_quat.copy(),
        omega=np.zeros((n, 3)), w_p=np.zeros(P), mass_p=np.zeros(P), w_q=np.zeros(n), mass_e=np.zeros(n),
        rest_length=setup.rest_length0.copy(), rest_offset=setup.offset0.copy(), radius=setup.radius.copy(),
        radius_p=_per_particle_max(setup.fp, setup.radius, P), integrity=np.ones(m),
        link_integrity=np.ones(n), crumbled=np.zeros(n, dtype=bool), limit_elem=np.full((n, 2), np.inf), limit_edge=np.full((m, 3), np.inf),
        element_ok=np.ones(n, dtype=bool), edge_ok=np.ones((m, 3), dtype=bool),
        component=np.zeros(n, dtype=np.int64), strain_ref_elem=np.zeros((n, 2)),
        strain_ref_edge=np.zeros((m, 3)), asleep=np.zeros(n, dtype=bool), held=np.zeros(n, dtype=bool),
        sleep_x=np.zeros((P, 3)),
        sleep_t=np.zeros(1), force=np.zeros((P, 3)), torque=np.zeros((n, 3)),
    )
    set_masses(setup, ms, np.zeros(n))
    ms.solved_rest_length, ms.solved_rest_offset = ms.rest_length.copy(), ms.rest_offset.copy()
    ms.solved_integrity, ms.solved_mass = ms.integrity.copy(), ms.mass_e.copy()
    sleep.wake_all(setup, ms)  # the first sleep window starts at rest
    ms.component = failure.components(setup, ms)
    return ms


def set_radius(setup: MechSetup, ms: MechState, radius: np.ndarray) -> None:
    """Contact radii ``radius`` per element, and per particle the larger of its elements'."""
    ms.radius = radius
    ms.radius_p = _per_particle_max(setup.fp, radius, setup.n_particles)


def set_masses(setup: MechSetup, ms: MechState, M: np.ndarray) -> None:
    """Element mass rho_dry (1 + M) pi r^2 l (docs/model.md §2), half to each particle; inverse masses
    and quaternion weights 1 / (4 I_rot) (zero where anchored or asleep: new masses wake no
    piece, :func:`sleep.hold`)."""
    ms.mass_e = setup.dry_mass * (1.0 + M)
    ms.mass_p = _particle_mass(setup, ms.mass_e)
    sleep.hold(setup, ms)


def external_forces(setup: MechSetup, t_days: float) -> np.ndarray:
    """(P, 3) load forces active at ``t_days`` ([[load]] days [start, end))."""
    f = np.zeros((setup.n_particles, 3))
    for d0, d1, fl in setup.loads:
        if d0 <= t_days < d1:
            f += fl
    return f


@nb.njit(parallel=True, cache=True)
def _predict(x, v, q, omega, w_p, w_q, mass_p, force, gravity, torque, damp, dt, x_old, q_old):
    for p in nb.prange(len(x)):
        for c in range(3):
            x_old[p, c] = x[p, c]
        if w_p[p] == 0.0:
            v[p, 0] = v[p, 1] = v[p, 2] = 0.0
            continue
        for c in range(3):
            v[p, c] = damp * v[p, c] + dt * (gravity[c] + force[p, c] / mass_p[p])
            x[p, c] += dt * v[p, c]
    for e in nb.prange(len(q)):
        for c in range(4):
            q_old[e, c] = q[e, c]
        if w_q[e] == 0.0:
            omega[e, 0] = omega[e, 1] = omega[e, 2] = 0.0
            continue
        q0, q1, q2, q3 = q[e, 0], q[e, 1], q[e, 2], q[e, 3]
        # body-frame torque conj(q) tau q, I^-1 = 4 w_q
        tb = rotate(q0, -q1, -q2, -q3, torque[e, 0], torque[e, 1], torque[e, 2])
        w0 = damp * omega[e, 0] + dt * 4.0 * w_q[e] * tb[0]
        w1 = damp * omega[e, 1] + dt * 4.0 * w_q[e] * tb[1]
        w2 = damp * omega[e, 2] + dt * 4.0 * w_q[e] * tb[2]
        omega[e, 0], omega[e, 1], omega[e, 2] = w0, w1, w2
        d = mul(q0, q1, q2, q3, 0.0, w0, w1, w2)
        n0, n1, n2, n3 = q0 + 0.5 * dt * d[0], q1 + 0.5 * dt * d[1], q2 + 0.5 * dt * d[2], q3 + 0.5 * dt * d[3]
        s = 1.0 / np.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
        q[e, 0], q[e, 1], q[e, 2], q[e, 3] = n0 * s, n1 * s, n2 * s, n3 * s


@nb.njit(parallel=True, cache=True)
def _velocities(x, v, q, omega, x_old, q_old, w_p, w_q, dt):
    for p in nb.prange(len(x)):
        if w_p[p] > 0.0:
            for c in range(3):
                v[p, c] = (x[p, c] - x_old[p, c]) / dt
    for e in nb.prange(len(q)):
        if w_q[e] > 0.0:
            d = mul(q_old[e, 0], -q_old[e, 1], -q_old[e, 2], -q_old[e, 3], q[e, 0], q[e, 1], q[e, 2], q[e, 3])
            sgn = 1.0 if d[0] >= 0.0 else -1.0
            omega[e, 0] = 2.0 * sgn * d[1] / dt
            omega[e, 1] = 2.0 * sgn * d[2] / dt
            omega[e, 2] = 2.0 * sgn * d[3] / dt


@dataclass(eq=False)
class Multipliers:
    """XPBD multipliers lambda of one substep (Eq. 1), per constraint kind."""

    s: np.ndarray  # (n,) stretch
    sh: np.ndarray  # (n, 2) shear
    j: np.ndarray  # (J, 3) strand joint bend-twist
    c: np.ndarray  # (m,) REG connection, colour order (:class:`RegSweep`)
    p: np.ndarray  # (m, 3) REG pair bend-twist, colour order

    def copy(self) -> "Multipliers":
        return Multipliers(*(getattr(self, f.name).copy() for f in fields(self)))


def multipliers(setup: MechSetup, fresh_reg: bool = False) -> Multipliers:
    """XPBD multipliers of one substep, zero. ``fresh_reg``: the REG ones uninitialised, for a
    first sweep that writes them (:func:`rods.reg_pass` ``fresh``)."""
    n, m = setup.n_elements, len(setup.edges)
    reg = np.empty if fresh_reg else np.zeros
    return Multipliers(np.zeros(n), np.zeros((n, 2)), np.zeros((len(setup.joints), 3)), reg(m), reg((m, 3)))


def joint_stiffness(setup: MechSetup, ms: MechState) -> tuple[np.ndarray, np.ndarray]:
    """Bend and twist stiffness of the strand joints, zero next to a failed element."""
    on = ms.element_ok[setup.joints[:, 0]] & ms.element_ok[setup.joints[:, 1]]
    return np.where(on, setup.joint_kb, 0.0), np.where(on, setup.joint_kt, 0.0)


def _project(setup: MechSetup, ms: MechState, kjoint, plan: "Stage1Plan", kreg, lam: Multipliers, dt: float,
             fresh: bool = False) -> None:
    """One sweep of Stage 1 and Stage 2; ``fresh``: the substep's first, which writes the REG
    multipliers before it reads them (:func:`rods.reg_pass`)."""
    fp, x, q = setup.fp, ms.x, ms.q
    strand_stage(setup, ms, kjoint, plan, lam, dt)
    sw = setup.sweep
    rods.reg_pass(sw.edges, kreg.ptr, kreg.active, fp, x, q, ms.w_p, ms.w_q, kreg.offset, kreg.k_conn, sw.rest,
                  sw.length, kreg.k_bend, kreg.k_twist, lam.c, lam.p, dt, fresh)


@dataclass(frozen=True, eq=False)
class Stage1Plan:
    """How Stage 1 solves which elements (:func:`stage1_plan`): the runs ``lo[t]:hi[t]`` of a
    strand's elements in one direct solve each, the rest by Gauss-Seidel over the colour classes
    ``elems`` (elements) and ``joint_sets`` (joints)."""

    lo: np.ndarray
    hi: np.ndarray
    elems: tuple
    joint_sets: tuple


def stage1_plan(setup: MechSetup, ms: MechState) -> Stage1Plan:
    """Stage 1's split between the strand solvers by ``setup.strand_solver``: ``gauss-seidel``
    solves nothing directly, ``direct`` every unbroken run of a strand's elements (a failed
    element ends a run), ``auto`` the runs that no intact REG edge ties to another strand (a lone
    strand, a stick broken free of the bundle). Gauss-Seidel moves a correction one element per
    sweep and leaves such a run far softer than E and G say (``benchmarks/cantilever.py --sweep``);
    in a bundle Stage 2 limits the stiffness and a direct solve there buys nothing at 8x the cost
    of Stage 1 (docs/decisions.md, "Stiff strands")."""
    if setup.strand_solver == "gauss-seidel":
        none = np.zeros(0, dtype=np.int64)
        return Stage1Plan(none, none, setup.elems, setup.joint_sets)
    lo, hi, direct = _direct_runs(setup.strand_offsets, ms.element_ok, setup.edges, ms.edge_ok, ms.integrity,
                                  setup.strand_solver == "auto")
    if not len(lo):
        return Stage1Plan(lo, hi, setup.elems, setup.joint_sets)
    return Stage1Plan(lo, hi, tuple(c[~direct[c]] for c in setup.elems),
                      tuple(j[~direct[setup.joints[j, 0]]] for j in setup.joint_sets))


@nb.njit(cache=True)
def _direct_runs(offsets, element_ok, edges, edge_ok, integrity, tied_only):
    """:func:`stage1_plan`'s runs ``lo:hi`` of intact elements within a strand and the mask of
    their elements; with ``tied_only`` only those no intact REG edge (any of its three flags,
    I_ij > 0) touches. One serial pass over the elements and the edges."""
    n = len(element_ok)
    bound = np.zeros(n, dtype=np.bool_)
    if tied_only:
        for k in range(len(edges)):
            if integrity[k] > 0.0 and (edge_ok[k, 0] or edge_ok[k, 1] or edge_ok[k, 2]):
                bound[edges[k, 0]] = True
                bound[edges[k, 1]] = True
    lo, hi = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    direct = np.zeros(n, dtype=np.bool_)
    runs = 0
    for s in range(len(offsets) - 1):
        e = offsets[s]
        while e < offsets[s + 1]:
            if not element_ok[e]:
                e += 1
                continue
            a, tied = e, False
            while e < offsets[s + 1] and element_ok[e]:
                tied = tied or bound[e]
                e += 1
            if not tied:
                lo[runs], hi[runs] = a, e
                direct[a:e] = True
                runs += 1
    return lo[:runs], hi[:runs], direct


def direct_runs_reference(offsets, element_ok, edges, edge_ok, integrity, tied_only):
    """Plain-numpy twin of :func:`_direct_runs`."""
    n = len(element_ok)
    first, last = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    first[offsets[:-1]], last[offsets[1:] - 1] = True, True
    start = element_ok & (first | ~np.roll(element_ok, 1))
    lo, hi = np.flatnonzero(start), np.flatnonzero(element_ok & (last | ~np.roll(element_ok, -1))) + 1
    if tied_only:
        bound = np.zeros(n, dtype=bool)
        bound[edges[edge_ok.any(axis=1) & (integrity > 0.0)].ravel()] = True
        tied = np.zeros(len(lo), dtype=bool)
        tied[(np.cumsum(start) - 1)[element_ok & bound]] = True
        lo, hi = lo[~tied], hi[~tied]
    direct = np.zeros(n, dtype=bool)
    for a, b in zip(lo, hi):
        direct[a:b] = True
    return lo, hi, direct


def strand_stage(setup: MechSetup, ms: MechState, kjoint, plan: Stage1Plan, lam: Multipliers, dt: float) -> None:
    """Stage 1: the strands' stretch, shear and bend-twist constraints, the runs of ``plan`` by
    one direct solve each, the rest by one red-black Gauss-Seidel sweep."""
    fp, x, q = setup.fp, ms.x, ms.q
    kb, kt = kjoint
    if len(plan.lo):
        strand_solve.solve_strands(plan.lo, plan.hi, setup.joint_of, fp, x, q, ms.w_p, ms.w_q, ms.rest_length,
                                   setup.k_stretch, setup.k_shear, ms.element_ok, setup.joint_rest,
                                   setup.joint_length, kb, kt, lam.s, lam.sh, lam.j, dt)
    for elems in plan.elems:
        if len(elems):
            rods.stretch_shear(elems, fp, x, q, ms.w_p, ms.w_q, ms.rest_length, setup.k_stretch, setup.k_shear,
                               ms.element_ok, lam.s, lam.sh, dt)
    for idx in plan.joint_sets:
        if len(idx):
            rods.bend_twist(setup.joints, idx, q, ms.w_q, setup.joint_rest, setup.joint_length, kb, kt, lam.j, dt)


class Stiffness(NamedTuple):
    """What a substep projects with (:func:`stiffness`)."""

    reg: RegStiffness
    joint: tuple[np.ndarray, np.ndarray]  # bend, twist stiffness of the strand joints
    plan: "Stage1Plan"
    tested: tuple[np.ndarray, np.ndarray] | None  # (elements, edges) the failure test reads; None: all


def stiffness(setup: MechSetup, ms: MechState) -> Stiffness:
    """The REG (:meth:`RegSweep.arrays`) and strand joint stiffness of the current state and its
    :func:`stage1_plan`, without the constraints that move nothing while pieces are still
    (:func:`without_still`), and what the failure test needs to test after a substep that tested
    everything (None: everything; else the elements that move and the REG edges with such an end:
    the others' strains and limits stay as they were); they change only with the failure flags,
    I_ij, dp and what is still."""
    kreg, kjoint, plan = setup.sweep.arrays(ms), joint_stiffness(setup, ms), stage1_plan(setup, ms)
    if not sleep.still(ms).any():
        return Stiffness(kreg, kjoint, plan, None)
    moves = movable(setup, ms)
    kreg, plan = without_still(setup, moves, kreg, plan)
    edges = setup.edges
    return Stiffness(kreg, kjoint, plan,
                     (np.flatnonzero(moves), np.flatnonzero(moves[edges[:, 0]] | moves[edges[:, 1]])))


def movable(setup: MechSetup, ms: MechState) -> np.ndarray:
    """The elements with a particle or a quaternion of nonzero weight."""
    return (ms.w_p[setup.fp] > 0.0) | (ms.w_p[setup.fp + 1] > 0.0) | (ms.w_q > 0.0)


def without_still(setup: MechSetup, moves: np.ndarray, kreg: RegStiffness, plan: Stage1Plan
                  ) -> tuple[RegStiffness, Stage1Plan]:
    """``kreg``'s active edges and ``plan``'s elements, joints and runs less those of which no
    element ``moves`` (:func:`movable`): every weight they would apply is zero, so their
    projections move nothing, and a sleeping or held piece costs no sweep. Returns (kreg, plan)."""
    edges, active = setup.sweep.edges, kreg.active
    active = active[moves[edges[active, 0]] | moves[edges[active, 1]]]
    kreg = kreg._replace(active=active, ptr=np.searchsorted(active, setup.sweep.ptr).astype(np.int64))
    je = setup.joints
    count = np.concatenate([[0], np.cumsum(moves)])
    run = count[plan.hi] > count[plan.lo]
    plan = Stage1Plan(plan.lo[run], plan.hi[run], tuple(c[moves[c]] for c in plan.elems),
                      tuple(j[moves[je[j, 0]] | moves[je[j, 1]]] for j in plan.joint_sets))
    return kreg, plan


def substep(model: WoodModel, state, dt: float) -> int:
    """One XPBD substep of ``state.mech`` with ``model.mech`` under the state's external forces
    (module docstring); returns the number of new failures."""
    return _substep(model.mech, state.mech, dt)


def _substep(setup: MechSetup, ms: MechState, dt: float, stiff: Stiffness | None = None, lam: Multipliers | None = None,
             check: bool = True, check_all: bool = True, record: bool = False) -> int:
    """:func:`substep`; ``stiff``: :func:`stiffness` of this state, if the caller holds it;
    ``lam``: a dict that receives the substep's multipliers (:func:`strain_excess`); ``check``:
    test for failures (:func:`failure.update`), else return 0; ``check_all``: test every
    constraint, else only those ``stiff`` names (the rest has not moved since a test of all),
    skipping those that moved too little since ``ms.fail_epoch`` to fail; ``record``: make this
    substep's test of all the epoch (:func:`failure.update`)."""
    x_old, q_old = np.empty_like(ms.x), np.empty_like(ms.q)
    _predict(ms.x, ms.v, ms.q, ms.omega, ms.w_p, ms.w_q, ms.mass_p, ms.force, setup.gravity, ms.torque,
             math.exp(-setup.damping * dt), dt, x_old, q_old)  # libm's, as wooddecay.fmath
    kreg, kjoint, plan, tested = stiff or stiffness(setup, ms)
    lam = multipliers(setup, fresh_reg=True) if lam is None else lam
    normal_force = np.zeros(setup.n_particles)
    refresh_pairs(setup, ms)
    # contact (docs/decisions.md "Contact"): the normal steps of colliders and pairs, then friction
    # against the push they gave each particle. A collider's depenetration is capped at
    # v_depenetration beyond the approach of this substep; a pair's only within the overlap it had
    # when it separated, shrinking at v_depenetration. Restitution 0 afterwards.
    push = setup.v_depenetration * dt
    hit_c = np.zeros((setup.n_particles, len(setup.colliders)), dtype=bool)
    hit_p = np.zeros(len(ms.pairs), dtype=bool)
    x_start = np.empty_like(ms.x)
    for it in range(setup.iterations):
        _project(setup, ms, kjoint, plan, kreg, lam, dt, fresh=it == 0)
        x_start[:] = ms.x
        contact.project_colliders(ms.x, ms.w_p, ms.radius_p, setup.colliders, setup.k_col, dt, normal_force,
                                  push, x_old, hit_c, checked=True)
        contact.project_contacts(ms.x, ms.w_p, setup.fp, ms.radius, ms.pairs, setup.k_col, dt, normal_force,
                                 push, hit_p, phi_rest=ms.pairs_rest, protect=ms.pairs_protect)
        contact.particle_friction(ms.x, x_start, x_old, setup.mu_f, setup.epsilon * dt)
    # the protected overlaps only shrink; they outlive the contact list
    keep_overlaps(ms.pairs_sep, ms.pairs_rest, ms.pairs_protect, ms.sep_overlap)
    _velocities(ms.x, ms.v, ms.q, ms.omega, x_old, q_old, ms.w_p, ms.w_q, dt)
    contact.collider_velocities(ms.v, ms.x, ms.w_p, setup.colliders, hit_c)
    contact.contact_velocities(ms.v, ms.x, ms.w_p, setup.fp, ms.radius, ms.pairs, hit_p)
    ms.t_seconds += dt
    if not check:
        return 0
    if check_all:
        return failure.update(setup, ms, record=record)
    return failure.update(setup, ms, tested, bounded=True)


def strain_excess(setup: MechSetup, ms: MechState) -> float:
    """How far the strand constraints are from their constitutive law after a substep: the
    excess of their strain over what their forces allow, relative and weighted by elastic energy,
    sum |C + alpha~ lambda| |lambda| / sum alpha~ lambda^2 over the stretch, shear and bend-twist
    constraints (0 when none is loaded).

    Eq. 1 makes C + alpha~ lambda = 0 at convergence; a Gauss-Seidel sweep that stops short leaves
    the strands softer than E and G say, and a clamped strand sags too far by about this figure
    (``benchmarks/cantilever.py --sweep``). One substep of a copy of ``ms`` gives the multipliers
    lambda (at the substep :func:`macro_step` takes under the state's forces); one more sweep of
    Stage 1 and 2 from them gives each constraint's
    dlambda = -(C + alpha~ lambda) / (W + alpha~) (alpha~ = 1 / (k dt^2), W and k as in
    :mod:`~wooddecay.sim.rods`). ``ms`` is left untouched."""
    probe, lam, dt = ms.copy(), multipliers(setup, fresh_reg=True), setup.dt / load_split(setup, ms.w_p, ms.force)
    _substep(setup, probe, dt, lam=lam)
    before = lam.copy()
    kreg, (kb, kt), plan, _ = stiffness(setup, probe)
    _project(setup, probe, (kb, kt), plan, kreg, lam, dt)
    fp, w_p, w_q, l = setup.fp, probe.w_p, probe.w_q, probe.rest_length
    wa, wb = w_p[fp], w_p[fp + 1]
    f = 2.0 / setup.joint_length
    Wj = f * f * (w_q[setup.joints[:, 0]] + w_q[setup.joints[:, 1]])
    kinds = (("s", wa + wb, setup.k_stretch / l),
             ("sh", ((wa + wb) / (l * l) + 4.0 * w_q)[:, None], (setup.k_shear * l)[:, None]),
             ("j", Wj[:, None], np.stack([kb, kb, kt], axis=1) * setup.joint_length[:, None]))
    num = den = 0.0
    for key, W, k in kinds:
        lam0 = getattr(before, key)
        at = np.divide(1.0, k * dt * dt, out=np.zeros_like(k * lam0), where=k > 0.0)
        num += float((np.abs(getattr(lam, key) - lam0) * (W + at) * np.abs(lam0)).sum())
        den += float((at * lam0 * lam0).sum())
    return num / den if den > 0.0 else 0.0


def convergence(setup: MechSetup, excess, residual, unconverged: int = 0, resolves: int = 0) -> dict:
    """The bake's convergence report from the :func:`strain_excess` and the
    :func:`~wooddecay.sim.equilibrium.equilibrium_residual` of the settled rods and of every frame
    (``excess``, ``residual``, in that order; the excess is None under the implicit solver, which
    has no multipliers), the implicit steps that stopped at their cap (``unconverged``) and those
    re-solved after breaks (``resolves``): the
    largest values, whether the solver converged (XPBD: the excess within
    STRAIN_EXCESS_TOLERANCE; implicit: every step within its tolerance) and, if not, the remedy."""
    rmax = max(residual)
    out = {"equilibrium_residual_settled": residual[0], "equilibrium_residual_max": rmax}
    if setup.solver == "implicit":
        ok = unconverged == 0
        return out | {"unconverged_steps": unconverged, "resolves_after_breaks": resolves, "converged": ok,
                      "remedy": None if ok else (
            f"{unconverged} implicit step(s) of the rods stopped at their Newton cap above their tolerance "
            f"(largest equilibrium residual {rmax:.3g}); lower mechanics.dt_mech or time.N_mech")}
    worst = max(excess)
    ok = worst <= STRAIN_EXCESS_TOLERANCE
    remedy = None if ok else (
        f"the strands are softer than mechanics.E and G say: their strain exceeds their forces' by "
        f"{worst:.0%} (tolerance {STRAIN_EXCESS_TOLERANCE:.0%}); raise mechanics.iterations (now "
        f"{setup.iterations}) or lower mechanics.dt_mech (now {setup.dt:g} s), or use mechanics.solver = "
        f"\"implicit\": a bundle converges at about {CONVERGED_ITERATIONS} iterations a substep, that many times "
        f"the mechanics, and the samples' fracture settings are tuned on the soft one")
    return {"strain_excess_settled": excess[0], "strain_excess_max": worst} | out | {
        "tolerance": STRAIN_EXCESS_TOLERANCE, "converged": ok, "remedy": remedy}


def refresh_pairs(setup: MechSetup, ms: MechState) -> None:
    """Contact candidates between components (a Verlet list with margin CONTACT_MARGIN r_s),
    rebuilt when a particle has moved half the margin since the last build or when
    :func:`failure.update` changed the components (it clears ``pairs_x``). Failed elements take
    no part: a broken element's segment joins the end of one piece to the start of the next
    (its second particle is the next element's first), so it is no longer wood and its capsule
    would drag through both pieces. Under XPBD nor do pairs of which no element can move
    (:func:`movable`; sleeping and held pieces): they move nothing. The implicit step moves every
    piece (its drying shrinks a held one too), so it keeps them. ``pairs_rest`` holds each pair's overlap at the rest
    positions (shrunk as brown rot shrank the pair), which contact does not push out (:mod:`~wooddecay.sim.contact`, "Rest overlap"), and
    ``pairs_protect`` the overlap beyond it that the pair had when its elements separated
    (``sep_keys``, ``sep_overlap``), which contact pushes out at most at v_depenetration."""
    margin = CONTACT_MARGIN * float(setup.radius.max(initial=0.0))
    if ms.pairs_x is not None and _within(ms.x, ms.pairs_x, 0.5 * margin):
        return
    ms.pairs = contact.candidate_pairs(ms.x, setup.fp, ms.radius, ms.component, margin, active=ms.element_ok)
    if setup.solver == "xpbd" and sleep.still(ms).any():  # a pair of which no element moves does nothing
        moves = movable(setup, ms)
        ms.pairs = ms.pairs[moves[ms.pairs[:, 0]] | moves[ms.pairs[:, 1]]]
    shrink = np.divide(ms.radius, setup.radius, out=np.ones_like(ms.radius), where=setup.radius > 0.0)  # brown rot
    ms.pairs_rest = (contact.pair_overlaps(setup.x_rest, setup.fp, setup.radius, ms.pairs)
                     * 0.5 * (shrink[ms.pairs[:, 0]] + shrink[ms.pairs[:, 1]]))
    ms.pairs_sep = np.full(len(ms.pairs), -1, dtype=np.int64)
    if len(ms.sep_keys) and len(ms.pairs):
        keys = ms.pairs[:, 0] * setup.n_elements + ms.pairs[:, 1]
        at = np.minimum(np.searchsorted(ms.sep_keys, keys), len(ms.sep_keys) - 1)
        found = ms.sep_keys[at] == keys
        ms.pairs_sep[found] = at[found]
    found = ms.pairs_sep >= 0
    ms.pairs_protect = np.zeros(len(ms.pairs))
    ms.pairs_protect[found] = np.maximum(ms.sep_overlap[ms.pairs_sep[found]] - ms.pairs_rest[found], 0.0)
    ms.pairs_x = ms.x.copy()


@nb.njit(cache=True)
def _within(x, x0, reach):
    """np.max(np.abs(x - x0), initial=0) < reach, exactly, without the temporaries: every
    coordinate within ``reach`` of ``x0``'s, stopping at the first that is not."""
    for p in range(len(x)):
        for c in range(3):
            if not abs(x[p, c] - x0[p, c]) < reach:
                return False
    return 0.0 < reach


@nb.njit(cache=True)
def keep_overlaps(pairs_sep, pairs_rest, pairs_protect, sep_overlap):
    """Each contact pair's protected overlap (rest plus protect) back to its row of ``sep_overlap``."""
    for q in range(len(pairs_sep)):
        if pairs_sep[q] >= 0:
            sep_overlap[pairs_sep[q]] = pairs_rest[q] + pairs_protect[q]


def settle(model: WoodModel, state, seconds: float, damping: float, tol: float | None = None,
           max_seconds: float = 10.0, run=None) -> float:
    """Let the rods of ``state`` come to rest under gravity with infinite limits (only decayed
    connections and crumbled elements fail, tested on the first substep: whether they fail does
    not depend on the positions), no external forces and viscous damping ``damping`` for
    ``seconds``, then take the strains they hold as the
    reference of :func:`failure.update` and zero the velocities (docs/decisions.md, "Settling"):
    the wood starts undamaged in equilibrium with its own weight, as a grown tree is, so only
    strain added later by shrinkage, decay, loads and impacts counts against L(M).

    With ``tol`` the settling goes on after ``seconds`` in chunks of :data:`SETTLE_CHUNK` until
    no constraint that can fail changes its strain by more than ``tol`` of its limit within a
    chunk (:func:`failure.drift`), or ``max_seconds`` in all: an overdamped soft structure (a
    decayed branch) is still sagging after a fixed time, and that sag would count against its
    limits once failure is on (docs/decisions.md, "Pull test"). The first ``seconds`` go in chunks
    of ``model.time.N_mech`` substeps, each called as ``run(chunk)`` when given (the thread choice
    of a bake, :mod:`wooddecay.sim.threads`); chunking changes no bit. Returns the seconds settled."""
    setup, ms = model.mech, state.mech
    limits = ms.limit_elem, ms.limit_edge
    ms.limit_elem, ms.limit_edge = np.full_like(limits[0], np.inf), np.full_like(limits[1], np.inf)
    damped = replace(setup, damping=float(damping))
    ms.force = np.zeros((setup.n_particles, 3))
    run = run or (lambda fn: fn())
    n, chunk = int(round(seconds / setup.dt)), max(int(model.time.N_mech), 1)
    checked = n > 0  # the first substep flags every failure settling can have, the others test nothing
    stiff = run(lambda: _advance(damped, ms, min(n, 1))[1])
    for start in range(1, n, chunk):
        stiff = run(lambda m=min(chunk, n - start), s=stiff: _advance(damped, ms, m, s, check=False)[1])
    done = float(seconds)
    now = failure.strains(setup, ms)
    if tol is not None:
        chunk = int(round(SETTLE_CHUNK / setup.dt))
        while done < max_seconds - 1e-12:
            before = now
            stiff = _advance(damped, ms, chunk, stiff, check=not checked)[1]
            checked, done = True, done + chunk * setup.dt
            now = failure.strains(setup, ms)
            if failure.drift(setup, ms, before, now, *limits) <= tol:
                break
    ms.limit_elem, ms.limit_edge = limits
    ms.strain_ref_elem, ms.strain_ref_edge = now
    ms.v[:] = 0.0
    ms.omega[:] = 0.0
    sleep.wake_all(setup, ms)  # the settled state starts the first sleep window
    return done


def advance(model: WoodModel, state, n_sub: int) -> int:
    """``n_sub`` substeps of ``model.mech.dt`` under the state's external forces, gathering the
    :func:`stiffness` only when the failure flags change; returns the new failures."""
    return _advance(model.mech, state.mech, n_sub)[0]


def _advance(setup: MechSetup, ms: MechState, n_sub: int, stiff: Stiffness | None = None,
             check: bool = True) -> tuple[int, Stiffness | None]:
    """:func:`advance`; returns (new failures, the stiffness to pass to the next call); ``check``
    as in :func:`_substep`. The first substep tests every constraint for failure, the others
    only those of elements that can move (:func:`stiffness`): still wood keeps its strains and,
    within a call, its limits."""
    new, ms.fail_epoch = 0, None
    for i in range(n_sub):
        stiff = stiffness(setup, ms) if stiff is None else stiff
        count = _substep(setup, ms, setup.dt, stiff, check=check, check_all=i == 0, record=i == 0 and n_sub > 1)
        new += count
        if count:  # flags changed
            stiff = None
    return new, stiff


def load_split(setup: MechSetup, w_p: np.ndarray, force: np.ndarray) -> int:
    """Into how many substeps each of ``setup.dt`` splits under the particle forces ``force``
    (inverse masses ``w_p``): the fewest k with (dt / k)^2 w_p |f_p| within LOAD_JUMP of the
    rest length of the particle's element for every particle. Each substep projects the
    constraints from the prediction x + dt^2 w f, linearised there; a point load that throws a
    light particle many element lengths off per substep (a tip load on a strand of elements far
    shorter than its radius) does not come to rest near the beam: unsettled at one iteration,
    9% softer at rest at two (docs/decisions.md, "Point loads split the substep")."""
    jump = setup.dt**2 * w_p * np.linalg.norm(force, axis=1)
    if not jump.any():
        return 1
    reach = _per_particle_max(setup.fp, setup.rest_length0, setup.n_particles)
    return max(1, int(np.ceil(np.sqrt((jump / (LOAD_JUMP * reach)).max()))))


def load_notes(setup: MechSetup) -> tuple[str, ...]:
    """A note per [[load]] whose force splits the substeps (:func:`load_split`, on the dry wood's
    masses: moist wood is heavier, decayed wood lighter)."""
    mass = _particle_mass(setup, setup.dry_mass)
    w_p = np.where(setup.anchored_p | (mass <= 0.0), 0.0, 1.0 / np.where(mass > 0.0, mass, 1.0))
    notes = []
    for i, (_, _, force) in enumerate(setup.loads):
        k = load_split(setup, w_p, force)
        if k > 1:
            notes.append(f"load[{i}]: its force moves a particle of the dry wood by more than {LOAD_JUMP:g} of an "
                         f"element's length per substep of mechanics.dt_mech; while it acts each substep is split "
                         f"into {k} (dt {setup.dt / k:.3g} s)")
    return tuple(notes)


def macro_step(model: WoodModel, state, n_sub: int) -> int:
    """Algorithm 1 lines 4-8: ``n_sub`` substeps of ``model.mech.dt`` under the loads of the day
    ``state.t_days``, each split in :func:`load_split` of them; returns new failures. With
    ``sleep_speed`` > 0 pieces that stopped moving sleep (:mod:`~wooddecay.sim.sleep`): the
    substeps stop at every end of a sleep window to update who sleeps, and a failure wakes the
    still pieces it touched and those touching them (:func:`sleep.wake_failed`)."""
    setup, ms = model.mech, state.mech
    ms.force = external_forces(setup, state.t_days)
    split = load_split(setup, ms.w_p, ms.force)
    if split > 1:
        setup, n_sub = replace(setup, dt=setup.dt / split), n_sub * split
    ms.pairs_x = None  # rebuild the contact list from this state (resumable bit-exactly)
    if setup.sleep_speed <= 0.0:  # nothing sleeps, but the schedule may hold pieces
        flags = ms.element_ok.copy(), ms.edge_ok.copy()
        new = _advance(setup, ms, n_sub)[0]
        if new:
            sleep.wake_failed(setup, ms, *flags, refresh_pairs)
        return new
    sleep.wake_loaded(setup, ms)
    new, stiff = 0, None
    while n_sub > 0:
        k = min(n_sub, max(sleep.substeps_left(setup, ms), 1))
        flags, stopped = (ms.element_ok.copy(), ms.edge_ok.copy()), sleep.still(ms)
        count, stiff = _advance(setup, ms, k, stiff)
        new, n_sub = new + count, n_sub - k
        if count:
            sleep.wake_failed(setup, ms, *flags, refresh_pairs)
        elif sleep.substeps_left(setup, ms) == 0:
            sleep.update(setup, ms)
        if not np.array_equal(stopped, sleep.still(ms)):  # the kernels skip what is still
            stiff, ms.pairs_x = None, None
    return new
