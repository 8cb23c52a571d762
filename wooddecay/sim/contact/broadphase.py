"""Broad phase of capsule contact: the element pairs within reach of Eq. 3 (woodstock §5.4, Eq. 3).

:func:`candidate_pairs` lists the element pairs i < j of different components whose capsules are
closer than a margin (dist(i, j) < r_i + r_j + margin, Eq. 3). Elements that share a particle (a
strand split between components) are never a pair: their axes meet at that particle.

It bins element centres in a uniform hash grid (Teschner et al. 2003) of cell
h = max(length + 2 r) + margin, so the partners of an element lie in the 27 cells around its own. A
counting sort orders the elements by bucket, each bucket by the lower bound of the element boxes
(segment bounds grown by r + margin / 2) along the axis where boxes are thinnest. Each element
visits its own cell and the 13 cells after it (every pair once), skips buckets whose bounding box
misses its box and, in a bucket, the entries outside the sweep window on that axis. Two passes run
in parallel over elements (count, then fill), each writing only its own rows, so the pairs are
bit-identical for any thread count; the count pass keeps up to KEPT partners per element, so the
fill pass mostly copies. :func:`candidate_pairs_reference` is the scipy/numpy version the tests
compare against.
"""
from __future__ import annotations

import numba as nb
import numpy as np
from scipy.spatial import cKDTree

from .closest import (
    _dot,
    _gap,
    _sub,
    closest_segment_segment,
    closest_segment_segment_reference,
)

#: partners per element the broad phase's count pass keeps for its fill pass
KEPT = 8
#: own cell first, then the 13 neighbour cells lexicographically after it
_OFFSETS = np.array([(0, 0, 0)] + [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
                                   if (a, b, c) > (0, 0, 0)], dtype=np.int64)


@nb.njit(cache=True, inline="always")
def _bucket(cx, cy, cz, mask):
    return ((cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)) & mask


@nb.njit(parallel=True, cache=True)
def _element_boxes(x, first_particle, radius, grow, center, box, ext):
    """Per element: segment centre, bounds grown by r + ``grow`` (lo, hi) and length + 2 r."""
    for e in nb.prange(len(first_particle)):
        a = first_particle[e]
        dx, dy, dz = _sub(x, a + 1, a)
        ext[e] = np.sqrt(dx * dx + dy * dy + dz * dz) + 2.0 * radius[e]
        g = radius[e] + grow
        for k in range(3):
            center[e, k] = 0.5 * (x[a, k] + x[a + 1, k])
            box[e, k] = min(x[a, k], x[a + 1, k]) - g
            box[e, 3 + k] = max(x[a, k], x[a + 1, k]) + g


@nb.njit(cache=True)
def _hash_grid(center, box, axis, h, cell, bucket, start, order):
    """Cells of side h, then a counting sort of the elements by the hash bucket of their cell,
    each bucket sorted by box lower bound along ``axis`` (ties: element order). Fills ``cell``,
    ``bucket``, ``start`` (n_buckets + 1, zeros on entry) and ``order``; returns the grid dims."""
    n = len(center)
    mask = len(start) - 2
    lx, ly, lz = center[:, 0].min(), center[:, 1].min(), center[:, 2].min()
    dx = dy = dz = 1
    for e in range(n):
        cx = int(np.floor((center[e, 0] - lx) / h))
        cy = int(np.floor((center[e, 1] - ly) / h))
        cz = int(np.floor((center[e, 2] - lz) / h))
        cell[e, 0], cell[e, 1], cell[e, 2] = cx, cy, cz
        dx, dy, dz = max(dx, cx + 1), max(dy, cy + 1), max(dz, cz + 1)
        bucket[e] = _bucket(cx, cy, cz, mask)
        start[bucket[e]] += 1
    for b in range(mask + 1):
        start[b + 1] += start[b]
    for e in range(n - 1, -1, -1):  # start[b] ends as the first slot of bucket b
        start[bucket[e]] -= 1
        order[start[bucket[e]]] = e
    for b in range(mask + 1):
        lo, hi = start[b], start[b + 1]
        if hi - lo > 32:  # crowded bucket: merge sort (stable)
            members = order[lo:hi].copy()
            order[lo:hi] = members[np.argsort(box[members, axis], kind="mergesort")]
            continue
        for u in range(lo + 1, hi):  # insertion sort (stable)
            e = order[u]
            w = u - 1
            while w >= lo and box[order[w], axis] > box[e, axis]:
                order[w + 1] = order[w]
                w -= 1
            order[w + 1] = e
    return dx, dy, dz


