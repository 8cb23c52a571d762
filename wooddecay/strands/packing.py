"""Strand positions on a cross-section profile: seeding and PBD packing.

Woodstock §5 (opening) and docs/model.md §2: strand positions on each profile are optimised with PBD so
that strands do not collide (centre distance >= 2 r_s) and stay inside the profile. Count per
profile: floor(phi_pack * area / (pi r_s^2)).

Positions are 2D points in the node frame (u, v) of :mod:`wooddecay.strands.topology`.
A profile's sites are the hex lattice (spacing >= 2 r_s, bisected to hold the count) that makes
the packing valid by construction; carried strands take the sites nearest their goals (minimum
total displacement) and PBD then pulls them back towards the goals, accepting only iterates that
satisfy every constraint (docs/decisions.md explains why PBD alone is not enough at phi_pack 0.8).
"""
from __future__ import annotations

import numba as nb
import numpy as np
from matplotlib.path import Path as _MplPath
from scipy.spatial import cKDTree

from .. import fmath as fm
from .assignment import assign_sites
from .profiles import Profile, closest_edge

#: separation actually enforced, a hair above 2 r_s so the invariant survives round-off
SEPARATION_SLACK = 1.0 + 1e-6


def strand_capacity(profile: Profile, r_s: float, phi_pack: float) -> int:
    """floor(phi_pack * A / (pi r_s^2)) strands fit on ``profile`` (docs/model.md §2)."""
    return int(np.floor(phi_pack * profile.area / (np.pi * r_s * r_s)))


