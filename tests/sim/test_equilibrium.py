"""The equilibrium residual: its forces are the gradient of its potential, it reads 1 for wood
that carries its weight undeformed and falls as XPBD converges."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from wooddecay.quaternion import mul_np, normalize_np, rotate_np
from wooddecay.sim import equilibrium, mechanics
from wooddecay.sim.state import initial_state

from ..conftest import sample
from .helpers import CONNECTIONS, perturbed, with_connection


def _energy(setup, ms):
    return equilibrium.forces(setup, ms)[0].energy


@pytest.fixture(scope="module", params=sorted(CONNECTIONS))
def jostled(request):
    setup, ms = perturbed("tiny", seed=1)
    setup = with_connection(setup, *CONNECTIONS[request.param])
    ms.rest_length = ms.rest_length * 0.99  # drying: every stretch loaded
    ms.rest_offset = ms.rest_offset * 0.98
    ms.mass_p[:] = 0.3
    ms.x[:, 2] -= 0.004  # into the ground: colliders load
    return setup, ms


def _slope(setup, ms, move, h=1e-7):
    """-dE/ds at s = 0 by central differences, ``move(copy, s)`` moving a copy of ``ms`` by s."""
    E = []
    for s in (h, -h):
        moved = ms.copy()
        move(moved, s)
        E.append(_energy(setup, moved))
    return -(E[0] - E[1]) / (2 * h)


def _shift(p, c):
    def move(ms, s):
        ms.x[p, c] += s
    return move


def _turn(e, c):
    def move(ms, s):
        dq = np.zeros(4)
        dq[0], dq[1 + c] = 1.0, 0.5 * s
        ms.q[e] = normalize_np(mul_np(dq[None], ms.q[e][None]))[0]
    return move


def test_forces_are_minus_the_gradient_of_the_potential(jostled):
    setup, ms = jostled
    F = equilibrium.forces(setup, ms)[0]
    rng = np.random.default_rng(0)
    for p in rng.choice(np.flatnonzero(~setup.anchored_p), 6, replace=False):
        for c in range(3):
            assert _slope(setup, ms, _shift(p, c)) == pytest.approx(F.f[p, c], rel=1e-4, abs=1e-6 * np.abs(F.f).max())


def test_torques_are_minus_the_gradient_under_world_rotations(jostled):
    setup, ms = jostled
    F = equilibrium.forces(setup, ms)[0]
    rng = np.random.default_rng(1)
    for e in rng.choice(np.flatnonzero(~setup.anchored_e), 6, replace=False):
        for c in range(3):
            assert _slope(setup, ms, _turn(e, c)) == pytest.approx(F.tau[e, c], rel=1e-4,
                                                                    abs=1e-6 * np.abs(F.tau).max())


def test_forces_balance_with_no_external_load(jostled):
    """Internal forces sum to zero, and so do the torques of the forces about the origin."""
    setup, ms = jostled
    free = ms.copy()
    free.mass_p[:] = 0.0
    free.x[:, 2] += 1.0  # off the ground
    F = equilibrium.forces(setup, free)[0]
    assert np.abs(F.f.sum(axis=0)).max() < 1e-9 * np.abs(F.f).max()
    # a particle force acts at its particle; element torques are couples
    moment = np.cross(free.x, F.f).sum(axis=0) + F.tau.sum(axis=0)
    assert np.abs(moment).max() < 1e-8 * (np.abs(np.cross(free.x, F.f)).max() + np.abs(F.tau).max())


def _clamped_tiny():
    """The tiny log at rest, lifted clear of the ground and clamped at its root end."""
    model = sample("tiny")[1]
    ms = initial_state(model, rods=True).mech
    setup = model.mech
    centre = 0.5 * (ms.x[setup.fp, 0] + ms.x[setup.fp + 1, 0])
    clamp = centre < 0.02
    pins = np.zeros(setup.n_particles, dtype=bool)
    pins[setup.fp[clamp]] = pins[setup.fp[clamp] + 1] = True
    ms.x[:, 2] += 1.0
    return replace(setup, anchored_e=clamp, anchored_p=pins), ms


def test_undeformed_wood_under_its_weight_reads_one():
    setup, ms = _clamped_tiny()
    ms.mass_p[:] = 0.1
    assert equilibrium.equilibrium_residual(setup, ms) == pytest.approx(1.0, rel=1e-9)


def test_a_piece_in_flight_is_not_judged():
    model = sample("tiny")[1]
    ms = initial_state(model, rods=True).mech
    ms.mass_p[:] = 0.1
    ms.x[:, 2] += 1.0
    assert equilibrium.equilibrium_residual(model.mech, ms) == 0.0


def test_a_shrinking_body_is_judged_even_without_weight():
    setup, ms = _clamped_tiny()
    ms.mass_p[:] = 0.0
    ms.rest_length = ms.rest_length * 0.99
    ends = equilibrium.equilibrium_residual(setup, ms)
    ms.rest_length = ms.rest_length * np.linspace(0.98, 1.0, len(ms.rest_length))
    graded = equilibrium.equilibrium_residual(setup, ms)
    # forces cancel inside a strand that shrinks evenly: only its ends and the REG are out of
    # balance (docs/limits.md, "The equilibrium residual"), a graded shrink is out of balance
    # throughout
    assert 0.01 < ends < graded <= 1.0


def test_residual_falls_as_xpbd_sweeps_converge():
    """Settling the tiny log (anchored, loaded by its weight and a drying shrink) with more sweeps
    a substep leaves it nearer equilibrium."""
    model = sample("tiny")[1]
    out = []
    for iterations in (1, 16):
        ms = initial_state(model, rods=True).mech
        setup = replace(model.mech, iterations=iterations)
        mechanics.set_masses(setup, ms, np.full(setup.n_elements, 0.5))
        ms.rest_length = ms.rest_length * 0.995
        for _ in range(400):
            mechanics._substep(setup, ms, setup.dt, check=False)
        out.append(equilibrium.equilibrium_residual(setup, ms))
    assert out[1] < 0.5 * out[0]


def _connection_energy(setup, ms, k):
    """The energy of REG edge ``k``'s connection alone."""
    only = np.zeros(len(setup.edges))
    only[k] = equilibrium.reg_stiffness(setup, ms)[0][k]
    P, n = setup.n_particles, setup.n_elements
    return equilibrium._connections(setup, ms, only, np.zeros((P, 3)), np.zeros((n, 3)), np.zeros(P))


