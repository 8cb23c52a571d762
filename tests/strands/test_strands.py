"""Strand packing, forks and terminations (docs/model.md §2 invariants)."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.model import stage_rng
from wooddecay.strands import packing, profiles
from wooddecay.strands.strands import _split_fork, build_strands
from wooddecay.strands.topology import build_topology

from ..conftest import SAMPLES


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
        pts = ss.uv[(ss.node == i) & (ss.frac == 1.0)]  # ends part-way along an edge are not on it
        if len(pts) == 0:
            continue
        assert profiles.contains(prof.polygon, pts).all(), f"node {scene.skeleton.ids[i]}"
        if len(pts) > 1:
            d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(len(pts)) * 1e9
            assert d.min() >= 2 * r_s * (1 - 1e-12), f"node {scene.skeleton.ids[i]}: {d.min() / r_s} r_s"


@pytest.mark.parametrize("name", ["tiny", "log", "tree"])
def test_every_profile_holds_its_capacity(name):
    """Counts follow floor(phi_pack A / (pi r_s^2)) on every profile strands reach (tapering
    strands end part-way along the next edge instead of at the node)."""
    scene = wd.load_scene(SAMPLES / f"{name}.toml")
    topo, ss = _strand_set(scene)
    st = scene.strands
    on = ss.frac == 1.0
    for i, prof in enumerate(scene.skeleton.profiles):
        cap = packing.strand_capacity(prof, st.r_s, st.phi_pack)
        count = int(np.sum(on & (ss.node == i)))
        if not topo.children[i]:  # a tip: strands that would begin there have no length
            assert count <= cap
        else:
            assert count == cap, f"node {scene.skeleton.ids[i]}: {count} != {cap}"


def test_strand_ends_are_staggered():
    scene = wd.load_scene(SAMPLES / "tree.toml")
    _, ss = _strand_set(scene)
    f = ss.frac[ss.frac < 1.0]
    assert len(f) > 50 and f.min() >= 0.15 and f.max() <= 0.85 and f.std() > 0.1


def test_fork_splits_by_area_and_side():
    scene = wd.load_scene(SAMPLES / "tree.toml")
    skel = scene.skeleton
    topo = build_topology(skel)
    forks = [i for i, c in enumerate(topo.children) if len(c) > 1]
    assert forks
    rng = np.random.default_rng(3)
    for f in forks:
        prof = skel.profiles[f]
        pts = packing.seed_positions(prof, packing.strand_capacity(prof, 0.0045, 0.8), 0.0045,
                                     packing.random_lattice(rng), rng)
        chosen = _split_fork(skel, topo, f, pts)
        # every strand goes to exactly one child, in proportion to the children's areas
        assert np.array_equal(np.sort(np.concatenate(chosen)), np.arange(len(pts)))
        areas = np.array([skel.profiles[c].area for c in topo.children[f]])
        quota = len(pts) * areas / areas.sum()
        counts = np.array([len(c) for c in chosen])
        assert np.all(np.abs(counts - quota) < 1.0)
        # a lateral child takes the strands on the side of the profile facing it
        for c, sel in zip(topo.children[f], chosen):
            d = skel.positions[c] - skel.positions[f]
            w = topo.frames[f, :2] @ d / np.linalg.norm(d)
            if np.linalg.norm(w) > 0.3 and len(sel):
                side = (pts[sel] - prof.centroid) @ (w / np.linalg.norm(w))
                assert side.mean() > 0.3 * prof.equivalent_radius


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


def test_edge_between_finds_the_reg_edge_of_a_pair_in_either_order():
    """strands.reg.edge_between: the edge's id for a joined pair, either order; not found where no
    edge joins them or the graph has no edges."""
    from wooddecay.strands.reg import edge_between

    edges = np.array([[0, 3], [2, 1], [4, 0]])
    edge, found = edge_between(edges, 5, np.array([3, 1, 0, 1, 2]), np.array([0, 2, 4, 4, 3]))
    np.testing.assert_array_equal(found, [True, True, True, False, False])
    np.testing.assert_array_equal(edge[found], [0, 1, 2])
    edge, found = edge_between(np.zeros((0, 2), dtype=np.int64), 5, np.array([0]), np.array([1]))
    assert not found.any() and len(edge) == 1
