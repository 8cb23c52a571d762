"""A branch's kinetic sites: sections, strand sites, ghost mirrors and element bounds (docs/model.md §5).

Woodstock §8.1: per branch, the strand sites P_i(d_t) are the strands' control points in their
nodes' cross-section frames (``model.cp_uv``, ``model.cp_s``), linear in d_t between the sections
``d``: the branch's node sections and the ends of its strands' runs. A strand is meshed in each
branch it crosses over the part of its path in that branch (its elements whose midpoint lies in
the branch, ``model.branch``).

Bounding the wood. Instead of clipping the Voronoi cells with the offset alpha-shape contour, the
sites within GHOST_DEPTH r_s of a node's profile are mirrored across it (ghost sites, linear in
d_t like the real ones, alive with their strand). A real site's cell then ends at the bisector
with its mirror, which is the tangent of the profile at the closest boundary point: the cells are
bounded, the bark surface follows the input profile (concave ones too), and all changes along
d_t stay continuous (a clipped alpha contour jumps at every alpha event). A strand near the bark
at some nodes only (a tapering branch) mirrors across the line square to its outward direction
there (:func:`_mirror_tapered`). Near a corner a second
mirror goes across the nearest edge turned by more than CORNER; on a smooth profile that edge
can lie on either side of the site from one node section to the next, and the ghost is split
there instead of interpolated across the flip (:func:`_steady_parts`). At a concave profile a mirror
can cut the wood itself: one that lands inside the profile (across an arm) and one with its foot
within r_s / 2 of a sharp reflex vertex (the bisector runs on into the wood) are left out
(:func:`_valid_mirrors`); the cells there end at their neighbours' mirrors. Mirrors across the
reflex vertices of a wide concave curve stay (without them the cells along the inside of a C
leaked into its hollow); across those of a tight bend they would cut the wood on both sides. Convex cells cannot
follow a reflex corner exactly: what they miss on one side of it they overhang on the other.
Forks: past a fork a branch's strands fill only part of the fork's profile (where side branches
leave, the strands that go on; where a side branch starts, its own). Its cells are bounded the
way the branches share the wood: at the fork section by the fork's profile and, up to a rise
section RISE r_s on, by the strands that leave into the other branches, carried as ghosts of no
site here (:func:`_foreign_sites`; the sweep makes the faces against them walls to those strands'
elements). From the rise section on the mirrors go across the convex hull of the branch's own
sites offset by r_s (:func:`~wooddecay.meshlets.offset.offset_contour`), so its cells do not swell
into the wood the other branch took. Where the source surface is known (a scene built from a mesh),
sections every JUNCTION r_s from the fork to the next node slice it, and the contour around the
branch's sites is its own section once it holds none of the leaving strands: from the first such
section on the mirrors go across it (a site outside it, carried straight from the fork's profile,
gets a cell OUTSIDE_GAP r_s deep), and the leaving strands bound the cells up to there. A site the fork's profile does not bound (deeper than
GHOST_DEPTH r_s there, or its mirror invalid) gets its ghost from the rise section on; at an inner
fork each ghost is two (one up to the fork section, one from it), and a mirror across the fork
profile's notches is held from the sections around instead of costing the strand its ghost for
the whole branch.
FAR_RING far sites around each section keep every real cell bounded even where no mirror reaches. ``docs/decisions.md``
(Meshlets) records this choice.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..wood import WoodModel
from .. import fmath as fm
from ..strands import profiles
from ..strands.mesh_skeleton import contour_around
from .offset import offset_contour

#: sites closer than this many r_s to the profile at each of their nodes get a mirrored ghost
#: site; those this close at only some nodes (a tapering branch) get one by :func:`_mirror_tapered`
GHOST_DEPTH = 4.0
#: far sites around every section of a branch, FAR_MARGIN r_s beyond its farthest real site: a
#: cell no mirror bounds overhangs the bark by about 2 r_s at most, while the ring stays clear of
#: the mirrored cells (their bisectors lie within r_s of their site's depth, the ring's at least
#: 2 r_s beyond the outermost sites)
FAR_RING = 64
FAR_MARGIN = 4.0
#: mirrors across a reflex vertex are kept where the profile bends with a radius over this many r_s
MILD_RADIUS = 4.0
#: past a fork the ghosts reach the hull of the branch's own sites RISE r_s on (at most halfway
#: to the next node): the crotch's wood between the branches tapers over that rise
RISE = 4.0
#: where the source surface is known (a scene built from a mesh), sections every JUNCTION r_s from
#: a fork to the next node mirror across the surface's own section there
JUNCTION = 1.0
#: a site outside the source surface's own section past a fork: its cell ends this many r_s beyond it
OUTSIDE_GAP = 0.25
#: a corner: the second mirror edge turns by more than this from the nearest one
CORNER = np.deg2rad(30.0)


@dataclass
class Branch:
    """The kinetic input of one branch (:func:`setup_branch`): real sites first, then ghosts, then
    the far ring."""

    chain: np.ndarray  # skeleton nodes along the branch (start node first)
    s_chain: np.ndarray  # their distance to the root
    d: np.ndarray  # kinetic sections
    P: np.ndarray  # (S, n, 2) sites (real first, then ghosts)
    alive: np.ndarray  # (S, n)
    strand: np.ndarray  # (n_real,) strand of each real site
    ghost_of: np.ndarray  # (n_ghost,) real site mirrored by each ghost (-1: another branch's strand)
    foreign: np.ndarray  # (n_ghost,) that strand (-1: a mirror)
    bounds: list  # per real site: element boundaries strictly inside its run
    elem0: np.ndarray  # per real site: its first element in this branch
    n_elem: np.ndarray  # per real site: its number of elements in this branch

    @property
    def n_real(self) -> int:
        return len(self.strand)


def _feet(poly: np.ndarray, pts: np.ndarray):
    """Feet of the two mirrors of each point: on its nearest profile edge, and on the nearest edge
    turned by more than CORNER from that one (inf distance where there is none). Returns
    (n, 2, 2) feet and (n, 2) distances."""
    a = np.asarray(poly, float)
    e = np.roll(a, -1, axis=0) - a
    ln2 = (e * e).sum(1)
    t = np.clip(((pts[:, None] - a[None]) * e[None]).sum(-1) / ln2[None], 0.0, 1.0)
    foot = a[None] + t[..., None] * e[None]
    dist = np.linalg.norm(pts[:, None] - foot, axis=-1)
    n = len(pts)
    e0 = np.argmin(dist, axis=1)
    u = e / np.sqrt(ln2)[:, None]
    turned = (u[e0] @ u.T) < fm.cos(CORNER)
    d1 = np.where(turned, dist, np.inf)
    e1 = np.argmin(d1, axis=1)
    rows = np.arange(n)
    feet = np.stack([foot[rows, e0], foot[rows, e1]], axis=1)
    return feet, np.stack([dist[rows, e0], d1[rows, e1]], axis=1)


def _valid_mirrors(poly: np.ndarray, pts: np.ndarray, feet: np.ndarray, r_s: float) -> np.ndarray:
    """(n, 2) whether the mirrors of ``pts`` at ``feet`` (:func:`_feet`) bound the wood: not one
    strictly inside ``poly``, across a reflex vertex of a tight bend (curvature radius under
    MILD_RADIUS r_s: the bisector, a line through the vertex, cuts into the wood on both sides),
    or with its foot within r_s / 2 of a sharp reflex vertex (turning by more than CORNER; the
    bisector runs on into the wood beyond it). Across a reflex vertex of a wide concave curve
    (radius R) the line cuts into a cell r_s across by r_s^2 / 8R only."""
    a = np.asarray(poly, float)
    e_in, e_out = a - np.roll(a, 1, axis=0), np.roll(a, -1, axis=0) - a
    reflex = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0] < 0.0  # CCW profiles
    l_in, l_out = np.linalg.norm(e_in, axis=1), np.linalg.norm(e_out, axis=1)
    turn = fm.arccos(np.clip((e_in * e_out).sum(1) / l_in / l_out, -1.0, 1.0))
    sharp = turn > CORNER
    tight = sharp | (0.5 * (l_in + l_out) < MILD_RADIUS * r_s * turn)  # or a radius under MILD_RADIUS r_s
    ghost = (2.0 * feet - pts[:, None]).reshape(-1, 2)
    cut = (profiles.signed_distance(a, ghost) > 0.0).reshape(feet.shape[:2])
    for v, r in zip(a[reflex & tight], np.where(sharp, 0.5 * r_s, 1e-9 * float(np.max(np.abs(a))))[reflex & tight]):
        cut |= np.linalg.norm(feet - v, axis=-1) <= r
    return ~cut


def _mirror_tapered(P, offset, nearest, polys, alive, depth, valid, r_s: float) -> dict:
    """Ghosts for the strands near the bark at some node section but deeper than GHOST_DEPTH r_s
    at another (a tapering branch; in place: ``offset`` rank 0, ``depth``, ``valid``; returns
    the sites given one). The
    nearest edge of a deep site can lie on any side, and mirrors across it cut the wood between
    sections; instead, at every node section the mirror goes across the line square to the
    site's outward direction at its nearest section, through the boundary along it, so the
    ghost stays on that side. A strand whose mirror lands inside a profile gets none."""
    reach = GHOST_DEPTH * r_s
    given = {}
    for i in np.flatnonzero((depth[:, 0] >= reach) & (nearest.min(axis=0) < reach)):
        rows = [k for k in polys if alive[k, i]]
        k0 = min(rows, key=lambda k: nearest[k, i])
        out = offset[k0, i, 0]
        if not np.linalg.norm(out) > 0.0:
            continue
        angle = float(fm.arctan2(out[1], out[0]))
        step = {k: float(profiles.ray_extent(polys[k], P[k, i], [angle])[0]) for k in rows}
        unit = out / np.linalg.norm(out)
        ghost = {k: P[k, i] + 2.0 * step[k] * unit for k in rows}
        if all(step[k] > 0.0 and profiles.signed_distance(polys[k], ghost[k][None])[0] <= 0.0 for k in rows):
            for k in rows:
                offset[k, i, 0] = ghost[k] - P[k, i]
            depth[i, 0] = min(nearest[k, i] for k in rows)
            valid[i, 0] = True
            given[int(i)] = unit
    return given


def _steady_parts(off: np.ndarray) -> list:
    """A corner ghost's offsets at its node sections (k, 2) split where consecutive ones turn by
    more than CORNER, as (start, stop) index ranges: on a smooth profile its nearest turned edge
    can lie on either side of it, and an offset interpolated between the two sides is too short
    (its bisector cuts the wood between the sections). Each part is a ghost of its own, alive
    from its first node section to its last (the run's ends for the first and last part)."""
    a, b = off[:-1], off[1:]
    cos = (a * b).sum(axis=1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
    cut = list(np.flatnonzero(cos < fm.cos(CORNER)) + 1)
    return list(zip([0, *cut], [*cut, len(off)]))


def _site_hull(pts: np.ndarray, r_s: float) -> np.ndarray | None:
    """The convex hull of the sites (the alpha shape with alpha = inf) offset outwards by r_s:
    what a branch's own strands fill past a fork (None for fewer than three or collinear)."""
    if len(pts) < 3:
        return None
    try:
        convex = ConvexHull(pts)
    except QhullError:
        return None
    return offset_contour(pts[convex.vertices], r_s, "round")[0]


def _mirrors(poly: np.ndarray, pts: np.ndarray, r_s: float, surface: bool = False):
    """Offsets (n, 2, 2) of the mirrors of ``pts`` across ``poly`` (:func:`_feet`), their
    distances and validity (:func:`_valid_mirrors`). Across the ``surface``'s own section a site
    can lie outside it (strands run straight between node sections, the surface need not): its
    cell ends OUTSIDE_GAP r_s beyond it, along the way out."""
    foot, dist = _feet(poly, pts)
    ok = _valid_mirrors(poly, pts, foot, r_s)
    off = 2.0 * (foot - pts[:, None])
    if surface:
        out = profiles.signed_distance(poly, pts) < 0.0
        way = pts[out] - foot[out, 0]
        off[out, 0] = 2.0 * OUTSIDE_GAP * r_s * way / np.maximum(np.linalg.norm(way, axis=1), 1e-300)[:, None]
        dist[out, 0], ok[out, 0] = 0.0, True
    return off, dist, ok


def section_frame(skel, topo, chain, s_chain, d):
    """Origin and axes (U, V) of the cross-section at distances ``d`` along a branch's chain:
    interpolated linearly between its nodes (re-orthonormalised)."""
    j = np.clip(np.searchsorted(s_chain, d, side="right") - 1, 0, len(chain) - 2)
    t = np.clip((d - s_chain[j]) / (s_chain[j + 1] - s_chain[j]), 0.0, 1.0)[:, None]
    na, nb = chain[j], chain[j + 1]
    origin = (1.0 - t) * skel.positions[na] + t * skel.positions[nb]
    U = (1.0 - t) * topo.frames[na, 0] + t * topo.frames[nb, 0]
    V = (1.0 - t) * topo.frames[na, 1] + t * topo.frames[nb, 1]
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    V -= (V * U).sum(1, keepdims=True) * U
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    return origin, U, V


def _foreign_sites(model: WoodModel, b: int, chain, s_chain, d: np.ndarray, k0: int, k1: int):
    """Where the strands that leave fork section ``k0`` into other branches than this one cross
    the sections ``k0..k1`` of branch ``b`` (uv in its frames; (k1 - k0 + 1, m, 2)), and those
    strands."""
    skel, topo = model.skeleton, model.topology
    fork = chain[int(np.searchsorted(s_chain, d[k0]))]
    cpo = model.cp_offsets
    cs = np.flatnonzero(model.cp_node == fork)
    strand = np.searchsorted(cpo, cs, side="right") - 1
    go_on = cs + 1 < cpo[strand + 1]
    cs, strand = cs[go_on], strand[go_on]
    keep = topo.branch[model.cp_node[cs + 1]] != b
    cs, strand = cs[keep], strand[keep]
    dd = d[k0:k1 + 1]
    origin, U, V = section_frame(skel, topo, chain, s_chain, dd)
    out = np.zeros((len(dd), len(cs), 2))
    frames = {}  # the sections of each branch the strands go on in, at dd
    for j, (c, st) in enumerate(zip(cs, strand)):
        ss, uv = model.cp_s[c:cpo[st + 1]], model.cp_uv[c:cpo[st + 1]]
        ob = int(topo.branch[model.cp_node[c + 1]])
        if ob not in frames:
            other = _branch_chain(topo, skel, ob)
            frames[ob] = section_frame(skel, topo, other, topo.s[other].astype(float), dd)
        o2, U2, V2 = frames[ob]
        x = np.stack([np.interp(dd, ss, uv[:, 0]), np.interp(dd, ss, uv[:, 1])], axis=1)
        X = o2 + x[:, :1] * U2 + x[:, 1:] * V2 - origin
        out[:, j] = np.stack([(X * U).sum(1), (X * V).sum(1)], axis=1)
    return out, strand


def _branch_chain(topo, skel, b: int) -> np.ndarray:
    nodes = np.flatnonzero(topo.branch == b)
    nodes = nodes[np.argsort(topo.s[nodes], kind="stable")]
    first = nodes[0]
    if skel.parent[first] >= 0:
        nodes = np.concatenate([[skel.parent[first]], nodes])
    return nodes


class _Runs(NamedTuple):
    """The strands meshed in a branch and their runs there (:func:`_branch_runs`)."""

    strand: np.ndarray  # (n,) the strands that own at least one element in the branch
    c0: np.ndarray  # (n,) first control point of each run
    c1: np.ndarray  # (n,) its last control point
    s0: np.ndarray  # (n,) where each run starts (``model.cp_s`` at c0)
    s1: np.ndarray  # (n,) where it ends
    elem0: np.ndarray  # (n,) each strand's first element in the branch
    n_elem: np.ndarray  # (n,) its number of elements in the branch


def _branch_runs(model: WoodModel, b: int) -> _Runs | None:
    """The runs of the strands through branch ``b``: the part of each strand's path whose segments
    end at a node of the branch, for the strands that own an element there (whose midpoint lies in
    the branch, ``model.branch``; docs/model.md §5). None when no element lies in the branch."""
    topo = model.topology
    cpo, node = model.cp_offsets, model.cp_node
    seg_branch = np.full(len(node), -1)
    seg_branch[:-1] = topo.branch[node[1:]]
    seg_branch[cpo[1:] - 1] = -1  # the last control point of a strand starts no segment
    segs = np.flatnonzero(seg_branch == b)
    if len(segs) == 0:
        return None
    cp_strand = np.repeat(np.arange(len(cpo) - 1), np.diff(cpo))
    strands, first_seg = np.unique(cp_strand[segs], return_index=True)
    last_seg = np.append(first_seg[1:], len(segs)) - 1
    c0, c1 = segs[first_seg], segs[last_seg] + 1
    e_br = model.branch
    keep, e0s, ns = [], [], []
    for k, st in enumerate(strands):
        e = np.arange(model.element_offsets[st], model.element_offsets[st + 1])
        mine = e[e_br[e] == b]
        if len(mine):
            keep.append(k)
            e0s.append(mine[0])
            ns.append(len(mine))
    if not keep:
        return None
    rows = np.array(keep, dtype=np.int64)
    strands, c0, c1 = strands[rows], c0[rows], c1[rows]
    return _Runs(strand=strands, c0=c0, c1=c1, s0=model.cp_s[c0], s1=model.cp_s[c1],
                 elem0=np.array(e0s), n_elem=np.array(ns))


class _Sections(NamedTuple):
    """A branch's kinetic sections and those past its forks (:func:`_sections`)."""

    d: np.ndarray  # (S,) the kinetic sections
    rise: dict  # fork section -> its rise section (distances along the branch)
    junction: dict  # fork section within the runs -> its junction sections (rise included)


def _sections(skel, topo, chain, s_chain, runs: _Runs, r_s: float) -> _Sections:
    """The kinetic sections of a branch: its node sections within the runs, the runs' ends, and
    the junction sections past each fork (where side branches leave this branch, at inner chain
    nodes, and where it starts as a side branch): its rise section RISE r_s on (at most halfway to
    the next node) and, where the source surface gives the branch's own section, every JUNCTION
    r_s up to the next node (docs/decisions.md "Forks and hull repair")."""
    s0, s1 = runs.s0, runs.s1
    starts = skel.parent[chain[0]] >= 0
    fork_at = [j for j in range(1, len(chain) - 1) if len(topo.children[chain[j]]) > 1]
    fork_at = [0, *fork_at] if starts else fork_at
    s_rise = {float(s_chain[j]): float(s_chain[j] + min(RISE * r_s, 0.5 * (s_chain[j + 1] - s_chain[j])))
              for j in fork_at}
    s_junction: dict[float, np.ndarray] = {}
    for j in fork_at:
        sk, v = float(s_chain[j]), s_rise[float(s_chain[j])]
        if s0.min() <= sk and v <= s1.max():
            every = (np.arange(sk + JUNCTION * r_s, s_chain[j + 1] - 0.5 * JUNCTION * r_s, JUNCTION * r_s)
                     if skel.surface is not None else np.zeros(0))
            s_junction[sk] = np.union1d(every, [v])
    d = np.unique(np.concatenate([s_chain[(s_chain >= s0.min()) & (s_chain <= s1.max())], s0, s1,
                                  *s_junction.values()]))
    return _Sections(d=d, rise=s_rise, junction=s_junction)


@dataclass(frozen=True, eq=False)
class _Sites:
    """A branch's real sites on its kinetic sections (:func:`_real_sites`)."""

    d: np.ndarray  # (S,) the kinetic sections
    P: np.ndarray  # (S, n, 2) the real sites (zero where dead)
    alive: np.ndarray  # (S, n)
    is_node: np.ndarray  # (S,) whether a section is a node's


def _real_sites(model: WoodModel, runs: _Runs, d: np.ndarray, s_chain: np.ndarray) -> _Sites:
    """The strand sites P_i(d_t) at the sections ``d``: the strands' control points in their
    nodes' section frames (``model.cp_uv``, ``model.cp_s``), linear in d_t, alive over their runs
    (docs/model.md §5)."""
    s0, s1 = runs.s0, runs.s1
    n = len(runs.strand)
    P = np.zeros((len(d), n, 2))
    alive = (d[:, None] >= s0[None]) & (d[:, None] <= s1[None])
    for i in range(n):
        cs, uv = model.cp_s[runs.c0[i]:runs.c1[i] + 1], model.cp_uv[runs.c0[i]:runs.c1[i] + 1]
        dd = d[alive[:, i]]
        P[alive[:, i], i, 0] = np.interp(dd, cs, uv[:, 0])
        P[alive[:, i], i, 1] = np.interp(dd, cs, uv[:, 1])
    return _Sites(d=d, P=P, alive=alive, is_node=np.isin(d, s_chain))


@dataclass(frozen=True, eq=False)
class _NodeMirrors:
    """The ghosts across the node profiles (:func:`_node_mirrors`), of rank 0 (across the nearest
    edge) and rank 1 (across the nearest edge turned by more than CORNER from it)."""

    offset: np.ndarray  # (S, n, 2, 2) ghost - site at the node sections (NaN elsewhere)
    dist: np.ndarray  # (S, n, 2) the site's distance to the mirror's edge there (-inf elsewhere)
    ok: np.ndarray  # (S, n, 2) whether the mirror bounds the wood there (:func:`_valid_mirrors`)
    depth: np.ndarray  # (n, 2) the largest of those distances
    valid: np.ndarray  # (n, 2) whether the mirror bounds the wood at every node section
    tapered: dict  # site -> outward unit direction of its rank-0 ghost (:func:`_mirror_tapered`)


def _node_mirrors(skel, chain, s_chain, sites: _Sites, r_s: float) -> _NodeMirrors:
    """The mirrors of the sites across each node profile alive there, their depth and validity;
    the ghosts of a tapering branch's strands by :func:`_mirror_tapered`. The offset ghost - site
    is linear between node sections and constant beyond them (docs/decisions.md "Mirror ghosts
    instead of clipping by the alpha contour")."""
    d, P, alive = sites.d, sites.P, sites.alive
    n = P.shape[1]
    node_at = {float(s): int(c) for s, c in zip(s_chain, chain)}
    offset = np.full((len(d), n, 2, 2), np.nan)
    nearest = np.full((len(d), n), np.inf)  # distance to the nearest edge at each node section
    row_dist = np.full((len(d), n, 2), -np.inf)
    row_valid = np.ones((len(d), n, 2), dtype=bool)
    polys = {}
    for k in np.flatnonzero(sites.is_node):
        idx = np.flatnonzero(alive[k])
        poly = polys[k] = skel.profiles[node_at[float(d[k])]].polygon
        foot, dist = _feet(poly, P[k, idx])
        row_dist[k, idx] = dist
        row_valid[k, idx] = _valid_mirrors(poly, P[k, idx], foot, r_s)
        nearest[k, idx] = dist[:, 0]
        offset[k, idx] = 2.0 * (foot - P[k, idx][:, None])
    depth, valid = row_dist.max(axis=0), row_valid.all(axis=0)
    tapered = _mirror_tapered(P, offset, nearest, polys, alive, depth, valid, r_s)
    return _NodeMirrors(offset=offset, dist=row_dist, ok=row_valid, depth=depth, valid=valid, tapered=tapered)


class _Junctions(NamedTuple):
    """What bounds a branch's cells past its forks (:func:`_junctions`)."""

    mirrors: dict  # junction section -> (fork section, sites, offsets, distances, valid, profile)
    forks: list  # the fork sections (past the branch's first) with junction mirrors past them
    surfaced: list  # the junction sections across the source surface
    leaving: list  # (fork section, last section, uv there, strand) of each strand leaving the branch


def _parted_sections(skel, topo, chain, s_chain, sites: _Sites, k: int, rows: np.ndarray, on: np.ndarray,
                     X: np.ndarray, near: np.ndarray, r_s: float) -> dict:
    """The source surface's own sections around the sites ``on`` at the junction sections ``rows``
    past fork section ``k``, by section, where they no longer hold a leaving strand near the sites
    (``X[:, near]``, from ``k`` on); none without a source surface
    (docs/decisions.md "Forks and hull repair")."""
    parted: dict[int, np.ndarray] = {}
    if skel.surface is None:
        return parted
    for kj, origin, U, V in zip(rows, *section_frame(skel, topo, chain, s_chain, sites.d[rows])):
        contour = contour_around(skel.surface, origin, U, V, sites.P[kj, on[sites.alive[kj, on]]], r_s)
        if contour is not None and not profiles.contains(contour, X[kj - k][near]).any():
            parted[int(kj)] = contour
    return parted


def _junctions(model: WoodModel, b: int, chain, s_chain, sections: _Sections, sites: _Sites) -> _Junctions:
    """Past each fork the sites fill only part of its profile (where side branches leave, the
    sites that go on; where this branch starts, its own): from the fork's profile at the fork
    they mirror, by the rise section, across the hull of their own sites offset by r_s; where the
    source surface is known, across its section around them at each junction section where it
    has parted from the other branches' (up to there the leaving strands near the sites bound
    them, as ghosts of no site here; docs/decisions.md "Forks and hull repair")."""
    skel, topo, r_s = model.skeleton, model.topology, model.r_s
    d, P, alive = sites.d, sites.P, sites.alive
    rise = {}  # rise section (the first parted junction section) -> fork section
    junction = {}
    surfaced: list[int] = []
    leaving = []
    for k in np.flatnonzero(np.isin(d, list(sections.junction))):
        rows = np.searchsorted(d, sections.junction[float(d[k])])
        kr = int(np.searchsorted(d, sections.rise[float(d[k])]))
        on = np.flatnonzero(alive[k] & alive[kr])
        if k > 0 and alive[k].sum() == len(on):
            continue
        hull = _site_hull(P[kr, on], r_s)
        if hull is None:
            continue
        X, other = _foreign_sites(model, b, chain, s_chain, d, k, max(kr, int(rows[-1])))
        near = np.linalg.norm(X[0][:, None] - P[k, alive[k]][None], axis=2).min(axis=1) < GHOST_DEPTH * r_s
        parted = _parted_sections(skel, topo, chain, s_chain, sites, k, rows, on, X, near, r_s)
        kr = min(parted, default=kr)  # the leaving strands bound the cells until the sections part
        leaving += [(k, kr, X[:kr - k + 1, j], int(other[j])) for j in np.flatnonzero(near)]
        for kj, poly in parted.items() if parted else [(kr, hull)]:
            here = on[alive[kj, on]]
            junction[kj] = (k, here, *_mirrors(poly, P[kj, here], r_s, surface=bool(parted)), poly)
        surfaced += list(parted)
        rise[kr] = k
    return _Junctions(mirrors=junction, forks=[k for k in rise.values() if k > 0], surfaced=surfaced,
                      leaving=leaving)


def _between_mirrors(skel, chain, s_chain, sites: _Sites, r_s: float) -> dict:
    """For each site whose run lies between two node sections: the feet (k, 2, 2) of its mirrors
    across the nearer node's profile at its sections (:func:`_feet`), and whether they bound the
    wood at all of them (2,) (:func:`_valid_mirrors`)."""
    between = {}
    for i in range(sites.P.shape[1]):
        rows_i = np.flatnonzero(sites.alive[:, i])
        if len(rows_i) and not sites.is_node[rows_i].any():
            poly = skel.profiles[chain[int(np.argmin(np.abs(s_chain - sites.d[rows_i].mean())))]].polygon
            foot, _ = _feet(poly, sites.P[rows_i, i])
            between[i] = foot, np.all(_valid_mirrors(poly, sites.P[rows_i, i], foot, r_s), axis=0)
    return between


class _Ghost(NamedTuple):
    """One ghost site of a branch."""

    P: np.ndarray  # (S, 2) where it is at each section (zero where dead)
    of: int  # the real site it mirrors (-1: another branch's strand)
    foreign: int  # that strand (-1: a mirror)
    rows: np.ndarray  # the sections where it is alive


def _junction_mirrors(junction: dict, tapered: dict, P: np.ndarray, i: int, r: int) -> tuple[dict, bool]:
    """Site ``i``'s rank-``r`` mirrors at the junction sections that hold it, by section: (fork
    section, its index among the sites there, offsets, distances, valid), and whether its ghost is
    a tapered one (:func:`_mirror_tapered`). A tapered ghost keeps its side: it mirrors across the
    junction profile along its direction, and has no mirror at a section where that ray finds none."""
    mine = {kj: (k, int(np.flatnonzero(on == i)[0]), off, dist, ok)
            for kj, (k, on, off, dist, ok, _) in junction.items() if i in on}
    steady = r == 0 and i in tapered
    if steady:
        unit, held = tapered[i], {}
        for kj, (k, c, off, dist, ok) in mine.items():
            step = float(profiles.ray_extent(junction[kj][5], P[kj, i], [fm.arctan2(unit[1], unit[0])])[0])
            if step > 0.0:
                off = off.copy()
                off[c, 0] = 2.0 * step * unit
                held[kj] = (k, c, off, dist, ok)
        mine = held
    return mine, steady


def _fork_bounds(mirrors: _NodeMirrors, k, i: int, r: int, r_s: float) -> bool:
    """Whether the profile at fork section ``k`` bounds site ``i``'s rank-``r`` ghost: its mirror
    is valid there and its edge within GHOST_DEPTH r_s (for a tapered ghost, its mirror line)."""
    if r == 0 and i in mirrors.tapered:
        return bool(0.5 * np.linalg.norm(mirrors.offset[k, i, 0]) < GHOST_DEPTH * r_s)
    return bool(mirrors.ok[k, i, r] and mirrors.dist[k, i, r] < GHOST_DEPTH * r_s)


def _ghost_start(mirrors: _NodeMirrors, mine: dict, steady: bool, i: int, r: int, lo, r_s: float):
    """Where site ``i``'s rank-``r`` ghost past fork section ``lo`` starts: at the fork where its
    profile and every junction section past it bound the site, else at the first junction section
    from which on they all do (the other branches' strands bound it up to there), else at the
    last one (docs/decisions.md "Forks and hull repair")."""
    js = sorted(kj for kj, (k, *_) in mine.items() if k == lo)
    bound = [steady or mine[kj][3][mine[kj][1], r] < GHOST_DEPTH * r_s for kj in js]
    if js and not (_fork_bounds(mirrors, lo, i, r, r_s) and all(bound)):
        lo = js[next((t for t in range(len(js)) if all(bound[t:])), len(js) - 1)]
    return lo


def _held_offsets(sites: _Sites, mirrors: _NodeMirrors, junctions: _Junctions, mine: dict, steady: bool,
                  i: int, r: int, rows: np.ndarray, r_s: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The sections among ``rows`` where site ``i``'s rank-``r`` ghost offset is known (node and
    junction sections) and those offsets; an invalid mirror at a fork or surface section (across
    a notch of the fork's profile) is left out and held from the sections around. None where
    they do not all bound the wood within GHOST_DEPTH r_s."""
    known = rows[sites.is_node[rows] | np.isin(rows, list(mine))]
    off, dist, ok = mirrors.offset[known, i, r].copy(), mirrors.dist[known, i, r].copy(), mirrors.ok[known, i, r].copy()
    for j, k in enumerate(known):
        if k in mine:
            _, c, o, t, v = mine[k]
            off[j], dist[j], ok[j] = o[c, r], t[c, r], v[c, r]
    if steady:
        dist, ok = np.full(len(known), mirrors.depth[i, 0]), np.ones(len(known), dtype=bool)
    drop = np.isin(known, junctions.forks + junctions.surfaced) & ~ok
    if drop.any() and not drop.all():
        known, off, dist, ok = known[~drop], off[~drop], dist[~drop], ok[~drop]
    if not (len(known) and dist.max() < GHOST_DEPTH * r_s and ok.all()):
        return None
    return known, off


def _interpolated_ghosts(sites: _Sites, i: int, r: int, rows: np.ndarray, known: np.ndarray,
                         off: np.ndarray) -> list[_Ghost]:
    """Site ``i``'s rank-``r`` ghosts over the sections ``rows``: the site plus its offset
    interpolated linearly between the ``known`` sections and constant beyond them; a corner ghost
    (rank 1) is split where its offset turns (:func:`_steady_parts`)."""
    d, P = sites.d, sites.P
    ghosts = []
    for k0, k1 in _steady_parts(off) if r == 1 else [(0, len(known))]:
        first = known[k0] if k0 else rows[0]
        last = known[k1 - 1] if k1 < len(known) else rows[-1]
        span = rows[(rows >= first) & (rows <= last)]
        g = np.zeros((len(d), 2))
        for c in range(2):
            g[span, c] = P[span, i, c] + np.interp(d[span], d[known[k0:k1]], off[k0:k1, c])
        ghosts.append(_Ghost(g, i, -1, span))
    return ghosts


def _site_ghosts(sites: _Sites, mirrors: _NodeMirrors, junctions: _Junctions, i: int, r: int,
                 r_s: float) -> list[_Ghost]:
    """Site ``i``'s rank-``r`` ghosts across the node profiles and the junction sections. At a
    fork the ghost is two: one up to it and one from it (:func:`_ghost_start`); docs/decisions.md
    "Mirror ghosts instead of clipping by the alpha contour" and "Forks and hull repair"."""
    rows_i = np.flatnonzero(sites.alive[:, i])
    mine, steady = _junction_mirrors(junctions.mirrors, mirrors.tapered, sites.P, i, r)
    cuts = sorted({k for k, *_ in mine.values() if k > 0})
    ghosts = []
    for lo, hi in zip([rows_i[0], *cuts], [*cuts, rows_i[-1]]):
        lo = _ghost_start(mirrors, mine, steady, i, r, lo, r_s)
        rows = rows_i[(rows_i >= lo) & (rows_i <= hi)]
        held = _held_offsets(sites, mirrors, junctions, mine, steady, i, r, rows, r_s)
        if held is not None:
            ghosts += _interpolated_ghosts(sites, i, r, rows, *held)
    return ghosts


def _ghosts(sites: _Sites, mirrors: _NodeMirrors, between: dict, junctions: _Junctions,
            r_s: float) -> list[_Ghost]:
    """All ghosts of a branch's sites, rank 0 of every site first, then rank 1, then those of no
    site here (the strands leaving into other branches past a fork): a site whose run lies
    between two node sections mirrors across the nearer node's profile (:func:`_between_mirrors`),
    the others across the node profiles and junction sections (:func:`_site_ghosts`)."""
    d, P = sites.d, sites.P
    ghosts = []
    for r, i in ((r, i) for r in range(2) for i in range(P.shape[1])):
        if i in between:
            foot, ok = between[i]
            if mirrors.depth[i, r] < GHOST_DEPTH * r_s and mirrors.valid[i, r] and ok[r]:
                rows_i = np.flatnonzero(sites.alive[:, i])
                g = np.zeros((len(d), 2))
                g[rows_i] = 2.0 * foot[:, r] - P[rows_i, i]
                ghosts.append(_Ghost(g, i, -1, rows_i))
        else:
            ghosts += _site_ghosts(sites, mirrors, junctions, i, r, r_s)
    for k, kr, x, strand in junctions.leaving:
        g = np.zeros((len(d), 2))
        g[k:kr + 1] = x
        ghosts.append(_Ghost(g, -1, strand, np.arange(k, kr + 1)))
    return ghosts


def _far_ring(sites: _Sites, r_s: float) -> np.ndarray:
    """(S, FAR_RING, 2) far sites per section, on a circle about the centre of its real sites'
    bounding box, FAR_MARGIN r_s beyond the farthest of them: they keep every real cell bounded
    even where no mirror reaches
    (docs/decisions.md "Mirror ghosts instead of clipping by the alpha contour")."""
    P, alive = sites.P, sites.alive
    lo = np.where(alive[:, :, None], P, np.inf).min(axis=1)
    hi = np.where(alive[:, :, None], P, -np.inf).max(axis=1)
    centre = 0.5 * (lo + hi)
    reach = np.where(alive, np.linalg.norm(P - centre[:, None], axis=2), 0.0).max(axis=1) + FAR_MARGIN * r_s
    ang = 2.0 * np.pi * np.arange(FAR_RING) / FAR_RING
    return centre[:, None] + reach[:, None, None] * np.stack([fm.cos(ang), fm.sin(ang)], 1)[None]


def _element_bounds(model: WoodModel, runs: _Runs) -> list:
    """Per real site: the boundaries between its elements in the branch strictly inside its run."""
    bounds = []
    for i in range(len(runs.strand)):
        e = np.arange(runs.elem0[i], runs.elem0[i] + runs.n_elem[i])
        inner = model.particle_s[model.first_particle[e[:-1]] + 1]
        bounds.append(inner[(inner > runs.s0[i]) & (inner < runs.s1[i])])
    return bounds


def setup_branch(model: WoodModel, b: int) -> Branch | None:
    """Sections, sites (real, ghosts, far ring) and element bounds of branch ``b`` of ``model``
    (see the module docstring); None when no element lies in the branch (a twig thinner than
    a strand holds none: its strands end before it or pass it by as the parent's)."""
    skel, topo, r_s = model.skeleton, model.topology, model.r_s
    chain = _branch_chain(topo, skel, b)
    s_chain = topo.s[chain].astype(float)
    runs = _branch_runs(model, b)
    if runs is None:
        return None
    sections = _sections(skel, topo, chain, s_chain, runs, r_s)
    sites = _real_sites(model, runs, sections.d, s_chain)
    mirrors = _node_mirrors(skel, chain, s_chain, sites, r_s)
    junctions = _junctions(model, b, chain, s_chain, sections, sites)
    between = _between_mirrors(skel, chain, s_chain, sites, r_s)
    ghosts = _ghosts(sites, mirrors, between, junctions, r_s)
    S = len(sites.d)
    G = np.stack([g.P for g in ghosts], axis=1) if ghosts else np.zeros((S, 0, 2))
    ghost_alive = np.array([np.isin(np.arange(S), g.rows) for g in ghosts], dtype=bool).reshape(-1, S).T
    P = np.concatenate([sites.P, G, _far_ring(sites, r_s)], axis=1)
    alive = np.concatenate([sites.alive, ghost_alive, np.ones((S, FAR_RING), dtype=bool)], axis=1)
    return Branch(chain=chain, s_chain=s_chain, d=sites.d, P=P, alive=alive, strand=runs.strand,
                  ghost_of=np.array([g.of for g in ghosts], dtype=np.int64),
                  foreign=np.array([g.foreign for g in ghosts], dtype=np.int64),
                  bounds=_element_bounds(model, runs), elem0=runs.elem0, n_elem=runs.n_elem)
