"""The backward Euler step: its static limit bends a clamped strand as beam theory says and brings
a clamped bundle to equilibrium in a few Newton iterations; its short steps converge on wood lying
on the ground."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import equilibrium, implicit, mechanics, rigid, schedule, sleep
from wooddecay.sim.state import initial_state
from wooddecay.studies import cantilever

from ..conftest import sample
from .helpers import CONNECTIONS, fragments, with_connection
from .test_equilibrium import _clamped_tiny


def test_static_cantilever_deflects_as_beam_theory():
    s = cantilever.strand()
    report = implicit.step(s.setup, s.ms, np.inf, tol=1e-5)
    assert report.converged and report.newton <= 5
    deflection = s.clamp[2] - s.ms.x[-1, 2]
    assert deflection == pytest.approx(s.q * s.length ** 4 / (8 * s.EI), rel=0.01)


def test_static_clamped_bundle_reaches_equilibrium():
    setup, ms = _clamped_tiny()
    ms.mass_p[:] = 0.1
    ms.rest_length = ms.rest_length * 0.995
    assert equilibrium.equilibrium_residual(setup, ms) > 0.05
    report = implicit.step(setup, ms, np.inf, tol=1e-3)
    assert report.converged and report.newton <= 5
    assert equilibrium.equilibrium_residual(setup, ms) <= 1e-3


@pytest.mark.parametrize("connection", sorted(CONNECTIONS))
def test_hessian_is_the_force_jacobian_at_rest(connection):
    """Where every constraint holds, Gauss-Newton drops nothing: H d = -(f(x + e d) - f(x)) / e."""
    setup, ms = _clamped_tiny()
    setup = with_connection(setup, *CONNECTIONS[connection])
    ms.mass_p[:] = 0.0
    H = implicit.hessian(setup, ms)
    rng = np.random.default_rng(0)
    P, n = setup.n_particles, setup.n_elements
    d = rng.normal(size=3 * (P + n)) * np.concatenate([np.full(3 * P, 1e-3), np.full(3 * n, 1e-2)])
    eps = 1e-6
    moved = ms.copy()
    moved.x = ms.x + eps * d[:3 * P].reshape(P, 3)
    moved.q = implicit._turned(ms.q, eps * d[3 * P:].reshape(n, 3))
    F0, F1 = equilibrium.forces(setup, ms)[0], equilibrium.forces(setup, moved)[0]
    df = -np.concatenate([(F1.f - F0.f).ravel(), (F1.tau - F0.tau).ravel()]) / eps
    Hd = H @ d
    assert np.abs(Hd - df).max() <= 1e-4 * np.abs(Hd).max()


def test_short_steps_converge_on_wood_lying_on_the_ground():
    """The tiny log, free on the ground, from rest under its weight: steps of 0.01 s converge
    within the Newton cap (17, 12, 6 iterations), and the log's static residual falls as it settles."""
    model = sample("tiny")[1]
    ms = initial_state(model, rods=True).mech
    setup = model.mech
    mechanics.set_masses(setup, ms, np.full(setup.n_elements, 0.5))
    before = equilibrium.equilibrium_residual(setup, ms)
    for _ in range(3):
        report = implicit.step(setup, ms, 0.01, tol=1e-3)
        assert report.converged
    assert equilibrium.equilibrium_residual(setup, ms) < 0.5 * before


def test_friction_forces_are_minus_the_gradient_of_its_energy():
    """Lagged friction at the collider and pair contacts of the tiny log broken into its blocks,
    squeezed so that they press on each other:
    its forces are the finite differences of its energy, in the stick and the slip regime."""
    sim = fragments()
    setup, ms = sim.model.mech, sim.state.mech
    ms.x = ms.x * np.array([1.0, 0.99, 1.0])  # squeezed across the grain: the blocks press on each other
    friction = implicit._friction(setup, ms, ms.x)
    assert len(friction.muN) and (friction.w[:, 1:] != 0.0).any()  # pairs as well as the ground
    rng = np.random.default_rng(2)
    for scale in (1e-7, 1e-4):  # within and beyond STICK of slip
        x = ms.x + rng.normal(scale=scale, size=ms.x.shape)
        f = friction.forces(x)
        for p in friction.blocks[rng.choice(len(friction.muN), 5, replace=False), 0]:
            for c in range(3):
                up, down = x.copy(), x.copy()
                up[p, c] += 1e-10
                down[p, c] -= 1e-10
                fd = -(friction.energy(up) - friction.energy(down)) / 2e-10
                assert fd == pytest.approx(f[p, c], rel=1e-3, abs=1e-6 * np.abs(f).max())


def test_wood_nothing_holds_falls_and_keeps_its_shape():
    """No anchor, no ground: no static equilibrium exists, so the settle falls in short steps for
    ``time.settle`` seconds (about g t^2 / 2, backward Euler's lag aside) and the wood keeps its
    shape, never scattered by a singular static solve."""
    scene = sample("tiny")[0]
    model = wd.build_model(wd.load_scene(scene.path, overrides={"mechanics.solver": "implicit",
                                                                "mechanics.ground": False}))
    state = initial_state(model, rods=True)
    x0 = state.mech.x.copy()
    implicit.settle(model, state)
    drop = x0[:, 2].mean() - state.mech.x[:, 2].mean()
    t = model.time.settle
    assert 0.8 * 0.5 * 9.81 * t * t < drop < 1.2 * 0.5 * 9.81 * t * t
    moved = state.mech.x - x0
    assert np.abs(moved - moved.mean(axis=0)).max() < 1e-3


