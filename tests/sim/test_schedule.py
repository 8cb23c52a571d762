"""The adaptive schedule (wooddecay.sim.schedule): mechanics runs when the rest data, integrity,
masses or loads changed past the tolerances, when something fails, and then until the wood is
quiet; a quiet model costs no substeps; resumed bakes decide as uninterrupted ones."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import schedule

from ..conftest import sample
from .helpers import digest


def tiny(**overrides):
    scene = wd.load_scene(sample("tiny")[0].path, overrides={"time.schedule": "adaptive", **overrides})
    return wd.Simulation(wd.build_model(scene))


def test_a_settled_model_is_quiet_and_runs_no_mechanics():
    sim = tiny()
    ms = sim.state.mech
    assert ms.quiet[0]
    t = ms.t_seconds
    assert schedule.due(sim.model, sim.state, sim.model.time.tolerances) is None
    assert ms.t_seconds == t


@pytest.mark.parametrize("change, reason", [
    ("rest_length", "strain"), ("rest_offset", "strain"), ("integrity", "integrity_mass"),
    ("mass_e", "integrity_mass")])
def test_each_change_past_its_tolerance_makes_mechanics_due(change, reason):
    """Half the tolerance is not due, twice the tolerance is, for the strain of rest lengths
    and offsets, for integrity and for relative masses."""
    sim = tiny()
    model, ms, tol = sim.model, sim.state.mech, sim.model.time.tolerances
    base = getattr(ms, change).copy()
    scale = {"rest_length": tol.strain * base[0], "rest_offset": tol.strain * model.mech.edge_length[0],
             "integrity": tol.relative, "mass_e": tol.relative * base[0]}[change]
    for factor, due in ((0.5, None), (2.0, reason)):
        v = base.copy()
        v[0] -= factor * scale
        setattr(ms, change, v)
        assert schedule.due(model, sim.state, tol) == due


@pytest.mark.parametrize("changes", [(), ("mass_e",), ("integrity",), ("rest_length",), ("rest_offset",),
                                     ("mass_e", "integrity", "rest_offset"), ("rest_length", "rest_offset", "integrity")])
def test_the_change_test_matches_its_numpy_twin(changes):
    """changed (one numba pass) gives changed_reference's reason and elements, for a few percent
    of the rest data moved by random amounts around their tolerances."""
    sim = tiny()
    model, ms, tol = sim.model, sim.state.mech, sim.model.time.tolerances
    rng = np.random.default_rng(len(changes))
    for change in changes:
        v = getattr(ms, change).copy()
        rows = rng.choice(len(v), size=max(3, len(v) // 30), replace=False)
        scale = {"rest_length": tol.strain * v[rows], "rest_offset": tol.strain * model.mech.edge_length[rows],
                 "integrity": tol.relative, "mass_e": tol.relative * v[rows]}[change]
        v[rows] += rng.uniform(-2.0, 2.0, len(rows)) * scale
        setattr(ms, change, v)
    reason, over = schedule.changed(model, ms, tol)
    want_reason, want_over = schedule.changed_reference(model, ms, tol)
    assert reason == want_reason and np.array_equal(over, want_over)
    assert (reason is None) == (not changes) and (over.any() == bool(changes))


def test_moving_loads_and_failures_make_mechanics_due():
    sim = tiny()
    model, state, ms, tol = sim.model, sim.state, sim.state.mech, sim.model.time.tolerances
    ms.quiet[0] = False
    assert schedule.due(model, state, tol) == "moving"
    ms.quiet[0] = True
    loaded = replace(model, mech=replace(model.mech, loads=((1.0, 2.0, np.zeros((model.mech.n_particles, 3))),)))
    state.t_days = 1.5
    assert schedule.due(loaded, state, tol) == "load"
    state.t_days = 0.0
    # a failure inside a piece is kept but starts no solve; one that splits a piece does
    e = np.flatnonzero(model.mech.inner)[0]
    ms.limit_elem[e] = -np.inf
    failures = ms.failures
    assert schedule.due(model, state, tol) is None
    assert not ms.element_ok[e] and ms.failures > failures
    half = model.centers[:, 0] > np.median(model.centers[:, 0])
    across = half[model.reg_edges[:, 0]] != half[model.reg_edges[:, 1]]
    links = model.mech.inner & (half != half[model.coupling.link_next])
    ms.limit_edge[across] = -np.inf
    ms.limit_elem[links] = -np.inf
    assert schedule.due(model, state, tol) == "failure" and schedule.big_pieces(ms) == 2


def test_a_solve_runs_until_the_wood_is_quiet():
    """The tiny log lifted 2 cm falls, lands and comes to rest within one solve of several
    chunks; a model at rest takes one chunk; max_mechanics caps a solve."""
    sim = tiny()
    model, state, ms = sim.model, sim.state, sim.state.mech
    tol = replace(model.time.tolerances, max_seconds=1.0)
    rest_z = ms.x[:, 2].min()
    assert schedule.solve(model, state, tol) == 1 and ms.quiet[0]
    ms.x[:, 2] += 0.02
    chunks = schedule.solve(model, state, tol)
    chunk = model.time.N_mech * model.mech.dt
    assert chunks * chunk > np.sqrt(2 * 0.02 / 9.81)  # at least the free fall
    assert ms.quiet[0] and abs(ms.x[:, 2].min() - rest_z) < 1e-3 and not ms.held.any()
    ms.x[:, 2] += 0.02
    capped = replace(tol, max_seconds=3 * chunk)
    assert schedule.solve(model, state, capped) == 3 and not ms.quiet[0]


def test_a_quiet_season_runs_few_solves_and_ends_at_rest():
    """The tiny log over 60 days: the adaptive schedule runs mechanics in a small share of the
    macro steps and ends at rest (one more chunk moves no particle faster than rest_speed).
    Under a constant climate: the tiny log is round, and where the ground wets its lowest row
    the heavier side rolls it a centimetre over the season (the log sample, an ellipse, stays:
    28 solves of 35 chunks over its first 240 temperate days)."""
    sim = tiny(**{"time.days": 60.0, "time.frames": 1, "climate.preset": "constant"})
    list(sim.run())
    summary = sim.schedule_summary()
    assert summary["macro_steps"] == 120 and 0 < summary["chunks"] < 30
    assert schedule.solve(sim.model, sim.state, sim.model.time.tolerances) == 1 and sim.state.mech.quiet[0]


@pytest.mark.slow
def test_drying_cracks_as_many_connections_as_the_fixed_schedule():
    """The tiny log drying in the open (test_fracture's recipe, S_R = S_T = 1) for 24 days: the failure
    test on skipped steps and the solves it triggers break as many REG connections as the fixed
    schedule, within 15%. Drying wood changes its rest strains past the tolerance in nearly
    every step and spalls small pieces that get time to fall, so the schedule runs more chunks
    than the fixed one (measured 699 / 240), but far from max_mechanics in every step: a crack's
    swinging elements do not keep it going."""
    from .test_fracture import DRYING

    out = {}
    for kind in ("fixed", "adaptive"):
        sim = tiny(**{**DRYING, "time.days": 24.0, "time.schedule": kind, "mechanics.S_R": 1.0,
                      "mechanics.S_T": 1.0})
        list(sim.run())
        summary = sim.schedule_summary()
        out[kind] = np.count_nonzero(~sim.state.mech.edge_ok[:, 0]), summary["mechanics_seconds"]
    print(out)
    (fixed, fixed_seconds), (adaptive, seconds) = out["fixed"], out["adaptive"]
    assert fixed > 50
    assert abs(adaptive - fixed) <= 0.15 * fixed
    assert seconds < 0.25 * fixed_seconds * 20  # 20 fixed macro steps: max_mechanics


def test_a_relaxing_chunk_is_the_shortest_that_sees_a_released_piece_fall():
    """12 substeps at the defaults, and a solve of wood at rest for changed rest data runs one
    such chunk; for any gravity, step and rest_speed a piece released from rest ends one faster
    than rest_speed (g T > rest_speed) and one substep less would not see it, unless N_mech caps
    the chunk; N_mech without gravity."""
    sim = tiny()
    model, ms = sim.model, sim.state.mech
    assert schedule.relax_substeps(model) == 12
    t0 = ms.t_seconds
    assert schedule.solve(model, sim.state, model.time.tolerances, "strain") == 1 and ms.quiet[0]
    assert ms.t_seconds - t0 == pytest.approx(12 * model.mech.dt)
    rng = np.random.default_rng(3)
    for _ in range(200):
        g, dt, v = rng.uniform(0.1, 30.0), 10 ** rng.uniform(-6, -2), 10 ** rng.uniform(-4, 0)
        m = replace(model, mech=replace(model.mech, gravity=np.array([0.0, 0.0, -g]), dt=dt),
                    time=replace(model.time, tolerances=replace(model.time.tolerances, rest_speed=v)))
        n = schedule.relax_substeps(m)
        assert 1 <= n <= model.time.N_mech
        if n < model.time.N_mech:
            assert g * n * dt > v
        if n > 1:
            assert g * (n - 1) * dt < schedule.CHUNK_MARGIN * v
    still = replace(model, mech=replace(model.mech, gravity=np.zeros(3)))
    assert schedule.relax_substeps(still) == model.time.N_mech


def test_resumed_adaptive_run_is_bit_identical(tmp_path):
    """The schedule's state (the rest data of the last solve, the quiet flag) is checkpointed."""
    over = {"time.days": 20.0, "time.frames": 3, "time.strain_tolerance": 1e-6}
    sim = tiny(**over)
    frames = list(sim.run())
    whole = digest(sim.state.mech)
    sim = tiny(**over)
    run = sim.run()
    next(run)
    sim.save_checkpoint(tmp_path / "c.npz")
    resumed = wd.Simulation.resume(sim.model, tmp_path / "c.npz")
    assert len(list(resumed.run())) == len(frames) - 1
    assert digest(resumed.state.mech) == whole
    assert resumed.schedule_summary()["solves"] > 0
