"""Rod elements, wood frames, REG, tissues, BSP and determinism of the built WoodModel."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.strands.reg import segment_distance_reference
from wooddecay.strands.rings import BARK, HEARTWOOD, PITH, SAPWOOD

from .conftest import ROOT, SAMPLES, sample


def _arrays(model):
    return {k: v for k, v in vars(model).items() if isinstance(v, np.ndarray)}


@pytest.mark.parametrize("name", ["tiny", "log", "board"])
def test_element_count_matches_strand_length(name):
    scene = wd.load_scene(SAMPLES / f"{name}.toml")
    m = wd.build_model(scene)
    L = scene.strands.rod_length
    assert abs(m.n_elements - m.rest_length.sum() / L) <= 0.02 * m.n_elements
    per_strand = np.add.reduceat(m.rest_length, m.element_offsets[:-1])
    assert np.all(np.abs(np.diff(m.element_offsets) - per_strand / L) <= 1.0)


def test_mass_uses_per_tissue_density_and_moisture():
    scene = wd.load_scene(SAMPLES / "tiny.toml", overrides={"tissue.bark.rho_dry": 900.0,
                                                             "tissue.bark.M_init": 0.3})
    m = wd.build_model(scene)
    bark = m.tissue == BARK
    expect = np.where(bark, 900.0 * 1.3, scene.mechanics.rho_dry * (1 + scene.moisture.M_init))
    np.testing.assert_allclose(m.mass, expect * np.pi * scene.strands.r_s**2 * m.rest_length)


def test_model_arrays_are_read_only(tiny_model):
    with pytest.raises(ValueError):
        tiny_model.centers[0, 0] = 1.0


def test_rest_lengths_staggered(log_model):
    m, L = log_model, sample("log")[0].strands.rod_length
    assert np.all(m.rest_length > 0.5 * L * 0.99) and np.all(m.rest_length < 1.5 * L * 1.01)
    # random phase: the first element boundaries of different strands do not line up
    first_len = m.rest_length[m.element_offsets[:-1]]
    assert np.std(first_len) > 0.2 * L


@pytest.mark.parametrize("fixture", ["tiny_model", "log_model", "board_model"])
def test_wood_frames_orthonormal_right_handed_along_segment(fixture, request):
    m = request.getfixturevalue(fixture)
    F = m.frames
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", F, F), np.broadcast_to(np.eye(3), F.shape), atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-10)
    seg = m.particles[m.first_particle + 1] - m.particles[m.first_particle]
    seg /= np.linalg.norm(seg, axis=1, keepdims=True)
    np.testing.assert_allclose(F[:, 2], seg, atol=1e-12)


def test_e_r_points_away_from_log_axis(log_model):
    m = log_model
    nodes = m.skeleton.positions
    axis_z = np.interp(m.centers[:, 0], nodes[:, 0], nodes[:, 2])
    off_axis = m.centers[:, 1:] - np.stack([np.zeros(len(axis_z)), axis_z], axis=1)
    far = np.linalg.norm(off_axis, axis=1) > 0.03
    cos = np.einsum("ni,ni->n", m.frames[far, 0, 1:], off_axis[far]) / np.linalg.norm(off_axis[far], axis=1)
    assert np.all(cos > 0.95)


def test_rest_quaternions_unit_and_d3_along_segment(tiny_model):
    q = tiny_model.rest_quat
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    w, x, y, z = q.T
    d3 = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
    np.testing.assert_allclose(d3, tiny_model.frames[:, 2], atol=1e-10)


@pytest.mark.parametrize("fixture", ["tiny_model", "log_model"])
def test_reg_symmetric_simple(fixture, request):
    m = request.getfixturevalue(fixture)
    e = m.reg_edges
    assert np.all(e[:, 0] < e[:, 1])  # no self-edges, canonical order
    assert len(np.unique(e, axis=0)) == len(e)  # no duplicates
    assert np.all(m.strand[e[:, 0]] != m.strand[e[:, 1]])
    # CSR is symmetric: j in N(i) <=> i in N(j)
    rows = np.repeat(np.arange(m.n_elements), np.diff(m.reg_indptr))
    pairs = set(zip(rows.tolist(), m.reg_indices.tolist()))
    assert all((j, i) in pairs for i, j in pairs)
    assert len(pairs) == 2 * len(e)
    np.testing.assert_allclose(m.reg_dir_weights.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(m.reg_rest_offset, np.linalg.norm(m.centers[e[:, 1]] - m.centers[e[:, 0]], axis=1))


def test_transport_graph_is_chains_plus_wider_pairs(tiny_model, tiny_scene):
    m = tiny_model
    chains = m.transport_edges[m.transport_kind == 1]
    assert np.all(chains[:, 1] == chains[:, 0] + 1)
    assert np.all(m.strand[chains[:, 0]] == m.strand[chains[:, 1]])
    assert len(chains) == m.n_elements - m.n_strands
    # the REG is exactly the transport pairs within connect_radius; the rest reach further
    np.testing.assert_array_equal(m.transport_edges[m.transport_kind == 0], m.reg_edges)
    wide = m.transport_edges[m.transport_kind == 2]
    assert len(wide) > 0 and np.all(m.strand[wide[:, 0]] != m.strand[wide[:, 1]])
    pa, pb = m.particles[m.first_particle], m.particles[m.first_particle + 1]
    i, j = wide[:, 0], wide[:, 1]
    d = segment_distance_reference(pa[i], pb[i], pa[j], pb[j])
    st = tiny_scene.strands
    assert np.all(d > st.connect_radius) and np.all(d <= st.transport_reach * st.r_s)


def test_tissues_ordered_by_bark_distance(log_model):
    m = log_model
    bd = m.bark_distance
    med = [np.median(bd[m.tissue == t]) for t in (BARK, SAPWOOD, HEARTWOOD, PITH)]
    assert all(np.sum(m.tissue == t) > 0 for t in (BARK, SAPWOOD, HEARTWOOD, PITH))
    assert med == sorted(med)
    assert bd[m.tissue == BARK].max() < bd[m.tissue != BARK].min()


CYLINDER = """
[[skeleton.node]]
id = "a"
position = [0.0, 0.0, 0.0]
profile = { kind = "circle", radius = 0.06 }
[[skeleton.node]]
id = "b"
position = [0.0, 0.0, 0.3]
parent = "a"
profile = { kind = "circle", radius = 0.06 }
[strands]
rod_length = 0.03
[rings]
ring_width = 0.006
bark_thickness = 0.004
eccentricity = 0.0
width_noise = 0.0
pith_blend = 0.0
sapwood_rings = 4
pith_rings = 2
"""


def test_tissues_strictly_ordered_on_a_concentric_log():
    """e = 0, no width noise, no pith blend, a cylinder: ring age is a function of bark distance,
    so the tissues are separated by bark distance exactly."""
    scene = wd.parse_scene(CYLINDER, source="cylinder.toml")
    m = wd.build_model(scene)
    bd = m.bark_distance
    present = [t for t in (BARK, SAPWOOD, HEARTWOOD, PITH) if np.any(m.tissue == t)]
    assert len(present) == 4
    for a, b in zip(present, present[1:]):
        assert bd[m.tissue == a].max() <= bd[m.tissue == b].min() + 1e-3 * scene.strands.r_s


def test_bsp_leaf_count_and_theta(log_model, log_scene):
    m = log_model
    assert m.bsp_cells == log_scene.bsp.cells
    np.testing.assert_array_equal(m.reg_theta, (m.bsp_leaf[m.reg_edges[:, 0]] != m.bsp_leaf[m.reg_edges[:, 1]]))
    assert 0.0 < m.reg_theta.mean() < 1.0


def test_bsp_disabled():
    scene = wd.load_scene(SAMPLES / "tiny.toml", overrides={"bsp.cells": 0})
    m = wd.build_model(scene)
    assert m.bsp_cells == 1 and not m.reg_theta.any()


def test_weak_points_in_range(log_model):
    assert log_model.W.min() >= 0.0 and log_model.W.max() <= 1.0
    assert log_model.W.std() > 0.02


def test_same_seed_identical_different_seed_differs(tiny_scene, tiny_model):
    again = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml"))
    a, b = _arrays(tiny_model), _arrays(again)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    other = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", overrides={"scene.seed": 2}))
    assert not np.array_equal(other.centers[:10], tiny_model.centers[:10]) or other.n_elements != tiny_model.n_elements


_DIGEST = """
import hashlib, sys, numpy as np, wooddecay as wd
m = wd.build_model(wd.load_scene(sys.argv[1]))
h = hashlib.sha256()
for k, v in sorted(vars(m).items()):
    if isinstance(v, np.ndarray):
        h.update(k.encode()); h.update(np.ascontiguousarray(v).tobytes())
