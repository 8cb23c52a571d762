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
    new = failure._flag_edges(*args, ref, limit, ok)
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
