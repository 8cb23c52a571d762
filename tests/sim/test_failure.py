"""Failure (wooddecay.sim.failure, woodstock §5.3): permanent flags, components, pair strains
against their numpy twin, the strain drift."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

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
