"""Sleeping pieces (wooddecay.sim.sleep): quiet pieces sleep, loud ones wake their neighbours,
loads wake everything, failures the pieces they touch, coupled changes wake only the pieces they changed past the
schedule's tolerances, so a coupled run sleeps."""
from __future__ import annotations

import numpy as np

import wooddecay as wd
from wooddecay.sim import contact, mechanics, schedule, sleep

from ..conftest import sample
from .helpers import fragments, quiet_window

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


def test_loads_wake_everything_failures_their_pieces_new_masses_nothing():
    sim = fragments()
    st, ms = sim.model.mech, sim.state.mech
    quiet_window(st, ms)
    window = ms.sleep_t.copy(), ms.sleep_x.copy()
    mechanics.set_masses(st, ms, np.full(st.n_elements, 0.3))
    assert ms.asleep.all() and not ms.w_p.any() and not ms.w_q.any()
    assert ms.sleep_t[0] == window[0][0] and np.array_equal(ms.sleep_x, window[1])
    ms.asleep[:] = False
    sleep.hold(st, ms)
    w_p, w_q = sleep.weights(st, ms)
    assert np.array_equal(ms.w_p, w_p) and np.array_equal(ms.w_q, w_q) and np.count_nonzero(w_p) > 0
    assert np.isclose(ms.mass_e.sum(), 1.3 * st.dry_mass.sum())
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
    piece = ms.component == ms.component[e]
    assert mechanics.macro_step(sim.model, sim.state, 1) > 0
    # the pieces the failure made and those touching them wake, the rest sleeps on
    near = set(np.unique(ms.component[piece]))
    pairs = contact.candidate_pairs(ms.x, st.fp, st.radius, ms.component, 0.0)
    pairs = pairs[ms.element_ok[pairs[:, 0]] & ms.element_ok[pairs[:, 1]]]
    c = ms.component[pairs[contact.pair_overlaps(ms.x, st.fp, st.radius, pairs)
                           > contact.pair_overlaps(st.x_rest, st.fp, st.radius, pairs)]]
    woken = near | {b for a, b in c if a in near} | {a for a, b in c if b in near}
    assert set(np.unique(ms.component[~ms.asleep])) == woken
    assert ms.asleep.any()


def test_only_the_pieces_that_changed_past_the_tolerances_wake():
    """A coupled change below the schedule's tolerances (masses 1%, integrity 0.01) leaves every
    piece asleep; a mass change of 5% on one piece, or an integrity drop of 0.1 on its REG pairs,
    wakes that piece alone, and the window goes on."""
    sim = fragments()
    model, st, ms = sim.model, sim.model.mech, sim.state.mech
    tol = model.time.tolerances
    schedule.mark(model, ms, 0.0, quiet=True)
    quiet_window(st, ms)
    piece = ms.component[0]
    mine = ms.component == piece
    ms.mass_e = ms.mass_e * 1.01
    ms.integrity = ms.integrity - 0.01
    assert schedule.wake_changed(model, sim.state, tol) is None and ms.asleep.all()
    for change in ("mass", "integrity"):
        quiet_window(st, ms)
        t = ms.sleep_t[0]
        if change == "mass":
            ms.mass_e = np.where(mine, ms.mass_e * 1.05, ms.mass_e)
        else:
            on = mine[st.edges[:, 0]] & mine[st.edges[:, 1]]
            ms.integrity = np.where(on, ms.integrity - 0.1, ms.integrity)
        assert schedule.wake_changed(model, sim.state, tol) == "integrity_mass"
        assert not ms.asleep[mine].any() and ms.asleep[~mine].all() and ms.sleep_t[0] == t
        assert np.count_nonzero(ms.w_p) > 0
        schedule.mark(model, ms, 0.0, quiet=True)


def test_a_coupled_run_sleeps():
    """The coupling's new masses after every biology step wake nothing, and changes within the
    schedule's tolerances (here 1) wake no piece, so in a coupled run whose macro steps are
    shorter than the sleep window the window still ends (0.1 s steps, a 0.2 s window, 0.3 s)
    and the quiet log falls asleep (limits of 10: no failure wakes it)."""
    scene = wd.load_scene(sample("tiny")[0].path, overrides={
        "mechanics.sleep_speed": 1.0, "mechanics.sleep_time": 0.2, "mechanics.N_mech": 1000,
        "time.schedule": "fixed", "time.tolerance": 1.0, "time.strain_tolerance": 1.0,
        **{f"mechanics.L_0_{k}": 10.0 for k in ("stretch", "shear", "bend", "twist", "bundle")}})
    sim = wd.Simulation(wd.build_model(scene))
    for _ in range(3):
        sim.macro_step(scene.time.dt_bio)
    assert sim.state.mech.asleep.all()
