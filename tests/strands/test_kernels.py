"""Numba kernels against their numpy references, and hand-checked cases of rings, BSP and noise."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from wooddecay.scene.schema import CONNECT_FACTOR
from wooddecay.strands import bsp, profiles, rings
from wooddecay.strands.elements import (
    arc_positions,
    matrix_to_quaternion,
    transport_frames_numba,
    transport_frames_reference,
)
from wooddecay.strands.reg import (
    segment_distance,
    segment_distance_reference,
    segment_pairs,
    segment_pairs_reference,
)
from wooddecay.strands.weakpoints import perlin3


def _brute_segment_distance(p1, q1, p2, q2, n=401):
    s = np.linspace(0, 1, n)
    a = p1 + (q1 - p1) * s[:, None]
    b = p2 + (q2 - p2) * s[:, None]
    return np.min(np.linalg.norm(a[:, None] - b[None], axis=-1))


coords = st.floats(-1.0, 1.0, allow_nan=False)
point = st.tuples(coords, coords, coords).map(np.array)


@settings(max_examples=200, deadline=None)
@given(point, point, point, point)
@example(np.zeros(3), np.array([0.5, 2.2294210663884868e-06, 0.5]), np.array([0.0, 0.0, 2.2294210663884868e-06]),
         np.array([0.5, 2.2294210663884868e-06, 0.5]))
def test_segment_distance_matches_reference_and_sampling(p1, q1, p2, q2):
    d = segment_distance(p1, q1, p2, q2)
    # round-off of near-parallel pairs: a distance from a squared distance near 0 carries
    # sqrt(eps) |segment| ~ 1.5e-8 (found: 1.2e-9 for two segments meeting at one end)
    assert d <= _brute_segment_distance(p1, q1, p2, q2) + 1e-7
    assert d >= _brute_segment_distance(p1, q1, p2, q2, n=401) - 2.0 * np.linalg.norm(q1 - p1 + q2 - p2) / 400 - 1e-9
    if np.linalg.norm(q1 - p1) > 1e-3 and np.linalg.norm(q2 - p2) > 1e-3:
        ref = segment_distance_reference(p1[None], q1[None], p2[None], q2[None])[0]
        # both take the root of a squared distance that is exact to round-off (found: 0 against
        # 8.3e-11 for two segments meeting at one end), so compare the squares
        assert abs(d * d - ref * ref) < 1e-12


def test_segment_distance_parallel_and_crossing():
    z = np.zeros(3)
    x = np.array([1.0, 0, 0])
    assert segment_distance(z, x, z + [0, 0.5, 0], x + [0, 0.5, 0]) == pytest.approx(0.5)
    assert segment_distance(z - [0, 1, 0], z + [0, 1, 0], z - x + [0, 0, 0.2], x + [0, 0, 0.2]) == pytest.approx(0.2)
    assert segment_distance(z, x, 2 * x, 3 * x) == pytest.approx(1.0)


def test_segment_pairs_numba_equals_reference(tiny_model, log_model):
    for m in (tiny_model, log_model):
        radius = CONNECT_FACTOR * m.r_s  # the samples' default connect_radius
        pa = m.particles[m.first_particle]
        pb = m.particles[m.first_particle + 1]
        np.testing.assert_array_equal(segment_pairs(pa, pb, m.strand, radius),
                                      segment_pairs_reference(pa, pb, m.strand, radius))
        np.testing.assert_array_equal(segment_pairs(pa, pb, m.strand, radius), m.reg_edges)


def test_transport_frames_numba_equals_reference(log_model):
    m = log_model
    tangent = m.frames[:, 2]
    d1_start = m.frames[m.element_offsets[:-1], 0]
    a = transport_frames_numba(m.element_offsets, tangent, d1_start)
    b = transport_frames_reference(m.element_offsets, tangent, d1_start)
    np.testing.assert_allclose(a, b, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", a, tangent), 0.0, atol=1e-12)


def test_parallel_transport_on_a_helix_has_no_twist_about_tangent():
    """Parallel transport is rotation-minimising: d1' has no component along d2 (Bishop frame)."""
    t = np.linspace(0, 4 * np.pi, 400)
    pts = np.stack([np.cos(t), np.sin(t), 0.3 * t], axis=1)
    tangent = np.diff(pts, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    d1_0 = np.cross(tangent[0], [0, 0, 1.0])
    d1_0 /= np.linalg.norm(d1_0)
    d1 = transport_frames_numba(np.array([0, len(tangent)]), tangent, d1_0[None])
    d2 = np.cross(tangent, d1)
    twist = np.einsum("ij,ij->i", np.diff(d1, axis=0), d2[:-1])
    # discrete transport: the d2 component of the step is O(ds) smaller than the step itself
    assert np.max(np.abs(twist)) < 1e-2 * np.max(np.linalg.norm(np.diff(d1, axis=0), axis=1))


def test_matrix_to_quaternion_round_trip():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(200, 3, 3))
    Q, _ = np.linalg.qr(A)
    Q *= np.sign(np.linalg.det(Q))[:, None, None]
    q = matrix_to_quaternion(Q)
    w, x, y, z = q.T
    R = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)
    np.testing.assert_allclose(R, Q, atol=1e-12)