def inside(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Strict point-in-polygon (matplotlib's compiled test): the hot-loop variant of
    :func:`wooddecay.strands.profiles.contains`, which also accepts points within round-off of
    the boundary."""
    return _MplPath(poly).contains_points(pts)


def hex_lattice(profile: Profile, spacing: float, lattice: tuple[float, np.ndarray]) -> np.ndarray:
    """Points inside the profile of a hexagonal lattice with the given orientation
    ``lattice = (angle, offset)`` (offset in spacings, about the profile's vertex mean).

    One orientation per model keeps consecutive profiles' lattices aligned, so strands run
    parallel and the REG is regular across the grain (docs/decisions.md)."""
    poly = profile.polygon
    c = poly.mean(axis=0)
    radius = np.max(np.linalg.norm(poly - c, axis=1)) + spacing
    n = int(np.ceil(radius / spacing)) + 1
    i, j = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1), indexing="ij")
    pts = np.stack([i + 0.5 * j, j * (np.sqrt(3.0) / 2.0)], axis=-1).reshape(-1, 2) * spacing
    a, offset = lattice
    rot = np.array([[fm.cos(a), -fm.sin(a)], [fm.sin(a), fm.cos(a)]])
    pts = (pts + np.asarray(offset) * spacing) @ rot.T + c
    return pts[inside(poly, pts)]


def random_lattice(rng: np.random.Generator) -> tuple[float, np.ndarray]:
    """A random lattice orientation (angle in [0, pi/3), offset in [-1/2, 1/2)^2 spacings)."""
    return float(rng.uniform(0.0, np.pi / 3.0)), rng.uniform(-0.5, 0.5, 2)


def seed_positions(profile: Profile, count: int, r_s: float, lattice: tuple[float, np.ndarray],
                   rng: np.random.Generator) -> np.ndarray:
    """``count`` non-overlapping positions: the densest hex lattice (spacing >= 2 r_s) holding
    at least ``count`` points inside the profile, thinned at random to ``count``.

    Returns fewer points only when even spacing 2 r_s cannot hold ``count``.
    """
    if count <= 0:
        return np.zeros((0, 2))
    lo = 2.0 * r_s * SEPARATION_SLACK
    best = hex_lattice(profile, lo, lattice)
    # a hex lattice of spacing a holds about area / (sqrt(3)/2 a^2) points: bracket around that
    guess = np.sqrt(profile.area / (count * np.sqrt(3.0) / 2.0))
    hi = max(lo, 1.1 * guess)
    if len(best) > count:
        for _ in range(14):  # bisection on the spacing: largest that still holds `count`
            mid = 0.5 * (lo + hi)
            pts = hex_lattice(profile, mid, lattice)
            if len(pts) >= count:
                lo, best = mid, pts
            else:
                hi = mid
    keep = np.sort(rng.choice(len(best), size=min(count, len(best)), replace=False))
    return best[keep]


def _edge_vectors(poly: np.ndarray) -> np.ndarray:
    """Edge vectors of a closed polygon: edge i runs from vertex i to vertex i + 1."""
    return np.roll(poly, -1, axis=0) - poly


def _inward_normals(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit inward normals of the edges (left normals: the polygon is counter-clockwise) and
    unit inward bisectors at the vertices (vertex i joins edges i - 1 and i)."""
    d = _edge_vectors(poly)
    edge_n = np.stack([-d[:, 1], d[:, 0]], axis=1)
    edge_n /= np.maximum(np.linalg.norm(edge_n, axis=1, keepdims=True), 1e-300)
    vert_n = edge_n + np.roll(edge_n, 1, axis=0)
    vert_n /= np.maximum(np.linalg.norm(vert_n, axis=1, keepdims=True), 1e-300)
    return edge_n, vert_n


def _project_inside(profile: Profile, pts: np.ndarray) -> np.ndarray:
    """Points outside the profile move onto its closest boundary point, nudged inside by
    round-off along the inward normal of the closest edge (the inward bisector where that
    point is a vertex), which is inward also on concave profiles."""
    poly = profile.polygon
    out = ~inside(poly, pts)
    if not out.any():
        return pts
    eps = 1e-9 * profile.equivalent_radius
    edge, t = closest_edge(poly, pts[out])
    d = _edge_vectors(poly)
    foot = poly[edge] + t[:, None] * d[edge]
    edge_n, vert_n = _inward_normals(poly)
    length = np.linalg.norm(d[edge], axis=1)
    normal = edge_n[edge]
    normal = np.where((t * length <= eps)[:, None], vert_n[edge], normal)
    normal = np.where(((1.0 - t) * length <= eps)[:, None], vert_n[(edge + 1) % len(poly)], normal)
    pts = pts.copy()
    pts[out] = foot + normal * eps
    return pts


def overlapping_pairs(pts: np.ndarray, r_s: float) -> np.ndarray:
    """(k, 2) index pairs closer than 2 r_s (the packing constraint)."""
    if len(pts) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    return cKDTree(pts).query_pairs(2.0 * r_s, output_type="ndarray")


@nb.njit(cache=True)
def collision_sweep(pts, pairs, target):
    """One Gauss-Seidel PBD sweep over the pair constraints |x_i - x_j| >= target.

    Sequential by design (Gauss-Seidel: each projection sees the previous ones), so the
    result is deterministic; packing is a small per-profile problem, not a parallel kernel.
    """
    for k in range(len(pairs)):
        i, j = pairs[k, 0], pairs[k, 1]
        dx = pts[j, 0] - pts[i, 0]
        dy = pts[j, 1] - pts[i, 1]
        dist = np.sqrt(dx * dx + dy * dy)
        if dist < target:
            if dist < 1e-15:
                dx, dy, dist = 1.0, 0.0, 1.0
                c = 0.5 * target
            else:
                c = 0.5 * (target - dist) / dist
            pts[i, 0] -= c * dx
            pts[i, 1] -= c * dy
            pts[j, 0] += c * dx
            pts[j, 1] += c * dy


def collision_sweep_reference(pts: np.ndarray, pairs: np.ndarray, target: float) -> None:
    """Plain numpy twin of :func:`collision_sweep` (the same projections in the same order)."""
    for i, j in pairs:
        d = pts[j] - pts[i]
        dist = float(np.sqrt(d[0] * d[0] + d[1] * d[1]))
        if dist >= target:
            continue
        if dist < 1e-15:
            d, c = np.array([1.0, 0.0]), 0.5 * target
        else:
            c = 0.5 * (target - dist) / dist
        pts[i] -= c * d
        pts[j] += c * d


def pbd_relax(
    profile: Profile, pts: np.ndarray, goal: np.ndarray, r_s: float, iterations: int,
    pull: float = 0.5, sweeps: int = 4,
) -> np.ndarray:
    """PBD packing: move a valid packing towards ``goal`` positions under the constraints.

    Each iteration pulls every point a fraction ``pull`` towards its goal, projects the pair
    constraints |x_i - x_j| >= 2 r_s with ``sweeps`` Gauss-Seidel sweeps and the inside
    constraint; an iterate is accepted only if every point is strictly inside and no pair
    overlaps, so the result is always a valid packing (the input, which must be valid, at worst).
    """
    target = 2.0 * r_s * SEPARATION_SLACK
    best = pts
    cur = pts.copy()
    for _ in range(iterations):
        cur = _project_inside(profile, cur + pull * (goal - cur))
        pairs = cKDTree(cur).query_pairs(1.5 * target, output_type="ndarray")
        for _ in range(sweeps):
            collision_sweep(cur, pairs, target)
            cur = _project_inside(profile, cur)
        if inside(profile.polygon, cur).all() and len(overlapping_pairs(cur, r_s)) == 0:
            best = cur.copy()
        else:
            cur = best.copy()
            pull *= 0.5
    return best


def pack_profile(
    profile: Profile, goal: np.ndarray, capacity: int, r_s: float, iterations: int,
    lattice: tuple[float, np.ndarray], rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Pack carried strands (at ``goal``) and new ones on a profile holding ``capacity``.

    Sites: the hex lattice holding ``capacity`` points (:func:`seed_positions`). If fewer sites
    than carried strands exist, a random subset of the carried strands continues. Carried
    strands take the sites nearest their goals (:func:`assign_sites`), the remaining sites start
    new strands, then :func:`pbd_relax` moves the carried strands back towards their goals.

    Returns
    -------
    pts : (k, 2) positions, carried strands first (in ``kept`` order), then new strands
    kept : indices into ``goal`` of the carried strands that continue
    n_new : number of new strands (the last ``n_new`` rows of ``pts``)
    """
    sites = seed_positions(profile, capacity, r_s, lattice, rng)
    kept = np.arange(len(goal))
    if len(goal) > len(sites):
        kept = np.sort(rng.choice(len(goal), size=len(sites), replace=False))
    site_of = assign_sites(goal[kept], sites)
    free = np.setdiff1d(np.arange(len(sites)), site_of)
    pts = np.vstack([sites[site_of], sites[free]])
    pts = pbd_relax(profile, pts, np.vstack([goal[kept], sites[free]]), r_s, iterations)
    return pts, kept, len(free)
