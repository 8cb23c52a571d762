"""Strands from root to tips: counts, packing, forks and terminations.

Woodstock §5 (opening), Fig. 3a-b; docs/model.md §2. Each profile holds
floor(phi_pack * area / (pi r_s^2)) strands packed with PBD. Walking the skeleton from the
roots, the strands of a node are carried to the next profile by a star-shaped map (the polar
angle is kept, the radius rescaled by the ratio of the two profiles' ray extents), re-packed, and
then:

* where the next profile holds fewer strands (taper), a random subset ends on the way: each gets a
  last control point at a random fraction (END_RANGE) of the edge, so strand ends are staggered
  and every profile keeps its full count;
* where it holds more, new strands begin in the free space;
* at a fork the strands are split among the children in proportion to their areas, each child
  taking the strands of the part of the parent profile that faces it (nearest to the child's
  direction projected into the parent's cross-section); the most lateral child chooses first.

The result is a set of control points per strand (node, u, v, world xyz) ordered root to tip.
A control point lies on its node's profile (``frac`` = 1) or, for an ending strand, at the
fraction ``frac`` of the edge from the previous control point's node to ``node``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .. import fmath as fm
from ..errors import InputError
from .packing import pack_profile, random_lattice, seed_positions, strand_capacity
from .profiles import polygon_centroid, ray_extent
from .skeleton import Skeleton
from .topology import Topology

#: where along an edge a tapering strand ends (fraction of the edge)
END_RANGE = (0.15, 0.85)


@dataclass(frozen=True, eq=False)
class StrandSet:
    """Strand control points in CSR layout (strand k owns rows offsets[k]:offsets[k+1])."""

    offsets: np.ndarray  # (n_strands + 1,) int64
    node: np.ndarray  # (n_cp,) skeleton node of each control point
    uv: np.ndarray  # (n_cp, 2) position in that node's profile frame
    xyz: np.ndarray  # (n_cp, 3) world position
    frac: np.ndarray  # (n_cp,) 1 on the node's profile, < 1 for an end part-way along the edge

    @property
    def count(self) -> int:
        return len(self.offsets) - 1


def star_map(src_poly: np.ndarray, dst_poly: np.ndarray, pts: np.ndarray, pad: float = 0.0) -> np.ndarray:
    """Map points inside ``src_poly`` into ``dst_poly`` keeping their polar angle about the
    centroids and scaling their radius by R_dst(phi) / (R_src(phi) + pad)."""
    c_src = polygon_centroid(src_poly)
    c_dst = polygon_centroid(dst_poly)
    rel = pts - c_src
    phi = fm.arctan2(rel[:, 1], rel[:, 0])
    scale = ray_extent(dst_poly, c_dst, phi) / (ray_extent(src_poly, c_src, phi) + pad)
    return c_dst + rel * scale[:, None]


def _subset_hull(pts: np.ndarray) -> np.ndarray | None:
    """Counter-clockwise convex hull of a strand subset, None if degenerate."""
    if len(pts) < 3:
        return None
    try:
        hull = ConvexHull(pts)
    except QhullError:
        return None
    return pts[hull.vertices]


def _split_fork(
    skel: Skeleton, topo: Topology, i: int, pts: np.ndarray
) -> list[np.ndarray]:
    """Indices of the strands at fork node ``i`` that go to each child (in child order)."""
    ch = topo.children[i]
    areas = np.array([skel.profiles[c].area for c in ch])
    n = len(pts)
    quota = n * areas / areas.sum()
    counts = np.floor(quota).astype(np.int64)
    rest = n - counts.sum()
    counts[np.argsort(-(quota - counts), kind="stable")[:rest]] += 1
    prof = skel.profiles[i]
    lateral = []
    targets = []
    for c in ch:
        d = skel.positions[c] - skel.positions[i]
        w = topo.frames[i, :2] @ d / np.linalg.norm(d)
        lateral.append(np.linalg.norm(w))
        targets.append(prof.centroid + w * prof.equivalent_radius)
    order = sorted(range(len(ch)), key=lambda k: (-lateral[k], k))
    remaining = np.arange(n)
    chosen: list[np.ndarray] = [np.zeros(0, dtype=np.int64)] * len(ch)
    for k in order[:-1]:
        dist = np.linalg.norm(pts[remaining] - targets[k], axis=1)
        take = np.argsort(dist, kind="stable")[: counts[k]]
        chosen[k] = np.sort(remaining[take])
        remaining = np.delete(remaining, take)
    chosen[order[-1]] = remaining
    return chosen


def build_strands(
    skel: Skeleton,
    topo: Topology,
    r_s: float,
    phi_pack: float,
    iterations: int,
    rng: np.random.Generator,
) -> StrandSet:
    """Generate the strand group SG of a skeleton (see module docstring)."""
    n_nodes = len(skel.ids)
    ids_at: list[np.ndarray] = [None] * n_nodes  # type: ignore[list-item]
    uv_at: list[np.ndarray] = [None] * n_nodes  # type: ignore[list-item]
    incoming: dict[int, tuple[np.ndarray, np.ndarray, bool]] = {}
    ends: list[tuple[np.ndarray, int, np.ndarray, np.ndarray]] = []  # (ids, node, uv, frac)
    next_id = 0
    lattice = random_lattice(rng)
    for i in range(n_nodes):
        prof = skel.profiles[i]
        cap = strand_capacity(prof, r_s, phi_pack)
        if skel.parent[i] < 0:
            pts = seed_positions(prof, cap, r_s, lattice, rng)
            if len(pts) == 0:
                raise InputError(skel.source, f"skeleton.node[{skel.ids[i]}].profile",
                                 f"holds no strand of r_s = {r_s:g} m (area {prof.area:.3g} m^2); "
                                 "lower strands.r_s or widen the profile")
            ids = np.arange(next_id, next_id + len(pts))
            next_id += len(pts)
        else:
            ids, src, whole = incoming.pop(i)
            p = skel.parent[i]
            hull = None if whole else _subset_hull(src)
            if whole:
                goal = star_map(skel.profiles[p].polygon, prof.polygon, src)
            elif hull is not None:
                goal = star_map(hull, prof.polygon, src, pad=r_s)
            elif len(src):
                goal = src - src.mean(axis=0) + prof.centroid
            else:
                goal = src
            pts, kept, n_new = pack_profile(prof, goal, cap, r_s, iterations, lattice, rng)
            gone = np.setdiff1d(np.arange(len(ids)), kept)
            if len(gone):
                ends.append((ids[gone], i, goal[gone], rng.uniform(*END_RANGE, len(gone))))
            ids = np.concatenate([ids[kept], np.arange(next_id, next_id + n_new)])
            next_id += n_new
        ids_at[i], uv_at[i] = ids.astype(np.int64), pts
        ch = topo.children[i]
        if len(ch) == 1:
            incoming[ch[0]] = (ids, pts, True)
        elif len(ch) > 1:
            for c, sel in zip(ch, _split_fork(skel, topo, i, pts)):
                incoming[c] = (ids[sel], pts[sel], False)
    return _collect(skel, topo, ids_at, uv_at, ends)


def _collect(
    skel: Skeleton, topo: Topology, ids_at: list[np.ndarray], uv_at: list[np.ndarray],
    ends: list[tuple[np.ndarray, int, np.ndarray, np.ndarray]],
) -> StrandSet:
    """Gather per-node positions and strand ends into per-strand control points (root to tip),
    dropping strands with a single control point (no length)."""
    sid = np.concatenate(ids_at + [e[0] for e in ends])
    node = np.concatenate([np.full(len(a), i, dtype=np.int64) for i, a in enumerate(ids_at)]
                          + [np.full(len(e[0]), e[1], dtype=np.int64) for e in ends])
    uv = np.concatenate(uv_at + [e[2] for e in ends])
    frac = np.concatenate([np.ones(len(a)) for a in ids_at] + [e[3] for e in ends])
    order = np.lexsort((node, sid))  # by strand, then topological (= root-to-tip) order
    sid, node, uv, frac = sid[order], node[order], uv[order], frac[order]
    good = np.bincount(sid)[sid] >= 2
    sid, node, uv, frac = sid[good], node[good], uv[good], frac[good]
    _, sid = np.unique(sid, return_inverse=True)  # renumber densely, order kept
    offsets = np.concatenate([[0], np.cumsum(np.bincount(sid))]).astype(np.int64)
    fr = topo.frames[node]
    xyz = skel.positions[node] + uv[:, :1] * fr[:, 0] + uv[:, 1:] * fr[:, 1]
    part = np.flatnonzero(frac < 1.0)  # ends lie between the previous control point and the node
    xyz[part] = (1.0 - frac[part, None]) * xyz[part - 1] + frac[part, None] * xyz[part]
    return StrandSet(offsets=offsets, node=node, uv=uv, xyz=xyz, frac=frac)
