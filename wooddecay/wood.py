"""The model's types: what :func:`wooddecay.model.build_model` hands on to every later stage.

``WoodModel`` (a frozen structure of arrays, docs/architecture.md "Data model") and the
configuration it carries: the scene's identity (:class:`SceneInfo`), the schedule
(:class:`TimeSpec`, :class:`Tolerances`), the rods' scalars and loads (:class:`MechConfig`,
:class:`Load`), the inoculations (:class:`Inoculation`) and the resolved ``[bark]`` section
(:class:`BarkSetup`). This module sits below ``sim/``, ``bark/``, ``meshlets/`` and ``export/``
so that every solver and exporter can annotate ``model: WoodModel``; the solvers' static data
(``bio``, ``mech``, ``coupling``, ``bark``) are their own types, named here for the type checker
only. Array fields give their shape (n: elements, m: REG edges, P: particles, K: strand control
points), dtype and unit.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .strands.materials import Materials
from .strands.rings import TISSUES
from .strands.skeleton import Skeleton
from .strands.topology import Topology

if TYPE_CHECKING:
    from .bark.sheet import BarkSheet
    from .sim.biology import BioSetup
    from .sim.coupling import CouplingSetup
    from .sim.mechanics import MechSetup

#: days in a simulated year (climate seasons, ``time.years``, bark shedding rates)
DAYS_PER_YEAR = 365.25


@dataclass(frozen=True)
class Tolerances:
    """The ``[time]`` keys of the adaptive schedule (module docstring)."""

    strain: float  # strain_tolerance
    relative: float  # tolerance: integrity and mass
    rest_speed: float  # m/s
    hold_speed: float  # m/s (:func:`hold_still`; 0: never)
    max_seconds: float  # max_mechanics, s per macro step


@dataclass(frozen=True)
class MechConfig:
    """The ``[mechanics]`` scalars the rod system is built with (docs/model.md §4; Table 3)."""

    gravity: tuple
    damping: float
    dt_mech: float
    iterations: int
    strand_solver: str
    solver: str
    residual_tolerance: float
    connection_shear: float
    reg_moduli: tuple | None  # a species' (a_R, a_T, a_L, b), Pa (wooddecay.species.RodModuli)
    inertia_scale: float
    k_col: float
    v_depenetration: float
    mu_f: float
    epsilon: float
    sleep_speed: float
    sleep_time: float


@dataclass(frozen=True)
class Load:
    """A ``[[load]]``: ``force`` (N, world) on the elements of ``mask`` over days [day0, day1)."""

    day0: float
    day1: float
    force: tuple
    mask: np.ndarray


@dataclass(frozen=True)
class Inoculation:
    """An inoculation resolved on the model: on ``day`` the activity of ``fungus`` ("white":
    R_w, "brown": R_b) rises to ``activity`` on the elements of ``mask``."""

    day: float
    fungus: str
    activity: float
    mask: np.ndarray


@dataclass(frozen=True)
class BarkSetup:
    """The resolved ``[bark]`` section (docs/scene.md; woodification §4-5), its species' presets
    filled in: what the crack sheet is built with and what the bark solver, the surface and the
    crack map read."""

    species: str
    cracks: bool
    pattern: str  # "fissures", "plates", "bands" or "none"
    threshold: float  # crack strain
    tip_gain: float
    noise: float
    growth: float  # weight of the growth strain
    drying: float  # weight of the drying strain
    bark_years: int  # year
    shadow: float  # m
    spacing: float  # r_s
    crack_width: float  # m
    crack_depth: float  # multiple of the width
    groove_width: float  # m
    shedding: float  # 1/year
    plate_area: float  # m^2


@dataclass(frozen=True)
class SceneInfo:
    """What outputs record of the scene a model was built from (USD customLayerData, glTF
    extras, checkpoints): its name, seed and the hash of the resolved scene, and the hash of the
    part the settled rods depend on (the settled-state cache's key)."""

    name: str
    seed: int
    hash: str
    settle_hash: str
    description: str = ""


@dataclass(frozen=True)
class TimeSpec:
    """The schedule of a simulation (Algorithm 1): ``days`` simulated in macro steps of at most
    ``dt_bio`` days, each with ``N_mech`` mechanics substeps; ``frames`` output frames played at
    ``fps``; ``settle`` seconds of settling with damping ``settle_damping`` before the first step.
    ``schedule`` "fixed" runs the N_mech substeps in every macro step, "adaptive" only when
    :mod:`wooddecay.sim.schedule` finds them due, within ``tolerances``."""

    days: float
    dt_bio: float
    frames: int
    fps: float
    N_mech: int
    settle: float
    settle_damping: float
    schedule: str  # "adaptive" or "fixed" (sim/schedule.py)
    tolerances: Tolerances  # of the adaptive schedule


@dataclass(frozen=True, eq=False)
class WoodModel:
    """Structure of arrays; element arrays have length ``n_elements``, edge arrays ``n_edges``.

    Public names follow docs/architecture.md: ``centers``, ``wood_coords`` (r, phi, s), ``frames`` (rows
    e_r, e_t, e_l), ``tissue``, ``ring_age``, ``bsp_leaf``, ``reg_edges``, ``reg_theta``.
    """

    # strands and particles: strand k owns particles particle_offsets[k]:particle_offsets[k + 1]
    # and elements element_offsets[k]:element_offsets[k + 1]; element e spans particles
    # first_particle[e] and first_particle[e] + 1
    particles: np.ndarray  # (P, 3) float64, m: rest particle positions (world)
    particle_offsets: np.ndarray  # (strands + 1,) int64
    element_offsets: np.ndarray  # (strands + 1,) int64
    # elements
    strand: np.ndarray  # (n,) int64: the strand of each element
    first_particle: np.ndarray  # (n,) int64
    centers: np.ndarray  # (n, 3) float64, m: rest centres (world)
    rest_length: np.ndarray  # (n,) float64, m: l_r
    radius: np.ndarray  # (n,) float64, m: r_s
    mass: np.ndarray  # (n,) float64, kg: rho_dry (1 + M_init) pi r_s^2 l_r
    rest_quat: np.ndarray  # (n, 4) float64: rest orientation (w, x, y, z), d_3 along the strand
    frames: np.ndarray  # (n, 3, 3) float64: wood frame, rows e_r, e_t, e_l
    wood_coords: np.ndarray  # (n, 3) float64: r (m), phi (rad), s (m from the root)
    bark_distance: np.ndarray  # (n,) float64, m: signed distance to the bark surface (inside > 0)
    ring_age: np.ndarray  # (n,) float64, year: age of the ring the element lies in
    tissue: np.ndarray  # (n,) int8: index into strands.rings.TISSUES
    branch: np.ndarray  # (n,) int64: skeleton branch (topology.branch numbering)
    bsp_leaf: np.ndarray  # (n,) int64: BSP cell
    W: np.ndarray  # (n,) float64 in [0, 1]: weak-point field (Eq. 20)
    anchored: np.ndarray  # (n,) bool: clamped to an anchored skeleton root
    # REG (rod-element graph): m undirected edges (i < j) and its CSR adjacency over elements
    reg_edges: np.ndarray  # (m, 2) int64
    reg_rest_offset: np.ndarray  # (m,) float64, m: rest distance between the two centres
    reg_rest_darboux: np.ndarray  # (m, 4) float64: rest relative rotation conj(q_i) q_j
    reg_dir_weights: np.ndarray  # (m, 3) float64: squared direction cosines (n_r^2, n_t^2, n_l^2)
    reg_theta: np.ndarray  # (m,) float64 in {0, 1}: 1 where the edge crosses a BSP cell face
    reg_indptr: np.ndarray  # (n + 1,) int64
    reg_indices: np.ndarray  # (2m,) int64: neighbour elements
    reg_edge_of: np.ndarray  # (2m,) int64: the REG edge of each adjacency entry
    # transport graph = strand chains + cross-strand pairs within transport_reach * r_s, t edges
    # (kind 0: a REG edge, 1: a chain link, 2: a wider transverse pair), CSR as the REG's
    transport_edges: np.ndarray  # (t, 2) int64
    transport_kind: np.ndarray  # (t,) int8
    transport_indptr: np.ndarray  # (n + 1,) int64
    transport_indices: np.ndarray  # (2t,) int64
    transport_edge_of: np.ndarray  # (2t,) int64
    # strand control points in their node's cross-section frame (what the meshlets sweep,
    # docs/model.md §5): strand k owns rows cp_offsets[k]:cp_offsets[k + 1]; cp_uv is the actual
    # position (an end part-way along an edge interpolated), cp_s its distance to the root
    cp_offsets: np.ndarray  # (strands + 1,) int64
    cp_node: np.ndarray  # (K,) int64: skeleton node
    cp_uv: np.ndarray  # (K, 2) float64, m: position in the node's profile plane
    cp_s: np.ndarray  # (K,) float64, m
    particle_s: np.ndarray  # (P,) float64, m: distance to the root (linear in arc between cps)
    # the skeleton graph and its topology (branches, node frames, s), and the strand radius r_s
    skeleton: Skeleton
    topology: Topology
    r_s: float
    bark_thickness: float  # 0: the wood has no bark (a board), its outer faces are wood
    # the scene's identity and schedule
    info: SceneInfo
    time: TimeSpec
    # per-tissue parameters, inoculations resolved on the elements, and the solvers' static data
    materials: Materials
    bio: BioSetup  # sim/biology.py: transport operator, climate, tissue tables
    mech: MechSetup  # sim/mechanics.py: the rod system
    coupling: CouplingSetup  # sim/coupling.py: Eqs. 16-19, 21 per element and edge
    inoculations: tuple[Inoculation, ...] = ()
    bark: BarkSheet | None = None  # the bark crack sheet ([bark] cracks, and the wood has bark)
    bark_setup: BarkSetup | None = None  # the resolved [bark] section, with ``bark``
    # bookkeeping
    build_seconds: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()  # what the build could not model as asked (:func:`narrow_notes`)

    @property
    def n_branches(self) -> int:
        return self.topology.n_branches

    @property
    def n_elements(self) -> int:
        return len(self.centers)

    @property
    def n_strands(self) -> int:
        return len(self.element_offsets) - 1

    @property
    def n_edges(self) -> int:
        return len(self.reg_edges)

    @property
    def reg_degree(self) -> np.ndarray:
        return np.diff(self.reg_indptr)

    @property
    def bsp_cells(self) -> int:
        return int(len(np.unique(self.bsp_leaf)))

    @property
    def nbytes(self) -> int:
        return int(sum(v.nbytes for v in vars(self).values() if isinstance(v, np.ndarray)))

    def tissue_counts(self) -> dict[str, int]:
        counts = np.bincount(self.tissue, minlength=len(TISSUES))
        return {name: int(c) for name, c in zip(TISSUES, counts)}
