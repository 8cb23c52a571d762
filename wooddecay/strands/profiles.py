"""Planar cross-section profiles of the skeleton graph (docs/model.md §1; woodstock Fig. 3a).

Every skeleton node carries a cross-section in its node frame, coordinates ``(u, v)`` in m:
a circle (radius), an ellipse (semi-axes ``a``, ``b`` and a rotation ``angle``) or a simple
counter-clockwise polygon. Circles and ellipses are discretised with ``PROFILE_SEGMENTS``
vertices so that all geometry below works on one representation, a ``(k, 2)`` vertex array
(the closing edge from the last vertex back to the first is implicit).

The queries (signed distance, closest boundary point, point-in-polygon, ray extent) are
vectorised over points x edges with numpy broadcasting; points are processed in blocks so that
the ``(n, k)`` temporaries stay bounded. Validation of user input lives in ``skeleton.py``:
the constructors here accept anything.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .. import fmath as fm

PROFILE_SEGMENTS = 64
"""Vertices used to discretise circles and ellipses."""

BOUNDARY_TOL = 1e-12
"""Points closer than this to the boundary (m) count as inside."""

_BLOCK_ENTRIES = 1 << 20
"""Largest points x edges block evaluated at once (bounds temporary memory)."""


@dataclass(frozen=True, eq=False)
class Profile:
    """A cross-section in the node frame.

    Attributes
    ----------
    kind : str
        ``"circle"``, ``"ellipse"`` or ``"polygon"``.
    params : tuple of (str, float)
        The defining parameters, e.g. ``(("radius", 0.1),)``; empty for polygons.
    polygon : np.ndarray
        ``(k, 2)`` counter-clockwise vertices (circles / ellipses: ``PROFILE_SEGMENTS`` of them).
    """

    kind: str
    params: tuple[tuple[str, float], ...]
    polygon: np.ndarray

    def param(self, name: str) -> float:
        """Return the parameter ``name`` (``KeyError`` when this kind has none)."""
        return dict(self.params)[name]

    @property
    def area(self) -> float:
        """Area in m^2: exact ``pi r^2`` / ``pi a b`` for circles / ellipses, shoelace otherwise."""
        if self.kind == "circle":
            return float(np.pi * self.param("radius") ** 2)
        if self.kind == "ellipse":
            return float(np.pi * self.param("a") * self.param("b"))
        return polygon_area(self.polygon)

    @property
    def centroid(self) -> np.ndarray:
        """Area centroid ``(2,)`` (the origin for circles and ellipses)."""
        if self.kind in ("circle", "ellipse"):
            return np.zeros(2)
        return polygon_centroid(self.polygon)

    @property
    def equivalent_radius(self) -> float:
        """Radius of the circle with the same area, ``sqrt(area / pi)``."""
        return float(np.sqrt(self.area / np.pi))


def _unit_angles(k: int) -> np.ndarray:
    """Return ``k`` angles evenly spaced over ``[0, 2 pi)``."""
    return np.arange(k) * (2.0 * np.pi / k)


def circle(radius: float) -> Profile:
    """Circle of ``radius`` centred at the origin.

    Parameters
    ----------
    radius : float
        Radius in m.

    Returns
    -------
    Profile
        ``kind="circle"`` with a ``PROFILE_SEGMENTS``-gon inscribed in the circle.
    """
    t = _unit_angles(PROFILE_SEGMENTS)
    poly = float(radius) * np.column_stack([fm.cos(t), fm.sin(t)])
    return Profile("circle", (("radius", float(radius)),), poly)


def ellipse(a: float, b: float, angle: float = 0.0) -> Profile:
    """Ellipse centred at the origin.

    Parameters
    ----------
    a, b : float
        Semi-axes in m along the rotated u and v axes.
    angle : float
        Rotation of the ``a`` axis from ``u`` in rad (counter-clockwise).

    Returns
    -------
    Profile
        ``kind="ellipse"`` with a ``PROFILE_SEGMENTS``-gon inscribed in the ellipse.
    """
    t = _unit_angles(PROFILE_SEGMENTS)
    local = np.column_stack([float(a) * fm.cos(t), float(b) * fm.sin(t)])
    c, s = fm.cos(angle), fm.sin(angle)
    poly = local @ np.array([[c, s], [-s, c]])
    params = (("a", float(a)), ("b", float(b)), ("angle", float(angle)))
    return Profile("ellipse", params, poly)


def polygon(points) -> Profile:
    """Polygon profile from ``(k, 2)`` vertices (taken as given, not validated).

    Parameters
    ----------
    points : array_like
        ``(k, 2)`` vertices in m, counter-clockwise for a valid profile.

    Returns
    -------
    Profile
        ``kind="polygon"``.
    """
    return Profile("polygon", (), np.array(points, dtype=np.float64).reshape(-1, 2))


def _edges(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return edge start points ``(k, 2)`` and edge vectors ``(k, 2)`` of a closed polygon."""
    a = np.asarray(poly, dtype=np.float64)
    return a, np.roll(a, -1, axis=0) - a


