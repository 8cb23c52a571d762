"""Colliders (woodstock §5.4, Eqs. 3-4): projections against their numpy references, signed
distances and normals of each kind, the table checks, the analytic resting penetration."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.sim import contact as C

from .helpers import DT, G, _colliders, _moved


def test_project_colliders_matches_reference():
    rng = np.random.default_rng(4)
    x = rng.random((5000, 3))
    x[:100] = [0.45, 0.8, 0.45]  # on the cylinder axis: radial normal by the fallback
    x[100:120] = [0.7, 0.7, 0.5]  # at the sphere centre
    w = rng.uniform(0.5, 2.0, len(x))
    w[::9] = 0.0
    prad = rng.uniform(0.0, 0.03, len(x))
    x1, x2, f1, f2 = x.copy(), x.copy(), np.zeros(len(x)), np.zeros(len(x))
    res1 = C.project_colliders(x1, w, prad, _colliders(), 30.0, DT, f1)
    res2 = C.project_colliders_reference(x2, w, prad, _colliders(), 30.0, DT, f2)
    assert res1[0] == res2[0] > 300 and res1[1] == pytest.approx(res2[1], abs=1e-15)
    assert np.allclose(x1, x2, rtol=0, atol=1e-12)
    assert np.allclose(f1, f2, rtol=1e-12, atol=1e-12)
    assert np.array_equal(x1[w == 0.0], x[w == 0.0])
    assert C.project_colliders(x1, w, prad, _colliders(), 0.0, DT, f1) == (0, 0.0)


@pytest.mark.parametrize(("row", "p", "sd", "n"), [
    (C.collider_row(C.PLANE, 0, 0, 1, 0, 0, 2), [3, 4, 0.9], -0.1, [0, 0, 1]),
    (C.collider_row(C.SPHERE, 1, 1, 1, 0.5), [1, 1.4, 1], -0.1, [0, 1, 0]),
    (C.collider_row(C.SPHERE, 1, 1, 1, 0.5), [1, 1, 1.55], 0.05, [0, 0, 1]),
    (C.collider_row(C.BOX, 0, 0, 0, 1, 2, 3), [0.5, 1.95, 1], -0.05, [0, 1, 0]),
    (C.collider_row(C.BOX, 0, 0, 0, 1, 2, 3), [0.04, 1, 1], -0.04, [-1, 0, 0]),
    (C.collider_row(C.BOX, 0, 0, 0, 1, 2, 3), [1.03, 2.04, 1], 0.05, [0.6, 0.8, 0]),
    (C.collider_row(C.CYLINDER, 0, 0, 0, 0, 0, 2, 0.5), [0.3, 0.3, 1], np.hypot(0.3, 0.3) - 0.5,
     [np.sqrt(0.5), np.sqrt(0.5), 0]),
    (C.collider_row(C.CYLINDER, 0, 0, 0, 0, 0, 2, 0.5), [0.1, 0, 1.97], -0.03, [0, 0, 1]),
    (C.collider_row(C.CYLINDER, 0, 0, 0, 0, 0, 2, 0.5), [0.1, 0, -0.02], 0.02, [0, 0, -1]),
    (C.collider_row(C.CYLINDER, 0, 0, 0, 0, 0, 2, 0.5), [0.53, 0, 2.04], 0.05, [0.6, 0, 0.8]),
])
def test_collider_pushes_out_along_its_normal(row, p, sd, n):
    got = C.collider_distance(row[None], 0, *map(float, p))
    assert got[0] == pytest.approx(sd, abs=1e-12)
    assert np.allclose(got[1:], n, atol=1e-12)
    x, f = np.array([p], dtype=np.float64), np.zeros(1)
    n_active, phi = C.project_colliders(x, np.ones(1), np.array([0.1]), row[None], 1e3, DT, f)
    assert n_active == 1 and phi == pytest.approx(0.1 - sd)
    dx = x[0] - p
    assert np.allclose(dx / np.linalg.norm(dx), n, atol=1e-12) and f[0] > 0.0
    x = np.array([p], dtype=np.float64)
    C.project_colliders(x, np.zeros(1), np.array([0.1]), row[None], 1e3, DT, f)
    assert np.array_equal(x[0], p)


def test_collider_table_is_checked():
    with pytest.raises(ValueError):
        C.collider_row(C.SPHERE, 0, 0, 0)
    with pytest.raises(ValueError):
        C.project_colliders(np.zeros((1, 3)), np.ones(1), np.ones(1), np.zeros((1, 8)), 1.0, DT, np.zeros(1))
    bad = [_colliders() for _ in range(3)]
    bad[0][0, 0] = 7  # unknown kind
    bad[1][0, 4:7] = [0, 0, 2]  # plane normal not unit
    bad[2][3, 4:7] = bad[2][3, 1:4]  # cylinder of length 0
    for table in bad:
        with pytest.raises(ValueError):
            C.project_colliders(np.zeros((1, 3)), np.ones(1), np.ones(1), table, 1.0, DT, np.zeros(1))


def test_particle_resting_on_ground_settles_at_eq4_penetration():
    """Explicit gravity, XPBD collider projection, velocity from positions: at rest the secant
    step carries k_col phi^2 = m g, phi = sqrt(m g / k_col)."""
    m, k_col, r = np.array([1.0, 0.2]), 1000.0, 0.3
    ground = C.collider_row(C.PLANE, 0, 0, 0, 0, 0, 1)[None]
    x = np.array([[0, 0, r], [1, 0, r]], dtype=np.float64)
    v = np.zeros_like(x)
    for _ in range(3000):
        v[:, 2] -= G * DT
        x_old = x.copy()
        x += v * DT
        f = np.zeros(2)
        C.project_colliders(x, 1 / m, np.full(2, r), ground, k_col, DT, f)
        v = (x - x_old) / DT
    assert r - x[:, 2] == pytest.approx(np.sqrt(m * G / k_col), rel=0.02)
    assert f == pytest.approx(m * G, rel=0.02)
    assert np.abs(v).max() < 1e-6


def test_colliders_with_cap_match_reference():
    rng = np.random.default_rng(7)
    x = rng.random((4000, 3))
    w = rng.uniform(0.5, 2.0, len(x))
    w[::9] = 0.0
    prad = rng.uniform(0.0, 0.03, len(x))
    x_prev, x = _moved(x, 7)
    out = []
    for proj, vel in ((C.project_colliders, C.collider_velocities),
                      (C.project_colliders_reference, C.collider_velocities_reference)):
        xk, f, hit = x.copy(), np.zeros(len(x)), np.zeros((len(x), 4), dtype=bool)
        proj(xk, w, prad, _colliders(), 1e6, DT, f, 1e-3, x_prev, hit)
        v = (xk - x_prev) / DT
        changed = vel(v, xk, w, _colliders(), hit)
        out.append((xk, f, hit, v, changed))
    (x1, f1, h1, v1, c1), (x2, f2, h2, v2, c2) = out
    assert h1.sum() > 300 and np.array_equal(h1, h2) and c1 == c2 > 0
    assert np.allclose(x1, x2, rtol=0, atol=1e-12) and np.allclose(f1, f2, rtol=1e-10, atol=1e-9)
    assert np.allclose(v1, v2, rtol=0, atol=1e-9)
