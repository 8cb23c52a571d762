"""Mechanics (wooddecay.sim.mechanics): the stiffness cache, determinism over threads, stability,
checkpoints, the ground, colliders and settling."""
from __future__ import annotations

from dataclasses import replace

import numba
import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import failure, mechanics
from wooddecay.sim.state import initial_state

from ..conftest import sample
from .helpers import digest, failing_tiny, run_tiny

def test_advance_equals_substeps_that_gather_the_stiffness():
    """mechanics.advance keeps the gathered stiffness until a substep has failures; the state is
    bit for bit that of substeps which gather it every time."""
    model, state = failing_tiny()
    a, b = state.copy(), state.copy()
    new = mechanics.advance(model, a, 30)
    for _ in range(30):
        mechanics.substep(model, b, model.mech.dt)
    assert new > 0 and a.mech.failures == b.mech.failures
    assert digest(a.mech) == digest(b.mech)


def test_same_result_with_one_or_two_threads():
    n0 = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        a = run_tiny()
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        b = run_tiny()
    finally:
        numba.set_num_threads(n0)
    assert a.failures > 0
    assert digest(a) == digest(b)


@pytest.mark.slow
@pytest.mark.parametrize("dt", [0.001, 0.005, 0.01, 0.02, 0.05])
def test_stability_on_the_log(dt):
    """No NaN and no energy growth without input (no gravity, no ground, random velocities)."""
    scene = wd.load_scene(sample("log")[0].path, overrides={"mechanics.gravity": [0, 0, 0],
                                                            "mechanics.ground": False})
    free = wd.build_model(scene)
    for iterations in (1, 2, 5, 10):
        model = replace(free, mech=replace(free.mech, iterations=iterations))
        state = initial_state(model, rods=True)
        ms = state.mech
        ms.v = np.random.default_rng(1).normal(scale=0.01, size=ms.v.shape) * (ms.w_p > 0)[:, None]
        ke0 = 0.5 * np.sum(ms.mass_p * np.sum(ms.v**2, axis=1))
        for _ in range(10):
            mechanics.substep(model, state, dt)
            ke = 0.5 * np.sum(ms.mass_p * np.sum(ms.v**2, axis=1))
            assert np.isfinite(ms.x).all() and np.isfinite(ms.q).all()
            assert ke <= ke0 * 1.0001, (dt, iterations, ke, ke0)


def test_checkpoint_resume_is_bit_exact(tmp_path):
    scene = wd.load_scene(sample("tiny")[0].path, overrides={"time.days": 4, "time.frames": 5,
                                                             "mechanics.N_mech": 5})
    model = wd.build_model(scene)
    full = list(wd.Simulation(model).run())
    sim = wd.Simulation(model, checkpoint_dir=tmp_path, checkpoint_every=2)
    for frame in sim.run():
        if frame.index == 2:
            break
    resumed = wd.Simulation.resume(model, tmp_path / "frame_00002.npz")
    rest = list(resumed.run())
    assert [f.index for f in rest] == [3, 4]
    for a, b in zip(full[3:], rest):
        for k in a.fields:
            assert np.array_equal(a.fields[k], b.fields[k])
        for k in a.mech:
            assert np.array_equal(a.mech[k], b.mech[k])
    other = wd.load_scene(sample("tiny")[0].path, overrides={"time.days": 5})
    with pytest.raises(ValueError):
        wd.Simulation.resume(wd.build_model(other), tmp_path / "frame_00002.npz")


def test_ground_holds_a_resting_log():
    """After settling, the tiny log rests on the ground: it barely moves, and its bottom capsules
    sink at most to sqrt(F / k_col) for the heaviest bottom load F = half the log's weight
    (penalty force k_col phi^2, Eq. 4)."""
    scene, model = sample("tiny")
    sim = wd.Simulation(model)
    ms, st = sim.state.mech, sim.model.mech
    ms.limit_elem[:] = np.inf
    ms.limit_edge[:] = np.inf
    for _ in range(200):
        mechanics.substep(model, sim.state, st.dt)
    weight = 9.81 * ms.mass_p.sum()
    assert ms.x[:, 2].min() > scene.strands.r_s - np.sqrt(0.5 * weight / st.k_col)
    assert np.abs(ms.v).max() < 0.05


def test_collider_scene_validation():
    text = (sample("tiny")[0].path).read_text()
    with pytest.raises(wd.InputError, match="collider\\[0\\].kind"):
        wd.parse_scene(text + '\n[[collider]]\nkind = "cone"\n')
    s = wd.parse_scene(text + '\n[[collider]]\nkind = "sphere"\ncenter = [0, 0, 1]\nradius = 0.2\n')
    setup = wd.build_model(s).mech
    assert setup.colliders.shape[0] == 2  # the ground and the sphere


