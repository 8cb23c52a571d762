"""Capsule contact (woodstock §5.4, Eqs. 3-4): the Jacobi XPBD projection against its numpy
reference, analytic equilibria, pinned particles, the depenetration cap, protected and separation
overlaps, restitution 0 and thread-count invariance."""
from __future__ import annotations

import numba
import numpy as np
import pytest

from wooddecay.sim import contact as C

from .helpers import DT, G, _colliders, _contact_setup, _moved, _rows


@pytest.mark.parametrize("seed", [0, 1])
def test_project_contacts_matches_reference(seed):
    x, w, fp, r, pairs = _contact_setup(seed)
    assert len(pairs) > 200
    x1, x2 = x.copy(), x.copy()
    f1, f2 = np.full(len(x), 0.5), np.full(len(x), 0.5)
    res1 = C.project_contacts(x1, w, fp, r, pairs, 50.0, DT, f1)
    res2 = C.project_contacts_reference(x2, w, fp, r, pairs, 50.0, DT, f2)
    assert res1[0] == res2[0] > 0 and res1[1] == pytest.approx(res2[1], abs=1e-15)
    assert np.allclose(x1, x2, rtol=0, atol=1e-12)
    assert np.allclose(f1, f2, rtol=1e-12, atol=1e-12)
    assert not np.array_equal(x1, x)
    assert np.array_equal(x1[w == 0.0], x[w == 0.0])  # pinned particles never move


def test_project_contacts_without_stiffness_or_pairs_does_nothing():
    x, w, fp, r, pairs = _contact_setup(0)
    x1, f = x.copy(), np.zeros(len(x))
    assert C.project_contacts(x1, w, fp, r, pairs, 0.0, DT, f) == (0, 0.0)
    assert C.project_contacts(x1, w, fp, r, pairs[:0], 10.0, DT, f) == (0, 0.0)
    assert np.array_equal(x1, x) and not f.any()


def test_two_capsules_pushed_apart_along_normal_with_momentum_conserved():
    # crossing capsules of radius 0.05, axes 0.06 apart along z: phi = 0.04
    x = _rows([-0.5, 0.1, 0], [0.3, 0.1, 0], [0, -0.2, 0.06], [0, 0.6, 0.06])
    fp, r = np.array([0, 2]), np.array([0.05, 0.05])
    w, f = np.ones(4), np.zeros(4)
    x0 = x.copy()
    n_active, phi = C.project_contacts(x, w, fp, r, np.array([[0, 1]]), 1e4, DT, f)
    assert n_active == 1 and phi == pytest.approx(0.04)
    dx = x - x0
    assert np.allclose(dx.sum(axis=0), 0.0, atol=1e-15)  # equal masses: momentum conserved
    assert np.allclose(dx[:, :2], 0.0, atol=1e-15)  # along the normal (0, 0, 1) only
    assert np.all(dx[:2, 2] < 0) and np.all(dx[2:, 2] > 0)
    s, t = 0.5 / 0.8, 0.3 / 0.8  # closest points: x = 0 on i, y = 0.1 on j
    g = np.array([1 - s, s, 1 - t, t])
    assert np.allclose(dx[:, 2] / dx[3, 2], g * [-1, -1, 1, 1] / t)
    W = (1 - s) ** 2 + s ** 2 + (1 - t) ** 2 + t ** 2
    dl = 1e4 * 0.04 ** 2 * DT ** 2 / (1 + W * 1e4 * 0.04 * DT ** 2)
    assert np.allclose(f, g * dl / DT ** 2, rtol=1e-12)
    # pinned first capsule: it stays, the other one takes the whole correction
    x = x0.copy()
    w = np.array([0.0, 0.0, 1.0, 1.0])
    C.project_contacts(x, w, fp, r, np.array([[0, 1]]), 1e4, DT, np.zeros(4))
    assert np.array_equal(x[:2], x0[:2]) and np.all(x[2:, 2] > x0[2:, 2])


def test_capsule_resting_on_pinned_capsule_settles_at_eq4_penetration():
    """A free horizontal capsule (two particles of mass m) crossing a pinned one at its middle:
    at rest k_col phi^2 = 2 m g (Eq. 4), each particle receives m g."""
    m, k_col, r = 0.5, 2000.0, 0.1
    x = _rows([-1, 0, 0], [1, 0, 0], [0, -1, 2 * r], [0, 1, 2 * r])
    fp, radius = np.array([0, 2]), np.array([r, r])
    w = np.array([0.0, 0.0, 1 / m, 1 / m])
    v = np.zeros_like(x)
    pairs = np.array([[0, 1]])
    for _ in range(3000):
        v[2:, 2] -= G * DT
        x_old = x.copy()
        x += v * DT
        f = np.zeros(4)
        C.project_contacts(x, w, fp, radius, pairs, k_col, DT, f)
        v = (x - x_old) / DT
    phi = 2 * r - (x[2, 2] - x[0, 2])
    assert phi == pytest.approx(np.sqrt(2 * m * G / k_col), rel=0.02)
    assert f[2:] == pytest.approx([m * G, m * G], rel=0.02)
    assert np.abs(v).max() < 1e-6


