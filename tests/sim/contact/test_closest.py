"""Closest points and capsule penetration (woodstock §5.4, Eq. 3): the numba helpers against their
numpy references and brute-force sampling, parallel and degenerate segments, crossing axes."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.sim import contact as C

from .helpers import _rows, _segment_soup


def _brute_distance(p1, q1, p2, q2, n=801):
    s = np.linspace(0, 1, n)
    a = p1 + (q1 - p1) * s[:, None]
    b = p2 + (q2 - p2) * s[:, None]
    return np.min(np.linalg.norm(a[:, None] - b[None], axis=-1))


def test_closest_points_match_reference_and_sampling():
    x, fp, _, _ = _segment_soup(1, n_seg=400)
    rng = np.random.default_rng(2)
    i, j = rng.integers(0, 400, 3000), rng.integers(0, 400, 3000)
    p1, q1, p2, q2 = x[fp[i]], x[fp[i] + 1], x[fp[j]], x[fp[j] + 1]
    s_ref, t_ref = C.closest_segment_segment_reference(p1, q1, p2, q2)
    for k in range(len(i)):
        X = np.stack([p1[k], q1[k], p2[k], q2[k]])
        s, t = C.closest_segment_segment(X, 0, 1, 2, 3)
        assert 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0
        assert abs(s - s_ref[k]) < 1e-12 and abs(t - t_ref[k]) < 1e-12
        d = np.linalg.norm(p2[k] + t * (q2[k] - p2[k]) - p1[k] - s * (q1[k] - p1[k]))
        if k < 300:
            assert d <= _brute_distance(p1[k], q1[k], p2[k], q2[k]) + 1e-12


def test_closest_points_special_cases():
    # parallel with overlap: the middle of the overlap
    X = _rows([0, 0, 0], [1, 0, 0], [0.5, 1, 0], [2, 1, 0])
    assert np.allclose(C.closest_segment_segment(X, 0, 1, 2, 3), (0.75, 1 / 6))
    # parallel without overlap: the nearest ends
    X = _rows([0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0])
    assert np.allclose(C.closest_segment_segment(X, 0, 1, 2, 3), (1.0, 0.0))
    # both degenerate, one degenerate
    X = _rows([1, 2, 3], [1, 2, 3], [0, 0, 0], [0, 0, 0])
    assert C.closest_segment_segment(X, 0, 1, 2, 3) == (0.0, 0.0)
    X = _rows([0.3, 1, 0], [0.3, 1, 0], [0, 0, 0], [1, 0, 0])
    assert np.allclose(C.closest_segment_segment(X, 0, 1, 2, 3), (0.0, 0.3))
    assert np.isclose(C.closest_point_segment(X, 0, 2, 3), 0.3)
    assert C.closest_point_segment(_rows([5, 0, 0], [0, 0, 0], [1, 0, 0]), 0, 1, 2) == 1.0


def test_capsule_contact_normal_when_axes_cross():
    X = _rows([-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0])
    s, t, nx, ny, nz, phi = C.capsule_contact(X, 0, 1, 0.1, 2, 3, 0.2)
    assert (s, t, phi) == (0.5, 0.5, pytest.approx(0.3))
    assert np.allclose(np.abs([nx, ny, nz]), [0, 0, 1])
    # coincident parallel axes: a normal perpendicular to them
    X = _rows([0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 0])
    _, _, nx, ny, nz, phi = C.capsule_contact(X, 0, 1, 0.1, 2, 3, 0.1)
    assert phi == pytest.approx(0.2) and abs(nx) < 1e-15 and np.isclose(ny * ny + nz * nz, 1.0)