def _cross(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """2D cross product ``x_u y_v - x_v y_u`` over the last axis (broadcasting)."""
    return x[..., 0] * y[..., 1] - x[..., 1] * y[..., 0]


def _signed_area(poly: np.ndarray) -> float:
    """Shoelace area, positive for counter-clockwise vertex order."""
    a, d = _edges(poly)
    return 0.5 * float(np.sum(_cross(a, a + d)))


def polygon_area(poly: np.ndarray) -> float:
    """Unsigned area of a simple polygon (shoelace).

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.

    Returns
    -------
    float
        Area in m^2 (non-negative whatever the orientation).
    """
    return abs(_signed_area(poly))


def polygon_centroid(poly: np.ndarray) -> np.ndarray:
    """Area centroid of a simple polygon.

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.

    Returns
    -------
    np.ndarray
        ``(2,)``; the vertex mean when the polygon has no area.
    """
    a, d = _edges(poly)
    w = _cross(a, a + d)
    total = float(np.sum(w))
    if total == 0.0:
        return np.mean(np.asarray(poly, dtype=np.float64), axis=0)
    return np.sum((2.0 * a + d) * w[:, None], axis=0) / (3.0 * total)


def polygon_perimeter(poly: np.ndarray) -> float:
    """Length of the closed polygon ``poly`` (``(k, 2)`` or ``(k, 3)``)."""
    return float(np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1).sum())


