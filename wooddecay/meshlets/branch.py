"""A branch's kinetic sites: sections, strand sites, ghost mirrors and element bounds (SPEC §5).

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
mirror goes across the nearest edge turned by more than CORNER. At a concave profile a mirror
can cut the wood itself: one that lands inside the profile (across an arm) and one with its foot
within r_s / 2 of a sharp reflex vertex (the bisector runs on into the wood) are left out
(:func:`_valid_mirrors`); the cells there end at their neighbours' mirrors. Mirrors across the
mild reflex vertices of a concave curve's polygon stay: without them the cells along the inside
of a C leaked into its hollow. Convex cells cannot
follow a reflex corner exactly: what they miss on one side of it they overhang on the other.
Where a side branch starts, the mirrors go across the hull of its sites offset by r_s
(:func:`~wooddecay.meshlets.offset.offset_contour`).
FAR_RING far sites around each section keep every real cell bounded even where no mirror reaches. ``docs/decisions.md``
(Meshlets) records this choice.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..strands import profiles
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
    ghost_of: np.ndarray  # (n_ghost,) real site mirrored by each ghost
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
    turned = (u[e0] @ u.T) < np.cos(CORNER)
    d1 = np.where(turned, dist, np.inf)
    e1 = np.argmin(d1, axis=1)
    rows = np.arange(n)
    feet = np.stack([foot[rows, e0], foot[rows, e1]], axis=1)
    return feet, np.stack([dist[rows, e0], d1[rows, e1]], axis=1)


def _valid_mirrors(poly: np.ndarray, pts: np.ndarray, feet: np.ndarray, r_s: float) -> np.ndarray:
    """(n, 2) whether the mirrors of ``pts`` at ``feet`` (:func:`_feet`) bound the wood: not one
    strictly inside ``poly`` or with its foot within r_s / 2 of a sharp reflex vertex (turning by
    more than CORNER; the bisector runs on into the wood beyond it). Across a mild reflex vertex (a
    concave curve's polygon) the bisector, a line through the vertex, cuts into the wood by about
    l^2 / 8R only (edge length l, curvature radius R)."""
    a = np.asarray(poly, float)
    e_in, e_out = a - np.roll(a, 1, axis=0), np.roll(a, -1, axis=0) - a
    reflex = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0] < 0.0  # CCW profiles
    cos_turn = (e_in * e_out).sum(1) / np.linalg.norm(e_in, axis=1) / np.linalg.norm(e_out, axis=1)
    ghost = (2.0 * feet - pts[:, None]).reshape(-1, 2)
    cut = (profiles.signed_distance(a, ghost) > 0.0).reshape(feet.shape[:2])
    for v in a[reflex & (cos_turn < np.cos(CORNER))]:
        cut |= np.linalg.norm(feet - v, axis=-1) <= 0.5 * r_s
    return ~cut


def _mirror_tapered(P, offset, nearest, polys, alive, depth, valid, r_s: float) -> None:
    """Ghosts for the strands near the bark at some node section but deeper than GHOST_DEPTH r_s
    at another (a tapering branch; in place: ``offset`` rank 0, ``depth``, ``valid``). The
    nearest edge of a deep site can lie on any side, and mirrors across it cut the wood between
    sections; instead, at every node section the mirror goes across the line square to the
    site's outward direction at its nearest section, through the boundary along it, so the
    ghost stays on that side. A strand whose mirror lands inside a profile gets none."""
    reach = GHOST_DEPTH * r_s
    for i in np.flatnonzero((depth[:, 0] >= reach) & (nearest.min(axis=0) < reach)):
        rows = [k for k in polys if alive[k, i]]
        k0 = min(rows, key=lambda k: nearest[k, i])
        out = offset[k0, i, 0]
        if not np.linalg.norm(out) > 0.0:
            continue
        angle = float(np.arctan2(out[1], out[0]))
        step = {k: float(profiles.ray_extent(polys[k], P[k, i], [angle])[0]) for k in rows}
        unit = out / np.linalg.norm(out)
        ghost = {k: P[k, i] + 2.0 * step[k] * unit for k in rows}
        if all(step[k] > 0.0 and profiles.signed_distance(polys[k], ghost[k][None])[0] <= 0.0 for k in rows):
            for k in rows:
                offset[k, i, 0] = ghost[k] - P[k, i]
            depth[i, 0] = min(nearest[k, i] for k in rows)
            valid[i, 0] = True


def _section_profile(skel, chain, node: int, pts: np.ndarray, r_s: float) -> np.ndarray:
    """The contour the ghosts mirror across at a node section: the node's profile, except where a
    side branch starts (its strands fill only part of the fork's profile): there the convex hull
    of the branch's sites (the alpha shape with alpha = inf) offset outwards by r_s."""
    if node != chain[0] or skel.parent[node] < 0 or node != skel.parent[chain[1]] or len(pts) < 3:
        return skel.profiles[node].polygon
    try:
        hull = ConvexHull(pts)
    except QhullError:
        return skel.profiles[node].polygon
    return offset_contour(pts[hull.vertices], r_s, "round")[0]


def _branch_chain(topo, skel, b: int) -> np.ndarray:
    nodes = np.flatnonzero(topo.branch == b)
    nodes = nodes[np.argsort(topo.s[nodes], kind="stable")]
    first = nodes[0]
    if skel.parent[first] >= 0:
        nodes = np.concatenate([[skel.parent[first]], nodes])
    return nodes


def setup_branch(model, b: int) -> Branch | None:
    """Sections, sites (real, ghosts, far ring) and element bounds of branch ``b`` of ``model``
    (see the module docstring); None when no strand runs through the branch."""
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
    rows, e0s, ns = [], [], []
    for k, st in enumerate(strands):
        e = np.arange(model.element_offsets[st], model.element_offsets[st + 1])
        mine = e[e_br[e] == b]
        if len(mine):
            rows.append(k)
            e0s.append(mine[0])
            ns.append(len(mine))
    rows = np.array(rows, dtype=np.int64)
    strands, c0, c1 = strands[rows], c0[rows], c1[rows]
    s0, s1 = model.cp_s[c0], model.cp_s[c1]
    d = np.unique(np.concatenate([s_chain[(s_chain >= s0.min()) & (s_chain <= s1.max())], s0, s1]))
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
    depth = np.full((n, 2), -np.inf)
    valid = np.ones((n, 2), dtype=bool)
    offset = np.full((len(d), n, 2, 2), np.nan)
    nearest = np.full((len(d), n), np.inf)  # distance to the nearest edge at each node section
    polys = {}
    for k in np.flatnonzero(is_node):
        idx = np.flatnonzero(alive[k])
        poly = polys[k] = _section_profile(skel, chain, node_at[float(d[k])], P[k, idx], r_s)
        foot, dist = _feet(poly, P[k, idx])
        depth[idx] = np.maximum(depth[idx], dist)
        nearest[k, idx] = dist[:, 0]
        valid[idx] &= _valid_mirrors(poly, P[k, idx], foot, r_s)
        offset[k, idx] = 2.0 * (foot - P[k, idx][:, None])
    _mirror_tapered(P, offset, nearest, polys, alive, depth, valid, r_s)
    # a run between two nodes: mirrors across the nearer node's profile
    between = {}
    for i in range(n):
        rows_i = np.flatnonzero(alive[:, i])
        if len(rows_i) and not is_node[rows_i].any():
            poly = skel.profiles[chain[int(np.argmin(np.abs(s_chain - d[rows_i].mean())))]].polygon
            foot, _ = _feet(poly, P[rows_i, i])
            valid[i] &= np.all(_valid_mirrors(poly, P[rows_i, i], foot, r_s), axis=0)
            between[i] = foot
    ghosts = [(i, r) for r in range(2) for i in np.flatnonzero((depth[:, r] < GHOST_DEPTH * r_s) & valid[:, r])]
    G = np.zeros((len(d), len(ghosts), 2))
    for j, (i, r) in enumerate(ghosts):
        rows_i = np.flatnonzero(alive[:, i])
        if i in between:
            G[rows_i, j] = 2.0 * between[i][:, r] - P[rows_i, i]
            continue
        known = rows_i[is_node[rows_i]]
        for c in range(2):
            G[rows_i, j, c] = P[rows_i, i, c] + np.interp(d[rows_i], d[known], offset[known, i, r, c])
    ghost_of = np.array([i for i, _ in ghosts], dtype=np.int64)
    # a far ring keeps every real cell bounded even where no mirror reaches: per section, around
    # the box of its real sites, FAR_MARGIN r_s beyond the farthest of them
    real = alive[:, :n, None]
    lo = np.where(real, P, np.inf).min(axis=1)
    hi = np.where(real, P, -np.inf).max(axis=1)
    centre = 0.5 * (lo + hi)
    reach = np.where(alive[:, :n], np.linalg.norm(P - centre[:, None], axis=2), 0.0).max(axis=1) + FAR_MARGIN * r_s
    ang = 2.0 * np.pi * np.arange(FAR_RING) / FAR_RING
    ring = centre[:, None] + reach[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], 1)[None]
    P = np.concatenate([P, G, ring], axis=1)
    alive = np.concatenate([alive, alive[:, ghost_of], np.ones((len(d), FAR_RING), dtype=bool)], axis=1)
    bounds = []
    for i in range(n):
        e = np.arange(e0s[i], e0s[i] + ns[i])
        inner = model.particle_s[model.first_particle[e[:-1]] + 1]
        bounds.append(inner[(inner > s0[i]) & (inner < s1[i])])
    return Branch(chain=chain, s_chain=s_chain, d=d, P=P, alive=alive, strand=strands,
                   ghost_of=ghost_of, bounds=bounds, elem0=np.array(e0s), n_elem=np.array(ns))
