"""Held pieces (wooddecay.sim.schedule.hold_still) and still wood in the kernels
(wooddecay.sim.mechanics.stiffness): what is still moves nothing and costs no sweep, with the
same bits as a sweep over everything; the schedule holds pieces at rest and coasting, and keeps
awake what falls, what starts to slide and what a heavy enough piece pushes."""
from __future__ import annotations

import numpy as np

from wooddecay.sim import mechanics, schedule, sleep

from .helpers import digest, fragments


def _half_held():
    """The tiny log in its BSP blocks, every other block held, the others weak enough to break
    as they fall."""
    sim = fragments()
    st, ms = sim.model.mech, sim.state.mech
    ms.held = ms.component % 2 == 0
    sleep.hold(st, ms)
    awake = ~ms.held
    weak = awake[st.edges[:, 0]] & awake[st.edges[:, 1]]
    ms.limit_edge[weak] = 2e-4
    return sim


def test_still_wood_is_skipped_with_the_same_bits(monkeypatch):
    runs = []
    for skip in (True, False):
        sim = _half_held()
        st, ms = sim.model.mech, sim.state.mech
        if not skip:  # every element counts as movable: nothing is left out
            monkeypatch.setattr(mechanics, "movable", lambda setup, ms: np.ones(setup.n_elements, dtype=bool))
        kreg, _, plan, tested = mechanics.stiffness(st, ms)
        held, x0 = ms.held.copy(), ms.x.copy()
        failures = mechanics.macro_step(sim.model, sim.state, 50)
        runs.append((digest(ms), failures, len(kreg.active), sum(len(c) for c in plan.elems), len(tested[1])))
        still_p = np.ones(st.n_particles, dtype=bool)
        still_p[st.fp[~held]] = still_p[st.fp[~held] + 1] = False
        assert ms.held.any() and np.array_equal(ms.x[still_p], x0[still_p])
    (d1, f1, *sizes1), (d2, f2, *sizes2) = runs
    assert f1 > 0 and f1 == f2 and d1 == d2
    assert all(a < b for a, b in zip(sizes1, sizes2))  # fewer edges, elements and tests


def test_resting_pieces_are_held_moving_and_pushed_ones_are_not():
    sim = fragments()
    st, ms = sim.model.mech, sim.state.mech
    hold = 1e-3
    m = schedule.motion(st, ms, ms.x, 1.0)
    a, b = sleep.touching(st, ms)
    pa = a[0]
    nbrs = {int(j) for i, j in zip(a, b) if i == pa} | {int(i) for i, j in zip(a, b) if j == pa}

    def awake_pieces(v_now, v_mean, mass, speed=hold):
        ms.held[:] = False
        schedule.hold_still(st, ms, m._replace(v_now=v_now, v_mean=v_mean, mass=mass), speed)
        return set(np.unique(ms.component[~ms.held]).tolist())

    zero = np.zeros_like(m.v_now)
    assert awake_pieces(zero, zero, m.mass) == set() and not ms.w_p.any()  # all at rest: all held
    fast = zero.copy()
    fast[pa] = 5 * hold
    heavy, light = m.mass.copy(), m.mass.copy()
    heavy[pa] = max(m.mass[j] for j in nbrs)
    light[pa] = min(m.mass[j] for j in nbrs) / 10
    assert awake_pieces(fast, zero, heavy) == {pa} | nbrs  # m v >= 5 M hold_speed: it pushes its neighbours
    assert awake_pieces(fast, zero, light) == {pa}  # m v <= M hold_speed / 2: it does not
    assert awake_pieces(zero, fast, heavy) == {pa} | nbrs  # moving on average over the chunk
    assert awake_pieces(zero, zero, m.mass, speed=0.0) == set(np.unique(ms.component).tolist())  # 0: never
    assert ms.w_p.any()
    schedule.release(st, ms)
    assert not ms.held.any()


def test_a_failure_releases_the_held_piece_it_breaks_without_sleeping_too():
    sim = fragments(**{"mechanics.sleep_speed": 0.0})
    st, ms = sim.model.mech, sim.state.mech
    ms.held[:] = True
    sleep.hold(st, ms)
    e = np.flatnonzero(st.inner & ms.element_ok & np.r_[False, ms.element_ok[:-2], False]
                       & np.r_[False, ms.element_ok[2:], False])[0]
    ms.limit_elem[e] = -np.inf
    piece = ms.component == ms.component[e]
    assert mechanics.macro_step(sim.model, sim.state, 1) > 0
    assert not ms.held[piece].any() and ms.held.any()


def test_a_still_quaternion_keeps_its_bits_beside_moving_wood():
    """A quaternion of weight 0 is not renormalised by a constraint that moves its neighbour
    (Stage 1's direct solve and Gauss-Seidel, the strands' and the pairs' bend-twist): every other
    element held, the held ones off unit length by a few ulp, a substep leaves them as they were."""
    for solver in ("direct", "gauss-seidel"):
        sim = fragments(**{"mechanics.strand_solver": solver})
        st, ms = sim.model.mech, sim.state.mech
        ms.held = np.arange(st.n_elements) % 2 == 0
        sleep.hold(st, ms)
        ms.q[ms.held] *= 1.0 + 4e-16
        q0 = ms.q.copy()
        mechanics.macro_step(sim.model, sim.state, 1)
        assert np.array_equal(ms.q[ms.held], q0[ms.held])
        assert not np.array_equal(ms.q[~ms.held], q0[~ms.held])
