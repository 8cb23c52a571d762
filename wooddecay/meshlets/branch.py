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


def setup_branch(model: WoodModel, b: int) -> Branch | None:
    """Sections, sites (real, ghosts, far ring) and element bounds of branch ``b`` of ``model``
    (see the module docstring); None when no element lies in the branch (a twig thinner than
    a strand holds none: its strands end before it or pass it by as the parent's)."""
    skel, topo, r_s = model.skeleton, model.topology, model.r_s
    chain = _branch_chain(topo, skel, b)
    s_chain = topo.s[chain].astype(float)
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
    # keep the strands that own at least one element in this branch
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
    s0, s1 = model.cp_s[c0], model.cp_s[c1]
    # forks: where side branches leave this branch (inner chain nodes) and where it starts as a
    # side branch (its first section); each gets a rise section past it
    starts = skel.parent[chain[0]] >= 0
    fork_at = [j for j in range(1, len(chain) - 1) if len(topo.children[chain[j]]) > 1]
    fork_at = [0, *fork_at] if starts else fork_at
    s_rise = {float(s_chain[j]): float(s_chain[j] + min(RISE * r_s, 0.5 * (s_chain[j + 1] - s_chain[j])))
              for j in fork_at}
    # the junction sections past a fork: its rise, and where the source surface gives the
    # branch's own section, every JUNCTION r_s up to the next node
    s_junction: dict[float, np.ndarray] = {}
    for j in fork_at:
        sk, v = float(s_chain[j]), s_rise[float(s_chain[j])]
        if s0.min() <= sk and v <= s1.max():
            every = (np.arange(sk + JUNCTION * r_s, s_chain[j + 1] - 0.5 * JUNCTION * r_s, JUNCTION * r_s)
                     if skel.surface is not None else np.zeros(0))
            s_junction[sk] = np.union1d(every, [v])
    d = np.unique(np.concatenate([s_chain[(s_chain >= s0.min()) & (s_chain <= s1.max())], s0, s1,
                                  *s_junction.values()]))
    n = len(strands)
    P = np.zeros((len(d), n, 2))
    alive = (d[:, None] >= s0[None]) & (d[:, None] <= s1[None])
    for i in range(n):
        cs, uv = model.cp_s[c0[i]:c1[i] + 1], model.cp_uv[c0[i]:c1[i] + 1]
        dd = d[alive[:, i]]
        P[alive[:, i], i, 0] = np.interp(dd, cs, uv[:, 0])
        P[alive[:, i], i, 1] = np.interp(dd, cs, uv[:, 1])
    # ghosts: mirrors across each node profile of the sites near it (ranks: the nearest edge and
    # the nearest edge turned by more than CORNER from it, for corners); the offset ghost - site is
    # linear between node sections and constant beyond them
    is_node = np.isin(d, s_chain)
    node_at = {float(s): int(c) for s, c in zip(s_chain, chain)}
    offset = np.full((len(d), n, 2, 2), np.nan)
    nearest = np.full((len(d), n), np.inf)  # distance to the nearest edge at each node section
    row_dist = np.full((len(d), n, 2), -np.inf)
    row_valid = np.ones((len(d), n, 2), dtype=bool)
    polys = {}
    for k in np.flatnonzero(is_node):
        idx = np.flatnonzero(alive[k])
        poly = polys[k] = skel.profiles[node_at[float(d[k])]].polygon
        foot, dist = _feet(poly, P[k, idx])
        row_dist[k, idx] = dist
        row_valid[k, idx] = _valid_mirrors(poly, P[k, idx], foot, r_s)
        nearest[k, idx] = dist[:, 0]
        offset[k, idx] = 2.0 * (foot - P[k, idx][:, None])
    depth, valid = row_dist.max(axis=0), row_valid.all(axis=0)
    tapered = _mirror_tapered(P, offset, nearest, polys, alive, depth, valid, r_s)
    # past a fork the sites fill only part of its profile (where side branches leave, the sites
    # that go on; where this branch starts, its own): from the fork's profile at the fork they
    # mirror, by the rise section, across the hull of their own sites offset by r_s; where the source
    # surface is known, across its section around them at each junction section where it has parted
    # from the other branches' (up to there the leaving strands bound them)
    rise = {}  # rise section (the first parted junction section) -> fork section
    junction = {}  # junction section -> (fork section, sites, offsets, distances, valid, profile)
    surfaced = []  # the junction sections across the source surface
    leaving = []  # the strands that leave into other branches, ghosts of no site here up to the rise
    for k in np.flatnonzero(np.isin(d, list(s_junction))):
        rows = np.searchsorted(d, s_junction[float(d[k])])
        kr = int(np.searchsorted(d, s_rise[float(d[k])]))
        on = np.flatnonzero(alive[k] & alive[kr])
        if k > 0 and alive[k].sum() == len(on):
            continue
        hull = _site_hull(P[kr, on], r_s)
        if hull is None:
            continue
        X, other = _foreign_sites(model, b, chain, s_chain, d, k, max(kr, int(rows[-1])))
        near = np.linalg.norm(X[0][:, None] - P[k, alive[k]][None], axis=2).min(axis=1) < GHOST_DEPTH * r_s
        parted = {}  # the surface's own section where it no longer holds a leaving strand
        if skel.surface is not None:
            for kj, origin, U, V in zip(rows, *section_frame(skel, topo, chain, s_chain, d[rows])):
                contour = contour_around(skel.surface, origin, U, V, P[kj, on[alive[kj, on]]], r_s)
                if contour is not None and not profiles.contains(contour, X[kj - k][near]).any():
                    parted[int(kj)] = contour
        kr = min(parted, default=kr)  # the leaving strands bound the cells until the sections part
        leaving += [(k, kr, X[:kr - k + 1, j], int(other[j])) for j in np.flatnonzero(near)]
        for kj, poly in parted.items() if parted else [(kr, hull)]:
            here = on[alive[kj, on]]
            junction[kj] = (k, here, *_mirrors(poly, P[kj, here], r_s, surface=bool(parted)), poly)
        surfaced += list(parted)
        rise[kr] = k
    forks = [k for k in rise.values() if k > 0]
    # a run between two nodes: mirrors across the nearer node's profile
    between = {}
    for i in range(n):
        rows_i = np.flatnonzero(alive[:, i])
        if len(rows_i) and not is_node[rows_i].any():
            poly = skel.profiles[chain[int(np.argmin(np.abs(s_chain - d[rows_i].mean())))]].polygon
            foot, _ = _feet(poly, P[rows_i, i])
            valid[i] &= np.all(_valid_mirrors(poly, P[rows_i, i], foot, r_s), axis=0)
            between[i] = foot
    G, ghost_of, foreign, ghost_alive = [], [], [], []

    def ghost(g: np.ndarray, i: int, rows: np.ndarray, strand: int = -1) -> None:
        G.append(g)
        ghost_of.append(i)
        foreign.append(strand)
        ghost_alive.append(np.isin(np.arange(len(d)), rows))

    def usable(k, i, r):  # the fork profile bounds site i's rank-r ghost there
        if r == 0 and i in tapered:
            return 0.5 * np.linalg.norm(offset[k, i, 0]) < GHOST_DEPTH * r_s
        return row_valid[k, i, r] and row_dist[k, i, r] < GHOST_DEPTH * r_s

    for r, i in ((r, i) for r in range(2) for i in range(n)):
        rows_i = np.flatnonzero(alive[:, i])
        if i in between:
            if depth[i, r] < GHOST_DEPTH * r_s and valid[i, r]:
                g = np.zeros((len(d), 2))
                g[rows_i] = 2.0 * between[i][:, r] - P[rows_i, i]
                ghost(g, i, rows_i)
            continue
        mine = {kj: (k, int(np.flatnonzero(on == i)[0]), off, dist, ok)
                for kj, (k, on, off, dist, ok, _) in junction.items() if i in on}
        steady = r == 0 and i in tapered
        if steady:  # a tapered ghost keeps its side: across the junction profile along its direction
            unit, held = tapered[i], {}
            for kj, (k, c, off, dist, ok) in mine.items():
                step = float(profiles.ray_extent(junction[kj][5], P[kj, i], [fm.arctan2(unit[1], unit[0])])[0])
                if step > 0.0:
                    off = off.copy()
                    off[c, 0] = 2.0 * step * unit
                    held[kj] = (k, c, off, dist, ok)
            mine = held
        # the ghost is two at a fork: one up to it and one from it, from the fork where its profile
        # and every junction section bound the site, else from the first junction section from which
        # on they all do (bounded by the other branches' strands up to there), else the rise
        cuts = sorted({k for k, *_ in mine.values() if k > 0})
        for lo, hi in zip([rows_i[0], *cuts], [*cuts, rows_i[-1]]):
            js = sorted(kj for kj, (k, *_) in mine.items() if k == lo)
            bound = [steady or mine[kj][3][mine[kj][1], r] < GHOST_DEPTH * r_s for kj in js]
            if js and not (usable(lo, i, r) and all(bound)):
                lo = js[next((t for t in range(len(js)) if all(bound[t:])), len(js) - 1)]
            rows = rows_i[(rows_i >= lo) & (rows_i <= hi)]
            known = rows[is_node[rows] | np.isin(rows, list(mine))]
            off, dist, ok = offset[known, i, r].copy(), row_dist[known, i, r].copy(), row_valid[known, i, r].copy()
            for j, k in enumerate(known):
                if k in mine:
                    _, c, o, t, v = mine[k]
                    off[j], dist[j], ok[j] = o[c, r], t[c, r], v[c, r]
            if steady:
                dist, ok = np.full(len(known), depth[i, 0]), np.ones(len(known), dtype=bool)
            drop = np.isin(known, forks + surfaced) & ~ok  # across notches: held from the sections around
            if drop.any() and not drop.all():
                known, off, dist, ok = known[~drop], off[~drop], dist[~drop], ok[~drop]
            if not (len(known) and dist.max() < GHOST_DEPTH * r_s and ok.all()):
                continue
            for k0, k1 in _steady_parts(off) if r == 1 else [(0, len(known))]:
                first = known[k0] if k0 else rows[0]
                last = known[k1 - 1] if k1 < len(known) else rows[-1]
                span = rows[(rows >= first) & (rows <= last)]
                g = np.zeros((len(d), 2))
                for c in range(2):
                    g[span, c] = P[span, i, c] + np.interp(d[span], d[known[k0:k1]], off[k0:k1, c])
                ghost(g, i, span)
    for k, kr, x, strand in leaving:  # ghosts of no site here
        g = np.zeros((len(d), 2))
        g[k:kr + 1] = x
        ghost(g, -1, np.arange(k, kr + 1), strand)
    G_all = np.stack(G, axis=1) if G else np.zeros((len(d), 0, 2))
    ghost_ids, foreign_ids = np.array(ghost_of, dtype=np.int64), np.array(foreign, dtype=np.int64)
    # a far ring keeps every real cell bounded even where no mirror reaches: per section, around
    # the box of its real sites, FAR_MARGIN r_s beyond the farthest of them
    real = alive[:, :n, None]
    lo = np.where(real, P, np.inf).min(axis=1)
    hi = np.where(real, P, -np.inf).max(axis=1)
    centre = 0.5 * (lo + hi)
    reach = np.where(alive[:, :n], np.linalg.norm(P - centre[:, None], axis=2), 0.0).max(axis=1) + FAR_MARGIN * r_s
    ang = 2.0 * np.pi * np.arange(FAR_RING) / FAR_RING
    ring = centre[:, None] + reach[:, None, None] * np.stack([fm.cos(ang), fm.sin(ang)], 1)[None]
    P = np.concatenate([P, G_all, ring], axis=1)
    alive = np.concatenate([alive, np.array(ghost_alive, dtype=bool).reshape(-1, len(d)).T,
                            np.ones((len(d), FAR_RING), dtype=bool)], axis=1)
    bounds = []
    for i in range(n):
        e = np.arange(e0s[i], e0s[i] + ns[i])
        inner = model.particle_s[model.first_particle[e[:-1]] + 1]
        bounds.append(inner[(inner > s0[i]) & (inner < s1[i])])
    return Branch(chain=chain, s_chain=s_chain, d=d, P=P, alive=alive, strand=strands,
                   ghost_of=ghost_ids, foreign=foreign_ids, bounds=bounds, elem0=np.array(e0s), n_elem=np.array(ns))