def test_a_protected_overlap_is_no_force_and_only_shrinks():
    """A protected overlap (what a pair overlapped when its elements separated) is no force: with
    every overlap of the tiny log's blocks protected, no pair pushes; once the pieces part by a
    millimetre, the protection shrinks by it and never grows back."""
    sim = fragments(**{"mechanics.solver": "implicit"})
    setup, ms = sim.model.mech, sim.state.mech
    ms.x = ms.x * np.array([1.0, 0.97, 1.0])  # squeezed across the grain: the blocks overlap
    phi = equilibrium.pair_contacts(setup, ms).phi
    assert phi.max() > 1e-4
    ms.pairs_protect = ms.pairs_protect + np.maximum(phi, 0.0)
    assert equilibrium.pair_contacts(setup, ms).phi.max() <= 1e-15  # k_col max(phi, 0)^2: no push
    protected = ms.pairs_protect.copy()
    ms.x = ms.x * np.array([1.0, 0.999, 1.0])  # a little further in: still protected as before
    implicit._part(setup, ms)
    assert np.array_equal(ms.pairs_protect, protected)
    ms.x = ms.x / np.array([1.0, 0.999, 1.0]) ** 2  # the blocks part
    implicit._part(setup, ms)
    shrunk = equilibrium.pair_contacts(setup, ms).phi
    assert (ms.pairs_protect <= protected).all() and (ms.pairs_protect < protected).any()
    assert np.allclose(shrunk[ms.pairs_protect > 0.0], 0.0, atol=1e-12)


def test_steps_shorten_after_a_stall_and_grow_back_while_easy():
    """The controller of a macro step's first step: a stall starts the next at BREAK_STEP, a step
    of at most EASY_NEWTON iterations doubles it, a harder one keeps it, and once it would reach
    the span the next is the whole span again (0)."""
    stalled = implicit.StepReport(newton=implicit.STALL + 1, residual=1.0, converged=False)
    easy = implicit.StepReport(newton=implicit.EASY_NEWTON, residual=0.01, converged=True)
    hard = implicit.StepReport(newton=implicit.EASY_NEWTON + 1, residual=0.01, converged=True)
    assert implicit.next_step(stalled, 1.0, 1.0) == implicit.BREAK_STEP
    h, steps = implicit.BREAK_STEP, []
    while h:
        steps.append(h)
        h = implicit.next_step(easy, h, 1.0)
    assert steps == [0.01 * 2 ** k for k in range(7)]
    assert implicit.next_step(hard, 0.04, 1.0) == 0.04
    assert implicit.next_step(hard, 1.0, 1.0) == 0.0


def test_the_implicit_step_keeps_the_contacts_of_still_pieces():
    """The schedule holds pieces at rest still, and XPBD then leaves out the contacts between
    them; the implicit step moves every piece (drying shrinks a held one too), so its contact
    list keeps them, or the pieces pass into each other unseen."""
    counts = {}
    for solver in ("xpbd", "implicit"):
        sim = fragments(**{"mechanics.solver": solver})
        setup, ms = sim.model.mech, sim.state.mech
        every = len(ms.pairs)
        ms.held[:] = True
        sleep.hold(setup, ms)
        ms.pairs_x = None
        mechanics.refresh_pairs(setup, ms)
        counts[solver] = (every, len(ms.pairs))
    assert counts["xpbd"][0] > 0 and counts["xpbd"][1] == 0
    assert counts["implicit"][1] == counts["implicit"][0] > 0


def test_the_wood_creeps_through_rest_changes_and_the_schedule_finds_it_quiet():
    """A macro step's first step answers rest data that changed over the days since the last one:
    the bound wood's displacement is creep over those days (v = dx / elapsed), so the tiny log
    lying on the ground, shrunk by 100x the strain tolerance two days on, ends its solve quiet in a
    step of BREAK_STEP (with dx / h it moved at cm/s, and the schedule would solve again)."""
    scene = sample("tiny")[0]
    sim = wd.Simulation(wd.build_model(wd.load_scene(scene.path, overrides={"mechanics.solver": "implicit"})))
    model, state = sim.model, sim.state
    ms = state.mech
    ms.rest_length *= 1.0 - 100.0 * model.time.tolerances.strain
    ms.stepped_day[0] = state.t_days
    state.t_days += 2.0
    ms.h_next[0] = implicit.BREAK_STEP
    x0 = ms.x.copy()
    assert schedule.solve(model, state, model.time.tolerances, "strain") == 1
    moved = np.linalg.norm(ms.x - x0, axis=1).max()
    assert moved / implicit.BREAK_STEP > model.time.tolerances.rest_speed
    assert np.linalg.norm(ms.v, axis=1).max() < 2.0 * moved / (2.0 * implicit.DAY)
    assert ms.quiet[0]


def test_rigid_pieces_keep_their_momentum_through_creep():
    """:func:`implicit.creep` spreads the bound wood's displacement over the elapsed days and
    leaves a rigid piece's velocity as its step made it (a falling block goes on falling)."""
    sim = fragments(**{"mechanics.solver": "implicit"})
    setup, ms = sim.model.mech, sim.state.mech
    implicit.step(setup, ms, implicit.BREAK_STEP, tol=setup.residual_tolerance)
    v, omega = ms.v.copy(), ms.omega.copy()
    rb = rigid.bodies(setup, ms)
    implicit.creep(ms, rb, implicit.BREAK_STEP, 2.0 * implicit.DAY)
    scale = implicit.BREAK_STEP / (2.0 * implicit.DAY)
    assert rb.n_pieces > 0 and np.abs(v[rb.particle >= 0]).max() > 1e-3
    assert np.array_equal(ms.v[rb.particle >= 0], v[rb.particle >= 0])
    assert np.array_equal(ms.omega[rb.element >= 0], omega[rb.element >= 0])
    assert np.allclose(ms.v[rb.particle < 0], v[rb.particle < 0] * scale, rtol=1e-12, atol=0.0)
