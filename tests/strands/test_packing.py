"""Strand packing on one profile: sparse site assignment, concave profiles, PBD validity."""
from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from wooddecay.strands import packing, profiles

#: a C-shaped profile (counter-clockwise), 0.1 m square with a notch cut in from the right;
#: its area centroid (0.045, 0.05) lies in the notch, outside the profile
C_SHAPE = profiles.polygon(0.1 * np.array([
    [0.0, 0.0], [1.0, 0.0], [1.0, 0.3], [0.2, 0.3], [0.2, 0.7], [1.0, 0.7], [1.0, 1.0], [0.0, 1.0],
]))


def _dense_cost(goal, sites):
    """Optimal total squared displacement (scipy's dense linear_sum_assignment)."""
    cost = ((goal[:, None] - sites[None]) ** 2).sum(-1)
    rows, cols = linear_sum_assignment(cost)
    return cost[rows, cols].sum()


def _near_goals(rng, n_sites, n_goals):
    """Random sites in the unit square and goals scattered about a random subset of them."""
    sites = rng.uniform(0.0, 1.0, (n_sites, 2))
    goal = sites[rng.permutation(n_sites)[:n_goals]]
    return goal + rng.normal(0.0, 0.5 / np.sqrt(n_sites), goal.shape), sites


def _assert_valid(profile, pts, r_s):
    """Every point inside the profile and no two closer than 2 r_s."""
    assert profiles.contains(profile.polygon, pts).all()
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(len(pts)) * 1e9
    assert d.min() >= 2.0 * r_s


def _lattice_goals(rng, profile, n_sites, n_goals, r_s, shrink=1.0):
    """Sites and goals from two independent hex lattices on ``profile`` (goals scaled by
    ``shrink`` about the centroid): the optimum reaches beyond the nearest candidates."""
    sites = packing.seed_positions(profile, n_sites, r_s, packing.random_lattice(rng), rng)
    goal = packing.seed_positions(profile, n_goals, r_s, packing.random_lattice(rng), rng)
    return profile.centroid + shrink * (goal - profile.centroid), sites


def _assert_optimal(goal, sites, site_of):
    """A full assignment with the dense optimum's total cost."""
    assert site_of.shape == (len(goal),) and len(np.unique(site_of)) == len(goal)
    total = ((goal - sites[site_of]) ** 2).sum()
    assert total == pytest.approx(_dense_cost(goal, sites), rel=1e-9)


@pytest.mark.parametrize("n_sites, n_goals", [(10, 7), (40, 40), (200, 150), (800, 700)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_assign_sites_matches_dense_optimum(n_sites, n_goals, seed):
    goal, sites = _near_goals(np.random.default_rng(seed), n_sites, n_goals)
    _assert_optimal(goal, sites, packing.assign_sites(goal, sites))


@pytest.mark.parametrize("shrink", [1.0, 0.75, 0.1])
@pytest.mark.parametrize("n_goals", [420, 500])
@pytest.mark.parametrize("seed", [0, 1])
def test_assign_sites_optimal_when_candidates_do_not_suffice(shrink, n_goals, seed):
    """Two lattices, goals shrunk by 0.75 (the optimum moves goals past their 16 nearest
    sites: the candidates double) or 0.1 (no full matching until the dense solver)."""
    rng = np.random.default_rng(seed)
    goal, sites = _lattice_goals(rng, profiles.ellipse(0.1, 0.07, 0.4), 500, n_goals, 0.002, shrink)
    _assert_optimal(goal, sites, packing.assign_sites(goal, sites))


def test_assign_sites_is_deterministic_and_handles_empty():
    goal, sites = _near_goals(np.random.default_rng(4), 300, 250)
    np.testing.assert_array_equal(packing.assign_sites(goal, sites), packing.assign_sites(goal, sites))
    assert len(packing.assign_sites(np.zeros((0, 2)), sites)) == 0
    assert len(packing.assign_sites(np.zeros((0, 2)), np.zeros((0, 2)))) == 0


@pytest.mark.parametrize("lattices", [False, True])
def test_assign_sites_3000_strands_is_fast(lattices):
    rng = np.random.default_rng(5)
    packing.assign_sites(*_near_goals(rng, 100, 90))  # compile the numba kernels
    if lattices:
        goal, sites = _lattice_goals(rng, profiles.circle(0.2), 3000, 3000, 0.2 * np.sqrt(0.8 / 3000))
    else:
        goal, sites = _near_goals(rng, 3200, 3000)
    t0 = time.perf_counter()
    site_of = packing.assign_sites(goal, sites)
    assert time.perf_counter() - t0 < 0.5
    assert len(np.unique(site_of)) == len(goal) >= 2900


def test_project_inside_moves_inwards_on_a_concave_profile():
    """Points in the notch of the C go to its arms, not towards the (outside) centroid."""
    assert not profiles.contains(C_SHAPE.polygon, C_SHAPE.centroid[None])[0]
    pts = np.array([[0.06, 0.032], [0.06, 0.068], [0.03, 0.05], [0.105, 0.105], [0.04, 0.04]])
    out = packing._project_inside(C_SHAPE, pts)
    assert packing.inside(C_SHAPE.polygon, out).all()
    np.testing.assert_allclose(out, [[0.06, 0.03], [0.06, 0.07], [0.02, 0.05], [0.1, 0.1], [0.04, 0.03]],
                               atol=1e-9)


def test_pack_concave_profile_inside_and_apart():
    rng = np.random.default_rng(6)
    r_s = 0.002
    capacity = packing.strand_capacity(C_SHAPE, r_s, 0.8)
    goal = rng.uniform(0.0, 0.1, (capacity - 20, 2))  # many goals in the notch, outside
    pts, kept, n_new = packing.pack_profile(C_SHAPE, goal, capacity, r_s, 40, packing.random_lattice(rng), rng)
    assert len(pts) == len(kept) + n_new and len(pts) > 0.9 * capacity
    _assert_valid(C_SHAPE, pts, r_s)


def test_pbd_relax_from_compressed_goals_stays_valid():
    rng = np.random.default_rng(7)
    r_s = 0.002
    for profile in (profiles.circle(0.05), C_SHAPE):
        sites = packing.seed_positions(profile, packing.strand_capacity(profile, r_s, 0.7), r_s,
                                       packing.random_lattice(rng), rng)
        goal = profile.centroid + 0.3 * (sites - profile.centroid)
        out = packing.pbd_relax(profile, sites, goal, r_s, 30)
        _assert_valid(profile, out, r_s)
        assert np.linalg.norm(out - goal, axis=1).sum() < np.linalg.norm(sites - goal, axis=1).sum()


def test_collision_sweep_equals_numpy_reference():
    """One Gauss-Seidel sweep of the pair constraints, numba against its numpy twin, on crowded
    random points (coincident ones included)."""
    rng = np.random.default_rng(3)
    pts = rng.uniform(0.0, 0.05, (200, 2))
    pts[7] = pts[3]  # a coincident pair takes the fixed direction
    pairs = packing.overlapping_pairs(pts, 0.004)
    pairs = np.vstack([pairs, [[3, 7]]])
    a, b = pts.copy(), pts.copy()
    packing.collision_sweep(a, pairs, 0.008)
    packing.collision_sweep_reference(b, pairs, 0.008)
    assert np.abs(a - pts).max() > 1e-4
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