@nb.njit(parallel=True, cache=True)
def _sorted_segments(first_particle, component, order, box, cell, dims, box_s, comp_s, fp_s, key_s):
    """Gather into grid order: boxes, component, first particle and linear cell key."""
    for a in nb.prange(len(order)):
        e = order[a]
        comp_s[a], fp_s[a] = component[e], first_particle[e]
        for k in range(6):
            box_s[a, k] = box[e, k]
        key_s[a] = (cell[e, 0] * dims[1] + cell[e, 1]) * dims[2] + cell[e, 2]


@nb.njit(cache=True, inline="always")
def _apart(box_u, u, box_v, v):
    """Boxes (lo, hi) row u of box_u and row v of box_v do not overlap."""
    return (box_u[u, 0] > box_v[v, 3] or box_u[u, 3] < box_v[v, 0] or box_u[u, 1] > box_v[v, 4]
            or box_u[u, 4] < box_v[v, 1] or box_u[u, 2] > box_v[v, 5] or box_u[u, 5] < box_v[v, 2])


@nb.njit(cache=True, inline="always")
def _overlap(box_u, u, box_v, v):
    """not _apart, without short-circuit branches."""
    return ((box_u[u, 0] <= box_v[v, 3]) & (box_u[u, 3] >= box_v[v, 0]) & (box_u[u, 1] <= box_v[v, 4])
            & (box_u[u, 4] >= box_v[v, 1]) & (box_u[u, 2] <= box_v[v, 5]) & (box_u[u, 5] >= box_v[v, 2]))


@nb.njit(parallel=True, cache=True)
def _bucket_boxes(box, start, out):
    """Bounding box of the element boxes of each bucket (empty: inverted, overlaps nothing)."""
    for b in nb.prange(len(start) - 1):
        for k in range(3):
            out[b, k] = np.inf
            out[b, 3 + k] = -np.inf
        for m in range(start[b], start[b + 1]):
            for k in range(3):
                out[b, k] = min(out[b, k], box[m, k])
                out[b, 3 + k] = max(out[b, 3 + k], box[m, 3 + k])