def test_arc_positions_staggered_ends():
    L = 0.04
    for phase in (0.0, 0.3, 0.99):
        a = arc_positions(1.0, L, phase)
        d = np.diff(a)
        assert a[0] == 0.0 and a[-1] == 1.0
        assert np.all(d >= 0.5 * L - 1e-12) and np.all(d <= 1.5 * L + 1e-12)
        np.testing.assert_allclose(d[1:-1], L)
    assert len(arc_positions(0.01, L, 0.5)) == 2  # shorter than a rod: one element


def test_weibull_cumulative_widths():
    noise = np.ones(50)
    Q = rings.cumulative_widths(30, 2.0, noise, 30)
    assert Q[0] == 0 and Q[-1] == pytest.approx(1.0) and np.all(np.diff(Q) > 0)
    w = np.diff(Q)
    peak = np.argmax(w)
    # "prime of life" peak at t = 1/sqrt(2) for c = 2 (juvenile rise, mature decline)
    t_peak = rings.T_BIRTH + (peak + 0.5) / 30 * (rings.T_LIFE - rings.T_BIRTH)
    assert abs(t_peak - 1 / np.sqrt(2)) < (rings.T_LIFE - rings.T_BIRTH) / 30
    # a young section of the same tree has the rings of the last years: narrow, declining
    twig = np.diff(rings.cumulative_widths(3, 2.0, noise, 30))
    np.testing.assert_allclose(twig / twig.sum(), w[-3:] / w[-3:].sum(), rtol=1e-12)


def test_eccentricity_widens_rings_on_the_upper_side():
    prof = profiles.circle(0.1)
    up = np.array([0.0, 1.0])
    pith, _ = rings.find_pith(prof, up, 0.4)
    assert pith[1] < -0.005  # the pith moves down for e > 0 (grid resolution 0.2 / 32)
    no = rings.radial_coordinate(prof, up, 0.0, 0.0, np.array([[0.0, 0.09], [0.0, -0.09]]))
    assert no[0] == pytest.approx(no[1], abs=0.02)
    q = rings.radial_coordinate(prof, up, 0.4, 0.0, np.array([[0.0, 0.09], [0.0, -0.09]]))
    # 1 cm under the bark: the wide-ringed upper side crosses fewer rings, so it is closer to
    # the bark in ring terms (woodification Eq. 3: wider where n.y > 0 for e > 0)
    assert q[0] > q[1] + 0.03


def test_radial_coordinate_circle_is_r_over_R():
    prof = profiles.circle(0.1)
    pts = np.array([[0.0, 0.0], [0.05, 0.0], [0.0, -0.08]])
    q = rings.radial_coordinate(prof, np.array([0.0, 1.0]), 0.0, 0.0, pts)
    np.testing.assert_allclose(q, [0.0, 0.5, 0.8], atol=0.01)


def test_bsp_hand_made_case():
    # 8 elements at the corners of a 4 x 1 x 1 box in (r, r phi, s): the first cut is across s
    r = np.array([1.0, 2.0] * 4)
    s = np.repeat([0.0, 4.0], 4)
    phi = np.tile([0.0, 0.0, 0.5, 0.25], 2)
    wc = np.stack([r, phi, s], axis=1)
    leaf = bsp.bsp_leaves(wc, np.zeros(8, dtype=np.int64), 2, 1.0, 0.0, np.random.default_rng(0))
    assert len(np.unique(leaf)) == 2
    assert len(np.unique(leaf[s == 0])) == 1 and leaf[0] != leaf[4]
    # elongation 8 shrinks s to 0.5: now the longest axis is r, the cut goes across r
    leaf = bsp.bsp_leaves(wc, np.zeros(8, dtype=np.int64), 2, 8.0, 0.0, np.random.default_rng(0))
    assert len(np.unique(leaf[r == 1.0])) == 1 and leaf[0] != leaf[1]
    edges = np.array([[0, 1], [0, 2], [1, 3], [0, 4]])
    np.testing.assert_array_equal(bsp.theta(leaf, edges), [1.0, 0.0, 0.0, 0.0])


def test_bsp_deterministic_and_exact_leaf_count():
    rng = np.random.default_rng(5)
    wc = np.stack([rng.uniform(0, 0.1, 3000), rng.uniform(-np.pi, np.pi, 3000), rng.uniform(0, 1, 3000)], 1)
    br = np.zeros(3000, dtype=np.int64)
    a = bsp.bsp_leaves(wc, br, 57, 1.0, 0.2, np.random.default_rng(1))
    b = bsp.bsp_leaves(wc, br, 57, 1.0, 0.2, np.random.default_rng(1))
    np.testing.assert_array_equal(a, b)
    assert len(np.unique(a)) == 57


def test_perlin_zero_on_lattice_and_bounded():
    perm = np.random.default_rng(0).permutation(256)
    lattice = np.array([[0.0, 0, 0], [1, 2, 3], [-4, 5, 7]])
    np.testing.assert_allclose(perlin3(lattice, perm), 0.0, atol=1e-12)
    x = np.random.default_rng(1).uniform(-10, 10, (5000, 3))
    v = perlin3(x, perm)
    assert np.abs(v).max() <= 1.0 + 1e-9 and v.std() > 0.1