print(h.hexdigest())
"""


@pytest.mark.slow
def test_identical_arrays_for_1_and_2_threads():
    out = []
    for threads in ("1", "2"):
        env = dict(os.environ, NUMBA_NUM_THREADS=threads)
        r = subprocess.run([sys.executable, "-c", _DIGEST, str(SAMPLES / "log.toml")], env=env,
                           capture_output=True, text=True, cwd=ROOT, check=True)
        out.append(r.stdout.strip())
    assert out[0] == out[1]


@pytest.mark.slow
def test_tree_builds_about_50k_elements():
    scene, m = sample("tree")
    assert 40_000 <= m.n_elements <= 60_000
    assert m.n_branches >= 10
    assert m.bsp_cells == scene.bsp.cells
    assert all(v > 0 for v in m.tissue_counts().values())
    assert json.dumps(m.tissue_counts())


def test_bsp_disabled_on_the_tree_has_no_theta():
    scene = wd.load_scene(SAMPLES / "tree.toml", overrides={"bsp.cells": 0, "strands.r_s": 0.02, "strands.rod_length": 0.1})
    m = wd.build_model(scene)
    assert m.bsp_cells == 1 and not m.reg_theta.any()


@pytest.mark.slow
def test_weak_points_raised_near_junctions_and_stretched_along_grain():
    scene, m = sample("tree")
    skel = scene.skeleton
    forks = np.array([i for i in range(len(skel.ids)) if np.sum(skel.parent == i) > 1])
    d = np.min(np.linalg.norm(m.centers[:, None] - skel.positions[forks][None], axis=-1), axis=1)
    near, far = d < 0.5 * scene.weakpoints.junction_radius, d > 3 * scene.weakpoints.junction_radius
    assert m.W[near].mean() > m.W[far].mean() + 0.1
    # stretched along the grain: W varies less along a strand than across strands
    chain = m.transport_edges[m.transport_kind == 1]
    reg = m.reg_edges
    assert np.mean(np.abs(np.diff(m.W[chain], axis=1))) < np.mean(np.abs(np.diff(m.W[reg], axis=1)))


def test_a_load_that_splits_the_substeps_is_noted():
    """A [[load]] whose force would throw its particles more than LOAD_JUMP of an element per
    substep gets a note naming it and the split (``summary.json`` notes, ``inspect``); a light
    one gets none."""
    import tomllib

    from wooddecay.scene import parse_scene

    data = tomllib.loads((SAMPLES / "tiny.toml").read_text())
    notes = []
    for newtons in (1.0, 1e5):
        data["load"] = [{"region": {"kind": "end", "which": "root", "depth": 0.03}, "force": [0.0, 0.0, -newtons],
                         "days": [0.0, 30.0]}]
        model = wd.build_model(parse_scene(data, source="tiny.toml", base_dir=SAMPLES))
        notes.append([n for n in model.notes if n.startswith("load[0]")])
    assert notes[0] == [] and len(notes[1]) == 1 and "split into" in notes[1][0], notes