@nb.njit(cache=True, inline="always")
def _lower_bound(box, axis, lo, hi, value):
    """First m in [lo, hi) with box[m, axis] >= value (the range is sorted on that column)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if box[mid, axis] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@nb.njit(parallel=True, cache=True)
def _pairs_pass(x, radius, box, bucket_box, comp, fp, elem, key, start, dims, axis, width, margin,
                counts, kept, base, out, fill):
    """Count (fill=False) or write (fill=True) the pairs owned by each element, in grid order:
    partners after it in its own cell and those of its 13 forward cells. A pair in reach has
    overlapping ``box`` (segment bounds grown by r + margin / 2): a bucket whose ``bucket_box``
    misses the element's box is skipped whole, and in a bucket (sorted by box lower bound along
    ``axis``, no box wider than ``width`` there) only the window of lower bounds in
    [lo - width, hi] is visited. The exact test is the capsule gap. The count pass keeps the first
    KEPT partners of each element in ``kept``; the fill pass copies them and searches again only
    for elements with more."""
    mask = len(start) - 2
    for a in nb.prange(len(box)):
        if fill and counts[a] <= KEPT:
            for k in range(counts[a]):
                out[base[a] + k, 0] = min(elem[a], kept[a, k])
                out[base[a] + k, 1] = max(elem[a], kept[a, k])
            continue
        k = 0
        lo, hi = box[a, axis], box[a, 3 + axis]
        ca, pa = comp[a], fp[a]
        cx, cy, cz = key[a] // (dims[1] * dims[2]), (key[a] // dims[2]) % dims[1], key[a] % dims[2]
        for o in range(len(_OFFSETS)):
            u = cx + _OFFSETS[o, 0]
            v = cy + _OFFSETS[o, 1]
            w = cz + _OFFSETS[o, 2]
            if u < 0 or u >= dims[0] or v < 0 or v >= dims[1] or w < 0 or w >= dims[2]:
                continue
            b = _bucket(u, v, w, mask)
            if o == 0:
                m0 = a + 1
            elif _apart(bucket_box, b, box, a):
                continue
            else:
                m0 = _lower_bound(box, axis, start[b], start[b + 1], lo - width)
            nkey = (u * dims[1] + v) * dims[2] + w
            for m in range(m0, start[b + 1]):
                if box[m, axis] > hi:
                    break
                # one well-predicted branch: & evaluates every test (most entries fail one at random)
                pm = fp[m]
                if not ((comp[m] != ca) & (key[m] == nkey) & (abs(pm - pa) > 1) & _overlap(box, m, box, a)):
                    continue
                s, t = closest_segment_segment(x, pa, pa + 1, pm, pm + 1)
                ex, ey, ez = _gap(x, pa, pa + 1, pm, pm + 1, s, t)
                lim = radius[elem[a]] + radius[elem[m]] + margin
                if ex * ex + ey * ey + ez * ez < lim * lim:
                    if fill:
                        out[base[a] + k, 0] = min(elem[a], elem[m])
                        out[base[a] + k, 1] = max(elem[a], elem[m])
                    elif k < KEPT:
                        kept[a, k] = elem[m]
                    k += 1
        if not fill:
            counts[a] = k


@nb.njit(parallel=True, cache=True)
def _sort_pairs(raw, indptr, out):
    """``raw`` (rows i < j) into ``out`` sorted lexicographically: a counting sort by i (``indptr``
    (n + 1,) zeros on entry), then each row by j."""
    n = len(indptr) - 1
    for q in range(len(raw)):
        indptr[raw[q, 0]] += 1
    for i in range(n):
        indptr[i + 1] += indptr[i]
    for q in range(len(raw) - 1, -1, -1):
        i = raw[q, 0]
        indptr[i] -= 1
        out[indptr[i], 0] = i
        out[indptr[i], 1] = raw[q, 1]
    for i in nb.prange(n):
        lo, hi = indptr[i], indptr[i + 1]
        if hi - lo > 32:  # crowded row
            out[lo:hi, 1].sort()
            continue
        for u in range(lo + 1, hi):  # insertion sort
            v = out[u, 1]
            w = u - 1
            while w >= lo and out[w, 1] > v:
                out[w + 1, 1] = out[w, 1]
                w -= 1
            out[w + 1, 1] = v


def candidate_pairs(x, first_particle, radius, component, margin, active=None) -> np.ndarray:
    """(k, 2) int64 element pairs i < j, sorted lexicographically, with component[i] !=
    component[j], no shared particle, and capsule gap dist(i, j) < r_i + r_j + margin (Eq. 3 with a
    margin, so the pairs can be reused over the substeps of a step); with ``active`` (a mask) only
    pairs of active elements, found among them alone. Callers pass the intact elements: a failed
    element's segment runs from the end of one piece to the start of another, metres long in a
    collapse, and would size the grid's cell (docs/decisions.md, "Broad phase among intact
    elements").

    A pair in reach has centres closer than the cell h (module docstring). Every array is allocated
    here with numpy and filled by the kernels: large allocations inside numba kernels page-fault
    on every call (several ms at 50k elements)."""
    if active is not None:
        idx = np.flatnonzero(active)
        return idx[candidate_pairs(x, first_particle[idx], radius[idx], component[idx], margin)]
    n = len(first_particle)
    if n < 2 or np.all(component == component[0]):
        return np.zeros((0, 2), dtype=np.int64)
    center, box, ext = np.empty((n, 3)), np.empty((n, 6)), np.empty(n)
    slack = 1e-9 * (float(np.abs(x).max()) + margin)  # the box tests only prune: never below round-off
    _element_boxes(x, first_particle, radius, 0.5 * margin + slack, center, box, ext)
    h = float(ext.max()) + margin
    if h <= 0.0:  # points of radius 0: nothing is closer than 0
        return np.zeros((0, 2), dtype=np.int64)
    widths = box[:, 3:] - box[:, :3]
    axis = int(np.argmin(widths.sum(axis=0)))  # the thinnest boxes: the sweep prunes most
    width = float(widths[:, axis].max()) + slack
    start = np.zeros((1 << max(1, (n // 2).bit_length())) + 1, dtype=np.int64)  # >= n / 2 buckets
    cell, bucket, order = np.empty((n, 3), dtype=np.int64), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    dims = np.array(_hash_grid(center, box, axis, h, cell, bucket, start, order), dtype=np.int64)
    if float(np.prod(dims.astype(np.float64))) >= 2.0**62:
        raise ValueError(f"hash grid of {dims} cells of {h} m: linear cell keys overflow")
    box_s, comp_s, fp_s, key_s = (np.empty((n, 6)), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64),
                                  np.empty(n, dtype=np.int64))
    _sorted_segments(first_particle, component, order, box, cell, dims, box_s, comp_s, fp_s, key_s)
    bucket_box = np.empty((len(start) - 1, 6))
    _bucket_boxes(box_s, start, bucket_box)
    args = (x, radius, box_s, bucket_box, comp_s, fp_s, order, key_s, start, dims, axis, width, float(margin))
    counts, kept = np.empty(n, dtype=np.int64), np.empty((n, KEPT), dtype=np.int64)
    _pairs_pass(*args, counts, kept, counts, np.zeros((0, 2), dtype=np.int64), False)
    base = np.concatenate(([0], np.cumsum(counts)))
    raw, out = np.empty((base[-1], 2), dtype=np.int64), np.empty((base[-1], 2), dtype=np.int64)
    _pairs_pass(*args, counts, kept, base, raw, True)
    _sort_pairs(raw, np.zeros(n + 1, dtype=np.int64), out)
    return out


def candidate_pairs_reference(x, first_particle, radius, component, margin) -> np.ndarray:
    """scipy/numpy version of :func:`candidate_pairs`: cKDTree on the centres, vectorised capsule gap."""
    n = len(first_particle)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pa, pb = x[first_particle], x[first_particle + 1]
    half = 0.5 * np.linalg.norm(pb - pa, axis=1)
    h = (2.0 * half.max() + 2.0 * radius.max() + margin) * (1.0 + 1e-9)
    cand = cKDTree(0.5 * (pa + pb)).query_pairs(h, output_type="ndarray").astype(np.int64)
    i, j = cand[:, 0], cand[:, 1]
    keep = (component[i] != component[j]) & (np.abs(first_particle[i] - first_particle[j]) > 1)
    i, j = i[keep], j[keep]
    s, t = closest_segment_segment_reference(pa[i], pb[i], pa[j], pb[j])
    d = (pa[j] + t[:, None] * (pb[j] - pa[j])) - (pa[i] + s[:, None] * (pb[i] - pa[i]))
    lim = radius[i] + radius[j] + margin
    keep = _dot(d, d) < lim * lim
    out = np.sort(np.stack([i[keep], j[keep]], axis=1), axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))]