def resample_closed(poly: np.ndarray, k: int) -> np.ndarray:
    """``k`` points equally spaced by arc length along the closed polygon ``poly`` (``(m, 2)`` or
    ``(m, 3)``), the first at its first vertex."""
    closed = np.vstack([poly, poly[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    t = np.arange(k) * arc[-1] / k
    return np.stack([np.interp(t, arc, closed[:, i]) for i in range(closed.shape[1])], axis=1)


def is_ccw(poly: np.ndarray) -> bool:
    """Return True when the vertices run counter-clockwise (positive signed area)."""
    return _signed_area(poly) > 0.0


def _orient(p: np.ndarray, q: np.ndarray, r: np.ndarray, tol: float) -> np.ndarray:
    """Sign (-1, 0, 1) of the turn p -> q -> r, zero within ``tol`` (broadcasting)."""
    c = _cross(q - p, r - p)
    return np.where(np.abs(c) <= tol, 0, np.sign(c)).astype(np.int8)


def _on_segment(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """For collinear p, q, r: whether r lies within the bounding box of segment pq."""
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    return np.all((r >= lo) & (r <= hi), axis=-1)


def _segments_intersect(p1, q1, p2, q2, tol: float) -> np.ndarray:
    """Whether closed segments p1q1 and p2q2 share a point (broadcasting over leading axes)."""
    o1, o2 = _orient(p1, q1, p2, tol), _orient(p1, q1, q2, tol)
    o3, o4 = _orient(p2, q2, p1, tol), _orient(p2, q2, q1, tol)
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    touch = ((o1 == 0) & _on_segment(p1, q1, p2)) | ((o2 == 0) & _on_segment(p1, q1, q2))
    touch |= ((o3 == 0) & _on_segment(p2, q2, p1)) | ((o4 == 0) & _on_segment(p2, q2, q1))
    return proper | touch


def is_simple(poly: np.ndarray) -> bool:
    """Whether a closed polygon is simple.

    Simple means at least 3 vertices, no repeated vertex, no two non-adjacent edges sharing a
    point and no adjacent edges folding back onto each other.

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.

    Returns
    -------
    bool
    """
    a, d = _edges(poly)
    k = len(a)
    if k < 3 or not np.all(np.isfinite(a)):
        return False
    scale = float(np.max(np.abs(a))) or 1.0
    tol = 1e-12 * scale * scale
    if len(np.unique(a, axis=0)) < k:
        return False
    nxt = np.roll(d, -1, axis=0)
    if np.any((np.abs(_cross(d, nxt)) <= tol) & (np.sum(d * nxt, axis=1) < 0.0)):
        return False
    i, j = np.triu_indices(k, 2)
    keep = (j - i) != k - 1
    i, j = i[keep], j[keep]
    b = a + d
    return not np.any(_segments_intersect(a[i], b[i], a[j], b[j], tol))


def _blocks(n: int, k: int):
    """Yield slices over ``n`` points so that each block has at most ``_BLOCK_ENTRIES`` x ``k``."""
    step = max(1, _BLOCK_ENTRIES // max(k, 1))
    for start in range(0, n, step):
        yield slice(start, min(n, start + step))


def closest_edge(poly: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the boundary edge closest to each point and the parameter t in [0, 1] of the
    closest point on it (edge i runs from vertex i to vertex i + 1).

    Returns
    -------
    edge : np.ndarray
        ``(n,)`` edge indices.
    t : np.ndarray
        ``(n,)`` position of the closest point along that edge.
    """
    a, d = _edges(poly)
    len2 = np.sum(d * d, axis=1)
    len2 = np.where(len2 > 0.0, len2, 1.0)
    edge = np.empty(len(pts), dtype=np.int64)
    t_best = np.empty(len(pts))
    for sl in _blocks(len(pts), len(a)):
        rel = pts[sl, None, :] - a[None, :, :]
        t = np.clip(np.sum(rel * d[None], axis=2) / len2, 0.0, 1.0)
        dist2 = np.sum((rel - t[..., None] * d[None]) ** 2, axis=2)
        best = np.argmin(dist2, axis=1)
        edge[sl] = best
        t_best[sl] = t[np.arange(len(best)), best]
    return edge, t_best


def _nearest_on_edges(poly: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest boundary point ``(n, 2)`` and its unsigned distance ``(n,)`` for each point."""
    a, d = _edges(poly)
    edge, t = closest_edge(poly, pts)
    closest = a[edge] + t[:, None] * d[edge]
    return closest, np.linalg.norm(pts - closest, axis=1)


def _crossing_parity(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Even-odd ray-casting test (ray towards +u); True for an odd number of crossings."""
    a, d = _edges(poly)
    b = a + d
    odd = np.empty(len(pts), dtype=bool)
    for sl in _blocks(len(pts), len(a)):
        py, px = pts[sl, 1:2], pts[sl, 0:1]
        straddle = (a[None, :, 1] > py) != (b[None, :, 1] > py)
        dy = np.where(d[:, 1] != 0.0, d[:, 1], 1.0)
        x_cross = a[None, :, 0] + (py - a[None, :, 1]) * (d[None, :, 0] / dy[None])
        odd[sl] = (np.count_nonzero(straddle & (px < x_cross), axis=1) % 2) == 1
    return odd


def _as_points(pts) -> np.ndarray:
    """Return ``pts`` as a float64 ``(n, 2)`` array."""
    return np.asarray(pts, dtype=np.float64).reshape(-1, 2)


def contains(poly: np.ndarray, pts) -> np.ndarray:
    """Point-in-polygon test; points within ``BOUNDARY_TOL`` of the boundary count as inside.

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.
    pts : array_like
        ``(n, 2)`` query points.

    Returns
    -------
    np.ndarray
        ``(n,)`` bool.
    """
    p = _as_points(pts)
    _, dist = _nearest_on_edges(poly, p)
    return _crossing_parity(poly, p) | (dist <= BOUNDARY_TOL)


def signed_distance(poly: np.ndarray, pts) -> np.ndarray:
    """Distance to the polygon boundary, positive inside and negative outside.

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.
    pts : array_like
        ``(n, 2)`` query points.

    Returns
    -------
    np.ndarray
        ``(n,)`` signed distances in m (0 on the boundary).
    """
    p = _as_points(pts)
    _, dist = _nearest_on_edges(poly, p)
    inside = _crossing_parity(poly, p) | (dist <= BOUNDARY_TOL)
    return np.where(inside, dist, -dist)


def closest_boundary_point(poly: np.ndarray, pts) -> np.ndarray:
    """Closest point on the polygon boundary for each query point.

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.
    pts : array_like
        ``(n, 2)`` query points.

    Returns
    -------
    np.ndarray
        ``(n, 2)`` boundary points.
    """
    closest, _ = _nearest_on_edges(poly, _as_points(pts))
    return closest


def _ray_hits(poly: np.ndarray, origin, angles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First boundary hit of rays from ``origin``.

    Returns
    -------
    dist : np.ndarray
        ``(n,)`` distance along each ray to its first hit beyond ``BOUNDARY_TOL`` (0 for none).
    edge : np.ndarray
        ``(n,)`` index of the edge hit (-1 for none).
    t : np.ndarray
        ``(n,)`` parameter along that edge in ``[0, 1]``.
    """
    a, d = _edges(poly)
    o = np.asarray(origin, dtype=np.float64).reshape(2)
    th = np.atleast_1d(np.asarray(angles, dtype=np.float64)).ravel()
    r = np.column_stack([fm.cos(th), fm.sin(th)])
    dist, edge, tpar = np.zeros(len(th)), np.full(len(th), -1), np.zeros(len(th))
    rel = a - o
    for sl in _blocks(len(th), len(a)):
        denom = _cross(r[sl, None, :], d[None])
        ok = np.abs(denom) > 1e-300
        safe = np.where(ok, denom, 1.0)
        s = _cross(rel[None], d[None]) / safe
        t = _cross(rel[None], r[sl, None, :]) / safe
        valid = ok & (t >= -1e-12) & (t <= 1.0 + 1e-12) & (s > BOUNDARY_TOL)
        s = np.where(valid, s, np.inf)
        best = np.argmin(s, axis=1)
        rows = np.arange(len(best))
        hit = np.isfinite(s[rows, best])
        dist[sl] = np.where(hit, s[rows, best], 0.0)
        edge[sl] = np.where(hit, best, -1)
        tpar[sl] = np.clip(t[rows, best], 0.0, 1.0)
    return dist, edge, tpar


def ray_extent(poly: np.ndarray, origin, angles) -> np.ndarray:
    """Distance from ``origin`` to the boundary along each direction (first exit).

    Used to map between star-shaped profiles: for an origin inside the polygon, the first
    boundary crossing along a ray is where the ray leaves the polygon.

    Parameters
    ----------
    poly : np.ndarray
        ``(k, 2)`` vertices.
    origin : array_like
        ``(2,)`` ray origin.
    angles : array_like
        ``(n,)`` ray directions in rad from the u axis.

    Returns
    -------
    np.ndarray
        ``(n,)`` distances in m; 0 where a ray meets no boundary.
    """
    return _ray_hits(poly, origin, angles)[0]


def narrow_area(poly: np.ndarray, r_s: float, cells: int = 400) -> float:
    """Area in m^2 of the largest connected part of the polygon that no disk of radius ``r_s``
    inside it reaches (the polygon minus its morphological opening by the disk): an arm or tip
    narrower than a strand, where no strand can lie. Rasterised on at most ``cells`` x ``cells``
    points with spacing h <= r_s / 4 (the opening by a Euclidean distance transform); a point
    counts with its cell's covered fraction clip(1/2 + sd / h, 0, 1), exact along straight edges."""
    lo, hi = poly.min(axis=0) - r_s, poly.max(axis=0) + r_s
    h = max(r_s / 4.0, float(np.max(hi - lo)) / cells)
    nx, ny = (np.ceil((hi - lo) / h).astype(int) + 1)
    gx, gy = np.meshgrid(lo[0] + h * np.arange(nx), lo[1] + h * np.arange(ny), indexing="ij")
    sd = signed_distance(poly, np.column_stack([gx.ravel(), gy.ravel()])).reshape(nx, ny)
    centres = sd >= r_s  # where a strand's axis may lie
    if not centres.any():
        return polygon_area(poly)
    reached = ndimage.distance_transform_edt(~centres) * h <= r_s
    cover = np.clip(0.5 + sd / h, 0.0, 1.0)
    labels, n = ndimage.label((cover > 0.0) & ~reached)
    return float(np.bincount(labels.ravel(), cover.ravel(), minlength=n + 1)[1:].max(initial=0)) * h * h
