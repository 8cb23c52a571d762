"""Friction after the normal steps (woodstock §5.4, Eqs. 5-7): against its numpy reference, a
sliding particle's deceleration, static and kinetic friction on inclines."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.sim import contact as C

from .helpers import G, _rows


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
