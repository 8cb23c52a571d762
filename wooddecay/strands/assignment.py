"""Minimum-displacement assignment of carried strands to lattice sites.

Used by :mod:`wooddecay.strands.packing`: each carried strand takes a site so that the summed
squared displacement is minimal. A shortest-augmenting-path solver (the method of scipy's dense
``linear_sum_assignment``) runs on each goal's k nearest sites; its dual variables then certify
optimality against all pairs, and k doubles (finally the dense solver) when they do not. The
result is always the exact optimum and deterministic (docs/decisions.md).
"""
from __future__ import annotations

import heapq

import numba as nb
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

#: candidate sites per goal in the sparse assignment (doubled until provably enough)
ASSIGN_CANDIDATES = 16
#: largest share of the sites a goal's candidates may be before the assignment goes dense
MAX_CANDIDATE_SHARE = 0.25


@nb.njit(cache=True)
def _shortest_augmenting_path(cur, cols, cost, u, v, row4col, dist, path, done, touched):
    """Dijkstra from row ``cur`` over the candidate pairs (reduced costs ``cost - u - v``) to
    the nearest free column, recording each column's distance and predecessor row.

    Returns ``(sink, its distance, number of columns touched)``; sink is -1 when no free column
    can be reached (no full matching).
    """
    heap = [(0.0, np.int64(0))]
    heap.pop()
    n_touched, i, min_val = 0, cur, 0.0
    while True:
        for e in range(cols.shape[1]):
            j = cols[i, e]
            r = min_val + cost[i, e] - u[i] - v[j]
            if not done[j] and r < dist[j]:
                if dist[j] == np.inf:
                    touched[n_touched] = j
                    n_touched += 1
                dist[j], path[j] = r, i
                heapq.heappush(heap, (r, j))
        j = -1
        while heap and j < 0:
            d, jj = heapq.heappop(heap)
            if not done[jj] and d == dist[jj]:
                j = jj
        if j < 0:
            return -1, min_val, n_touched
        done[j], min_val = True, dist[j]
        if row4col[j] < 0:
            return j, min_val, n_touched
        i = row4col[j]


@nb.njit(cache=True)
def _augment(cur, sink, min_val, touched, u, v, col4row, row4col, dist, path, done):
    """Update the duals after the search from row ``cur``, flip the path ending at ``sink``
    and reset the search arrays of the ``touched`` columns."""
    u[cur] += min_val
    for j in touched:
        if done[j]:
            v[j] -= min_val - dist[j]
            if j != sink:
                u[row4col[j]] += min_val - dist[j]
    j = sink
    while True:
        i = path[j]
        row4col[j] = i
        col4row[i], j = j, col4row[i]
        if i == cur:
            break
    for j in touched:
        dist[j], path[j], done[j] = np.inf, -1, False


@nb.njit(cache=True)
def _sparse_lap(cols, cost, n_sites):
    """Minimum-cost assignment of every row to a distinct column among its candidates
    ``cols[i]`` (costs ``cost[i]``), rows <= columns.

    Successive shortest augmenting paths: Crouse's algorithm (the one behind scipy's dense
    linear_sum_assignment) with a heap over the candidate pairs only. Returns ``(col4row, u,
    v)`` with duals u (rows) and v (columns, <= 0, < 0 only on matched columns) such that
    ``cost - u - v`` is >= 0 on every candidate pair and 0 on the matched ones; ``col4row`` is
    empty when no full matching exists.
    """
    n = cols.shape[0]
    u, v = np.zeros(n), np.zeros(n_sites)
    col4row = np.full(n, -1, np.int64)
    row4col = np.full(n_sites, -1, np.int64)
    dist = np.full(n_sites, np.inf)
    path = np.full(n_sites, -1, np.int64)
    done = np.zeros(n_sites, np.bool_)
    touched = np.empty(n_sites, np.int64)
    for cur in range(n):
        sink, min_val, n_touched = _shortest_augmenting_path(cur, cols, cost, u, v, row4col, dist, path,
                                                             done, touched)
        if sink < 0:
            return col4row[:0], u, v
        _augment(cur, sink, min_val, touched[:n_touched], u, v, col4row, row4col, dist, path, done)
    return col4row, u, v


@nb.njit(cache=True)
def _duals_feasible(goal, sites, u, v, tol):
    """Whether ``|goal_i - site_j|^2 - u_i - v_j >= -tol`` for every pair, candidate or not:
    then the assignment meeting these duals is optimal over all pairs (LP duality).
    O(goals x sites) time, no memory."""
    for i in range(len(goal)):
        for j in range(len(sites)):
            dx, dy = goal[i, 0] - sites[j, 0], goal[i, 1] - sites[j, 1]
            if dx * dx + dy * dy - u[i] - v[j] < -tol:
                return False
    return True


def _sparse_assignment(goal: np.ndarray, sites: np.ndarray, k: int) -> np.ndarray | None:
    """Minimum-cost assignment restricted to each goal's ``k`` nearest sites; None unless it
    is a full matching that its duals prove optimal over all pairs."""
    dist, cols = cKDTree(sites).query(goal, k=k)
    cols = cols.reshape(len(goal), k).astype(np.int64)
    if len(np.unique(cols)) < len(goal):  # fewer candidate sites than goals: no full matching
        return None
    cost = dist.reshape(len(goal), k) ** 2
    col4row, u, v = _sparse_lap(cols, cost, len(sites))
    if len(col4row) < len(goal) or not _duals_feasible(goal, sites, u, v, 1e-9 * cost.max()):
        return None
    return col4row


def assign_sites(goal: np.ndarray, sites: np.ndarray) -> np.ndarray:
    """Site index for each goal position minimising the summed squared displacement
    (``len(goal) <= len(sites)``).

    Sparse first: each goal may take one of its ``ASSIGN_CANDIDATES`` nearest sites
    (:func:`_sparse_lap`), doubling the candidates until the result is provably optimal; once
    they would exceed ``MAX_CANDIDATE_SHARE`` of the sites, scipy's dense linear_sum_assignment.
    Deterministic.
    """
    k = ASSIGN_CANDIDATES
    while len(goal) and k <= MAX_CANDIDATE_SHARE * len(sites):
        site_of = _sparse_assignment(goal, sites, k)
        if site_of is not None:
            return site_of
        k *= 2
    cost = ((goal[:, None, :] - sites[None, :, :]) ** 2).sum(-1)
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(len(goal), dtype=np.int64)
    out[rows] = cols
    return out
