"""A scanned point cloud of a log, board or stump -> a closed surface mesh (:class:`MeshInput`),
which :mod:`.mesh_skeleton` then slices like any mesh (``[skeleton] points = "FILE"``,
``wooddecay init --from-points``).

Branch-fracture §3.1-3.2 scans a branch, reconstructs a surface mesh from the points and takes the
outer contour of each cross-section. Here the contours come from the points directly and the
surface is lofted through them: the cloud is cut into slabs SLAB r_s thick across its principal
axis. A slab's points are closed by a disc of radius rho (ALPHA mean spacings of the points along
their convex hull; a morphological closing on a grid, the 2D alpha hull of Edelsbrunner et al.
1983): the outer contour of what the disc cannot reach from outside follows concave sections of
any shape and ignores noise inside the surface. Where the scan has a gap (the underside of a log
on the ground) the points trace an open curve and the closing encloses almost nothing (under
OPEN of the convex hull's area). For such slabs, and for every slab whose closed contour is
star-shaped about the slab's centroid, the contour is the farthest point per angle bin about the
centroid (ANGLES of them), empty bins taking the value of their angular neighbours: between
sparse points it follows the arc where the closing's discs dip in; bins that run out and in (a cut
face across the slab: bins the surface does not reach keep points inside the wood; a perimeter
over SPIKY times the hull's) take the slab's convex hull. The contours are resampled at
one count (a point per r_s of the longest, ANGLES to MAX_AROUND), each turned to match the
previous one, and joined into a tube closed by two flat, ear-clipped caps at the cloud's ends (there the
contour of the slab next to the end: the end slabs hold the cut faces' points): a watertight,
outward-wound mesh.

Formats: PLY (its vertices), XYZ/TXT/CSV (the first three columns of each row, whitespace or
comma separated), LAS and LAZ (laspy with the lazrs backend; scaled coordinates). Checks, one line
each: unreadable or unknown format, fewer than MIN_POINTS points, non-finite coordinates, a slab
with too few points to hold a contour (the cloud is not one log along a line, or a scan with a gap
across it).
"""
from __future__ import annotations

import math

import numpy as np

from wooddecay.errors import InputError
from wooddecay.strands.mesh_input import Y_TO_Z_UP, MeshInput, checked_path
from wooddecay.strands.mesh_skeleton import plane_basis, principal_axis
from wooddecay.strands.profiles import (
    is_ccw,
    polygon_area,
    polygon_perimeter,
    ray_extent,
    resample_closed,
)

from .. import fmath as fm

SUFFIXES = (".ply", ".xyz", ".txt", ".csv", ".las", ".laz")
#: fewest points a cloud must have
MIN_POINTS = 200
#: slab thickness in r_s
SLAB = 2.0
#: angle bins of a slab's contour
ANGLES = 72
#: the angle bins' lower edges (rad)
BINS = np.linspace(-np.pi, np.pi, ANGLES, endpoint=False)
#: a slab needs at least this share of its angle bins filled
MIN_FILLED = 0.5
#: closing radius in mean spacings of a slab's points along its convex hull (the largest gap of
#: n points scattered at random along a curve is about ln n of them)
ALPHA = 6.0
#: a closed contour holding less than this share of its convex hull's area is an open curve
OPEN = 0.25
#: a contour whose polar angle turns back by more than this (rad) is not star-shaped
STAR_TOLERANCE = 0.02
#: radii per angle bin are spiky (a cut face across the slab) when their polygon is longer than
#: this many times its convex hull
SPIKY = 1.2
#: most grid cells of a slab's closing
MAX_CELLS = 400_000
#: most points of a lofted contour
MAX_AROUND = 720


