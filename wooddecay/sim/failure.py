"""Failure and connectivity (woodstock §5.3; limits L(M) of Eqs. 18-19 from
:mod:`wooddecay.sim.coupling`).

Strains are measured after every substep, as the change since the settled reference state
(:func:`wooddecay.sim.mechanics.settle`; zero when not settled):

* element stretch |p_b - p_a| / l_r - 1 (tension) and shear |gamma - (gamma . d3) d3| with
  gamma = (p_b - p_a) / l_r, against the element's limits. A failed element cuts its strand: its
  stretch, shear and joint constraints are switched off (the strand separates there; the element
  stays with the strand part before it). Its REG connections stay and fail on their own strain,
  like every other pair ("still permitting other constraints", §5.3): clearing them with the
  element released all its pre-strained connections at once and mixed every orientation into the
  crack statistics (docs/decisions.md). Only an inner element whose strand neighbours are both
  intact can fail: at a strand end, or next to an element that already failed, a failure
  separates nothing and would leave a particle that no element holds, flopping on the REG
  connections of its element's centre (its strain there is no longer the wood's);
* pair (REG edge) bundle strain (|c_j - c_i| - dp) / max(dp_0, r_s) (tension), bend and twist angles of the
  relative rotation conj(Omega_0) conj(q_i) q_j (bend: about axes across the grain, twist: about
  d3), against the pair's limits. Bend or twist over its limit clears that flag; bundle over its
  limit clears all three, since a separated pair transmits no moment;
* separation from decay (woodstock §7.1, Eq. 21): a pair whose integrity I_ij fell below
  ``I_fail`` clears all three flags, and an element whose strand link e, e + 1 did
  (``ms.link_integrity``) fails as if over its limit. With theta_ij brown rot's carbohydrate loss
  reaches I_fail on the BSP cell boundaries only, so the cells come apart as blocks; white rot's
  lignin loss lowers every pair alike. A crumbled element (consumed, ``ms.crumbled``) fails
  whatever its neighbours, and its pairs and links have integrity 0: it leaves the mechanics.

Flags never come back. After a substep with a new element or connection failure the connected
components (strand links of unbroken elements plus intact REG connections) are recomputed;
labels are numbered in order of each component's smallest element id, so they are
deterministic, and the capsule pairs that overlapped when they separated are recorded
(:func:`record_separations`). The edge kernels write only their own edge's entries (race-free); elements are
flagged in one serial pass in element order (the neighbour rule reads the flags it writes).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .. import fmath as fm
from ..quaternion import conj_np, mul, mul_np, rotate
from ..unionfind import labels, union
from . import contact


@nb.njit(cache=True)
def element_strains(fp, x, q, rest_length):
    """(n, 2) stretch and shear strain of every element."""
    out = np.empty((len(fp), 2))
    _strains_at(np.arange(len(fp)), fp, x, q, rest_length, out)
    return out


@nb.njit(parallel=True, cache=True)
def _strains_at(idx, fp, x, q, rest_length, out):
    """:func:`element_strains` of the elements ``idx`` into their rows of ``out``."""
    for t in nb.prange(len(idx)):
        e = idx[t]
        a = fp[e]
        b = a + 1
        l = rest_length[e]
        gx, gy, gz = (x[b, 0] - x[a, 0]) / l, (x[b, 1] - x[a, 1]) / l, (x[b, 2] - x[a, 2]) / l
        out[e, 0] = math.sqrt(gx * gx + gy * gy + gz * gz) - 1.0
        d3 = rotate(q[e, 0], q[e, 1], q[e, 2], q[e, 3], 0.0, 0.0, 1.0)
        g3 = gx * d3[0] + gy * d3[1] + gz * d3[2]
        sx, sy, sz = gx - g3 * d3[0], gy - g3 * d3[1], gz - g3 * d3[2]
        out[e, 1] = math.sqrt(sx * sx + sy * sy + sz * sz)


@nb.njit(inline="always", cache=True)
def _pair_bundle(k, edges, fp, x, rest_offset, edge_length):
    """Bundle strain of REG edge k."""
    ai, aj = fp[edges[k, 0]], fp[edges[k, 1]]
    dx = 0.5 * (x[aj, 0] + x[aj + 1, 0] - x[ai, 0] - x[ai + 1, 0])
    dy = 0.5 * (x[aj, 1] + x[aj + 1, 1] - x[ai, 1] - x[ai + 1, 1])
    dz = 0.5 * (x[aj, 2] + x[aj + 1, 2] - x[ai, 2] - x[ai + 1, 2])
    return (math.sqrt(dx * dx + dy * dy + dz * dz) - rest_offset[k]) / edge_length[k]


@nb.njit(inline="always", cache=True)
def _pair_rotation(k, edges, q, edge_rest):
    """The relative rotation conj(Omega_0) conj(q_i) q_j of REG edge k, its scalar part >= 0."""
    i, j = edges[k, 0], edges[k, 1]
    om = mul(q[i, 0], -q[i, 1], -q[i, 2], -q[i, 3], q[j, 0], q[j, 1], q[j, 2], q[j, 3])
    r = mul(edge_rest[k, 0], -edge_rest[k, 1], -edge_rest[k, 2], -edge_rest[k, 3], om[0], om[1], om[2], om[3])
    s = 1.0 if r[0] >= 0.0 else -1.0
    return s * r[0], r[1], r[2], r[3]


@nb.njit(inline="always", cache=True)
def _angles(r0, r1, r2, r3):
    """Bend and twist angle of the rotation (r0 >= 0, r1, r2, r3)."""
    vn = math.sqrt(r1 * r1 + r2 * r2 + r3 * r3)
    angle = 2.0 * math.atan2(vn, r0)
    f = angle / vn if vn > 0.0 else 0.0
    return f * math.sqrt(r1 * r1 + r2 * r2), f * abs(r3)


@nb.njit(parallel=True, cache=True)
def pair_strains(edges, fp, x, q, rest_offset, edge_length, edge_rest):
    """(m, 3) bundle strain, bend angle and twist angle of every REG edge."""
    m = len(edges)
    out = np.empty((m, 3))
    for k in nb.prange(m):
        out[k, 0] = _pair_bundle(k, edges, fp, x, rest_offset, edge_length)
        r = _pair_rotation(k, edges, q, edge_rest)
        out[k, 1], out[k, 2] = _angles(r[0], r[1], r[2], r[3])
    return out


@nb.njit(cache=True)
def _flag_elements(idx, strain, limit, link_integrity, I_fail, crumbled, inner, element_ok):
    """New failures among the elements ``idx`` (increasing), in element order (serial, so
    deterministic): a crumbled element fails; an element over its limit, or whose strand link has
    decayed below ``I_fail``, cuts its strand only where that separates something, i.e. it is
    ``inner`` (a neighbour on both sides in its strand) and both neighbours are intact (module
    docstring)."""
    new = np.zeros(len(element_ok), dtype=np.bool_)
    for t in range(len(idx)):
        e = idx[t]
        if element_ok[e] and crumbled[e]:
            element_ok[e] = False
            new[e] = True
        elif (element_ok[e] and inner[e] and element_ok[e - 1] and element_ok[e + 1]
                and (strain[e, 0] > limit[e, 0] or strain[e, 1] > limit[e, 1] or link_integrity[e] < I_fail[e])):
            element_ok[e] = False
            new[e] = True
    return new


@nb.njit(parallel=True, cache=True)
def _flag_edges(idx, edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit, integrity, I_fail,
                edge_ok):
    """New failures per edge among the edges ``idx``: 0 none, 1 bend / twist only, 2 connection
    (all flags: over the bundle limit, or decayed below ``I_fail``). The strains
    (:func:`pair_strains`) are measured on intact edges only, in the same pass as the test. The
    angles 2 atan(v / r0) (v / |v|) are bounded by 2 v / r0 (atan z <= z); where that bound, with
    a margin far above rounding, is within the limit the edge cannot fail and the atan2 is
    skipped, so the flags are those of the exact test."""
    new = np.zeros(len(edge_ok), dtype=np.int8)
    for t in nb.prange(len(idx)):
        k = idx[t]
        if not edge_ok[k, 0]:
            continue
        if (integrity[k] < I_fail[k]
                or _pair_bundle(k, edges, fp, x, rest_offset, edge_length) - strain_ref[k, 0] > limit[k, 0]):
            edge_ok[k, 0] = edge_ok[k, 1] = edge_ok[k, 2] = False
            new[k] = 2
            continue
        r0, r1, r2, r3 = _pair_rotation(k, edges, q, edge_rest)
        if r0 > 0.0:
            g = 2.0 * (1.0 + 1e-9) / r0
            if (g * math.sqrt(r1 * r1 + r2 * r2) - strain_ref[k, 1] <= limit[k, 1]
                    and g * abs(r3) - strain_ref[k, 2] <= limit[k, 2]):
                continue
        bend, twist = _angles(r0, r1, r2, r3)
        if edge_ok[k, 1] and bend - strain_ref[k, 1] > limit[k, 1]:
            edge_ok[k, 1] = False
            new[k] = 1
        if edge_ok[k, 2] and twist - strain_ref[k, 2] > limit[k, 2]:
            edge_ok[k, 2] = False
            new[k] = 1
    return new


def record_separations(setup, ms, before: np.ndarray) -> int:
    """Remember the overlap of every pair of intact capsules (only they become contacts) whose
    elements were in one component (``before``) and are now in different ones (``ms.component``),
    in ``ms.sep_keys`` (keys i n + j, i < j, sorted) and ``ms.sep_overlap``: contact pushes such
    an overlap out at most at v_depenetration (:func:`mechanics.refresh_pairs`, docs/decisions.md
    "Separation overlap"). Components only split, so a pair is recorded once. Returns the number
    of pairs added."""
    pairs = contact.candidate_pairs(ms.x, setup.fp, ms.radius, ms.component, 0.0, active=ms.element_ok)
    pairs = pairs[before[pairs[:, 0]] == before[pairs[:, 1]]]
    keys = pairs[:, 0] * setup.n_elements + pairs[:, 1]
    new = ~np.isin(keys, ms.sep_keys)
    if not new.any():
        return 0
    keys = np.concatenate([ms.sep_keys, keys[new]])
    vals = np.concatenate([ms.sep_overlap, contact.pair_overlaps(ms.x, setup.fp, ms.radius, pairs[new])])
    order = np.argsort(keys, kind="stable")
    ms.sep_keys, ms.sep_overlap = keys[order], vals[order]
    return int(new.sum())


def components(setup, ms) -> np.ndarray:
    """Connected-component label per element (module docstring)."""
    return _components(setup.n_elements, setup.joints, ms.element_ok, setup.edges, ms.edge_ok)


@nb.njit(cache=True)
def _components(n, joints, element_ok, edges, edge_ok):
    """:func:`components` by union-find over the strand links (joints whose first element is
    intact) and the intact REG connections, then labels in order of each component's smallest
    element (serial, no allocation per link). Not scipy's search
    (:func:`components_reference`): its sparse matrix cost 2 ms a call on the Fig. 12 log, 4% of
    its bake (docs/decisions.md, "Components by union-find")."""
    parent = np.arange(n)
    for k in range(len(joints)):
        if element_ok[joints[k, 0]]:
            union(parent, joints[k, 0], joints[k, 1])
    for k in range(len(edges)):
        if edge_ok[k, 0]:
            union(parent, edges[k, 0], edges[k, 1])
    return labels(parent)


def components_reference(setup, ms) -> np.ndarray:
    """:func:`components` by scipy's connected components on the link graph."""
    n = setup.n_elements
    links = setup.joints[ms.element_ok[setup.joints[:, 0]]]
    reg = setup.edges[ms.edge_ok[:, 0]]
    e = np.concatenate([links, reg])
    g = sp.coo_matrix((np.ones(len(e), dtype=np.int8), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    return connected_components(g, directed=False)[1].astype(np.int64)


def strains(setup, ms) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) element and (m, 3) pair strains of the current state."""
    return (element_strains(setup.fp, ms.x, ms.q, ms.rest_length),
            pair_strains(setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest))


def drift(setup, ms, before: tuple, after: tuple, limit_elem: np.ndarray, limit_edge: np.ndarray) -> float:
    """Largest |strain change| / limit from ``before`` to ``after`` ((element, pair) strains as
    :func:`strains` returns them) over the constraints that can still fail: intact inner elements
    and the intact flags of REG edges, with a positive finite limit (a zero limit fails at any
    strain, an infinite one never)."""
    ok_e = ms.element_ok & setup.inner
    ratio_e = _ratio(np.abs(after[0] - before[0]), limit_elem, ok_e[:, None])
    ratio_k = _ratio(np.abs(after[1] - before[1]), limit_edge, ms.edge_ok)
    return max(ratio_e, ratio_k)


def _ratio(change: np.ndarray, limit: np.ndarray, ok: np.ndarray) -> float:
    use = ok & (limit > 0.0) & np.isfinite(limit)
    return float(np.max(change[use] / limit[use], initial=0.0))


def pair_strains_reference(edges, fp, x, q, rest_offset, edge_length, edge_rest):
    """Plain-numpy :func:`pair_strains`."""
    i, j = edges[:, 0], edges[:, 1]
    d = 0.5 * (x[fp[j]] + x[fp[j] + 1] - x[fp[i]] - x[fp[i] + 1])
    bundle = (np.linalg.norm(d, axis=1) - rest_offset) / edge_length
    r = mul_np(conj_np(edge_rest), mul_np(conj_np(q[i]), q[j]))
    r = r * np.where(r[:, :1] >= 0.0, 1.0, -1.0)
    vn = np.linalg.norm(r[:, 1:], axis=1)
    f = np.where(vn > 0.0, 2.0 * fm.arctan2(vn, r[:, 0]) / np.where(vn > 0.0, vn, 1.0), 0.0)
    return np.stack([bundle, f * np.linalg.norm(r[:, 1:3], axis=1), f * np.abs(r[:, 3])], axis=1)


def update(setup, ms, tested: tuple | None = None) -> int:
    """Flag the constraints whose strain beyond the settled reference (``ms.strain_ref_*``,
    :func:`mechanics.settle`) exceeds their limit; recompute components if anything separated.
    ``tested``: (elements, edges), increasing indices, to test only those (the rest has been
    tested at its current positions and limits, :func:`mechanics.stiffness`); None: all.
    Returns the number of new failures (elements plus edges)."""
    idx_e, idx_k = tested if tested is not None else (setup.all_elements, setup.all_edges)
    elem = np.empty((setup.n_elements, 2))
    _strains_at(idx_e, setup.fp, ms.x, ms.q, ms.rest_length, elem)
    new_e = _flag_elements(idx_e, elem - ms.strain_ref_elem, ms.limit_elem, ms.link_integrity, setup.I_fail_elem,
                           ms.crumbled, setup.inner, ms.element_ok)
    new_k = _flag_edges(idx_k, setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length,
                        setup.edge_rest, ms.strain_ref_edge, ms.limit_edge, ms.integrity, setup.I_fail_edge,
                        ms.edge_ok)
    count_e, count_k = np.count_nonzero(new_e), np.count_nonzero(new_k)
    count = int(count_e + count_k)
    if count_e or (count_k and (new_k == 2).any()):
        before = ms.component
        ms.component = components(setup, ms)
        record_separations(setup, ms, before)
        ms.pairs_x = None  # new pieces: rebuild the contact list (mechanics.refresh_pairs)
    ms.failures += count
    return count
