"""Strand packing, forks and terminations (SPEC §2 invariants)."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.model import stage_rng
from wooddecay.strands import packing, profiles
from wooddecay.strands.strands import build_strands
from wooddecay.strands.topology import build_topology

from .conftest import SAMPLES


def _strand_set(scene):
    topo = build_topology(scene.skeleton)
    st = scene.strands
    return topo, build_strands(scene.skeleton, topo, st.r_s, st.phi_pack, st.packing_iterations,
                               stage_rng(scene.seed, "strands"))


@pytest.mark.parametrize("name", ["board", "log", "tree"])
def test_strands_apart_and_inside_every_profile(name):
    scene = wd.load_scene(SAMPLES / f"{name}.toml")
    _, ss = _strand_set(scene)
    r_s = scene.strands.r_s
    for i, prof in enumerate(scene.skeleton.profiles):
        pts = ss.uv[ss.node == i]
        if len(pts) == 0:
            continue
        assert profiles.contains(prof.polygon, pts).all(), f"node {scene.skeleton.ids[i]}"
        if len(pts) > 1:
            d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(len(pts)) * 1e9
            assert d.min() >= 2 * r_s * (1 - 1e-12), f"node {scene.skeleton.ids[i]}: {d.min() / r_s} r_s"


def test_root_count_follows_area():
    scene = wd.load_scene(SAMPLES / "log.toml")
    _, ss = _strand_set(scene)
    prof = scene.skeleton.profiles[0]
    cap = packing.strand_capacity(prof, scene.strands.r_s, scene.strands.phi_pack)
    assert cap == int(np.floor(0.8 * np.pi * 0.15**2 / (np.pi * scene.strands.r_s**2)))
    # every seeded root position either continues or ends right there; none is lost to overlap
    rng = np.random.default_rng(0)
    assert packing.seed_positions(prof, cap, scene.strands.r_s, packing.random_lattice(rng), rng).shape == (cap, 2)


def test_fork_splits_by_area_and_side():
    scene = wd.load_scene(SAMPLES / "tree.toml")
    topo, ss = _strand_set(scene)
    skel = scene.skeleton
    forks = [i for i, c in enumerate(topo.children) if len(c) > 1]
    assert forks
    for f in forks:
        at_fork = {int(s) for s in np.searchsorted(ss.offsets, np.flatnonzero(ss.node == f), "right") - 1}
        per_child = {}
        for c in topo.children[f]:
            rows = np.flatnonzero(ss.node == c)
            strands_c = set((np.searchsorted(ss.offsets, rows, "right") - 1).tolist())
            per_child[c] = strands_c & at_fork
        # a strand goes to one child only
        sets = list(per_child.values())
        assert not set.intersection(*sets)
        areas = np.array([skel.profiles[c].area for c in per_child])
        counts = np.array([len(s) for s in per_child.values()], dtype=float)
        # the lateral child gets about its share of the strands (terminations at the child's
        # profile can only reduce it)
        share = areas / areas.sum()
        assert np.all(counts <= share * len(at_fork) + 1.0)


def test_pbd_relax_keeps_valid_packing_and_moves_to_goal():
    prof = profiles.circle(0.05)
    r_s = 0.004
    rng = np.random.default_rng(1)
    sites = packing.seed_positions(prof, 100, r_s, packing.random_lattice(rng), rng)
    goal = sites * 0.9  # compressed: infeasible target, must stay valid
    out = packing.pbd_relax(prof, sites, goal, r_s, 30)
    assert len(packing.overlapping_pairs(out, r_s)) == 0
    assert profiles.contains(prof.polygon, out).all()
    # it moved towards the goal
    assert np.linalg.norm(out - goal) < np.linalg.norm(sites - goal)


def test_taper_terminates_strands():
    scene = wd.load_scene(SAMPLES / "tree.toml")
    _, ss = _strand_set(scene)
    tip_counts = np.bincount(ss.node, minlength=len(scene.skeleton.ids))
    root_count = tip_counts[0]
    assert 0 < tip_counts.max() <= root_count
    # the trunk top holds fewer strands than the base: strands ended along the way
    top = scene.skeleton.ids.index("t9")
    assert tip_counts[top] < root_count / 2
