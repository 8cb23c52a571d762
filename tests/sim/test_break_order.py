"""Failure in order (wooddecay.sim.break_order): a round breaks the constraint furthest over its
limit in each neighbourhood, holds back the rest near it, and lets decay separate everything."""
import numpy as np
from scipy.spatial import cKDTree

from wooddecay.sim import break_order, failure

from .helpers import failing_tiny


def _places(setup, ms, elements, edges):
    centre = 0.5 * (ms.x[setup.fp] + ms.x[setup.fp + 1])
    return np.concatenate([centre[elements], 0.5 * (centre[setup.edges[edges, 0]] + centre[setup.edges[edges, 1]])])


def test_a_round_breaks_the_worst_of_each_neighbourhood_and_holds_back_the_rest():
    model, state = failing_tiny()
    setup, ms = model.mech, state.mech
    j = break_order.judge(setup, ms)
    e, k = np.flatnonzero(j.over_e), np.flatnonzero(j.over_k)
    assert len(e) + len(k) > 20  # the jostled tiny log with low limits: many over at once
    sel_e, sel_k = break_order.select(setup, ms)
    kept_e, kept_k = np.intersect1d(sel_e, e), np.intersect1d(sel_k, k)
    assert 0 < len(kept_e) + len(kept_k) < len(e) + len(k)
    ratio = np.concatenate([j.ratio_e[e], j.ratio_k[k]])
    kept = np.concatenate([np.isin(e, kept_e), np.isin(k, kept_k)])
    assert kept[np.argmax(ratio)]  # the furthest over its limit breaks
    where = _places(setup, ms, e, k)
    radius = break_order.SHIELD * np.median(setup.offset0)
    tree = cKDTree(where[kept])
    assert not tree.query_pairs(0.999 * radius)  # no two breaks of a round shield each other
    for c in np.flatnonzero(~kept):  # each one held back is near a break at least as far over
        near = tree.query_ball_point(where[c], radius * 1.001)
        assert near and ratio[kept][near].max() >= ratio[c]
    # what is selected fails by failure's own test, and nothing else does
    before_e, before_k = ms.element_ok.copy(), ms.edge_ok.copy()
    count = failure.update(setup, ms, tested=(sel_e, sel_k))
    assert count == len(kept_e) + np.count_nonzero((before_k != ms.edge_ok).any(axis=1))
    assert set(np.flatnonzero(before_e != ms.element_ok)) == set(kept_e)
    assert set(np.flatnonzero((before_k != ms.edge_ok).any(axis=1))) == set(kept_k)


def test_decay_separates_everything_it_reaches_in_the_first_round():
    model, state = failing_tiny()
    setup, ms = model.mech, state.mech
    ms.integrity[::7] = 0.0  # below I_fail: separate by decay
    sel_e, sel_k = break_order.select(setup, ms)
    decayed = np.flatnonzero(ms.edge_ok[:, 0] & (ms.integrity < setup.I_fail_edge))
    assert len(decayed) and np.isin(decayed, sel_k).all()