def test_connection_shear_holds_an_offset_that_turns_with_the_wood():
    """The co-rotated offset costs nothing at rest and under a rigid turn of the whole wood; a
    slip of one centre across the pair's direction by eps costs 1/2 s k_conn eps^2, which the
    central spring (s = 0) does not resist to second order."""
    model = sample("tiny")[1]
    ms = initial_state(model, rods=True).mech
    k = 7
    i, j = model.mech.edges[k]
    kc = equilibrium.reg_stiffness(model.mech, ms)[0][k]
    turn = np.array([np.cos(0.35), *(np.sin(0.35) * np.array([0.48, -0.6, 0.64]))])
    turned = ms.copy()
    turned.x = rotate_np(np.broadcast_to(turn, (len(ms.x), 4)), ms.x)
    turned.q = normalize_np(mul_np(np.broadcast_to(turn, ms.q.shape), ms.q))
    fp = model.mech.fp
    c = 0.5 * (ms.x[fp] + ms.x[fp + 1])
    d = c[j] - c[i]
    across = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 * np.linalg.norm(d) else [1.0, 0.0, 0.0])
    eps = 1e-5
    slipped = ms.copy()
    slipped.x[[fp[j], fp[j] + 1]] += eps * across / np.linalg.norm(across)
    for s in (0.0, 0.4):
        setup = with_connection(model.mech, 1.0 - s, (s, s, s))
        assert _connection_energy(setup, ms, k) < 1e-12 * kc * eps ** 2
        assert _connection_energy(setup, turned, k) < 1e-6 * kc * eps ** 2
        assert _connection_energy(setup, slipped, k) == pytest.approx(0.5 * s * kc * eps ** 2, rel=1e-3,
                                                                      abs=1e-3 * kc * eps ** 2)
