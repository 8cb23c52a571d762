"""WoodModel: everything the stages after the scene read, built once (docs/architecture.md "Data model").

Woodstock §3 and §5 (opening), Fig. 3; docs/model.md §2. ``build_model(scene)`` runs skeleton -> topology
-> strands -> rod elements -> rings and tissues -> REG -> BSP -> W, resolves the per-tissue
parameters (:class:`~wooddecay.strands.materials.Materials`) and the inoculation and load regions,
and builds the solvers' static data (``bio``, ``mech``, ``coupling``). It returns a frozen
structure of arrays (no per-element Python objects): the scene stops here, and the simulation,
meshlets and exporters read only the model. Every random choice draws from a generator seeded by
(scene.seed, stage), so the same seed gives identical arrays.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import fields, replace
from typing import NamedTuple, cast

import numpy as np

from . import fmath as fm
from .arrays import group_rows
from .bark.sheet import build_sheet, recent_growth
from .scene import TISSUE_KEYS
from .sim import biology, climate, contact, coupling, mechanics
from .sim.biology import BioSetup
from .sim.coupling import CouplingSetup
from .sim.mechanics import MechSetup
from .species import SPECIES
from .strands import bsp as bsp_mod
from .strands.elements import element_geometry, sample_strands
from .strands.materials import Materials
from .strands.profiles import narrow_area, signed_distance
from .strands.reg import build_reg, csr_adjacency, transport_graph
from .strands.regions import region_mask
from .strands.rings import (
    TISSUES,
    age_of,
    classify_tissue,
    cumulative_widths,
    profile_years,
    radial_coordinate,
    year_noise,
)
from .strands.skeleton import Skeleton
from .strands.strands import build_strands
from .strands.topology import build_topology
from .strands.weakpoints import weak_point_field
from .wood import BarkSetup, Inoculation, Load, MechConfig, SceneInfo, TimeSpec, Tolerances, WoodModel

#: random streams, one per build stage (index into the seed sequence)
_STREAMS = {"strands": 1, "sampling": 2, "rings": 3, "bsp": 4, "weakpoints": 5, "bark": 6}


def stage_rng(seed: int, stage: str) -> np.random.Generator:
    """Independent generator for one build stage, determined by the scene seed."""
    return np.random.default_rng([int(seed), _STREAMS[stage]])


@contextmanager
def _timed(seconds: dict, stage: str):
    t0 = time.perf_counter()
    yield
    seconds[stage] = time.perf_counter() - t0


def _lerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    t = t.reshape(t.shape + (1,) * (a.ndim - 1))
    return (1.0 - t) * a + t * b


def _particle_s(strands, samp, cp_s: np.ndarray) -> np.ndarray:
    """Distance to the root of every particle: linear in the spline parameter between the strand's
    control points (as the elements' ``s``), exact at its two ends (one iteration per strand)."""
    out = np.empty(len(samp.u))
    for k in range(strands.count):
        o0, o1 = strands.offsets[k], strands.offsets[k + 1]
        P = strands.xyz[o0:o1]
        u_cp = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
        p0, p1 = samp.particle_offsets[k], samp.particle_offsets[k + 1]
        out[p0:p1] = np.interp(samp.u[p0:p1], u_cp, cp_s[o0:o1])
    return out


def _collider_rows(scene) -> np.ndarray:
    """The ground plane (``[mechanics] ground``) and the ``[[collider]]`` tables as rows of
    :func:`contact.collider_row`."""
    rows = []
    mech = scene.mechanics
    if mech.ground:
        rows.append(contact.collider_row(contact.PLANE, 0.0, 0.0, mech.ground_height, 0.0, 0.0, 1.0))
    for c in scene.colliders:
        kind = c["kind"]
        if kind == "plane":
            rows.append(contact.collider_row(contact.PLANE, *c["point"], *c["normal"]))
        elif kind == "box":
            rows.append(contact.collider_row(contact.BOX, *c["min"], *c["max"]))
        elif kind == "sphere":
            rows.append(contact.collider_row(contact.SPHERE, *c["center"], c["radius"]))
        else:
            rows.append(contact.collider_row(contact.CYLINDER, *c["a"], *c["b"], c["radius"]))
    return np.array(rows, dtype=np.float64).reshape(-1, contact.COLLIDER_COLUMNS)


#: a profile part narrower than a strand worth a note: this many strand cross-sections (pi r_s^2);
#: a polygon tip of half-angle 10 degrees leaves about 1.4
NARROW_STRANDS = 4.0


def narrow_notes(skel: Skeleton, r_s: float) -> tuple[str, ...]:
    """One note per ellipse or polygon profile with a part that no strand can reach larger than
    NARROW_STRANDS strand cross-sections (:func:`wooddecay.strands.profiles.narrow_area`)."""
    notes = []
    for node, prof in zip(skel.ids, skel.profiles):
        if prof.kind == "circle":
            continue
        area = narrow_area(prof.polygon, r_s)
        if area > NARROW_STRANDS * np.pi * r_s**2:
            notes.append(f"skeleton.node[{node}].profile: a part of {area * 1e4:.2g} cm^2 is narrower than a strand "
                         f"(2 r_s = {2e3 * r_s:g} mm); no strand fills it and the meshlets stretch over it; a "
                         "smaller strands.r_s fills it")
    return tuple(notes)


def empty_branch_notes(skel: Skeleton, topo, branch: np.ndarray, r_s: float, rod_length: float) -> tuple[str, ...]:
    """One note naming the branches that hold no rod element (``branch``: each element's), by
    their first node: twigs thinner than a strand, or whose strands end within a rod length,
    are left out of the wood (and of the meshlets)."""
    empty = np.flatnonzero(np.bincount(branch, minlength=topo.n_branches) == 0)
    if len(empty) == 0:
        return ()
    first = [skel.ids[np.flatnonzero(topo.branch == b)[0]] for b in empty]
    named = ", ".join(first[:5]) + (f" and {len(first) - 5} more" if len(first) > 5 else "")
    return (f"skeleton: {len(empty)} branch(es) hold no rod element at strands.r_s = {1e3 * r_s:g} mm and "
            f"rod_length = {1e3 * rod_length:g} mm (from node {named}); they are left out of the wood; a smaller "
            "strands.r_s or rod_length keeps them",)


def _scene_info(scene) -> SceneInfo:
    return SceneInfo(name=str(scene.name), seed=int(scene.seed), hash=scene.hash, settle_hash=scene.settle_hash,
                     description=str(scene.description))


def _time_spec(scene) -> TimeSpec:
    return TimeSpec(days=float(scene.time.days), dt_bio=float(scene.time.dt_bio), frames=int(scene.time.frames),
                    fps=float(scene.time.fps), N_mech=int(scene.mechanics.N_mech),
                    settle=float(scene.mechanics.settle), settle_damping=float(scene.mechanics.settle_damping),
                    schedule=str(scene.time.schedule),
                    tolerances=Tolerances(strain=float(scene.time.strain_tolerance),
                                          relative=float(scene.time.tolerance),
                                          rest_speed=float(scene.time.rest_speed),
                                          hold_speed=float(scene.time.hold_speed),
                                          max_seconds=float(scene.time.max_mechanics)))


def _climate(scene) -> climate.Climate:
    """The :class:`Climate` of a validated scene: ``[climate] seasons`` if given, else its
    ``preset``'s keyframes; the ground plane of ``[mechanics]``."""
    c = scene.climate
    rows = np.array(c.seasons if len(c.seasons) else climate.PRESETS[c.preset], dtype=np.float64)
    ground = float(scene.mechanics.ground_height) if scene.mechanics.ground else None
    return climate.Climate(days=rows[:, 0].copy(), start_day=float(c.start_day), w=rows[:, 1:].copy(), k_ground=float(c.k_ground),
                   ground_z=ground, ground_depth=float(c.ground_depth))


def retimed(model: WoodModel, scene) -> WoodModel:
    """The model of ``scene``, from the ``model`` of a scene with the same
    :attr:`~wooddecay.scene.types.Scene.model_hash` (it differs at most in [time], [export], its
    name and description): only the schedule and the scene's identity change."""
    return replace(model, info=_scene_info(scene), time=_time_spec(scene), build_seconds={})


class Rings(NamedTuple):
    """What the rings stage gives the elements (docs/model.md §2): control points' profile
    positions ``cp_uv`` (K, 2) m and distances to the root ``cp_s`` (K,) m, the particles'
    ``particle_s`` (P,) m, and per element its profile position ``uv`` (n, 2) m, bark distance
    ``bd`` (n,) m, ring age (n,) years and tissue (n,) int8; per node its profile's years, and the
    year-width noise the bark's growth strain reads."""

    cp_uv: np.ndarray
    cp_s: np.ndarray
    particle_s: np.ndarray
    uv: np.ndarray
    bd: np.ndarray
    age: np.ndarray
    tissue: np.ndarray
    years: np.ndarray
    noise: np.ndarray


def _control_point_s(strands, topo) -> np.ndarray:
    """Distance to the root of every control point: its node's, or for a strand end part-way
    along an edge, linear between the edge's nodes."""
    part = np.flatnonzero(strands.frac < 1.0)
    f = strands.frac[part]
    cp_prev = np.where(part > 0, strands.node[np.maximum(part - 1, 0)], 0)
    cp_s = topo.s[strands.node].astype(float)
    cp_s[part] = (1.0 - f) * topo.s[cp_prev] + f * topo.s[strands.node[part]]
    return cp_s


def _clamp_cuts(skel: Skeleton, strands, cp_s: np.ndarray, depth: float) -> np.ndarray:
    """Per strand, the distance to the root of its clamp plane (``[mechanics] clamp_depth``) when
    its tree's root is anchored and the strand starts before the plane, else NaN."""
    root_of = np.arange(len(skel.ids))
    for i in range(len(skel.ids)):  # parents precede children
        if skel.parent[i] >= 0:
            root_of[i] = root_of[skel.parent[i]]
    first = strands.offsets[:-1]
    held = skel.anchored[root_of[strands.node[first]]] & (cp_s[first] < depth)
    return np.where(held, depth, np.nan)


def _anchored(samp, n_elements: int) -> np.ndarray:
    """The elements inside a clamp: those of a held strand before its particle on the plane."""
    local = np.arange(n_elements) - samp.element_offsets[samp.strand]
    return local < samp.cut[samp.strand]


def _rings(skel: Skeleton, topo, strands, samp, cp_s: np.ndarray, node_a: np.ndarray, node_b: np.ndarray,
           edge_t: np.ndarray, rg, rng: np.random.Generator) -> Rings:
    """Rings and tissues of the elements: bark distance and radial coordinate q on every control
    point in its node's profile (a strand end between two profiles interpolated), then each
    element's ring age and tissue (:mod:`wooddecay.strands.rings`)."""
    # bark distance and radial coordinate q on every control point, in its node's profile
    n_cp = len(strands.node)
    cp_bd, cp_q = np.zeros(n_cp), np.zeros(n_cp)
    years = np.array([profile_years(p, rg.ring_width) for p in skel.profiles])
    noise = year_noise(int(years.max()) + 1, rg.width_noise, rng)
    for i, rows in enumerate(group_rows(strands.node, len(skel.ids))):
        if len(rows):
            prof, pts = skel.profiles[i], strands.uv[rows]
            cp_bd[rows] = signed_distance(prof.polygon, pts)
            cp_q[rows] = radial_coordinate(prof, topo.up2d[i], rg.eccentricity, rg.pith_blend, pts)
    part = np.flatnonzero(strands.frac < 1.0)  # strand ends between two profiles
    f = strands.frac[part]
    cp_uv = strands.uv.copy()
    for v in (cp_bd, cp_q, cp_uv):
        fv = f.reshape(f.shape + (1,) * (v.ndim - 1))
        v[part] = (1.0 - fv) * v[part - 1] + fv * v[part]
    cp, t = samp.cp, samp.t
    particle_s = _particle_s(strands, samp, cp_s)
    uv = _lerp(cp_uv[cp], cp_uv[cp + 1], t)
    bd = _lerp(cp_bd[cp], cp_bd[cp + 1], t)
    q = _lerp(cp_q[cp], cp_q[cp + 1], t)
    age_a, age_b = np.zeros(len(q)), np.zeros(len(q))
    for i, (ra, rb) in enumerate(zip(group_rows(node_a, len(skel.ids)), group_rows(node_b, len(skel.ids)))):
        age_a[ra] = age_of(q[ra], years[i], rg.weibull_c, noise, int(years.max()))
        age_b[rb] = age_of(q[rb], years[i], rg.weibull_c, noise, int(years.max()))
    age = _lerp(age_a, age_b, edge_t)
    elem_years = _lerp(years[node_a].astype(float), years[node_b].astype(float), edge_t)
    tissue = classify_tissue(bd, age, elem_years, bark_thickness=rg.bark_thickness,
                             sapwood_rings=rg.sapwood_rings, pith_rings=rg.pith_rings)
    return Rings(cp_uv, cp_s, particle_s, uv, bd, age, tissue, years, noise)


def build_model(scene) -> WoodModel:
    """Build the wood model of a validated :class:`wooddecay.scene.Scene`."""
    sec: dict[str, float] = {}
    skel = scene.skeleton
    st, rg, bp, wp = scene.strands, scene.rings, scene.bsp, scene.weakpoints
    with _timed(sec, "topology"):
        topo = build_topology(skel)
    with _timed(sec, "strands"):
        strands = build_strands(skel, topo, st.r_s, st.phi_pack, st.packing_iterations,
                                stage_rng(scene.seed, "strands"))
        notes = narrow_notes(skel, float(st.r_s))
    with _timed(sec, "elements"):
        cp_s = _control_point_s(strands, topo)
        samp = sample_strands(strands, st.rod_length, stage_rng(scene.seed, "sampling"), cp_s,
                              _clamp_cuts(skel, strands, cp_s, float(scene.mechanics.clamp_depth)))
        node_a, node_b = strands.node[samp.cp], strands.node[samp.cp + 1]
        edge_t = samp.t * strands.frac[samp.cp + 1]  # a strand's end lies part-way along its edge
        geo = element_geometry(samp, node_a, node_b, edge_t, skel.positions, topo.frames, topo.s)
    with _timed(sec, "rings"):
        cp_uv, cp_s, particle_s, uv, bd, age, tissue, years, noise = _rings(
            skel, topo, strands, samp, cp_s, node_a, node_b, edge_t, rg, stage_rng(scene.seed, "rings"))
        wood_coords = np.stack([fm.hypot(uv[:, 0], uv[:, 1]), fm.arctan2(uv[:, 1], uv[:, 0]), geo.s], axis=1)
        materials = Materials({k: tuple(scene.tissue_param(t, k) for t in TISSUES) for k in TISSUE_KEYS}, tissue)
        mass = (materials.per_element("rho_dry") * (1.0 + materials.per_element("M_init")) * np.pi * st.r_s**2
                * geo.rest_length)
        branch = topo.branch[node_b]
        notes += empty_branch_notes(skel, topo, branch, float(st.r_s), float(st.rod_length))
        anchored = _anchored(samp, len(geo.centers))
    with _timed(sec, "reg"):
        pa = samp.particles[samp.first_particle]
        pb = samp.particles[samp.first_particle + 1]
        pairs, is_reg, chains = transport_graph(pa, pb, samp.strand, samp.element_offsets,
                                                st.connect_radius, st.transport_reach * st.r_s)
        reg = build_reg(pairs[is_reg], geo.centers, geo.rest_quat, geo.wood_frames)
        t_edges = np.vstack([pairs, chains])
        t_kind = np.concatenate([np.where(is_reg, 0, 2).astype(np.int8), np.ones(len(chains), np.int8)])
        t_indptr, t_indices, t_edge_of = csr_adjacency(len(geo.centers), t_edges)
    with _timed(sec, "bsp"):
        leaf = bsp_mod.bsp_leaves(wood_coords, branch, bp.cells, bp.elongation, bp.jitter,
                                  stage_rng(scene.seed, "bsp"))
        reg_theta = bsp_mod.theta(leaf, reg.edges)
    with _timed(sec, "weakpoints"):
        forks = np.array([i for i, c in enumerate(topo.children) if len(c) > 1], dtype=np.int64)
        W = weak_point_field(uv, geo.s, geo.centers, skel.positions[forks], scale=wp.scale,
                             stretch=wp.stretch, octaves=wp.octaves, junction_boost=wp.junction_boost,
                             junction_radius=wp.junction_radius, rng=stage_rng(scene.seed, "weakpoints"))
    model = WoodModel(
        particles=samp.particles, particle_offsets=samp.particle_offsets,
        element_offsets=samp.element_offsets, strand=samp.strand, first_particle=samp.first_particle,
        centers=geo.centers, rest_length=geo.rest_length, radius=np.full(len(geo.centers), st.r_s),
        mass=mass, rest_quat=geo.rest_quat, frames=geo.frames, wood_coords=wood_coords,
        bark_distance=bd, ring_age=age, tissue=tissue, branch=branch, bsp_leaf=leaf, W=W,
        anchored=anchored, reg_edges=reg.edges, reg_rest_offset=reg.rest_offset,
        reg_rest_darboux=reg.rest_darboux, reg_dir_weights=reg.dir_weights, reg_theta=reg_theta,
        reg_indptr=reg.indptr, reg_indices=reg.indices, reg_edge_of=reg.edge_of,
        transport_edges=t_edges,
        transport_kind=t_kind, transport_indptr=t_indptr, transport_indices=t_indices,
        transport_edge_of=t_edge_of,
        cp_offsets=strands.offsets, cp_node=strands.node, cp_uv=cp_uv, cp_s=cp_s, particle_s=particle_s,
        skeleton=skel, topology=topo, r_s=float(st.r_s), bark_thickness=float(rg.bark_thickness),
        materials=materials,
        info=_scene_info(scene), time=_time_spec(scene), build_seconds=sec, notes=notes,
        # the solvers' prepare() read only the wood arrays above; their setups replace these below
        bio=cast(BioSetup, None), mech=cast(MechSetup, None), coupling=cast(CouplingSetup, None),
    )
    with _timed(sec, "solvers"):
        model = replace(model, inoculations=tuple(
            Inoculation(day=float(ino["day"]), fungus=str(ino["fungus"]), activity=float(ino["activity"]),
                        mask=region_mask(model, ino["region"])) for ino in scene.inoculations))
        bio = biology.prepare(model, phi_pack=float(st.phi_pack), k_W=float(scene.weakpoints.k_W),
                              climate=_climate(scene))
        species = SPECIES.get(scene.wood["species"])
        config = MechConfig(**{f.name: scene.mechanics[f.name] for f in fields(MechConfig) if f.name != "reg_moduli"},
                            reg_moduli=None if species is None else tuple(species.rod_moduli()[2:]))
        loads = tuple(Load(day0=ld["days"][0], day1=ld["days"][1], force=tuple(ld["force"]),
                           mask=region_mask(model, ld["region"])) for ld in scene.loads)
        mech = mechanics.prepare(model, config, _collider_rows(scene), loads)
        model = replace(model, bio=bio, mech=mech, coupling=coupling.prepare(model),
                        notes=model.notes + mechanics.load_notes(mech))
    with _timed(sec, "bark"):
        bark = BarkSetup(**{f.name: scene.bark[f.name] for f in fields(BarkSetup)})
        if bark.cracks and rg.bark_thickness > 0.0:
            tree_years = int(years.max())
            recent = np.array([recent_growth(cumulative_widths(int(y), rg.weibull_c, noise, tree_years), bark.bark_years)
                               for y in years])
            model = replace(model, bark=build_sheet(model, bark, recent, rg.eccentricity, stage_rng(scene.seed, "bark")),
                            bark_setup=bark)
    for v in vars(model).values():  # the model is static: solvers change a SimState, never it
        if isinstance(v, np.ndarray):
            v.flags.writeable = False
    return model