def read_points(path, scale: float = 1.0, source: str | None = None, up: str | None = None) -> np.ndarray:
    """The cloud's points ``(n, 3)`` in m (times ``scale``), turned to z-up if ``up`` is "y";
    checked (module docstring)."""
    path = checked_path(path, source, "point cloud", SUFFIXES)
    suffix = path.suffix.lower()
    name = str(path)
    try:
        if suffix == ".ply":
            import trimesh

            pts = np.asarray(trimesh.load(str(path), process=False).vertices, float)
        elif suffix in (".las", ".laz"):
            import laspy

            pts = np.asarray(laspy.read(str(path)).xyz, float)
        else:
            text = path.read_text().replace(",", " ")
            rows = [line.split()[:3] for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
            if any(len(r) < 3 for r in rows):
                raise ValueError("a row has fewer than three columns")
            pts = np.array(rows, dtype=float)
    except Exception as err:  # each reader raises its own types for a bad file
        raise InputError(name, "", f"cannot read the point cloud: {err}") from None
    pts = pts.reshape(-1, 3)
    if len(pts) < MIN_POINTS:
        raise InputError(name, "", f"{len(pts)} points: a log's scan needs at least {MIN_POINTS}")
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise InputError(name, "", f"{int(bad.sum())} points are not finite")
    return (pts @ Y_TO_Z_UP.T if up == "y" else pts) * float(scale)


def loft(points: np.ndarray, resolution: float, source: str) -> MeshInput:
    """The closed surface through the slab contours of ``points`` (module docstring)."""
    import trimesh

    mean = points.mean(axis=0)
    axis = principal_axis(points)
    u, v = plane_basis(axis)
    s = (points - mean) @ axis
    n_slabs = max(3, int(math.ceil((s.max() - s.min()) / (SLAB * resolution))))
    slab = np.minimum(((s - s.min()) / (s.max() - s.min()) * n_slabs).astype(np.int64), n_slabs - 1)
    contours, centres = [], []  # per slab: a closed loop, or radii per angle bin
    for k in range(n_slabs):
        p = points[slab == k] - mean
        q = np.column_stack([p @ u, p @ v])
        c = q.mean(axis=0)
        contours.append(_slab_contour(q - c, resolution, source, k, n_slabs))
        if _spiky(contours[-1]):
            contours[-1] = _hull_radii(contours[-1])
        centres.append(mean + float(s[slab == k].mean()) * axis + c[0] * u + c[1] * v)
    closed = [c for c in contours if c.ndim == 2]
    around = int(np.clip(math.ceil(max(map(polygon_perimeter, closed)) / resolution), ANGLES, MAX_AROUND)) if closed else ANGLES
    theta = np.linspace(-np.pi, np.pi, around, endpoint=False)
    rings = []
    for centre, contour in zip(centres, contours):
        if contour.ndim == 1:  # star-shaped: vertices at fixed angles, so consecutive rings match
            r = np.interp(theta, BINS, contour, period=2 * np.pi)
            q = r[:, None] * np.column_stack([fm.cos(theta), fm.sin(theta)])
        else:
            q = resample_closed(contour, around)
        ring = centre + q[:, :1] * u + q[:, 1:] * v
        rings.append(_turned_to(ring, rings[-1]) if contour.ndim == 2 and rings else ring)
    # the end slabs hold the cut faces' points, which fill a section only partly where a cut is
    # not square to the axis: the ends take their neighbour's contour, moved to the cloud's ends
    for end, nxt, sk in ((0, 1, s.min()), (-1, -2, s.max())):
        rings[end] = rings[nxt] + (sk - (centres[nxt] - mean) @ axis) * axis
    mesh = trimesh.Trimesh(*_capped_tube(np.array(rings), u, v), process=False)
    if mesh.volume < 0:
        mesh.invert()
    return MeshInput(mesh, (f"lofted a surface through {len(rings)} slices of {len(points)} points "
                            f"({len(closed)} of them not star-shaped)",), source)


def _turned_to(ring: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """``ring`` cyclically shifted to lie closest (least squares) to ``previous`` point by point:
    the lofted tube does not twist (a circular cross-correlation by FFT)."""
    corr = sum(np.fft.ifft(np.fft.fft(ring[:, i]) * np.conj(np.fft.fft(previous[:, i]))).real for i in range(3))
    return np.roll(ring, -int(np.argmax(corr)), axis=0)


def _closed_contour(q: np.ndarray, resolution: float) -> np.ndarray | None:
    """The outer contour (counter-clockwise) of a slab's points ``q`` closed by a disc of radius
    rho = ALPHA mean spacings (module docstring); None where the points trace an open curve.

    On a grid of resolution / 4 (exact Euclidean distances, ``scipy.ndimage.distance_transform_edt``):
    the cells farther than rho from every point that the grid's border reaches are outside; the
    closed section is what lies farther than rho from the outside, its boundary the zero contour
    of that distance minus rho (marching squares, ``contourpy``)."""
    from contourpy import contour_generator
    from scipy import ndimage
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(q)
    except QhullError:
        return None
    rho = ALPHA * hull.area / len(q)  # a 2D hull's "area" is its perimeter
    extent = q.max(axis=0) - q.min(axis=0) + 4.0 * rho
    h = max(resolution / 4.0, math.sqrt(np.prod(extent) / MAX_CELLS))
    rho = max(rho, 2.0 * h)  # a dense scan: the disc spans two cells
    lo = q.min(axis=0) - 2.0 * rho - 2.0 * h
    shape = np.ceil((q.max(axis=0) + 2.0 * rho + 2.0 * h - lo) / h).astype(np.int64) + 1
    empty = np.ones(shape, bool)
    ij = np.round((q - lo) / h).astype(np.int64)
    empty[ij[:, 0], ij[:, 1]] = False
    free = ndimage.distance_transform_edt(empty) * h > rho
    label, _ = ndimage.label(free)
    border = np.unique(np.concatenate([label[0], label[-1], label[:, 0], label[:, -1]]))
    outside = np.isin(label, border[border > 0])
    depth = ndimage.distance_transform_edt(~outside) * h - rho - 0.5 * h  # the outside cells start h / 2 beyond rho
    x, y = lo[0] + h * np.arange(shape[0]), lo[1] + h * np.arange(shape[1])
    lines = [ln for ln in contour_generator(y, x, depth).lines(0.0) if len(ln) > 3]
    if not lines:
        return None
    loop = max((ln[:, ::-1] for ln in lines), key=polygon_area)
    loop = loop[:-1] if np.allclose(loop[0], loop[-1]) else loop
    if polygon_area(loop) < OPEN * hull.volume:
        return None
    return loop if is_ccw(loop) else loop[::-1]


def _star_shaped(loop: np.ndarray) -> bool:
    """Whether every ray from the origin leaves the counter-clockwise ``loop`` once: its polar
    angle never turns back by more than STAR_TOLERANCE."""
    ang = np.unwrap(fm.arctan2(loop[:, 1], loop[:, 0]))
    return bool(np.all(np.diff(ang) > -STAR_TOLERANCE))


def _slab_contour(q: np.ndarray, resolution: float, source: str, k: int, n_slabs: int) -> np.ndarray:
    """Slab ``k``'s contour about its centroid (the origin of ``q``): the closed contour ``(m, 2)``
    where it is not star-shaped, else the farthest point's distance per angle bin (module
    docstring)."""
    loop = _closed_contour(q, resolution)
    if loop is not None and not _star_shaped(loop):
        return loop
    ang = fm.arctan2(q[:, 1], q[:, 0])
    b = np.minimum(((ang + np.pi) / (2 * np.pi) * ANGLES).astype(np.int64), ANGLES - 1)
    r = np.full(ANGLES, -np.inf)
    np.maximum.at(r, b, fm.hypot(q[:, 0], q[:, 1]))
    filled = np.isfinite(r)
    if filled.mean() < MIN_FILLED:
        raise InputError(source, "", f"slice {k + 1} of {n_slabs} along the cloud's axis has points at "
                         f"{int(filled.sum())} of {ANGLES} angles: not one log along a line, or a gap in the scan")
    return np.interp(BINS, BINS[filled], r[filled], period=2 * np.pi)


def _spiky(contour: np.ndarray) -> bool:
    """Whether radii per angle bin run out and in (a cut face across the slab: bins the surface
    does not reach keep a point inside the wood): a perimeter over SPIKY times its hull's."""
    from scipy.spatial import ConvexHull

    if contour.ndim == 2:
        return False
    poly = _radii_polygon(contour)
    return polygon_perimeter(poly) > SPIKY * ConvexHull(poly).area


def _hull_radii(radii: np.ndarray) -> np.ndarray:
    """Radii per angle bin of the convex hull of the polygon ``radii`` describe (the slab's
    silhouette where a cut face crosses it)."""
    from scipy.spatial import ConvexHull

    poly = _radii_polygon(radii)
    return ray_extent(poly[ConvexHull(poly).vertices], np.zeros(2), BINS)


def _radii_polygon(radii: np.ndarray) -> np.ndarray:
    return radii[:, None] * np.column_stack([fm.cos(BINS), fm.sin(BINS)])


def tube_sides(along: int, around: int) -> np.ndarray:
    """Triangles joining ``along`` closed rings of ``around`` vertices each (ring-major)."""
    i = np.arange(along - 1)[:, None] * around
    j = np.arange(around)[None, :]
    a0, a1 = i + j, i + (j + 1) % around
    return np.concatenate([np.stack([a0, a1, a1 + around], -1).reshape(-1, 3),
                           np.stack([a0, a1 + around, a0 + around], -1).reshape(-1, 3)])


def closed_tube(rings: np.ndarray, start, end) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of the tube through ``rings`` (along, around, 3), each ring a
    closed loop, capped by fans about the points ``start`` and ``end`` (in the first and the
    last ring's plane, each ring star-shaped about them)."""
    along, around = rings.shape[:2]
    first, last = np.arange(around), (along - 1) * around + np.arange(around)
    n = along * around
    return np.vstack([rings.reshape(-1, 3), start, end]), np.concatenate([
        tube_sides(along, around), np.stack([np.full(around, n), np.roll(first, -1), first], -1),
        np.stack([np.full(around, n + 1), last, np.roll(last, -1)], -1)])


def _capped_tube(rings: np.ndarray, u, v) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of the tube through ``rings`` (along, around, 3), each ring
    counter-clockwise in the plane basis ``u``, ``v``, closed by the ear-clipped polygons of its
    first and last ring (mapbox_earcut: a cap of any simple contour), facing out."""
    import mapbox_earcut

    along, around = rings.shape[:2]
    caps = []
    for k, outward in ((0, -1.0), (along - 1, 1.0)):
        q = np.column_stack([rings[k] @ u, rings[k] @ v])
        t = mapbox_earcut.triangulate_float64(q, np.array([around], dtype=np.uint32)).reshape(-1, 3).astype(np.int64)
        a, b, c = q[t[:, 0]], q[t[:, 1]], q[t[:, 2]]
        ccw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
        caps.append(k * around + np.where((ccw == (outward > 0))[:, None], t, t[:, ::-1]))
    return rings.reshape(-1, 3), np.concatenate([tube_sides(along, around), *caps])
