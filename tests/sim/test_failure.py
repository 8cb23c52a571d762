"""Failure (wooddecay.sim.failure, woodstock §5.3): permanent flags, components, pair strains
against their numpy twin, the strain drift."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from wooddecay.quaternion import conj_np, mul_np, normalize_np, rotate_np
from wooddecay.sim import failure

from .helpers import perturbed

def test_failure_flags_are_permanent_and_components_split():
    setup, ms = perturbed(seed=5)
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


@pytest.mark.parametrize("fraction", [0.0, 0.3, 0.7, 1.0])
def test_components_equal_scipy_reference(fraction):
    """The union-find labels equal scipy's connected components, label for label, with a
    fraction of the elements and REG connections failed at random (0: one piece; 1: every
    element alone but for its strand links)."""
    setup, ms = perturbed(seed=3)
    rng = np.random.default_rng(int(10 * fraction))
    ms.element_ok[rng.random(len(ms.element_ok)) < fraction] = False
    ms.edge_ok[rng.random(len(ms.edge_ok)) < fraction, 0] = False
    label = failure.components(setup, ms)
    np.testing.assert_array_equal(label, failure.components_reference(setup, ms))
    assert label.dtype == np.int64
    if fraction in (0.0, 1.0):
        assert (label.max() > 0) == (fraction == 1.0)


def test_pair_strains_and_flags_equal_numpy_reference():
    """failure.pair_strains against its numpy twin; the fused flagging (which skips the atan2
    where a bound keeps an edge below its limit) flags exactly the edges whose strain beyond the
    reference exceeds the limit, with limits set within 1e-12 of the strains on either side."""
    setup, ms = perturbed(seed=7)
    args = (setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest)
    pair = failure.pair_strains(*args)
    np.testing.assert_allclose(pair, failure.pair_strains_reference(*args), rtol=1e-10, atol=1e-13)
    rng = np.random.default_rng(2)
    ref = rng.uniform(-0.01, 0.01, pair.shape)
    limit = (pair - ref) * (1.0 + rng.choice([-1e-12, 1e-12], pair.shape))
    limit[rng.random(pair.shape) < 0.3] += 1.0  # far from failing: the atan2 is skipped
    ok = np.ones_like(ms.edge_ok)
    m = len(ok)
    new = failure._flag_edges(np.arange(m), *args, ref, limit, np.ones(m), np.zeros(m), ok)
    over = pair - ref > limit
    np.testing.assert_array_equal(~ok[:, 0], over[:, 0])
    np.testing.assert_array_equal(ok[:, 1:], ~over[:, :1] & ~over[:, 1:])
    np.testing.assert_array_equal(new, np.where(over[:, 0], 2, np.where(over[:, 1:].any(axis=1), 1, 0)))
    assert 0 < over[:, 1].sum() < len(over)


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


@pytest.mark.parametrize("fungus", ["brown", "white"])
def test_decay_below_I_fail_separates_bsp_blocks_or_frays(fungus):
    """Separation from decay (woodstock §7.1, Eq. 21): carbohydrate loss (brown rot) takes the
    integrity of the pairs and strand links across BSP cells below I_fail and leaves every cell
    one piece; lignin loss (white rot) does so inside the cells as well, down to loose strand
    pieces. No strain is involved (limits infinite). The cells are elongated 3x along the grain
    (samples/log.toml) so that each spans more than one element: an element cuts only one of two
    consecutive strand links."""
    import wooddecay as wd
    from wooddecay.sim import coupling
    from wooddecay.sim.state import initial_state

    from ..conftest import SAMPLES

    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", {"bsp.elongation": 3.0}))
    state = initial_state(model, rods=True)
    field = "H_c" if fungus == "brown" else "H_l"
    setattr(state, field, np.full(model.n_elements, 0.1))
    coupling.step(model, state)
    ms = state.mech
    ms.limit_elem[:] = np.inf
    ms.limit_edge[:] = np.inf
    assert failure.update(model.mech, ms) > 0
    leaf, piece = model.bsp_leaf, ms.component
    same_leaf = leaf[model.reg_edges[:, 0]] == leaf[model.reg_edges[:, 1]]
    if fungus == "brown":
        # every broken connection crosses a cell boundary, every intact one inside a cell holds
        assert ms.edge_ok[same_leaf, 0].all() and not ms.edge_ok[~same_leaf, 0].any()
        pure = np.array([np.bincount(leaf[piece == p]).max() / np.sum(piece == p) for p in np.unique(piece)])
        assert piece.max() + 1 >= len(np.unique(leaf)) and np.quantile(pure, 0.25) == 1.0
    else:
        assert not ms.edge_ok[:, 0].any()
        assert piece.max() + 1 > 2 * len(np.unique(leaf))


def _turn(rho, i, j):
    """The angle of conj(rho_i) rho_j."""
    p = mul_np(conj_np(rho[i]), rho[j])
    return 2.0 * np.arctan2(np.linalg.norm(p[:, 1:], axis=1), np.abs(p[:, 0]))


def test_motion_bounds_the_pair_strain_change():
    """The bounds :func:`failure._flag_moved_edges` skips edges by: after random moves and turns
    of every element, each edge's bundle strain changed by at most |delta_j - delta_i| / its
    length and, within the angles where it is used, its bend and twist angles by at most
    LOG_LIPSCHITZ times the angle of conj(rho_i) rho_j (:func:`failure._motion`); wood shifted and
    turned as a whole turns no edge and moves its ends only by the turn of their offset; and they
    are tight enough to skip nearly every edge of wood that moves by microns."""
    setup, ms = perturbed(seed=11)
    args = (setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest)
    before, x0, q0 = failure.pair_strains(*args), ms.x.copy(), ms.q.copy()
    past = failure.epoch(setup, ms)
    rng = np.random.default_rng(4)
    i, j = setup.edges[:, 0], setup.edges[:, 1]
    n = setup.n_elements
    delta, rho, size = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 2))
    for scale, turn, share in ((1e-3, 0.01, 0.5), (1e-6, 1e-6, 0.99)):
        ms.x[:] = x0 + rng.normal(scale=scale, size=ms.x.shape)
        ms.q[:] = normalize_np(q0 + rng.normal(scale=turn, size=ms.q.shape))
        failure._motion(setup.fp, ms.x, ms.q, past.c0, past.q0, delta, rho, size)
        after = failure.pair_strains(*args)
        moved = np.linalg.norm(delta[j] - delta[i], axis=1) / setup.edge_length
        assert np.all(np.abs(after[:, 0] - before[:, 0]) <= moved + 1e-15)
        assert np.all(moved <= (size[i, 0] + size[j, 0]) / setup.edge_length + 1e-15)
        angle = _turn(rho, i, j)
        assert np.all(angle <= size[i, 1] + size[j, 1] + 1e-15)
        within = (before[:, 1:].max(axis=1) < failure.EPOCH_ANGLE) & (angle <= failure.MOVE_ANGLE)
        assert within.mean() > share
        bound = failure.LOG_LIPSCHITZ * angle[within, None]
        assert np.all(np.abs(after[within, 1:] - before[within, 1:]) <= bound + 1e-15)
    assert np.mean(moved < 1e-3) > 0.99
    # a rigid motion: a turn by 0.3 rad about a random axis and a shift by 5 cm
    axis = rng.normal(size=3)
    spin = np.concatenate([[np.cos(0.15)], np.sin(0.15) * axis / np.linalg.norm(axis)])
    ms.x[:] = rotate_np(np.broadcast_to(spin, (len(x0), 4)), x0) + 0.05
    ms.q[:] = mul_np(np.broadcast_to(spin, q0.shape), q0)
    failure._motion(setup.fp, ms.x, ms.q, past.c0, past.q0, delta, rho, size)
    c = 0.5 * (x0[setup.fp] + x0[setup.fp + 1])
    offset = np.linalg.norm(c[j] - c[i], axis=1)
    assert np.all(np.linalg.norm(delta[j] - delta[i], axis=1) <= 2.0 * np.sin(0.15) * offset * (1 + 1e-9) + 1e-15)
    assert np.all(_turn(rho, i, j) < 1e-7)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_moved_edges_flag_as_the_exact_test(seed):
    """After an epoch, :func:`failure._flag_moved_edges` flags exactly the edges
    :func:`failure._flag_edges` flags, with limits set within 1e-12 of the moved strains on either
    side for a third of the edges and far for the rest (so both the skip and the test are taken)."""
    setup, ms = perturbed(seed=seed)
    args = (setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest)
    rng = np.random.default_rng(seed)
    m = len(setup.edges)
    ms.strain_ref_edge = rng.uniform(-0.01, 0.01, (m, 3))
    ms.limit_edge = np.full((m, 3), 1.0)
    x0, q0 = ms.x.copy(), ms.q.copy()
    x1 = x0 + rng.normal(scale=1e-4, size=ms.x.shape)
    q1 = normalize_np(q0 + rng.normal(scale=1e-3, size=ms.q.shape))
    ms.x[:], ms.q[:] = x1, q1
    near = rng.random(m) < 1 / 3
    edge = (failure.pair_strains(*args) - ms.strain_ref_edge) * (1.0 + rng.choice([-1e-12, 1e-12], (m, 3)))
    ms.limit_edge[near] = edge[near]
    ms.x[:], ms.q[:] = x0, q0
    past = failure.epoch(setup, ms)
    ms.x[:], ms.q[:] = x1, q1
    n = setup.n_elements
    delta, rho, size = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 2))
    failure._motion(setup.fp, ms.x, ms.q, past.c0, past.q0, delta, rho, size)
    common = (ms.strain_ref_edge, ms.limit_edge, np.ones(m), np.zeros(m))
    ok_exact, ok_moved = np.ones_like(ms.edge_ok), np.ones_like(ms.edge_ok)
    new_exact = failure._flag_edges(np.arange(m), *args, *common, ok_exact)
    new_moved = failure._flag_moved_edges(np.arange(m), *args, *common, ok_moved, delta, rho, size, past.margin_b,
                                          past.margin_a, past.round_off)
    np.testing.assert_array_equal(new_moved, new_exact)
    np.testing.assert_array_equal(ok_moved, ok_exact)
    assert 0 < np.count_nonzero(new_exact) <= near.sum()


@pytest.mark.parametrize("origin", [4.5, 30.0, 100.0])
def test_moved_edges_flag_as_the_exact_test_far_from_the_origin(origin):
    """Far from the origin the exact test's bundle length rounds at the coordinates' scale: two
    elements one 4.5 mm edge apart whose particles move by a few units in the last place, with the
    limit between the epoch's strain and the moved one, flag alike in both tests (without the
    epoch's round_off a skipped edge flagged in 22 of 20,000 such trials 100 m out)."""
    rng = np.random.default_rng(int(origin))
    fp, edges, L = np.array([0, 2]), np.array([[0, 1]]), 4.5e-3
    q, rest = np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)), np.array([[1.0, 0.0, 0.0, 0.0]])
    setup = SimpleNamespace(fp=fp, edges=edges, edge_length=np.array([L]), edge_rest=rest)
    tried = 0
    for _ in range(3000):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        base = origin * np.array([1.0, 0.7, 0.3]) + rng.uniform(-0.01, 0.01, 3)
        x0 = np.array([base - 0.3 * L * d, base + 0.3 * L * d, base + 0.7 * L * d, base + 1.3 * L * d])
        x1 = x0 + rng.integers(-2, 3, x0.shape) * np.spacing(x0)
        offset = np.array([np.linalg.norm(0.5 * (x0[2] + x0[3] - x0[0] - x0[1]))])
        b0, b1 = (failure._pair_bundle(0, edges, fp, x, offset, setup.edge_length) for x in (x0, x1))
        if b1 <= b0:
            continue
        tried += 1
        ms = SimpleNamespace(x=x0, q=q, rest_offset=offset, strain_ref_edge=np.zeros((1, 3)),
                             limit_edge=np.array([[0.5 * (b0 + b1), 1.0, 1.0]]), edge_ok=np.ones((1, 3), bool))
        past = failure.epoch(setup, ms)
        delta, rho, size = np.empty((2, 3)), np.empty((2, 4)), np.empty((2, 2))
        failure._motion(fp, x1, q, past.c0, past.q0, delta, rho, size)
        args = (np.arange(1), edges, fp, x1, q, offset, setup.edge_length, rest, ms.strain_ref_edge, ms.limit_edge,
                np.ones(1), np.zeros(1))
        exact = failure._flag_edges(*args, np.ones((1, 3), bool))
        moved = failure._flag_moved_edges(*args, np.ones((1, 3), bool), delta, rho, size, past.margin_b,
                                          past.margin_a, past.round_off)
        assert exact[0] == 2 and moved[0] == 2
    assert tried > 500
