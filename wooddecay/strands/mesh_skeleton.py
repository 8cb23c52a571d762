"""A skeleton and its profiles from a closed surface mesh (:mod:`.mesh_input`): a centreline
through cross-section centroids for logs, boards and stumps, branches traced through the
cross-sections for a branching mesh (:func:`tree_nodes`), and at every node the mesh sliced
perpendicular to it, its outer contour resampled as a polygon profile.

Branch-fracture §3.1-3.3 voxelises a scanned branch, takes each cross-section's outer contour and
grows the rings inwards from it by erosion. We slice the surface exactly instead of voxelising
(a 512^3 grid resolves a log's section with a few dozen voxels across, the slice with the
mesh's own vertices), and the rings come from the contours by reversed growth as for any polygon
profile (:mod:`.rings`).

Centreline (:func:`centreline`): the principal axis of the surface (area-weighted) spans the
mesh; ``n`` segments of about ``spacing`` (default: the mean equivalent radius sqrt(A / pi) of
the sections, so that a bend is followed) put ``n - 1`` interior nodes at the centroids of the
largest contour of the slices perpendicular to that axis; a gap is halved (down to REFINE_MIN r_s)
while a slice within it (PROBES) strays by more than r_s from the linear interpolation of its nodes' ray
extents (woodstock interpolates profiles between nodes that way), so knots and swellings get
nodes and a smooth log few. The end nodes continue the centreline
to the log's cut ends, square to them (:func:`_end_node`), so the end profiles are whole sections.

Profiles (:func:`profile_at`): the slice through each node perpendicular to its frame's T
(:func:`~wooddecay.strands.topology.build_topology`, the frame the strands are packed in), the
contour around the node (else the largest), in the frame's (U, V) coordinates, smoothed along its
length by a Gaussian of SMOOTH r_s (scaled back to the slice's area), its pockets shallower than
POCKET r_s filled, and resampled to points ``resolution`` apart along it (at
least MIN_POINTS): strands of radius r_s resolve no finer detail. A contour that is not a simple polygon after resampling is an error naming the node.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, cKDTree

from wooddecay.errors import InputError
from wooddecay.strands import profiles
from wooddecay.strands.mesh_input import MeshInput
from wooddecay.strands.skeleton import Skeleton
from wooddecay.strands.topology import build_topology

#: the end nodes stop this fraction of their distance to the last interior node short of the
#: end (a slice through the end face itself is degenerate)
END_INSET = 1e-3
#: a second contour beside a section's (not inside it) larger than this share of it: the mesh
#: branches across the slice (:func:`tree_nodes`)
APART = 0.1
#: a branch's contour continues the chain whose last centroid lies within this many times the
#: sum of their radii
TRACK = 1.5
#: rays per section when comparing a section with its neighbours' interpolation
RAYS = 180
#: where between two nodes the slices are compared with the nodes' interpolation
PROBES = (0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875)
#: node gaps are halved down to this many r_s
REFINE_MIN = 2.0
#: a face of a cut end turns less than this (rad) from the centreline
CAP_ANGLE = math.radians(30.0)
#: a rounded or broken end: its node sits where the section keeps this share of the last
#: interior node's area
END_AREA = 0.9
#: contours are smoothed along their length by a Gaussian of this many r_s (their detail below
#: r_s is noise to the strands, and its small reflex corners leave the meshlets' bark unbounded:
#: :mod:`wooddecay.meshlets.branch`)
SMOOTH = 1.0
#: pockets of a contour shallower than this many r_s are filled to its hull: strands do not
#: resolve them, and the meshlets' bark overhangs at reflex corners (:mod:`wooddecay.meshlets.branch`)
POCKET = 0.5
#: fewest points of a profile polygon
MIN_POINTS = 16
#: most points of a profile polygon (a 5 m perimeter at 1 cm)
MAX_POINTS = 512


def contour_loops(mesh, origin, normal) -> list[np.ndarray]:
    """The closed contours of the slice of ``mesh`` by the plane through ``origin`` with
    ``normal``, each an ``(k, 3)`` array of points in order (open chains are dropped)."""
    from trimesh.intersections import mesh_plane

    seg = mesh_plane(mesh, plane_normal=normal, plane_origin=origin)
    if len(seg) == 0:
        return []
    pts = seg.reshape(-1, 3)
    # the two segments meeting at a mesh edge end at the same point up to rounding: merge within
    # a tolerance (rounding to a grid splits the pairs that straddle a grid line)
    pairs = cKDTree(pts).query_pairs(1e-9 * float(np.max(mesh.extents)), output_type="ndarray")
    n = len(pts)
    _, vid = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                  directed=False)
    first = np.zeros(vid.max() + 1, dtype=np.int64)
    first[vid] = np.arange(n)  # a representative of each merged point
    vid = vid.reshape(-1, 2)
    vid = vid[vid[:, 0] != vid[:, 1]]
    nbr: dict[int, list[int]] = {}
    for a, b in vid.tolist():
        nbr.setdefault(a, []).append(b)
        nbr.setdefault(b, []).append(a)
    loops, seen = [], set()
    for start, ends in nbr.items():
        if start in seen or len(ends) != 2:
            continue
        loop, prev, cur = [start], -1, start
        seen.add(start)
        while True:
            nxt = [v for v in nbr[cur] if v != prev]
            if len(nbr[cur]) != 2 or not nxt:
                loop = None
                break
            prev, cur = cur, nxt[0]
            if cur == start:
                break
            if cur in seen:
                loop = None
                break
            seen.add(cur)
            loop.append(cur)
        if loop is not None and len(loop) >= 3:
            loops.append(pts[first[loop]])
    return loops


def _planar(loop: np.ndarray, origin, u, v) -> np.ndarray:
    """``loop`` in the plane coordinates (u, v) about ``origin``, counter-clockwise."""
    d = loop - origin
    poly = np.stack([d @ u, d @ v], axis=1)
    return poly if profiles.is_ccw(poly) else poly[::-1]


def plane_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (u, v) spanning the plane across ``normal``, with u x v along it."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def outer_contours(mesh, origin, normal, u, v) -> list[np.ndarray]:
    """The contours of the slice through ``origin`` with ``normal`` that lie inside no other (a
    hollow's cavity does), as CCW polygons in the plane's (u, v) about ``origin``."""
    polys = [_planar(loop, origin, u, v) for loop in contour_loops(mesh, origin, normal)]
    return [p for i, p in enumerate(polys)
            if not any(j != i and profiles.polygon_area(q) > profiles.polygon_area(p) and profiles.contains(q, p[:1])[0]
                       for j, q in enumerate(polys))]


def _main_contour(polys: list[np.ndarray]) -> np.ndarray | None:
    """Of a slice's outer contours, the one around the slice's origin, else the largest."""
    around = [p for p in polys if profiles.contains(p, np.zeros((1, 2)))[0]]
    return max(around or polys, key=profiles.polygon_area, default=None)


def section(mesh, origin, normal, u=None, v=None):
    """The outer contour of the slice through ``origin`` with ``normal`` (:func:`_main_contour`),
    as a CCW polygon in (u, v) (a basis of the plane if not given), or None if the plane misses
    the mesh."""
    if u is None:
        u, v = plane_basis(normal)
    return _main_contour(outer_contours(mesh, origin, normal, u, v))


def principal_axis(points: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """The unit direction of largest (weighted) spread of ``points`` (n, 3), its largest
    component positive."""
    w = np.ones(len(points)) if weights is None else weights
    d = points - (w[:, None] * points).sum(0) / w.sum()
    axis = np.linalg.eigh((w[:, None] * d).T @ d)[1][:, -1]
    return axis if axis[int(np.argmax(np.abs(axis)))] > 0 else -axis


def _along_axis(mesh):
    """The principal axis, a basis (u, v) of the planes across it, the mesh's extent s0..s1
    along it and the point of the axis line at s = 0."""
    axis = principal_axis(mesh.triangles_center, mesh.area_faces)
    u, v = plane_basis(axis)
    s = mesh.vertices @ axis
    return axis, u, v, float(s.min()), float(s.max()), mesh.centroid - (mesh.centroid @ axis) * axis


def _extend(mesh, tip: np.ndarray, back: np.ndarray, gap: float, reach: float) -> np.ndarray:
    """The end node beyond ``tip`` on the way from ``back`` (:func:`_end_node`): the surface up
    to 2 ``gap`` beyond ``tip``, within ``reach`` of the line, bounds how far."""
    t = (tip - back) / np.linalg.norm(tip - back)
    d = mesh.vertices - tip
    along = d @ t
    near = (along > 0) & (along < 2.0 * gap) & (np.linalg.norm(d - along[:, None] * t, axis=1) <= reach)
    return _end_node(mesh, tip, t, float(along[near].max(initial=0.0)), reach)


def centreline(mi: MeshInput, spacing: float | None, resolution: float) -> np.ndarray:
    """Node positions ``(n + 1, 3)`` along the mesh's centreline (module docstring)."""
    mesh = mi.mesh
    axis, u, v, s0, s1, centre = _along_axis(mesh)
    length = s1 - s0
    angles = np.linspace(-np.pi, np.pi, RAYS, endpoint=False)
    cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def at(t: float):
        """Centroid and ray extents (about it) of the slice perpendicular to the axis at t."""
        if t not in cache:
            o = centre + t * axis
            polys = outer_contours(mesh, o, axis, u, v)
            poly = _main_contour(polys)
            if poly is None:
                raise InputError(mi.source, "", f"no closed cross-section {t - s0:.3f} m along the mesh's axis")
            if any(p is not poly and profiles.polygon_area(p) > APART * profiles.polygon_area(poly) for p in polys):
                raise _Branches
            c = profiles.polygon_centroid(poly)
            cache[t] = (o + c[0] * u + c[1] * v, profiles.ray_extent(poly, c, angles))
        return cache[t]

    def strays(a: float, b: float) -> bool:
        """Whether a slice between a and b (at PROBES points) strays by more than ``resolution``
        from the linear interpolation of theirs."""
        return any(np.abs(at(a + w * (b - a))[1] - ((1 - w) * at(a)[1] + w * at(b)[1])).max() > resolution
                   for w in PROBES)

    radii = [float(np.sqrt(np.mean(at(t)[1] ** 2))) for t in np.linspace(s0, s1, 10)[1:-1]]
    if spacing is None:
        spacing = float(np.mean(radii))
    n = max(3, math.ceil(length / spacing))
    stations = list(s0 + length * np.arange(1, n) / n)
    # halve a gap while the section between its two nodes strays by more than ``resolution`` from
    # their linear interpolation (a knot, a swelling), down to REFINE_MIN r_s
    gap = length / n
    while gap / 2 >= REFINE_MIN * resolution:
        gap /= 2
        mids = [0.5 * (a + b) for a, b in zip(stations[:-1], stations[1:]) if b - a > 1.5 * gap and strays(a, b)]
        if not mids:
            break
        stations = sorted(stations + mids)
    inner = np.array([at(t)[0] for t in stations])
    ends = [_extend(mesh, tip, back, length / n, 1.5 * max(radii)) for tip, back in ((inner[0], inner[1]),
                                                                                     (inner[-1], inner[-2]))]
    return np.vstack([ends[0], inner, ends[1]])


def _area_at(mesh, origin, normal) -> float:
    poly = section(mesh, origin, normal)
    return 0.0 if poly is None else profiles.polygon_area(poly)


def _end_node(mesh, tip, t, far: float, reach: float) -> np.ndarray:
    """The end node beyond the last interior node ``tip`` (direction ``t``, the surface up to
    ``far`` along it). A cut end (faces beyond ``tip`` within ``reach`` of the centreline,
    turned less than CAP_ANGLE from ``t``, of at least half the section's area): on the line
    from ``tip`` along the cut's mean normal, END_INSET of ``far`` short of the cut's plane, so
    the end profile (square to the line from ``tip``) is a full section. Otherwise (a rounded or
    broken end) where the section perpendicular to ``t`` keeps END_AREA of the section at ``tip``
    (bisection)."""
    rel = mesh.triangles_center - tip
    along = rel @ t
    w = mesh.area_faces * ((along > 0) & (mesh.face_normals @ t > math.cos(CAP_ANGLE))
                           & (np.linalg.norm(rel - along[:, None] * t, axis=1) <= reach))
    a0 = _area_at(mesh, tip, t)
    if w.sum() >= 0.5 * a0:
        normal = (w @ mesh.face_normals) / np.linalg.norm(w @ mesh.face_normals)
        depth = float((w @ rel) / w.sum() @ normal)
        return tip + (depth - END_INSET * far) * normal
    lo, hi = 0.0, far
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _area_at(mesh, tip + mid * t, t) >= END_AREA * a0 else (lo, mid)
    return tip + max(lo - END_INSET * far, 0.0) * t


def _fill_shallow(poly: np.ndarray, depth: float) -> np.ndarray:
    """``poly`` (counter-clockwise) with its pockets (the runs between consecutive convex-hull
    vertices) shallower than ``depth`` flattened onto their hull edge."""
    hull = ConvexHull(poly).vertices  # counter-clockwise, as ``poly``
    out = poly.copy()
    n = len(poly)
    for i, j in zip(hull, np.roll(hull, -1)):
        run = (np.arange(i, i + (j - i) % n + 1)) % n
        a, b = poly[i], poly[j]
        e = (b - a) / np.linalg.norm(b - a)
        rel = poly[run] - a
        off = e[0] * rel[:, 1] - e[1] * rel[:, 0]  # distance inside (left of) the hull edge
        if off.max() < depth:
            out[run] = a + np.outer(rel @ e, e)
    return out


def _resample(poly: np.ndarray, spacing: float, most: int) -> np.ndarray:
    """Points about ``spacing`` apart along the closed polygon (MIN_POINTS to ``most``)."""
    k = math.ceil(profiles.polygon_perimeter(poly) / spacing)
    return profiles.resample_closed(poly, int(np.clip(k, MIN_POINTS, most)))


def _contour_polygon(poly: np.ndarray, resolution: float) -> np.ndarray | None:
    """A slice's contour as the strands resolve it (module docstring, Profiles): smoothed,
    scaled back to its area, its shallow pockets filled, resampled ``resolution`` apart, CCW;
    None where that is not a simple polygon of positive area."""
    fine = _resample(poly, resolution / 4.0, MAX_POINTS * 4)
    step = np.linalg.norm(fine[1] - fine[0])
    smooth = gaussian_filter1d(fine, SMOOTH * resolution / step, axis=0, mode="wrap")
    # smoothing shrinks a convex contour by its curvature: scale back to the slice's area
    c = profiles.polygon_centroid(smooth)
    fine = _fill_shallow(c + (smooth - c) * math.sqrt(profiles.polygon_area(poly) / profiles.polygon_area(smooth)),
                         POCKET * resolution)
    out = _resample(fine, resolution, MAX_POINTS)
    if not profiles.is_simple(out) or not profiles.polygon_area(out) > 0.0:
        return None
    return out if profiles.is_ccw(out) else out[::-1]


def profile_at(mi: MeshInput, origin, frame, resolution: float, node: str) -> profiles.Profile:
    """The polygon profile at a node (module docstring); ``frame`` rows U, V, T."""
    poly = section(mi.mesh, origin, frame[2], frame[0], frame[1])
    if poly is None:
        raise InputError(mi.source, f"node {node}", "the slice perpendicular to the centreline misses the mesh")
    out = _contour_polygon(poly, resolution)
    if out is None:
        raise InputError(mi.source, f"node {node}", f"the mesh's cross-section there is not a simple polygon at "
                         f"{resolution * 1e3:.1f} mm resolution")
    return profiles.polygon(out)


def contour_around(mesh, origin, U, V, sites: np.ndarray, resolution: float) -> np.ndarray | None:
    """Of the slice through ``origin`` across U x V, the outer contour that holds the most of
    ``sites`` ((n, 2) in (U, V)), as :func:`profile_at` makes a profile of it; None where no
    contour holds one of them or the result is not a simple polygon (past a fork:
    :mod:`wooddecay.meshlets.branch`)."""
    polys = outer_contours(mesh, origin, np.cross(U, V), U, V)
    held = [int(profiles.contains(p, sites).sum()) for p in polys]
    if not polys or max(held) == 0:
        return None
    return _contour_polygon(polys[int(np.argmax(held))], resolution)


class _Branches(Exception):
    """A slice across the principal axis cuts the mesh in several places: it branches."""


def _mean_radius(mesh, axis, u, v, s0: float, s1: float, centre) -> float:
    """The mean radius sqrt(A / pi) of the largest outer contour of 8 slices evenly across the
    mesh's extent s0..s1 along ``axis`` (the node spacing :func:`tree_nodes` defaults to)."""
    areas = [max((profiles.polygon_area(p) for p in outer_contours(mesh, centre + t * axis, axis, u, v)),
                 default=0.0) for t in np.linspace(s0, s1, 10)[1:-1]]
    return float(np.mean(np.sqrt(np.array(areas) / np.pi)))


def _cross_sections(mesh, o, axis, u, v) -> list[tuple[np.ndarray, float]]:
    """The outer contours of the slice through ``o`` across ``axis``: each one's centroid (3D)
    and radius sqrt(A / pi)."""
    found = []
    for poly in outer_contours(mesh, o, axis, u, v):
        c = profiles.polygon_centroid(poly)
        found.append((o + c[0] * u + c[1] * v, math.sqrt(profiles.polygon_area(poly) / math.pi)))
    return found


class _Chains:
    """The chains of nodes that :func:`tree_nodes` traces from slice to slice: the nodes'
    positions, parents, radii and the first node of each one's chain; the loose chains; the chains
    still being traced and the finished ones."""

    def __init__(self, source, s0: float):
        self.source, self.s0 = source, s0
        self.pos: list[np.ndarray] = []
        self.parent: list[int] = []
        self.radius: list[float] = []
        self.start: list[int] = []  # the first node of each node's chain
        self.loose: dict[int, int] = {}  # first node of a loose chain -> the node it joined (-1: not yet)
        self.active: list[int] = []  # the last node of each chain still being traced
        self.ends: list[int] = []  # the last node of each finished chain

    def fail(self, t: float, what: str) -> InputError:
        return InputError(self.source, "", f"{what} {t - self.s0:.3f} m along the mesh's axis: the mesh is not a "
                          "log or a tree (give an explicit skeleton)")

    def near(self, found, a: int, j: int) -> bool:
        """Cross-section j of ``found`` lies within TRACK times the sum of its and node a's radii
        of node a."""
        return bool(np.linalg.norm(found[j][0] - self.pos[a]) < TRACK * (found[j][1] + self.radius[a]))

    def claim(self, found) -> dict[int, list[int]]:
        """The cross-sections of ``found`` each chain continues into: per chain's last node, those
        nearest it of all chains within reach; a cross-section near none under its own key -1 - j."""
        claimed: dict[int, list[int]] = {}
        for j in range(len(found)):
            cands = [(np.linalg.norm(found[j][0] - self.pos[a]), a) for a in self.active if self.near(found, a, j)]
            claimed.setdefault(min(cands)[1] if cands else -1 - j, []).append(j)
        return claimed

    def join(self, found, claimed: dict[int, list[int]], t: float) -> None:
        """A chain that claimed nothing but lies near another's claimed cross-sections joins it:
        the loose one of the two ends there, joined to the other's last node, and the other goes
        on (into those of the cross-sections near it); two chains both loose or both not raise."""
        for a in self.active:
            if a in claimed:
                continue
            joined = [b for b, js in claimed.items() if b >= 0 and any(self.near(found, a, j) for j in js)]
            if not joined:
                continue
            b = joined[0]
            if (self.start[b] in self.loose) == (self.start[a] in self.loose):
                raise self.fail(t, "two branches join")
            if self.start[b] in self.loose:  # the chain that is not loose goes on, the loose one ends here
                js = [j for j in claimed.pop(b) if self.near(found, a, j)]
                claimed[a] = js
                a, b = b, a
            self.loose[self.start[a]] = b

    def advance(self, found, claimed: dict[int, list[int]], k: int) -> None:
        """Slice k's nodes: each chain continues into the largest of its cross-sections, each other
        one starts a branch from the chain's last node; a cross-section near no chain after the
        first slice starts a loose chain. Chains that claimed nothing end."""
        self.ends += [a for a in self.active if a not in claimed]
        self.active = []
        for a, js in claimed.items():
            for i, j in enumerate(sorted(js, key=lambda j: -found[j][1])):  # the largest part continues
                self.pos.append(found[j][0])
                self.parent.append(max(a, -1))
                self.radius.append(found[j][1])
                self.start.append(self.start[a] if a >= 0 and i == 0 else len(self.pos) - 1)
                if a < 0 and k > 0:
                    self.loose[len(self.pos) - 1] = -1
                self.active.append(len(self.pos) - 1)

    def hang_loose(self, parent: np.ndarray) -> list[int]:
        """Turn each loose chain around in ``parent``: its last node hangs from the node it joined.
        Returns the tips: the last nodes of the other chains (node 0, at the root end, excepted),
        then the first nodes of the loose ones."""
        tips = [e for e in self.ends if e > 0 and self.start[e] not in self.loose]
        for first, joint in self.loose.items():
            last = next(e for e in self.ends if self.start[e] == first)
            path = [last]
            while path[-1] != first:
                path.append(int(parent[path[-1]]))
            parent[path[0]] = joint
            parent[path[1:]] = path[:-1]
            tips.append(first)
        return tips


def _with_end_nodes(mi: MeshInput, pos: np.ndarray, parent: np.ndarray, tips: list[int], gap: float,
                    reach: float) -> tuple[np.ndarray, np.ndarray]:
    """The traced nodes with end nodes beyond the root end and each tip (:func:`_extend`), in an
    order with every parent before its children, and their parents (the root's -1)."""
    first = np.flatnonzero(parent == 0)
    if len(first) == 0:
        raise InputError(mi.source, "", "the mesh is too short along its axis for a skeleton")
    root = _extend(mi.mesh, pos[0], pos[first[0]], gap, reach)
    ends_xyz = [_extend(mi.mesh, pos[e], pos[parent[e]], gap, reach) for e in tips]
    # the root's end node first (its parent -1), the traced nodes one index later (the first of
    # them hangs from the root's end node), then the tips' end nodes; parents before children
    nodes = np.vstack([root, pos, *ends_xyz])
    par = np.concatenate([[-1], parent + 1, np.array(tips, dtype=np.int64) + 1])
    order = np.arange(len(par)) if np.all(par < np.arange(len(par))) else _parents_first(par)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return nodes[order], np.where(par[order] < 0, -1, rank[np.maximum(par[order], 0)]).astype(np.int64)


def tree_nodes(mi: MeshInput, spacing: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Node positions and parents of a branching mesh (module docstring): slices across the
    principal axis from the root end, their contours chained from slice to slice (a contour
    continues the chain whose last centroid is nearest, within TRACK of their radii); where a
    chain's contour splits, the largest part continues it and each other part starts a branch
    from the chain's last node. A contour near no chain starts a loose chain: a branch that turns
    back towards the root end, met tip first; where it joins a chain it ends, and its nodes are
    turned around to hang from that chain's node. Chains end in end nodes like a log's."""
    mesh = mi.mesh
    axis, u, v, s0, s1, centre = _along_axis(mesh)
    length = s1 - s0
    if spacing is None:
        spacing = _mean_radius(mesh, axis, u, v, s0, s1, centre)
    n = max(3, math.ceil(length / spacing))
    chains = _Chains(mi.source, s0)
    for k, t in enumerate(s0 + length * np.arange(1, n) / n):
        found = _cross_sections(mesh, centre + t * axis, axis, u, v)
        if k == 0 and len(found) != 1:
            raise InputError(mi.source, "", f"{len(found)} cross-sections next to the root end: the mesh must start "
                             "from one stem (give an explicit skeleton)")
        claimed = chains.claim(found)
        chains.join(found, claimed, t)
        for b, js in claimed.items():
            if b >= 0 and len(js) > 1 and chains.start[b] in chains.loose:
                raise chains.fail(t, "a branch that turns back forks")
        chains.advance(found, claimed, k)
    chains.ends += chains.active
    if any(j < 0 for j in chains.loose.values()):
        raise InputError(mi.source, "", "a part of the mesh joins no branch: the mesh is not one log or tree "
                         "(give an explicit skeleton)")
    pos, parent = np.array(chains.pos), np.array(chains.parent, dtype=np.int64)
    tips = chains.hang_loose(parent)
    return _with_end_nodes(mi, pos, parent, tips, length / n, 1.5 * max(chains.radius))


def _parents_first(parent: np.ndarray) -> np.ndarray:
    """An order of the nodes of the tree ``parent`` (root -1) in which every parent comes before
    its children (breadth first from the root; ties keep the index order)."""
    children = [[] for _ in parent]
    for i, p in enumerate(parent):
        if p >= 0:
            children[p].append(i)
    order = [int(np.flatnonzero(parent < 0)[0])]
    for i in order:
        order.extend(children[i])
    return np.array(order, dtype=np.int64)


def mesh_skeleton(mi: MeshInput, resolution: float, spacing: float | None = None) -> Skeleton:
    """The skeleton of a mesh: a centreline for a log, board or stump, branches for a branching
    mesh (:func:`tree_nodes`), and polygon profiles."""
    try:
        pos = centreline(mi, spacing, resolution)
        parent = np.arange(-1, len(pos) - 1, dtype=np.int64)
    except _Branches:
        pos, parent = tree_nodes(mi, spacing)
    n = len(pos)
    ids = tuple(f"m{i}" for i in range(n))
    circle = profiles.circle(1.0)  # node frames depend on positions and parents only
    rough = Skeleton(ids, pos, parent, (circle,) * n, np.zeros(n, bool), mi.source)
    frames = build_topology(rough).frames
    profs = tuple(profile_at(mi, pos[i], frames[i], resolution, ids[i]) for i in range(n))
    return Skeleton(ids, pos, parent, profs, np.zeros(n, bool), mi.source, mi.mesh)
