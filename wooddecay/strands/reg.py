"""The rod element graph (REG) and the transport graph.

Woodstock §3, §5 (opening), Fig. 3c; docs/model.md §2. An REG edge joins two elements of different
strands whose segments come within ``connect_radius`` of each other (the minimum distance between
the two segments, the proximity construction of Macklin et al. 2016). Per edge: the rest offset
dp_0 = |c_i - c_j| (Eq. 2), the rest Darboux quaternion conj(q_i) q_j, and the squared components
of the edge direction in the wood frame (n_r^2, n_t^2, n_l^2), averaged over the two ends.
The transport graph used by the biology is the strand chains (links between consecutive
elements of a strand) plus every cross-strand pair within ``transport_reach * r_s``, a superset of
the REG (docs/decisions.md: a hex ring alone cannot carry anisotropic diffusion with positive
weights).

The search is a numba kernel over a uniform hash grid (cell = connect_radius + longest element):
two passes (count, then fill) over elements in parallel, each element writing only its own rows,
so the result is race-free and identical for any thread count. ``segment_pairs_reference`` is the
plain scipy/numpy version the tests compare against.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from scipy.spatial import cKDTree


@nb.njit(cache=True, inline="always")
def _clamp01(x):
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


@nb.njit(cache=True)
def segment_distance(p1, q1, p2, q2):
    """Minimum distance between segments p1q1 and p2q2 (Ericson, Real-Time Collision
    Detection §5.1.9, degenerate segments handled). Scalar arithmetic: no allocation."""
    d1x, d1y, d1z = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d2x, d2y, d2z = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    rx, ry, rz = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-30
    if a <= eps and e <= eps:
        s = 0.0
        t = 0.0
    elif a <= eps:
        s = 0.0
        t = _clamp01(f / e)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            t = 0.0
            s = _clamp01(-c / a)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            den = a * e - b * b
            s = _clamp01((b * f - c * e) / den) if den > eps * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = _clamp01(-c / a)
            elif t > 1.0:
                t = 1.0
                s = _clamp01((b - c) / a)
    dx = rx + d1x * s - d2x * t
    dy = ry + d1y * s - d2y * t
    dz = rz + d1z * s - d2z * t
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def segment_distance_reference(p1, q1, p2, q2):
    """Vectorised numpy version of :func:`segment_distance` (rows are segment pairs)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    den = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(den > 1e-30 * a * e, np.clip((b * f - c * e) / den, 0, 1), 0.0)
        t = (b * s + f) / e
        s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
        t = np.clip(t, 0, 1)
    diff = (p1 + d1 * s[:, None]) - (p2 + d2 * t[:, None])
    return np.linalg.norm(diff, axis=1)


