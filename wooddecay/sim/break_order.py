"""Failure in order: which over-limit constraints break in one round of the implicit solver
(docs/decisions.md, "Failure in order").

Breaking every constraint over its limit at once, after a step that loaded them all, breaks the
neighbours a first break would have relieved: a honeycomb of small cracks instead of a few that
shield each other (woodstock §5.3). In each round (:func:`wooddecay.sim.implicit.macro_step`)
the constraint furthest over its limit breaks, and every other one within SHIELD connection
lengths of it waits for the re-solve (warm-started from the state the round found), which
judges it on the state the break leaves; farther on, the next furthest over its limit breaks,
and so on: a greedy suppression in order of (strain - reference) / limit, serial and so
deterministic. Separation by decay (I below I_fail, a crumbled element) is not a stress and
shields nothing: it all goes in the first round. The kernels of :mod:`~wooddecay.sim.failure`
flag what this selects (:func:`wooddecay.sim.failure.update` on the selection), so a selected
constraint fails by the same test as in the XPBD solver.
"""
from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np
from scipy.spatial import cKDTree

from . import failure
from .mechanics import MechSetup, MechState

#: radius, in median REG connection rest lengths, within which a break holds back the others
SHIELD = 2.0


def _over(strain: np.ndarray, limit: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: whether an intact column is over its limit, and the largest strain / limit of
    those (inf at a zero limit)."""
    over = ok & (strain > limit)
    ratio = np.where(over, strain / np.where(limit > 0.0, limit, 1.0), 0.0)
    ratio = np.where(over & (limit <= 0.0), np.inf, ratio)
    return over.any(axis=1), ratio.max(axis=1, initial=0.0)


class Judged(NamedTuple):
    """What :func:`wooddecay.sim.failure.update` would flag now, as masks, and how far over."""

    over_e: np.ndarray  # (n,) bool: element over a limit (and free to cut its strand)
    ratio_e: np.ndarray  # (n,) largest (strain - reference) / limit of its columns over
    over_k: np.ndarray  # (m,) bool: REG edge with an intact flag over its limit
    ratio_k: np.ndarray  # (m,)
    decay_e: np.ndarray  # (n,) bool: element separating by decay (crumbled, link below I_fail)
    decay_k: np.ndarray  # (m,) bool: connection below I_fail


def judge(setup: MechSetup, ms: MechState) -> Judged:
    """The :class:`Judged` of the current state (the tests of :mod:`~wooddecay.sim.failure`)."""
    ok = ms.element_ok
    can_cut = ok & setup.inner & np.roll(ok, 1) & np.roll(ok, -1)
    elem, edge = failure.strains(setup, ms)
    over_e, ratio_e = _over(elem - ms.strain_ref_elem, ms.limit_elem, np.repeat(can_cut[:, None], 2, axis=1))
    over_k, ratio_k = _over(edge - ms.strain_ref_edge, ms.limit_edge, ms.edge_ok)
    decay_e = ok & (ms.crumbled | (can_cut & (ms.link_integrity < setup.I_fail_elem)))
    decay_k = ms.edge_ok[:, 0] & (ms.integrity < setup.I_fail_edge)
    return Judged(over_e & ~decay_e, ratio_e, over_k & ~decay_k, ratio_k, decay_e, decay_k)


@nb.njit(cache=True)
def _suppress(order, ptr, neighbours):
    """Greedy suppression: walk ``order``; keep a candidate no kept one is a neighbour of (CSR
    ``ptr``, ``neighbours``), and hold back its neighbours. Serial: the order decides."""
    kept = np.zeros(len(order), dtype=np.bool_)
    held = np.zeros(len(order), dtype=np.bool_)
    for t in range(len(order)):
        c = order[t]
        if held[c]:
            continue
        kept[c] = True
        for s in range(ptr[c], ptr[c + 1]):
            held[neighbours[s]] = True
    return kept


def select(setup: MechSetup, ms: MechState) -> tuple[np.ndarray, np.ndarray]:
    """This round's (elements, edges) to test, increasing (module docstring)."""
    j = judge(setup, ms)
    centre = 0.5 * (ms.x[setup.fp] + ms.x[setup.fp + 1])
    e, k = np.flatnonzero(j.over_e), np.flatnonzero(j.over_k)
    where = np.concatenate([centre[e], 0.5 * (centre[setup.edges[k, 0]] + centre[setup.edges[k, 1]])])
    ratio = np.concatenate([j.ratio_e[e], j.ratio_k[k]])
    radius = SHIELD * float(np.median(setup.offset0)) if len(setup.offset0) else 0.0
    pairs = cKDTree(where).query_pairs(radius, output_type="ndarray") if len(where) > 1 else np.zeros((0, 2), int)
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.lexsort((both[:, 1], both[:, 0]))]
    ptr = np.searchsorted(both[:, 0], np.arange(len(where) + 1))
    kept = _suppress(np.argsort(-ratio, kind="stable"), ptr, both[:, 1].astype(np.int64))
    elements = np.union1d(e[kept[:len(e)]], np.flatnonzero(j.decay_e))
    edges = np.union1d(k[kept[len(e):]], np.flatnonzero(j.decay_k))
    return elements.astype(np.int64), edges.astype(np.int64)
