"""Sleeping pieces (wooddecay.sim.sleep): quiet pieces sleep, loud ones wake their neighbours,
failures, new masses and loads wake everything, a coupled run never sleeps."""
from __future__ import annotations

import numpy as np

import wooddecay as wd
from wooddecay.sim import contact, mechanics, sleep

from ..conftest import sample
from .helpers import fragments, quiet_window, sleep_digest

def test_quiet_pieces_sleep_and_hold_still():
    sim = fragments()
    st, ms = sim.model.mech, sim.state.mech
    pieces = int(ms.component.max()) + 1
    assert pieces > 5
    assert quiet_window(st, ms) == pieces
    assert ms.asleep.all() and not ms.w_p.any() and not ms.w_q.any() and not ms.v.any()
    x = ms.x.copy()
    mechanics.macro_step(sim.model, sim.state, 50)
    assert np.array_equal(ms.x, x) and not ms.v.any()


def test_a_loud_piece_wakes_the_pieces_it_touches_and_no_other():
    """A piece that moved faster than WAKE_FACTOR sleep_speed over the window stays awake and
    wakes exactly the sleeping pieces it overlaps beyond their rest overlap; a piece that moved
    a little more than sleep_speed stays awake without waking anything."""
    sim = fragments()
    st, ms = sim.model.mech, sim.state.mech
    quiet_window(st, ms)
    pairs = contact.candidate_pairs(ms.x, st.fp, st.radius, ms.component, 0.0)
    pairs = pairs[ms.element_ok[pairs[:, 0]] & ms.element_ok[pairs[:, 1]]]
    touch = (contact.pair_overlaps(ms.x, st.fp, st.radius, pairs)
             > contact.pair_overlaps(st.x_rest, st.fp, st.radius, pairs))
    c = ms.component[pairs[touch]]
    loud = np.bincount(c.ravel()).argmax()
    neighbours = set(c[c[:, 0] == loud, 1]) | set(c[c[:, 1] == loud, 0])
    assert 0 < len(neighbours) < ms.component.max()
    for factor, woken in ((1.5, {loud}), (2.0 * sleep.WAKE_FACTOR, neighbours | {loud})):
        quiet_window(st, ms)
        mine = np.zeros(st.n_particles, dtype=bool)  # particles of no other piece
        mine[st.fp[ms.component == loud]] = True
        others = st.fp[ms.component != loud]
        mine[others] = mine[others + 1] = False
        moved = np.zeros((st.n_particles, 3))
        moved[mine, 0] = factor * st.sleep_speed * st.sleep_time
        quiet_window(st, ms, moved)
        assert set(np.unique(ms.component[~ms.asleep])) == woken


def test_failures_new_masses_and_loads_wake_everything():
    sim = fragments()
    st, ms = sim.model.mech, sim.state.mech
    quiet_window(st, ms)
    mechanics.set_masses(st, ms, np.full(st.n_elements, 0.3))
    assert not ms.asleep.any() and ms.sleep_t[0] == ms.t_seconds and np.array_equal(ms.sleep_x, ms.x)
    w_p, w_q = sleep.weights(st, ms)
    assert np.array_equal(ms.w_p, w_p) and np.array_equal(ms.w_q, w_q) and np.count_nonzero(w_p) > 0
    quiet_window(st, ms)
    ms.force = np.zeros((st.n_particles, 3))
    sleep.wake_loaded(st, ms)
    assert ms.asleep.all()
    ms.force[0, 2] = 1e-3
    sleep.wake_loaded(st, ms)
    assert not ms.asleep.any()
    quiet_window(st, ms)
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
    assert sleep_digest(states[0]) == sleep_digest(states[1])
