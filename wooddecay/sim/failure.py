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

Within a chunk of substeps (:func:`wooddecay.sim.mechanics._advance`) the first test is exact on
every edge and records an :class:`Epoch`; the later ones skip the edges whose ends moved and
turned too little since then to reach their limits (:func:`_flag_moved_edges`), so they flag
what the exact test flags (docs/decisions.md, "Failure test after an epoch").

Flags never come back. After a substep with a new element or connection failure the connected
components (strand links of unbroken elements plus intact REG connections) are recomputed;
labels are numbered in order of each component's smallest element id, so they are
deterministic, and the capsule pairs that overlapped when they separated are recorded
(:func:`record_separations`). The edge kernels write only their own edge's entries (race-free); elements are
flagged in one serial pass in element order (the neighbour rule reads the flags it writes).
"""
from __future__ import annotations

import math
from typing import NamedTuple

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


@nb.njit(inline="always", cache=True)
def _angle_bounds(r0, r1, r2, r3):
    """Upper bounds of the bend and twist angles of the rotation (r0 > 0, r1, r2, r3): 2 v / r0
    per part (atan z <= z), with a margin far above rounding."""
    g = 2.0 * (1.0 + 1e-9) / r0
    return g * math.sqrt(r1 * r1 + r2 * r2), g * abs(r3)


@nb.njit(inline="always", cache=True)
def _flag_edge(k, edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit, integrity, I_fail,
               edge_ok):
    """The failure test of REG edge k (intact): 0 none, 1 bend / twist only, 2 connection (all
    flags: over the bundle limit, or decayed below ``I_fail``). Where the angles' upper bounds
    (:func:`_angle_bounds`) are within the limits the edge cannot fail and the atan2 is skipped,
    so the flags are those of the exact test."""
    if (integrity[k] < I_fail[k]
            or _pair_bundle(k, edges, fp, x, rest_offset, edge_length) - strain_ref[k, 0] > limit[k, 0]):
        edge_ok[k, 0] = edge_ok[k, 1] = edge_ok[k, 2] = False
        return 2
    r0, r1, r2, r3 = _pair_rotation(k, edges, q, edge_rest)
    if r0 > 0.0:
        bend, twist = _angle_bounds(r0, r1, r2, r3)
        if bend - strain_ref[k, 1] <= limit[k, 1] and twist - strain_ref[k, 2] <= limit[k, 2]:
            return 0
    bend, twist = _angles(r0, r1, r2, r3)
    new = 0
    if edge_ok[k, 1] and bend - strain_ref[k, 1] > limit[k, 1]:
        edge_ok[k, 1] = False
        new = 1
    if edge_ok[k, 2] and twist - strain_ref[k, 2] > limit[k, 2]:
        edge_ok[k, 2] = False
        new = 1
    return new


@nb.njit(parallel=True, cache=True)
def _flag_edges(idx, edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit, integrity, I_fail,
                edge_ok):
    """New failures per edge among the edges ``idx`` (:func:`_flag_edge`); the strains
    (:func:`pair_strains`) are measured on intact edges only, in the same pass as the test."""
    new = np.zeros(len(edge_ok), dtype=np.int8)
    for t in nb.prange(len(idx)):
        k = idx[t]
        if edge_ok[k, 0]:
            new[k] = _flag_edge(k, edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit,
                                integrity, I_fail, edge_ok)
    return new


class Epoch(NamedTuple):
    """The element centres and orientations at an exact failure test of every REG edge, and how
    far each intact edge then was from failing (:func:`epoch`): its bundle strain's margin to its
    limit, and the smaller of its bend and twist margins (the angles' upper bound 2 v / r0; -1
    where the relative rotation is past ``EPOCH_ANGLE``: such an edge is always tested)."""

    c0: np.ndarray  # (n, 3)
    q0: np.ndarray  # (n, 4)
    margin_b: np.ndarray  # (m,)
    margin_a: np.ndarray  # (m,)
    round_off: float  # m: COORD_ULPS units in the last place of the largest coordinate


#: an edge's angle margin holds while its relative rotation stays within EPOCH_ANGLE + MOVE_ANGLE
#: (rad) of none: there the rotation vector (the log map) moves by at most LOG_LIPSCHITZ times the
#: angle between the rotations, (a / 2) / sin(a / 2) at a = 0.6, rounded up
EPOCH_ANGLE = 0.5
MOVE_ANGLE = 0.1
LOG_LIPSCHITZ = 1.02
#: absolute slack (strain, rad) on every bound, far above the rounding of the exact test
BOUND_SLACK = 1e-12
#: the exact test's bundle length and the moves of the element centres are rounded at the scale
#: of the coordinates, not of the moves: an edge skips only if it stays this many units in the
#: last place of the largest coordinate (at its epoch) within its margin (a skipped edge with
#: round-off larger than the slack flagged 22 times in 20,000 random trials 100 m from the origin)
COORD_ULPS = 16.0


def epoch(setup, ms) -> Epoch:
    """The :class:`Epoch` of the current state (run right after an exact test of every edge)."""
    fp, m = setup.fp, len(setup.edges)
    margin_b, margin_a = np.empty(m), np.empty(m)
    _margins(setup.edges, fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest, ms.strain_ref_edge,
             ms.limit_edge, ms.edge_ok, margin_b, margin_a)
    round_off = COORD_ULPS * float(np.finfo(np.float64).eps) * float(np.abs(ms.x).max(initial=0.0))
    return Epoch(0.5 * (ms.x[fp] + ms.x[fp + 1]), ms.q.copy(), margin_b, margin_a, round_off)


@nb.njit(parallel=True, cache=True)
def _margins(edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit, edge_ok, margin_b, margin_a):
    """:class:`Epoch`'s margins of every edge (failed ones: -1)."""
    for k in nb.prange(len(edges)):
        margin_b[k] = margin_a[k] = -1.0
        if not edge_ok[k, 0]:
            continue
        margin_b[k] = limit[k, 0] - (_pair_bundle(k, edges, fp, x, rest_offset, edge_length) - strain_ref[k, 0])
        r0, r1, r2, r3 = _pair_rotation(k, edges, q, edge_rest)
        if r0 <= 0.0:
            continue
        bend, twist = _angle_bounds(r0, r1, r2, r3)
        if bend * bend + twist * twist > EPOCH_ANGLE * EPOCH_ANGLE:
            continue
        a = np.inf
        if edge_ok[k, 1]:
            a = min(a, limit[k, 1] - (bend - strain_ref[k, 1]))
        if edge_ok[k, 2]:
            a = min(a, limit[k, 2] - (twist - strain_ref[k, 2]))
        margin_a[k] = a


