"""Sleeping pieces (wooddecay.sim.sleep) and debris settling (wooddecay.studies.debris; woodstock §5.4,
Fig. 12): the tiny log broken into its BSP blocks."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.studies import debris
from wooddecay.sim import contact, mechanics, sleep

from ..conftest import sample
from ..test_mechanics import _digest as mech_digest


def _fragments(**overrides):
    scene, model = sample("tiny")
    if overrides:
        model = wd.build_model(wd.load_scene(scene.path, overrides=overrides))
    sim = wd.Simulation(model)
    debris.fragment(sim)
    mechanics.refresh_pairs(sim.model.mech, sim.state.mech)
    return sim


def _quiet_window(st, ms, moved=None) -> int:
    """End a full window in which the particles moved by ``moved`` (P, 3) (default: not at all)."""
    ms.sleep_x = ms.x.copy() if moved is None else ms.x - moved
    ms.sleep_t = np.array([ms.t_seconds - st.sleep_time])
    return sleep.update(st, ms)


def _digest(ms) -> str:
    """The mechanics digest of tests/test_mechanics.py and the sleep state."""
    h = hashlib.sha256(mech_digest(ms).encode())
    for a in (ms.w_p, ms.w_q, ms.asleep):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def test_quiet_pieces_sleep_and_hold_still():
    sim = _fragments()
    st, ms = sim.model.mech, sim.state.mech
    pieces = int(ms.component.max()) + 1
    assert pieces > 5
    assert _quiet_window(st, ms) == pieces
    assert ms.asleep.all() and not ms.w_p.any() and not ms.w_q.any() and not ms.v.any()
    x = ms.x.copy()
    mechanics.macro_step(sim.model, sim.state, 50)
    assert np.array_equal(ms.x, x) and not ms.v.any()


def test_a_loud_piece_wakes_the_pieces_it_touches_and_no_other():
    """A piece that moved faster than WAKE_FACTOR sleep_speed over the window stays awake and
    wakes exactly the sleeping pieces it overlaps beyond their rest overlap; a piece that moved
    a little more than sleep_speed stays awake without waking anything."""
    sim = _fragments()
    st, ms = sim.model.mech, sim.state.mech
    _quiet_window(st, ms)
    pairs = contact.candidate_pairs(ms.x, st.fp, st.radius, ms.component, 0.0)
    pairs = pairs[ms.element_ok[pairs[:, 0]] & ms.element_ok[pairs[:, 1]]]
    touch = (contact.pair_overlaps(ms.x, st.fp, st.radius, pairs)
             > contact.pair_overlaps(st.x_rest, st.fp, st.radius, pairs))
    c = ms.component[pairs[touch]]
    loud = np.bincount(c.ravel()).argmax()
    neighbours = set(c[c[:, 0] == loud, 1]) | set(c[c[:, 1] == loud, 0])
    assert 0 < len(neighbours) < ms.component.max()
    for factor, woken in ((1.5, {loud}), (2.0 * sleep.WAKE_FACTOR, neighbours | {loud})):
        _quiet_window(st, ms)
        mine = np.zeros(st.n_particles, dtype=bool)  # particles of no other piece
        mine[st.fp[ms.component == loud]] = True
        others = st.fp[ms.component != loud]
        mine[others] = mine[others + 1] = False
        moved = np.zeros((st.n_particles, 3))
        moved[mine, 0] = factor * st.sleep_speed * st.sleep_time
        _quiet_window(st, ms, moved)
        assert set(np.unique(ms.component[~ms.asleep])) == woken


def test_failures_new_masses_and_loads_wake_everything():
    sim = _fragments()
    st, ms = sim.model.mech, sim.state.mech
    _quiet_window(st, ms)
    mechanics.set_masses(st, ms, np.full(st.n_elements, 0.3))
    assert not ms.asleep.any() and ms.sleep_t[0] == ms.t_seconds and np.array_equal(ms.sleep_x, ms.x)
    w_p, w_q = sleep.weights(st, ms)
    assert np.array_equal(ms.w_p, w_p) and np.array_equal(ms.w_q, w_q) and np.count_nonzero(w_p) > 0
    _quiet_window(st, ms)
    ms.force = np.zeros((st.n_particles, 3))
    sleep.wake_loaded(st, ms)
    assert ms.asleep.all()
    ms.force[0, 2] = 1e-3
    sleep.wake_loaded(st, ms)
    assert not ms.asleep.any()
    _quiet_window(st, ms)
    e = np.flatnonzero(st.inner & ms.element_ok & np.r_[False, ms.element_ok[:-2], False]
                       & np.r_[False, ms.element_ok[2:], False])[0]
    ms.limit_elem[e] = -np.inf
    assert mechanics.macro_step(sim.model, sim.state, 1) > 0
    assert not ms.asleep.any()


def test_coupled_run_is_unchanged_by_sleeping():
    """The coupling sets new masses after every biology step, which wakes everything and restarts
    the sleep window, so a coupled run whose macro steps are shorter than the window never sleeps
    (here 0.1 s steps and a 0.2 s window over 0.3 s; without the restart the window would end
    with the second step and the third would be asleep), and its state does not depend on sleep_speed."""
    states = []
    for speed in (0.0, 1.0):  # 1 m/s: everything would be quiet
        scene = wd.load_scene(sample("tiny")[0].path, overrides={
            "mechanics.sleep_speed": speed, "mechanics.sleep_time": 0.2, "mechanics.N_mech": 1000})
        sim = wd.Simulation(wd.build_model(scene))
        for _ in range(3):
            sim.macro_step(scene.time.dt_bio)
        states.append(sim.state.mech)
    assert not states[1].asleep.any()
    assert _digest(states[0]) == _digest(states[1])


@pytest.mark.slow
def test_debris_settles_asleep_without_interpenetrating():
    """Issue "Debris": the pieces fall 5 cm, pile up and come to rest: within 8 s every piece
    sleeps and stays asleep for 0.5 s (so the largest speed is 0 < 1e-3 m/s), each fell asleep only after its particles
    had moved less than sleep_speed over a whole window, and no two capsules of different pieces
    overlap by more than 0.1 r_s beyond their rest overlap. Resuming from the arrays a checkpoint
    holds, while some pieces sleep and others move, continues bit for bit."""
    sim = _fragments()
    st, ms = sim.model.mech, sim.state.mech
    records, forked = [], None
    for r in debris.drop(sim, 0.05, 8.0):
        records.append(r)
        if len(records) > 5 and all(q.asleep == q.pieces for q in records[-5:]):
            break  # asleep for 0.5 s
        if forked is None and 0 < r.asleep < r.pieces:
            forked = mechanics.initial_state(sim.model)
            for k, v in ms.arrays().items():
                setattr(forked, k, v.copy())
            forked.t_seconds, forked.failures = ms.t_seconds, ms.failures
            twin = ms.copy()
            for s in (twin, forked):
                state = sim.state.copy()
                state.mech = s
                mechanics.macro_step(sim.model, state, 3000)
            assert _digest(twin) == _digest(forked)
            assert 0 < np.unique(twin.component[twin.asleep]).size < r.pieces
    assert forked is not None
    settled = next(k for k in range(len(records)) if all(r.asleep == r.pieces for r in records[k:]))
    print(f"pieces {records[-1].pieces}, settled at {records[settled].t:.1f} s, penetration "
          f"{max(r.penetration for r in records[settled:]):.3f} r_s, window speed before "
          f"{records[settled - 1].window_speed:.2e} m/s")
    assert records[0].max_speed > 0.1  # it fell
    assert records[-1].max_speed < 1e-3 and records[-1].asleep == records[-1].pieces
    assert all(r.penetration < 0.1 for r in records[settled:])
    assert records[-1].z_min > 0.0