@pytest.mark.parametrize("seed", [0, 1])
def test_contacts_with_cap_match_reference(seed):
    x, w, fp, r, pairs = _contact_setup(seed)
    x_prev, x = _moved(x, seed)
    out = []
    for fn in (C.project_contacts, C.project_contacts_reference):
        xk, f, hit = x.copy(), np.zeros(len(x)), np.zeros(len(pairs), dtype=bool)
        fn(xk, w, fp, r, pairs, 1e6, DT, f, 1e-3, hit)
        v = (xk - x_prev) / DT
        (C.contact_velocities if fn is C.project_contacts else C.contact_velocities_reference)(
            v, xk, w, fp, r, pairs, hit)
        out.append((xk, f, hit, v))
    (x1, f1, h1, v1), (x2, f2, h2, v2) = out
    assert h1.sum() > 100 and np.array_equal(h1, h2)
    assert np.allclose(x1, x2, rtol=0, atol=1e-12) and np.allclose(f1, f2, rtol=1e-10, atol=1e-9)
    assert np.allclose(v1, v2, rtol=0, atol=1e-9)


def test_restitution_zero_keeps_approach_and_removes_separation():
    # two capsules crossing along z (normal +z from i to j): j moving up separates, down approaches
    x = _rows([-0.5, 0.1, 0], [0.3, 0.1, 0], [0, -0.2, 0.09], [0, 0.6, 0.09])
    fp, r, w = np.array([0, 2]), np.array([0.05, 0.05]), np.ones(4)
    pairs, hit = np.array([[0, 1]]), np.array([True])
    for vz, moved in ((1.0, 1), (-1.0, 0)):
        v = np.zeros((4, 3))
        v[2:, 2] = vz
        assert C.contact_velocities(v, x, w, fp, r, pairs, hit) == moved
        s, t = 0.625, 0.375
        vn = (1 - t) * v[2, 2] + t * v[3, 2] - (1 - s) * v[0, 2] - s * v[1, 2]
        assert vn == pytest.approx(0.0 if moved else vz, abs=1e-12)
        assert np.sum(v[:, 2]) == pytest.approx(2 * vz)  # equal masses: momentum kept


@pytest.mark.parametrize("seed", [0, 1])
def test_depenetration_cap_matches_reference(seed):
    x, w, fp, r, pairs = _contact_setup(seed)
    push = 1e-4
    x1, x2 = x.copy(), x.copy()
    f1, f2 = np.zeros(len(x)), np.zeros(len(x))
    C.project_contacts(x1, w, fp, r, pairs, 1e8, DT, f1, push)
    C.project_contacts_reference(x2, w, fp, r, pairs, 1e8, DT, f2, push)
    assert np.allclose(x1, x2, rtol=0, atol=1e-13) and np.allclose(f1, f2, rtol=1e-12)
    x3 = x.copy()
    C.project_contacts(x3, w, fp, r, pairs, 1e8, DT, np.zeros(len(x)))
    assert np.abs(x3 - x).max() > 10 * np.abs(x1 - x).max()  # uncapped, the overlaps push further


def test_depenetration_cap_bounds_the_relative_push():
    # the crossing capsules above (phi = 0.04) under a stiff contact part by exactly max_push
    x = _rows([-0.5, 0.1, 0], [0.3, 0.1, 0], [0, -0.2, 0.06], [0, 0.6, 0.06])
    fp, r = np.array([0, 2]), np.array([0.05, 0.05])
    w, f = np.ones(4), np.zeros(4)
    s, t = 0.625, 0.375  # closest points of the two axes

    def gap():
        return (1 - t) * x[2, 2] + t * x[3, 2] - (1 - s) * x[0, 2] - s * x[1, 2]
    gap0 = gap()
    C.project_contacts(x, w, fp, r, np.array([[0, 1]]), 1e8, DT, f, 1e-3)
    assert gap() - gap0 == pytest.approx(1e-3, rel=1e-9)


@pytest.mark.parametrize("seed", [0, 1])
def test_contacts_with_protected_overlap_match_reference(seed):
    x, w, fp, r, pairs = _contact_setup(seed)
    x = _moved(x, seed)[1]
    prot = np.random.default_rng(seed).uniform(0.0, 0.02, len(pairs)) * (np.arange(len(pairs)) % 3 == 0)
    out = []
    for fn in (C.project_contacts, C.project_contacts_reference):
        xk, f, pk = x.copy(), np.zeros(len(x)), prot.copy()
        fn(xk, w, fp, r, pairs, 1e8, DT, f, 1e-3, protect=pk)
        out.append((xk, f, pk))
    (x1, f1, p1), (x2, f2, p2) = out
    assert np.allclose(x1, x2, rtol=0, atol=1e-12) and np.allclose(f1, f2, rtol=1e-10, atol=1e-9)
    assert np.array_equal(p1, p2) and np.all(p1 <= prot) and np.any(p1 < prot)


