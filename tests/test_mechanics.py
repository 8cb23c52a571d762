"""Mechanics: rod kernels against their numpy references, determinism, stability, coupling
(Eqs. 16-19, 21), failure and checkpoints."""
from __future__ import annotations

import hashlib
from dataclasses import replace
from types import SimpleNamespace

import numba
import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import coupling, failure, mechanics, rods
from wooddecay.sim.state import initial_state
from wooddecay.quaternion import normalize_np

from .conftest import sample


def _perturbed_state(name="tiny", seed=0):
    """(model, state) of a sample with the rods at rest, then jostled and partly decayed."""
    model = sample(name)[1]
    state = initial_state(model, rods=True)
    setup, ms = model.mech, state.mech
    rng = np.random.default_rng(seed)
    ms.x += rng.normal(scale=1e-3, size=ms.x.shape) * (ms.w_p > 0)[:, None]
    ms.q = normalize_np(ms.q + rng.normal(scale=0.02, size=ms.q.shape) * (ms.w_q > 0)[:, None])
    ms.integrity = rng.uniform(0.2, 1.0, len(setup.edges))
    return model, state


def _perturbed(name="tiny", seed=0):
    """(model.mech, state.mech) of :func:`_perturbed_state`, for the kernels' own tests."""
    model, state = _perturbed_state(name, seed)
    return model.mech, state.mech