@nb.njit(parallel=True, cache=True)
def _motion(fp, x, q, c0, q0, delta, rho, size):
    """Per element, the move of its centre since ``c0``, its turn since ``q0`` as the world
    rotation rho with q = rho q0, and their sizes: |delta| and an upper bound of rho's angle
    (2 v / w; infinite past 0.29 rad)."""
    for e in nb.prange(len(fp)):
        a = fp[e]
        for c in range(3):
            delta[e, c] = 0.5 * (x[a, c] + x[a + 1, c]) - c0[e, c]
        r = mul(q[e, 0], q[e, 1], q[e, 2], q[e, 3], q0[e, 0], -q0[e, 1], -q0[e, 2], -q0[e, 3])
        rho[e, 0], rho[e, 1], rho[e, 2], rho[e, 3] = r
        size[e, 0] = math.sqrt(delta[e, 0] ** 2 + delta[e, 1] ** 2 + delta[e, 2] ** 2)
        size[e, 1] = _turn_bound(r[0], r[1], r[2], r[3])


@nb.njit(inline="always", cache=True)
def _turn_bound(w, v1, v2, v3):
    """An upper bound of the angle of the unit quaternion (w, v): 2 |v| / |w| (atan z <= z),
    infinite where |w| <= 0.99."""
    w = abs(w)
    return 2.0 * (1.0 + 1e-9) * math.sqrt(v1 * v1 + v2 * v2 + v3 * v3) / w if w > 0.99 else np.inf