def test_protected_overlap_parts_at_max_push_and_new_penetration_is_resolved():
    # the crossing capsules of the cap test (phi = 0.04) under a stiff contact
    x0 = _rows([-0.5, 0.1, 0], [0.3, 0.1, 0], [0, -0.2, 0.06], [0, 0.6, 0.06])
    fp, r, w = np.array([0, 2]), np.array([0.05, 0.05]), np.ones(4)
    s, t = 0.625, 0.375

    def gap(x):
        return (1 - t) * x[2, 2] + t * x[3, 2] - (1 - s) * x[0, 2] - s * x[1, 2]
    # all of it protected: it parts by max_push, and the protection shrinks by as much
    x, prot = x0.copy(), np.array([0.04])
    C.project_contacts(x, w, fp, r, np.array([[0, 1]]), 1e8, DT, np.zeros(4), 1e-3, protect=prot)
    assert gap(x) - gap(x0) == pytest.approx(1e-3, rel=1e-9)
    assert prot[0] == pytest.approx(0.039, rel=1e-12)
    # half of it protected: the other half is resolved at once whatever max_push
    x, prot = x0.copy(), np.array([0.02])
    C.project_contacts(x, w, fp, r, np.array([[0, 1]]), 1e8, DT, np.zeros(4), 1e-3, protect=prot)
    assert gap(x) - gap(x0) == pytest.approx(0.021, rel=1e-9)
    # no protection: the plain XPBD step (as without a cap)
    x, x_free = x0.copy(), x0.copy()
    C.project_contacts(x, w, fp, r, np.array([[0, 1]]), 1e8, DT, np.zeros(4), 1e-3,
                       protect=np.zeros(1))
    C.project_contacts(x_free, w, fp, r, np.array([[0, 1]]), 1e8, DT, np.zeros(4))
    assert np.array_equal(x, x_free)


def test_record_separations_keeps_the_first_overlap_of_newly_separated_pairs():
    from types import SimpleNamespace

    from wooddecay.sim import failure
    # three parallel capsules of radius 0.01, 0.015 apart along y: (0, 1) and (1, 2) overlap
    # by 0.005, (0, 2) are apart
    x = _rows([0, 0, 0], [1, 0, 0], [0, 0.015, 0], [1, 0.015, 0], [0, 0.03, 0], [1, 0.03, 0])
    setup = SimpleNamespace(fp=np.array([0, 2, 4]), n_elements=3)
    ms = SimpleNamespace(x=x, component=np.array([0, 1, 1]), sep_keys=np.zeros(0, np.int64), sep_overlap=np.zeros(0),
                         element_ok=np.array([True, False, True]), radius=np.full(3, 0.01))
    assert failure.record_separations(setup, ms, np.zeros(3, np.int64)) == 0  # a failed element is no contact
    ms.element_ok[:] = True
    assert failure.record_separations(setup, ms, np.zeros(3, np.int64)) == 1  # (0, 1) only: (1, 2) stay together
    assert ms.sep_keys.tolist() == [0 * 3 + 1] and ms.sep_overlap == pytest.approx([0.005])
    ms.x = x + [0, 0.001, 0] * np.array([[0], [0], [1], [1], [1], [1]])  # now 0.004
    ms.component = np.array([0, 1, 2])
    assert failure.record_separations(setup, ms, np.array([0, 1, 1])) == 1  # (1, 2); (0, 1) is kept as first seen
    assert ms.sep_keys.tolist() == [1, 5] and ms.sep_overlap == pytest.approx([0.005, 0.005])


def test_bit_identical_for_one_and_two_threads():
    x, w, fp, r, _ = _contact_setup(6)
    comp = np.random.default_rng(6).integers(0, 6, len(fp)).astype(np.int64)
    prad = np.full(len(x), 0.02)
    runs = []
    try:
        for k in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(k)
            pairs = C.candidate_pairs(x, fp, r, comp, 0.01)
            xk, f = x.copy(), np.zeros(len(x))
            C.project_contacts(xk, w, fp, r, pairs, 40.0, DT, f)
            C.project_colliders(xk, w, prad, _colliders(), 40.0, DT, f)
            xk2, f2, hit = x.copy(), np.zeros(len(x)), np.zeros(len(pairs), dtype=bool)
            x_prev = xk2 + 1e-3
            C.project_contacts(xk2, w, fp, r, pairs, 1e6, DT, f2, 1e-3, hit)
            C.particle_friction(xk2, xk, x_prev, 0.7, 1e-6 * DT)
            v = (xk2 - x_prev) / DT
            C.contact_velocities(v, xk2, w, fp, r, pairs, hit)
            runs.append((pairs, xk, f, xk2, f2, v))
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    for a, b in zip(runs[0], runs[1]):
        assert np.array_equal(a, b)