def test_settled_wood_at_rest_does_not_break():
    """Settling (mechanics.settle) takes the strains of the wood at rest under its own weight as
    the failure reference: resting wood at the default moisture then holds, its strain changes
    a small fraction of L(M)."""
    scene, model = sample("tiny")
    sim = wd.Simulation(model)
    ms, st = sim.state.mech, sim.model.mech
    assert np.abs(ms.strain_ref_edge).max() > 0.0 and not ms.v.any()
    for _ in range(4):
        sim.macro_step(scene.time.dt_bio)
    assert ms.failures == 0 and ms.edge_ok.all() and ms.element_ok.all()
    pair = failure.strains(st, ms)[1] - ms.strain_ref_edge
    assert np.max(pair / ms.limit_edge) < 0.2
    assert sim.history[-1]["mechanics"]["max_speed"] < 0.05


@pytest.mark.slow
def test_the_shipped_log_settles_at_rest_on_the_ground():
    """samples/log.toml settles into its resting orientation: 0.1 s of mechanics afterwards moves
    no particle by more than 0.3 mm (at the default settling it rocked 1.5 mm in that time and
    8.3 mm over its first year's mechanics; docs/decisions.md, "Settling")."""
    _, model = sample("log")
    sim = wd.Simulation(model)
    x0 = sim.state.mech.x.copy()
    mechanics.advance(model, sim.state, round(0.1 / model.mech.dt))
    moved = np.linalg.norm(sim.state.mech.x - x0, axis=1).max()
    print(f"log after settling: {1e3 * moved:.3f} mm in 0.1 s")
    assert moved < 3e-4


def test_settle_tests_failure_once_with_the_bits_of_testing_every_substep(monkeypatch):
    """With its limits infinite, settling fails only decayed connections, which fail whatever the
    positions: it tests them on its first substep alone (mechanics.settle), and the state, flags and
    failure count are those of a settle that tests every substep."""
    scene, model = sample("tiny")
    s0 = wd.Simulation(model, settle=False).state
    decayed = np.arange(0, len(model.mech.edges), 7)
    s0.mech.integrity[decayed] = 0.0
    a, b = s0.copy(), s0.copy()
    mechanics.settle(model, a, 0.01, scene.mechanics.settle_damping, tol=0.05)
    advance = mechanics._advance
    monkeypatch.setattr(mechanics, "_advance", lambda *args, check=True: advance(*args))
    mechanics.settle(model, b, 0.01, scene.mechanics.settle_damping, tol=0.05)
    assert not a.mech.edge_ok[decayed, 0].any() and a.mech.failures >= len(decayed)
    assert a.mech.failures == b.mech.failures
    assert digest(a.mech) == digest(b.mech)


def test_settle_with_tol_stops_at_the_first_quiet_chunk():
    """mechanics.settle(tol=...) goes on in chunks until the strain drift of a chunk is within
    tol of the limits: the last chunk is within it, the one before is not, and the state is that
    of a plain settle of the same length (positions and rotations; strains depend on nothing
    else), with the reference strains of that state."""
    scene, model = sample("tiny")
    sim = wd.Simulation(model, settle=False)
    st, s0 = sim.model.mech, sim.state
    tol, damping = 0.05, scene.mechanics.settle_damping
    s = s0.copy()
    ms = s.mech
    done = mechanics.settle(model, s, 0.0, damping, tol=tol)
    chunk = mechanics.SETTLE_CHUNK
    assert done >= 2 * chunk - 1e-12

    def plain(seconds):
        m = s0.copy()
        mechanics.settle(model, m, seconds, damping)
        return m.mech

    last, before, earlier = plain(done), plain(done - chunk), plain(done - 2 * chunk)
    np.testing.assert_array_equal(last.x, ms.x)
    np.testing.assert_array_equal(last.q, ms.q)
    np.testing.assert_array_equal(ms.strain_ref_edge, last.strain_ref_edge)
    limits = ms.limit_elem, ms.limit_edge
    strains = [failure.strains(st, m) for m in (earlier, before, last)]
    assert failure.drift(st, ms, strains[1], strains[2], *limits) <= tol
    assert failure.drift(st, ms, strains[0], strains[1], *limits) > tol


def test_contact_list_helpers_equal_numpy():
    """The Verlet list's reach test is numpy's max |x - x0| < reach, empty and NaN rows included,
    and the protected overlaps go back to their rows as numpy's masked assignment puts them."""
    rng = np.random.default_rng(2)
    x0 = rng.normal(size=(50, 3))
    for x, reach in ((x0 + 0.01, 0.02), (x0 + 0.01, 0.005), (x0[:0], 0.1), (x0[:0], 0.0), (x0, 0.0),
                     (np.where(np.arange(150).reshape(50, 3) == 7, np.nan, x0), 1.0)):
        expect = np.max(np.abs(x - x0[:len(x)]), initial=0.0) < reach
        assert mechanics._within(x, x0[:len(x)], reach) == expect
    sep = np.array([3, -1, 0, -1, 5])
    rest, protect = rng.random(5), rng.random(5)
    a, b = np.zeros(6), np.zeros(6)
    mechanics.keep_overlaps(sep, rest, protect, a)
    keep = sep >= 0
    b[sep[keep]] = rest[keep] + protect[keep]
    assert np.array_equal(a, b)