@nb.njit(parallel=True, cache=True)
def _flag_moved_edges(idx, edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit, integrity,
                      I_fail, edge_ok, delta, rho, size, margin_b, margin_a, round_off):
    """:func:`_flag_edges` after an :class:`Epoch`: an edge whose ends moved and turned against
    each other (``delta``, ``rho``, ``size``: :func:`_motion`) less than its margins allow cannot
    fail and is not tested. Its bundle strain moves by at most |delta_j - delta_i| / its length
    (triangle inequality), which is at most (|delta_i| + |delta_j|) / its length; its relative
    rotation by the angle of conj(rho_i) rho_j (the angle between rotations is bi-invariant), at
    most the sum of the two turns' angles, and its bend and twist angles by at most LOG_LIPSCHITZ
    times that, with the bundle's reach less ``round_off`` (m, :data:`COORD_ULPS`). The sums are
    tried first; a piece that shifts or turns as a whole moves or turns
    none of its edges by the differences. Integrity, rest data and limits are those of the epoch.
    So the flags are those of :func:`_flag_edges`."""
    new = np.zeros(len(edge_ok), dtype=np.int8)
    for t in nb.prange(len(idx)):
        k = idx[t]
        if not edge_ok[k, 0]:
            continue
        i, j = edges[k, 0], edges[k, 1]
        reach = (margin_b[k] - BOUND_SLACK) * edge_length[k] / (1.0 + 1e-9) - round_off
        moved = size[i, 0] + size[j, 0] < reach
        if not moved:
            dx, dy, dz = delta[j, 0] - delta[i, 0], delta[j, 1] - delta[i, 1], delta[j, 2] - delta[i, 2]
            moved = math.sqrt(dx * dx + dy * dy + dz * dz) < reach
        if moved:
            turn = size[i, 1] + size[j, 1]
            if turn > MOVE_ANGLE or LOG_LIPSCHITZ * turn + BOUND_SLACK >= margin_a[k]:
                p = mul(rho[i, 0], -rho[i, 1], -rho[i, 2], -rho[i, 3], rho[j, 0], rho[j, 1], rho[j, 2], rho[j, 3])
                turn = _turn_bound(p[0], p[1], p[2], p[3])
            if turn <= MOVE_ANGLE and LOG_LIPSCHITZ * turn + BOUND_SLACK < margin_a[k]:
                continue
        new[k] = _flag_edge(k, edges, fp, x, q, rest_offset, edge_length, edge_rest, strain_ref, limit, integrity,
                            I_fail, edge_ok)
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


def update(setup, ms, tested: tuple | None = None, record: bool = False, bounded: bool = False) -> int:
    """Flag the constraints whose strain beyond the settled reference (``ms.strain_ref_*``,
    :func:`mechanics.settle`) exceeds their limit; recompute components if anything separated.
    ``tested``: (elements, edges), increasing indices, to test only those (the rest has been
    tested at its current positions and limits, :func:`mechanics.stiffness`); None: all.
    ``bounded``: skip the edges that moved too little since ``ms.fail_epoch`` to fail
    (:func:`_flag_moved_edges`, the same flags; all tested without an epoch); ``record``: set
    ``ms.fail_epoch`` to this test (an exact test of every edge). Returns the number of new
    failures (elements plus edges)."""
    idx_e, idx_k = tested if tested is not None else (setup.all_elements, setup.all_edges)
    elem = np.zeros((setup.n_elements, 2))  # the rows outside idx_e are subtracted, never flagged
    _strains_at(idx_e, setup.fp, ms.x, ms.q, ms.rest_length, elem)
    new_e = _flag_elements(idx_e, elem - ms.strain_ref_elem, ms.limit_elem, ms.link_integrity, setup.I_fail_elem,
                           ms.crumbled, setup.inner, ms.element_ok)
    args = (idx_k, setup.edges, setup.fp, ms.x, ms.q, ms.rest_offset, setup.edge_length, setup.edge_rest,
            ms.strain_ref_edge, ms.limit_edge, ms.integrity, setup.I_fail_edge, ms.edge_ok)
    past = ms.fail_epoch
    if bounded and past is not None:
        n = setup.n_elements
        delta, rho, size = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 2))
        _motion(setup.fp, ms.x, ms.q, past.c0, past.q0, delta, rho, size)
        new_k = _flag_moved_edges(*args, delta, rho, size, past.margin_b, past.margin_a, past.round_off)
    else:
        new_k = _flag_edges(*args)
    if record and tested is None:
        ms.fail_epoch = epoch(setup, ms)
    count_e, count_k = np.count_nonzero(new_e), np.count_nonzero(new_k)
    count = int(count_e + count_k)
    if count_e or (count_k and (new_k == 2).any()):
        before = ms.component
        ms.component = components(setup, ms)
        record_separations(setup, ms, before)
        ms.pairs_x = None  # new pieces: rebuild the contact list (mechanics.refresh_pairs)
    ms.failures += count
    return count