def test_rod_kernels_equal_numpy_reference():
    setup, ms = _perturbed()
    dt = 1e-3
    sw = setup.sweep
    offset, k_conn, k_bend, k_twist = sw.arrays(ms)
    results = []
    for kernels in ((rods.stretch_shear, rods.bend_twist, rods.reg_pass),
                    (rods.stretch_shear_reference, rods.bend_twist_reference, rods.reg_pass_reference)):
        x, q = ms.x.copy(), ms.q.copy()
        lam = mechanics._multipliers(setup)
        ss, bt, rp = kernels
        for elems in setup.elems:
            ss(elems, setup.fp, x, q, ms.w_p, ms.w_q, ms.rest_length, setup.k_stretch, setup.k_shear,
               ms.element_ok, lam["s"], lam["sh"], dt)
        for idx in setup.joint_sets:
            bt(setup.joints, idx, q, ms.w_q, setup.joint_rest, setup.joint_length, setup.joint_kb,
               setup.joint_kt, lam["j"], dt)
        for c in range(len(sw.ptr) - 1):
            rp(sw.edges, sw.ptr[c], sw.ptr[c + 1], setup.fp, x, q, ms.w_p, ms.w_q, offset, k_conn, sw.rest,
               sw.length, k_bend, k_twist, lam["c"], lam["p"], dt)
        results.append((x, q, lam))
    (x1, q1, l1), (x2, q2, l2) = results
    assert np.abs(x1 - ms.x).max() > 1e-6  # the projections did something
    np.testing.assert_allclose(x1, x2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(q1, q2, rtol=0, atol=1e-12)
    for k in l1:
        np.testing.assert_allclose(l1[k], l2[k], rtol=1e-9, atol=1e-15)


def test_reg_colouring_has_no_shared_particle():
    setup = sample("log")[1].mech
    sw = setup.sweep
    ptr, order = sw.ptr, sw.order
    assert sorted(order.tolist()) == list(range(len(setup.edges)))
    np.testing.assert_array_equal(sw.edges, setup.edges[order])  # the sweep's data is the edges'
    np.testing.assert_array_equal(sw.rest, setup.edge_rest[order])
    for c in range(len(ptr) - 1):
        assert np.all(np.diff(order[ptr[c]:ptr[c + 1]]) > 0)  # each class in increasing id
        e = sw.edges[ptr[c]:ptr[c + 1]]
        parts = np.concatenate([setup.fp[e[:, 0]], setup.fp[e[:, 0]] + 1, setup.fp[e[:, 1]], setup.fp[e[:, 1]] + 1])
        assert len(np.unique(parts)) == len(parts)
    assert len(ptr) - 1 < 80


def test_sweep_arrays_equal_numpy_gather():
    """RegSweep.arrays: the state's dp and stiffness (base x I_ij, 0 where failed) in colour order."""
    setup, ms = _perturbed()
    rng = np.random.default_rng(1)
    ms.edge_ok[:] = rng.random(ms.edge_ok.shape) > 0.3
    ms.rest_offset = ms.rest_offset * rng.uniform(0.9, 1.0, len(ms.rest_offset))
    sw = setup.sweep
    o = sw.order
    want = (ms.rest_offset[o],) + tuple(np.where(ms.edge_ok[o, c], ms.integrity[o] * k0, 0.0)
                                        for c, k0 in enumerate((sw.k_conn0, sw.k_pb0, sw.k_pt0)))
    for got, w in zip(sw.arrays(ms), want):
        np.testing.assert_array_equal(got, w)
    assert (want[1] == 0).any() and (want[1] > 0).any()


def _digest(ms) -> str:
    h = hashlib.sha256()
    for a in (ms.x, ms.v, ms.q, ms.omega, ms.component, ms.edge_ok, ms.element_ok):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _failing_tiny():
    model, state = _perturbed_state(seed=3)
    state.mech.limit_elem[:] = 2e-3  # some failures happen
    state.mech.limit_edge[:] = 2e-3
    return model, state


def _run_tiny(substeps=30):
    model, state = _failing_tiny()
    for _ in range(substeps):
        mechanics.substep(model, state, 1e-3)
    return state.mech


def test_advance_equals_substeps_that_gather_the_stiffness():
    """mechanics.advance keeps the gathered stiffness until a substep has failures; the state is
    bit for bit that of substeps which gather it every time."""
    model, state = _failing_tiny()
    a, b = state.copy(), state.copy()
    new = mechanics.advance(model, a, 30)
    for _ in range(30):
        mechanics.substep(model, b, model.mech.dt)
    assert new > 0 and a.mech.failures == b.mech.failures
    assert _digest(a.mech) == _digest(b.mech)


def test_same_result_with_one_or_two_threads():
    n0 = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        a = _run_tiny()
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        b = _run_tiny()
    finally:
        numba.set_num_threads(n0)
    assert a.failures > 0
    assert _digest(a) == _digest(b)


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


def test_coupling_equations():
    scene, model = sample("tiny")
    setup = model.mech
    state = initial_state(model, rods=True)
    ms = state.mech
    M_0 = scene.mechanics.M_0
    state.M[:] = M_0 - 0.1
    state.H_c[:] = 0.5
    state.H_l[:] = 1.0
    assert scene.moisture.M_1 == 1.0 and scene.moisture.M_2 == 0.1 and not scene.moisture.schedule
    coupling.step(model, state)
    np.testing.assert_allclose(ms.rest_length, setup.rest_length0 * (1 - 0.1 * scene.mechanics.s))  # Eq. 17
    mech = scene.mechanics
    dw = model.reg_dir_weights
    g_edge = mech.S * (mech.S_R * dw[:, 0] + mech.S_T * dw[:, 1]) + mech.s * dw[:, 2]
    np.testing.assert_allclose(ms.rest_offset, setup.offset0 * (1 - 0.1 * g_edge))  # Eq. 16
    expect_I = np.where(model.reg_theta == 1, 1 - mech.k_c * 0.5, 1.0)  # Eq. 21, H_l = 1
    np.testing.assert_allclose(ms.integrity, expect_I)
    f = ((M_0 - 0.1 - 0.1) / 0.9) ** mech.p_l_stretch  # Eq. 19
    # Eq. 21 on the strand link e, e + 1: theta = 1 where the two lie in different BSP leaves
    leaf, n = model.bsp_leaf, model.n_elements
    nxt = np.minimum(np.arange(n) + 1, n - 1)
    crosses = (leaf != leaf[nxt]) & ~np.isin(np.arange(n), model.element_offsets[1:] - 1)
    assert crosses.sum() > 100
    np.testing.assert_allclose(ms.limit_elem[:, 0], mech.L_0_stretch * f * np.where(crosses, 1 - mech.k_c * 0.5, 1.0))
    assert coupling.limit_factor(np.array(0.05), 1.0, 0.1, 4.0) == 0.0
    assert coupling.limit_factor(np.array(1.5), 1.0, 0.1, 4.0) == 1.0


def test_failure_flags_are_permanent_and_components_split():
    setup, ms = _perturbed(seed=5)
    ms.limit_elem[:] = np.inf
    ms.limit_edge[:] = np.inf
    # pull the two halves of the tiny log apart along x
    half = ms.x[:, 0] > np.median(ms.x[:, 0])
    ms.x[half, 0] += 0.05
    ms.limit_elem[:] = 0.5
    ms.limit_edge[:] = 0.5
    new = failure.update(setup, ms)
    assert new > 0 and ms.component.max() >= 1
    assert ms.component[0] == 0  # labels in order of the smallest element
    broken = (~ms.edge_ok).copy()
    ms.x[half, 0] -= 0.05  # closing the gap does not heal anything
    failure.update(setup, ms)
    assert np.all(~ms.edge_ok[broken])


def test_pair_strains_and_flags_equal_numpy_reference():
    """failure.pair_strains against its numpy twin; the fused flagging (which skips the atan2
    where a bound keeps an edge below its limit) flags exactly the edges whose strain beyond the
    reference exceeds the limit, with limits set within 1e-12 of the strains on either side."""
    setup, ms = _perturbed(seed=7)
    args = (setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest)
    pair = failure.pair_strains(*args)
    np.testing.assert_allclose(pair, failure.pair_strains_reference(*args), rtol=1e-10, atol=1e-13)
    rng = np.random.default_rng(2)
    ref = rng.uniform(-0.01, 0.01, pair.shape)
    limit = (pair - ref) * (1.0 + rng.choice([-1e-12, 1e-12], pair.shape))
    limit[rng.random(pair.shape) < 0.3] += 1.0  # far from failing: the atan2 is skipped
    ok = np.ones_like(ms.edge_ok)
    new = failure._flag_edges(*args, ref, limit, ok)
    over = pair - ref > limit
    np.testing.assert_array_equal(~ok[:, 0], over[:, 0])
    np.testing.assert_array_equal(ok[:, 1:], ~over[:, :1] & ~over[:, 1:])
    np.testing.assert_array_equal(new, np.where(over[:, 0], 2, np.where(over[:, 1:].any(axis=1), 1, 0)))
    assert 0 < over[:, 1].sum() < len(over)


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


def test_drift_is_the_largest_strain_change_over_the_limits():
    """failure.drift: |change| / limit over the constraints that can still fail (intact inner
    elements, intact edge flags, positive finite limits)."""
    setup = SimpleNamespace(inner=np.array([False, True, True, True]))
    ms = SimpleNamespace(element_ok=np.array([True, True, False, True]),
                         edge_ok=np.array([[True, True, False], [True, False, True]]))
    e0, k0 = np.zeros((4, 2)), np.zeros((2, 3))
    e1 = np.array([[9.0, 9.0], [0.1, -0.3], [9.0, 9.0], [0.0, 0.05]])  # element 0 not inner, 2 failed
    k1 = np.array([[0.2, -0.1, 9.0], [0.5, 9.0, 0.01]])  # flags (0, 2) and (1, 1) failed
    le = np.array([[1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [np.inf, 0.01]])
    lk = np.array([[0.1, 1.0, 1.0], [0.0, 1.0, 0.1]])  # a zero limit fails at any strain
    assert failure.drift(setup, ms, (e0, k0), (e1, k1), le, lk) == pytest.approx(5.0)  # element 3 shear
    le[3, 1] = 1.0
    assert failure.drift(setup, ms, (e0, k0), (e1, k1), le, lk) == pytest.approx(2.0)  # edge 0 bundle
    lk[0, 0] = 1.0
    assert failure.drift(setup, ms, (e0, k0), (e1, k1), le, lk) == pytest.approx(0.3)  # element 1 shear


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
