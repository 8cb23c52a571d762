"""Contact (woodstock §5.4, Eqs. 3-7): numba kernels against their numpy references, analytic
equilibria, collider normals, pinned particles and thread-count invariance."""
from __future__ import annotations

import numba
import numpy as np
import pytest

from wooddecay.sim import contact as C

G = 9.81
DT = 0.01


def _brute_distance(p1, q1, p2, q2, n=801):
    s = np.linspace(0, 1, n)
    a = p1 + (q1 - p1) * s[:, None]
    b = p2 + (q2 - p2) * s[:, None]
    return np.min(np.linalg.norm(a[:, None] - b[None], axis=-1))


def _segment_soup(seed, n_seg=600, n_comp=6):
    """Random segments in a unit box with parallel, collinear and degenerate ones mixed in:
    (x, first_particle, radius, component). Every segment owns its two particles."""
    rng = np.random.default_rng(seed)
    p = rng.random((n_seg, 3))
    d = rng.normal(size=(n_seg, 3)) * 0.04
    d[: n_seg // 4] = [0.05, 0.0, 0.0]  # parallel
    d[n_seg // 4: n_seg // 3, 1:] = 0.0  # parallel to x, different lengths
    d[n_seg // 3: n_seg // 3 + 20] = 0.0  # points
    p[:40, 1:] = 0.5  # collinear along x
    x = np.stack([p, p + d], axis=1).reshape(-1, 3)
    fp = np.arange(0, 2 * n_seg, 2, dtype=np.int64)
    return x, fp, rng.uniform(0.005, 0.03, n_seg), rng.integers(0, n_comp, n_seg).astype(np.int64)


def _chains(seed, n_strands=40, n_seg=15):
    """Strands (chains sharing particles) of random components crossing a small box."""
    rng = np.random.default_rng(seed)
    xs = []
    for _ in range(n_strands):
        start, step = rng.random(3) * 0.3, rng.normal(size=3)
        xs.append(start + np.outer(np.arange(n_seg + 1), 0.02 * step / np.linalg.norm(step)))
    x = np.concatenate(xs)
    fp = (np.arange(n_strands)[:, None] * (n_seg + 1) + np.arange(n_seg)).ravel().astype(np.int64)
    comp = np.repeat(rng.integers(0, 4, n_strands), n_seg).astype(np.int64)
    comp[5:9] = 7  # a strand split into components: neighbours sharing a particle are no pair
    return x, fp, np.full(len(fp), 0.012), comp


def _rows(*pts):
    return np.array(pts, dtype=np.float64)


# ----------------------------------------------------------------------------- closest points


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


# ----------------------------------------------------------------------------- broad phase


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("margin", [0.0, 0.01])
def test_candidate_pairs_match_reference(seed, margin):
    x, fp, r, comp = _segment_soup(seed)
    got = C.candidate_pairs(x, fp, r, comp, margin)
    ref = C.candidate_pairs_reference(x, fp, r, comp, margin)
    assert len(ref) > 100
    assert got.dtype == np.int64 and got.shape[1] == 2
    assert np.array_equal(got, ref)
    # brute force on every pair
    i, j = np.triu_indices(len(fp), 1)
    keep = comp[i] != comp[j]
    i, j = i[keep], j[keep]
    s, t = C.closest_segment_segment_reference(x[fp[i]], x[fp[i] + 1], x[fp[j]], x[fp[j] + 1])
    d = x[fp[j]] + t[:, None] * (x[fp[j] + 1] - x[fp[j]]) - x[fp[i]] - s[:, None] * (x[fp[i] + 1] - x[fp[i]])
    lim = r[i] + r[j] + margin
    hit = np.einsum("ij,ij->i", d, d) < lim * lim
    assert np.array_equal(got, np.stack([i[hit], j[hit]], axis=1))


def test_candidate_pairs_chains_skip_shared_particles():
    x, fp, r, comp = _chains(3)
    got = C.candidate_pairs(x, fp, r, comp, 0.005)
    assert np.array_equal(got, C.candidate_pairs_reference(x, fp, r, comp, 0.005))
    assert len(got) > 0
    assert np.all(np.abs(fp[got[:, 0]] - fp[got[:, 1]]) > 1)
    assert np.all(comp[got[:, 0]] != comp[got[:, 1]])
    assert np.all(got[:, 0] < got[:, 1])
    assert np.array_equal(got, got[np.lexsort((got[:, 1], got[:, 0]))])


def test_candidate_pairs_crowded():
    """Long segments in a small box: crowded buckets and rows, most elements with more than KEPT
    partners (the fill pass searches again)."""
    rng = np.random.default_rng(7)
    p = rng.random((1500, 3)) * 0.05
    x = np.stack([p, p + rng.normal(size=(1500, 3)) * 0.1], axis=1).reshape(-1, 3)
    fp, r, comp = np.arange(0, 3000, 2), np.full(1500, 0.001), rng.integers(0, 3, 1500)
    got = C.candidate_pairs(x, fp, r, comp, 0.0)
    assert np.bincount(got[:, 0], minlength=1500).max() > 4 * C.KEPT
    assert np.array_equal(got, C.candidate_pairs_reference(x, fp, r, comp, 0.0))


def test_candidate_pairs_trivial_inputs():
    x, fp, r, comp = _segment_soup(0, n_seg=50)
    assert C.candidate_pairs(x, fp, r, np.zeros(50, dtype=np.int64), 0.1).shape == (0, 2)
    assert C.candidate_pairs(x, fp[:1], r[:1], comp[:1], 0.1).shape == (0, 2)
    X = np.zeros((4, 3))
    assert C.candidate_pairs(X, np.array([0, 2]), np.zeros(2), np.array([0, 1]), 0.0).shape == (0, 2)


# ----------------------------------------------------------------------------- capsule contacts


def _contact_setup(seed):
    x, fp, r, comp = _segment_soup(seed, n_seg=500)
    r = r * 2.0
    pairs = C.candidate_pairs(x, fp, r, comp, 0.0)
    w = np.random.default_rng(seed).uniform(0.5, 2.0, len(x))
    w[::7] = 0.0
    return x, w, fp, r, pairs


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


# ----------------------------------------------------------------------------- colliders


def _colliders():
    return np.stack([
        C.collider_row(C.PLANE, 0, 0, 0.1, 0.2, 0.1, 1.0),
        C.collider_row(C.BOX, 0.2, 0.2, 0.2, 0.5, 0.4, 0.6),
        C.collider_row(C.SPHERE, 0.7, 0.7, 0.5, 0.15),
        C.collider_row(C.CYLINDER, 0.3, 0.8, 0.2, 0.6, 0.8, 0.7, 0.1),
    ])


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


# ----------------------------------------------------------------------------- friction


def _slide(normal, v0, steps, mu=0.5, k_col=1e6, m=0.01, r=0.005, dt=1e-3):
    """A particle on the plane through the origin with unit ``normal``, run through the
    substep of :func:`wooddecay.sim.mechanics.substep`: gravity, prediction, collider projection
    with the depenetration cap, then friction against its push from the start-of-substep
    positions (:func:`contact.particle_friction`), velocities, restitution 0. Starts at rest
    penetration with velocity ``v0``; returns the velocity history."""
    n = np.asarray(normal, dtype=np.float64)
    ground = C.collider_row(C.PLANE, 0, 0, 0, *n)[None]
    x = (r - np.sqrt(m * G * n[2] / k_col)) * n[None, :]
    v = np.array([v0], dtype=np.float64)
    w, rad = np.array([1 / m]), np.array([r])
    out = []
    for _ in range(steps):
        v[:, 2] -= G * dt
        x_old = x.copy()
        x += v * dt
        hit = np.zeros((1, 1), dtype=bool)
        x_start = x.copy()
        C.project_colliders(x, w, rad, ground, k_col, dt, np.zeros(1), 0.1 * dt, x_old, hit)
        C.particle_friction(x, x_start, x_old, mu, 1e-6 * dt)
        v = (x - x_old) / dt
        C.collider_velocities(v, x, w, ground, hit)
        out.append(v[0].copy())
    return np.array(out)


def test_friction_decelerates_a_sliding_particle_by_mu_g_dt_and_stops_it():
    """Once the contact has settled into its discrete equilibrium penetration (the first ~50
    steps start 3% above it) the speed drops by mu g dt per step."""
    mu, dt = 0.5, 1e-3
    v = _slide([0, 0, 1], [0.3, 0.4, 0], 150, mu=mu, dt=dt)
    speed = np.linalg.norm(v[:, :2], axis=1)
    decel = -np.diff(speed[50:95]) / dt
    assert decel == pytest.approx(np.full(len(decel), mu * G), rel=2e-3)  # Eq. 7: mu |F_n| / m
    assert np.allclose(np.cross(v[:95, :2], [0.3, 0.4]), 0.0, atol=1e-12)  # no turning
    assert np.abs(v[-1]).max() < 1e-9  # stops after 0.5 / (mu g) = 0.1 s and never reverses


@pytest.mark.parametrize("angle", [20.0, 35.0])
def test_friction_on_an_incline_is_static_inside_the_cone_and_kinetic_outside(angle):
    """mu = 0.5 (cone 26.6 deg): at 20 deg the particle stays; at 35 deg it slides down with
    g (sin - mu cos)."""
    mu, dt, steps = 0.5, 1e-3, 300
    a = np.radians(angle)
    v = _slide([np.sin(a), 0, np.cos(a)], [0, 0, 0], steps, mu=mu, dt=dt)
    if np.tan(a) < mu:
        assert np.abs(v[-100:]).max() < 1e-9
    else:
        down = np.array([np.cos(a), 0, -np.sin(a)])
        accel = (v[-1] - v[-101]) @ down / (100 * dt)
        assert accel == pytest.approx(G * (np.sin(a) - mu * np.cos(a)), rel=1e-3)


def _moved(x, seed):
    """x displaced as by a substep: the start-of-substep positions and the predicted ones."""
    x_prev = x.copy()
    return x_prev, x + np.random.default_rng(seed).normal(0.0, 2e-3, x.shape)


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


# ----------------------------------------------------------------------------- determinism


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


# ----------------------------------------------------------------------------- friction after the normal steps


def test_particle_friction_matches_reference():
    rng = np.random.default_rng(11)
    x_prev = rng.random((3000, 3))
    x_start = x_prev + rng.normal(0.0, 1e-3, x_prev.shape)
    x = x_start + rng.normal(0.0, 1e-4, x_prev.shape) * (rng.random((3000, 1)) < 0.6)  # 40% not pushed
    out = []
    for fn in (C.particle_friction, C.particle_friction_reference):
        xk = x.copy()
        fn(xk, x_start, x_prev, 0.7, 1e-7)
        out.append(xk)
    assert np.allclose(out[0], out[1], rtol=0, atol=1e-15)
    pushed = np.any(x != x_start, axis=1)
    assert np.array_equal(out[0][~pushed], x[~pushed])  # friction needs a normal push
    assert np.abs(out[0][pushed] - x[pushed]).max() > 1e-5
    # the displacement along the push is kept, the tangential part shrinks
    n = (x - x_start)[pushed]
    n /= np.linalg.norm(n, axis=1)[:, None]
    d0, d1 = (x - x_prev)[pushed], (out[0] - x_prev)[pushed]
    assert np.allclose(np.sum(d0 * n, axis=1), np.sum(d1 * n, axis=1), atol=1e-15)
    t0 = np.linalg.norm(d0 - np.sum(d0 * n, axis=1)[:, None] * n, axis=1)
    t1 = np.linalg.norm(d1 - np.sum(d1 * n, axis=1)[:, None] * n, axis=1)
    assert np.all(t1 <= t0 + 1e-15)


def test_capsule_across_two_pinned_ones_holds_on_a_slope_inside_the_cone():
    """A free capsule lying across two pinned ones, each of its particles in both pair contacts
    (mu 0.5, cone 26.6 degrees). It settles under the normal part g cos(a) of gravity, then the
    tangential part g sin(a) along the pinned axes is added: friction after the normal steps
    holds it at 20 degrees (friction inside each pair, measured before the other pair's push,
    let such a piece creep) and lets it slide with g (sin - mu cos) at 35 degrees."""
    m, k_col, r, dt, mu = 0.01, 1e6, 0.01, 1e-4, 0.5
    for angle in (20.0, 35.0):
        a = np.radians(angle)
        # start at the resting depth: each particle averages its two pairs' corrections (module
        # docstring), so each pair holds 2 m g cos(a) there
        z = 2 * r - np.sqrt(2 * m * G * np.cos(a) / k_col)
        x = _rows([-0.3, -1, 0], [-0.3, 1, 0], [0.3, -1, 0], [0.3, 1, 0], [-0.5, 0, z], [0.5, 0, z])
        fp, radius = np.array([0, 2, 4]), np.full(3, r)
        pairs = np.array([[0, 2], [1, 2]])
        w = np.array([0, 0, 0, 0, 1 / m, 1 / m], dtype=np.float64)
        v = np.zeros_like(x)
        vy = []
        for step in range(4000):
            g = G * np.array([0.0, np.sin(a) if step >= 2000 else 0.0, -np.cos(a)])
            v[4:] += g * dt
            x_old = x.copy()
            x += v * dt
            hit, x_start = np.zeros(2, dtype=bool), x.copy()
            C.project_contacts(x, w, fp, radius, pairs, k_col, dt, np.zeros(6), 0.1 * dt, hit,
                               protect=np.zeros(2))
            C.particle_friction(x, x_start, x_old, mu, 1e-6 * dt)
            v = (x - x_old) / dt
            C.contact_velocities(v, x, w, fp, radius, pairs, hit)
            vy.append(v[4:, 1].mean())
        if np.tan(a) < mu:
            assert np.abs(vy[2000:]).max() < 1e-9
        else:
            accel = (vy[-1] - vy[-1001]) / (1000 * dt)
            assert accel == pytest.approx(G * (np.sin(a) - mu * np.cos(a)), rel=0.01)


# ----------------------------------------------------------------------------- separation overlap


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
    setup = SimpleNamespace(fp=np.array([0, 2, 4]), radius=np.full(3, 0.01), n_elements=3)
    ms = SimpleNamespace(x=x, component=np.array([0, 1, 1]), sep_keys=np.zeros(0, np.int64), sep_overlap=np.zeros(0))
    assert failure.record_separations(setup, ms, np.zeros(3, np.int64)) == 1  # (0, 1) only: (1, 2) stay together
    assert ms.sep_keys.tolist() == [0 * 3 + 1] and ms.sep_overlap == pytest.approx([0.005])
    ms.x = x + [0, 0.001, 0] * np.array([[0], [0], [1], [1], [1], [1]])  # now 0.004
    ms.component = np.array([0, 1, 2])
    assert failure.record_separations(setup, ms, np.array([0, 1, 1])) == 1  # (1, 2); (0, 1) is kept as first seen
    assert ms.sep_keys.tolist() == [1, 5] and ms.sep_overlap == pytest.approx([0.005, 0.005])
