"""Broad phase (woodstock §5.4, Eq. 3): candidate pairs against the cKDTree reference and brute
force, strands sharing particles, crowded buckets, trivial inputs."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.sim import contact as C

from .helpers import _segment_soup


def _chains(seed, n_strands=40, n_seg=15):
    """Strands (chains sharing particles) of random components crossing a small box."""
    rng = np.random.default_rng(seed)
    xs = []
    for _ in range(n_strands):
        start, step = rng.random(3) * 0.3, rng.normal(size=3)
        xs.append(start + np.outer(np.arange(n_seg + 1), 0.02 * step / np.linalg.norm(step)))
    x = np.concatenate(xs)
    fp = (np.arange(n_strands)[:, None] * (n_seg + 1) + np.arange(n_seg)).ravel().astype(np.int64)
    comp = np.repeat(rng.integers(0, 4, n_strands), n_seg).astype(np.int64)
    comp[5:9] = 7  # a strand split into components: neighbours sharing a particle are no pair
    return x, fp, np.full(len(fp), 0.012), comp


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("margin", [0.0, 0.01])
def test_candidate_pairs_match_reference(seed, margin):
    x, fp, r, comp = _segment_soup(seed)
    got = C.candidate_pairs(x, fp, r, comp, margin)
    ref = C.candidate_pairs_reference(x, fp, r, comp, margin)
    assert len(ref) > 100
    assert got.dtype == np.int64 and got.shape[1] == 2
    assert np.array_equal(got, ref)
    # brute force on every pair
    i, j = np.triu_indices(len(fp), 1)
    keep = comp[i] != comp[j]
    i, j = i[keep], j[keep]
    s, t = C.closest_segment_segment_reference(x[fp[i]], x[fp[i] + 1], x[fp[j]], x[fp[j] + 1])
    d = x[fp[j]] + t[:, None] * (x[fp[j] + 1] - x[fp[j]]) - x[fp[i]] - s[:, None] * (x[fp[i] + 1] - x[fp[i]])
    lim = r[i] + r[j] + margin
    hit = np.einsum("ij,ij->i", d, d) < lim * lim
    assert np.array_equal(got, np.stack([i[hit], j[hit]], axis=1))


def test_candidate_pairs_chains_skip_shared_particles():
    x, fp, r, comp = _chains(3)
    got = C.candidate_pairs(x, fp, r, comp, 0.005)
    assert np.array_equal(got, C.candidate_pairs_reference(x, fp, r, comp, 0.005))
    assert len(got) > 0
    assert np.all(np.abs(fp[got[:, 0]] - fp[got[:, 1]]) > 1)
    assert np.all(comp[got[:, 0]] != comp[got[:, 1]])
    assert np.all(got[:, 0] < got[:, 1])
    assert np.array_equal(got, got[np.lexsort((got[:, 1], got[:, 0]))])


def test_candidate_pairs_crowded():
    """Long segments in a small box: crowded buckets and rows, most elements with more than KEPT
    partners (the fill pass searches again)."""
    rng = np.random.default_rng(7)
    p = rng.random((1500, 3)) * 0.05
    x = np.stack([p, p + rng.normal(size=(1500, 3)) * 0.1], axis=1).reshape(-1, 3)
    fp, r, comp = np.arange(0, 3000, 2), np.full(1500, 0.001), rng.integers(0, 3, 1500)
    got = C.candidate_pairs(x, fp, r, comp, 0.0)
    assert np.bincount(got[:, 0], minlength=1500).max() > 4 * C.KEPT
    assert np.array_equal(got, C.candidate_pairs_reference(x, fp, r, comp, 0.0))


def test_candidate_pairs_of_active_elements():
    """With ``active`` the pairs are those of the active elements in the full list, however long
    the inactive segments are (a failed element spans two pieces)."""
    x, fp, r, comp = _chains(4)
    active = np.random.default_rng(4).random(len(fp)) > 0.3
    for e in np.flatnonzero(~active)[:3]:  # a few inactive segments metres long: their strands' tails move away
        x[fp[e] + 1:(fp[e] // 16 + 1) * 16] += 5.0
    full = C.candidate_pairs(x, fp, r, comp, 0.005)
    got = C.candidate_pairs(x, fp, r, comp, 0.005, active=active)
    assert len(got) > 0 and np.array_equal(got, full[active[full[:, 0]] & active[full[:, 1]]])


def test_candidate_pairs_trivial_inputs():
    x, fp, r, comp = _segment_soup(0, n_seg=50)
    assert C.candidate_pairs(x, fp, r, np.zeros(50, dtype=np.int64), 0.1).shape == (0, 2)
    assert C.candidate_pairs(x, fp[:1], r[:1], comp[:1], 0.1).shape == (0, 2)
    X = np.zeros((4, 3))
    assert C.candidate_pairs(X, np.array([0, 2]), np.zeros(2), np.array([0, 1]), 0.0).shape == (0, 2)