def edge_between(reg_edges: np.ndarray, n_elements: int, a: np.ndarray, b: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The REG edge joining elements ``a[k]`` and ``b[k]`` (either order) and whether there is
    one (where not, the edge id is meaningless)."""
    if not len(reg_edges):
        return np.zeros(len(a), dtype=np.int64), np.zeros(len(a), dtype=bool)
    keys = np.minimum(reg_edges[:, 0], reg_edges[:, 1]) * n_elements + np.maximum(reg_edges[:, 0], reg_edges[:, 1])
    order = np.argsort(keys)
    sorted_keys = keys[order]
    q = np.minimum(a, b) * n_elements + np.maximum(a, b)
    pos = np.clip(np.searchsorted(sorted_keys, q), 0, len(keys) - 1)
    return order[pos], sorted_keys[pos] == q


@nb.njit(cache=True)
def _cell_range(keys, key):
    lo = np.searchsorted(keys, key, side="left")
    hi = np.searchsorted(keys, key, side="right")
    return lo, hi


@nb.njit(parallel=True, cache=True)
def _pairs_pass(pa, pb, center, half, strand, cell, order, keys, dims, radius, counts, out, fill):
    """One pass of the grid search: count (fill=False) or write (fill=True) j > i neighbours.

    Segments within ``radius`` have centres within radius + half_i + half_j: that cheap test
    runs before the exact segment distance."""
    n = len(pa)
    for i in nb.prange(n):
        k = 0
        base = counts[i] if fill else 0
        cx, cy, cz = cell[i, 0], cell[i, 1], cell[i, 2]
        for ox in range(-1, 2):
            x = cx + ox
            if x < 0 or x >= dims[0]:
                continue
            for oy in range(-1, 2):
                y = cy + oy
                if y < 0 or y >= dims[1]:
                    continue
                for oz in range(-1, 2):
                    z = cz + oz
                    if z < 0 or z >= dims[2]:
                        continue
                    lo, hi = _cell_range(keys, (x * dims[1] + y) * dims[2] + z)
                    for m in range(lo, hi):
                        j = order[m]
                        if j <= i or strand[j] == strand[i]:
                            continue
                        reach = radius + half[i] + half[j]
                        dx = center[j, 0] - center[i, 0]
                        dy = center[j, 1] - center[i, 1]
                        dz = center[j, 2] - center[i, 2]
                        if dx * dx + dy * dy + dz * dz > reach * reach:
                            continue
                        if segment_distance(pa[i], pb[i], pa[j], pb[j]) <= radius:
                            if fill:
                                out[base + k] = j
                            k += 1
        if not fill:
            counts[i] = k


@nb.njit(parallel=True, cache=True)
def pair_distances(pa, pb, i, j):
    """Segment distance of each pair (i[k], j[k]) (the same arithmetic as the search)."""
    out = np.empty(len(i))
    for k in nb.prange(len(i)):
        out[k] = segment_distance(pa[i[k]], pb[i[k]], pa[j[k]], pb[j[k]])
    return out


def segment_pairs(pa, pb, strand, radius):
    """(m, 2) sorted pairs i < j of segments of different strands within ``radius``."""
    n = len(pa)
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    centers = 0.5 * (pa + pb)
    half = 0.5 * np.linalg.norm(pb - pa, axis=1)
    h = radius + 2.0 * float(half.max())
    lo = centers.min(axis=0)
    cell = np.floor((centers - lo) / h).astype(np.int64)
    dims = cell.max(axis=0) + 1
    key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    order = np.argsort(key, kind="stable")
    keys = key[order]
    counts = np.zeros(n, dtype=np.int64)
    dummy = np.zeros(0, dtype=np.int64)
    _pairs_pass(pa, pb, centers, half, strand, cell, order, keys, dims, radius, counts, dummy, False)
    starts = np.concatenate([[0], np.cumsum(counts)])
    out = np.empty(starts[-1], dtype=np.int64)
    _pairs_pass(pa, pb, centers, half, strand, cell, order, keys, dims, radius, starts[:-1].copy(), out, True)
    i = np.repeat(np.arange(n), counts)
    idx = np.lexsort((out, i))
    return np.stack([i[idx], out[idx]], axis=1)


def segment_pairs_reference(pa, pb, strand, radius):
    """scipy/numpy reference of :func:`segment_pairs`."""
    centers = 0.5 * (pa + pb)
    h = radius + float(np.max(np.linalg.norm(pb - pa, axis=1)))
    cand = cKDTree(centers).query_pairs(h, output_type="ndarray")
    cand = cand[strand[cand[:, 0]] != strand[cand[:, 1]]]
    i, j = cand[:, 0], cand[:, 1]
    keep = segment_distance_reference(pa[i], pb[i], pa[j], pb[j]) <= radius
    cand = np.sort(cand[keep], axis=1)
    return cand[np.lexsort((cand[:, 1], cand[:, 0]))]


def quat_conj_mul(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """conj(qa) * qb for rows of (w, x, y, z) quaternions."""
    w1, v1 = qa[:, :1], -qa[:, 1:]
    w2, v2 = qb[:, :1], qb[:, 1:]
    return np.concatenate([w1 * w2 - np.sum(v1 * v2, axis=1, keepdims=True),
                           w1 * v2 + w2 * v1 + np.cross(v1, v2)], axis=1)


def csr_adjacency(n: int, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Symmetric CSR of an undirected edge list: indptr (n+1,), indices, edge id per entry
    (rows sorted by neighbour)."""
    m = len(edges)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    eid = np.concatenate([np.arange(m), np.arange(m)])
    order = np.lexsort((cols, rows))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))]).astype(np.int64)
    return indptr, cols[order].astype(np.int64), eid[order].astype(np.int64)


@dataclass(frozen=True, eq=False)
class REG:
    edges: np.ndarray  # (m, 2) i < j, sorted
    rest_offset: np.ndarray  # (m,) dp_0
    rest_darboux: np.ndarray  # (m, 4) conj(q_i) q_j
    dir_weights: np.ndarray  # (m, 3) n_r^2, n_t^2, n_l^2 in the two elements' cross-section frames
    indptr: np.ndarray  # CSR adjacency of the REG
    indices: np.ndarray
    edge_of: np.ndarray  # edge id of each CSR entry


def build_reg(edges, centers, rest_quat, frames) -> REG:
    """REG of the given edges (pairs within connect_radius) with their rest quantities; ``frames``
    the elements' cross-section frames (rows e_R, e_T, e_L) that weigh each offset's direction."""
    i, j = edges[:, 0], edges[:, 1]
    d = centers[j] - centers[i]
    rest = np.linalg.norm(d, axis=1)
    nrm = d / np.maximum(rest, 1e-300)[:, None]
    w = 0.5 * (np.einsum("mkc,mc->mk", frames[i], nrm) ** 2 + np.einsum("mkc,mc->mk", frames[j], nrm) ** 2)
    indptr, indices, edge_of = csr_adjacency(len(centers), edges)
    return REG(edges=edges, rest_offset=rest, rest_darboux=quat_conj_mul(rest_quat[i], rest_quat[j]),
               dir_weights=w, indptr=indptr, indices=indices, edge_of=edge_of)


def transport_graph(pa, pb, strand, element_offsets, connect_radius, reach_radius):
    """Proximity pairs within ``max(connect_radius, reach_radius)`` plus the strand chains.

    Returns (pairs, is_reg, chains): the cross-strand pairs (sorted, i < j), a mask of those
    within ``connect_radius`` (the REG, a subset), and the chain links.
    """
    pairs = segment_pairs(pa, pb, strand, max(connect_radius, reach_radius))
    i, j = pairs[:, 0], pairs[:, 1]
    is_reg = pair_distances(pa, pb, i, j) <= connect_radius
    return pairs, is_reg, chain_edges(element_offsets)


def chain_edges(element_offsets: np.ndarray) -> np.ndarray:
    """(k, 2) links between consecutive elements of each strand."""
    n = element_offsets[-1]
    last = np.zeros(n, dtype=bool)
    last[element_offsets[1:] - 1] = True
    first = np.flatnonzero(~last)
    return np.stack([first, first + 1], axis=1)
