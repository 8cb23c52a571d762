"""Cross-section geometry (docs/model.md §1; woodstock Fig. 3a)."""
import numpy as np
import pytest

from wooddecay.strands import profiles as pf

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
# L shape: the unit square [0, 2] x [0, 2] minus the upper-right quadrant [1, 2] x [1, 2].
L_SHAPE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]])


def test_circle_and_ellipse_exact_area_and_ccw_polygon():
    c = pf.circle(0.2)
    assert c.polygon.shape == (pf.PROFILE_SEGMENTS, 2)
    assert c.area == pytest.approx(np.pi * 0.04, rel=1e-15)
    assert c.equivalent_radius == pytest.approx(0.2)
    assert pf.is_ccw(c.polygon) and pf.is_simple(c.polygon)
    e = pf.ellipse(0.3, 0.1, np.pi / 2)
    assert e.area == pytest.approx(np.pi * 0.03)
    assert pf.is_ccw(e.polygon)
    # rotated by 90 degrees: the long axis is along v
    assert np.max(e.polygon[:, 1]) == pytest.approx(0.3)
    assert np.max(e.polygon[:, 0]) == pytest.approx(0.1)
    np.testing.assert_allclose(e.centroid, [0.0, 0.0])


def test_polygon_area_centroid_orientation():
    assert pf.polygon_area(L_SHAPE) == pytest.approx(3.0)
    assert pf.polygon_area(L_SHAPE[::-1]) == pytest.approx(3.0)
    assert pf.is_ccw(L_SHAPE) and not pf.is_ccw(L_SHAPE[::-1])
    # L = three unit squares centred at (0.5, 0.5), (1.5, 0.5), (0.5, 1.5)
    np.testing.assert_allclose(pf.polygon_centroid(L_SHAPE), [2.5 / 3, 2.5 / 3])
    p = pf.polygon(L_SHAPE)
    assert p.kind == "polygon" and p.area == pytest.approx(3.0)


def test_signed_distance_unit_square_exact():
    pts = np.array([[0.5, 0.5], [0.25, 0.5], [0.5, 0.1], [1.5, 0.5], [2.0, 2.0], [1.0, 0.3], [-0.5, -0.5]])
    expected = np.array([0.5, 0.25, 0.1, -0.5, -np.sqrt(2.0), 0.0, -np.sqrt(0.5)])
    np.testing.assert_allclose(pf.signed_distance(SQUARE, pts), expected, atol=1e-15)


def test_signed_distance_circle_matches_analytic():
    r = 0.5
    c = pf.circle(r)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1.0, 1.0, size=(2000, 2))
    analytic = r - np.linalg.norm(pts, axis=1)
    # the inscribed 64-gon is at most r (1 - cos(pi / 64)) inside the circle
    sagitta = r * (1.0 - np.cos(np.pi / pf.PROFILE_SEGMENTS))
    err = pf.signed_distance(c.polygon, pts) - analytic
    assert np.all(err <= 1e-12) and np.all(err >= -sagitta - 1e-12)


def test_closest_boundary_point():
    pts = np.array([[0.5, 0.2], [2.0, 0.5], [1.5, 1.5], [-1.0, -1.0]])
    expected = np.array([[0.5, 0.0], [1.0, 0.5], [1.0, 1.0], [0.0, 0.0]])
    np.testing.assert_allclose(pf.closest_boundary_point(SQUARE, pts), expected, atol=1e-15)
    q = pf.closest_boundary_point(pf.circle(1.0).polygon, [[3.0, 0.0]])
    np.testing.assert_allclose(q, [[1.0, 0.0]])


def test_contains_square_and_l_shape():
    assert pf.contains(SQUARE, [[0.5, 0.5], [1.0, 0.5], [0.0, 0.0], [1.0 + 1e-13, 0.5], [1.1, 0.5]]).tolist() == [
        True, True, True, True, False]
    inside = [[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.0, 1.0], [1.5, 1.0]]
    outside = [[1.5, 1.5], [1.01, 1.01], [2.5, 0.5], [-0.1, 1.0], [1.9, 1.9]]
    assert np.all(pf.contains(L_SHAPE, inside))
    assert not np.any(pf.contains(L_SHAPE, outside))


def test_contains_many_points_agrees_with_signed_distance():
    pts = np.random.default_rng(2).uniform(-0.5, 2.5, size=(5000, 2))
    sd = pf.signed_distance(L_SHAPE, pts)
    np.testing.assert_array_equal(pf.contains(L_SHAPE, pts), sd >= 0.0)
    in_l = (pts[:, 0] >= 0) & (pts[:, 1] >= 0) & (pts[:, 0] <= 2) & (pts[:, 1] <= 2)
    in_l &= ~((pts[:, 0] > 1) & (pts[:, 1] > 1))
    np.testing.assert_array_equal(sd >= 0.0, in_l)


def test_ray_extent_square_and_l_shape():
    d = pf.ray_extent(SQUARE, [0.5, 0.5], [0.0, np.pi / 2, np.pi, -np.pi / 2, np.pi / 4])
    np.testing.assert_allclose(d, [0.5, 0.5, 0.5, 0.5, np.sqrt(0.5)])
    # from (0.5, 0.5) in the L: +u exits at u = 2, +v exits at v = 2, the diagonal at the notch corner
    d = pf.ray_extent(L_SHAPE, [0.5, 0.5], [0.0, np.pi / 2, np.pi / 4, np.pi])
    np.testing.assert_allclose(d, [1.5, 1.5, np.sqrt(0.5), 0.5])
    # a ray towards the notch from (1.5, 0.5) leaves through the edge v = 1
    np.testing.assert_allclose(pf.ray_extent(L_SHAPE, [1.5, 0.5], [np.pi / 2]), [0.5])
    r = pf.ray_extent(pf.circle(1.0).polygon, [0.0, 0.0], np.linspace(0, 2 * np.pi, 50))
    assert np.all((r <= 1.0 + 1e-12) & (r >= np.cos(np.pi / pf.PROFILE_SEGMENTS) - 1e-12))


def test_is_simple():
    bow_tie = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    assert not pf.is_simple(bow_tie)
    assert pf.is_simple(SQUARE) and pf.is_simple(L_SHAPE)
    assert not pf.is_simple(SQUARE[:2])
    assert not pf.is_simple(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]))
    # touching: vertex 4 lies on edge 0-1
    assert not pf.is_simple(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.5, 1.0], [1.0, 0.0], [0.0, 1.0]]))
    # degenerate fold-back spike
    assert not pf.is_simple(np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.0]]))
