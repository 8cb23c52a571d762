"""A scanned point cloud of a log, board or stump -> a closed surface mesh (:class:`MeshInput`),
which :mod:`.mesh_skeleton` then slices like any mesh (``[skeleton] points = "FILE"``,
``wooddecay init --from-points``).

Branch-fracture §3.1-3.2 scans a branch, reconstructs a surface mesh from the points and takes the
outer contour of each cross-section. Here the contours come from the points directly and the
surface is lofted through them: the cloud is cut into slabs SLAB r_s thick across its principal
axis; in each slab the outer contour is, per angle bin about the slab's centroid (ANGLES of
them), the farthest point, so the scanner's noise inside the surface and the odd point of the
bark's far side do not matter and concave-but-star-shaped sections keep their shape; empty bins
(a gap in the scan) take the value of their angular neighbours. Consecutive contours are joined
into a tube closed by two flat caps at the cloud's ends (there the contour of the slab next to the
end: the end slabs hold the cut faces' points): a watertight, outward-wound mesh.

Formats: PLY (its vertices), XYZ/TXT/CSV (the first three columns of each row, whitespace or
comma separated) and LAS (laspy; scaled coordinates). Checks, one line each: unreadable or
unknown format, fewer than MIN_POINTS points, non-finite coordinates, a slab with too few points
to hold a contour (the cloud is not one log along a line, or a scan with a gap across it).
"""
from __future__ import annotations

import math
import numpy as np

from wooddecay.errors import InputError
from wooddecay.strands.mesh_input import Y_TO_Z_UP, MeshInput, checked_path
from wooddecay.strands.mesh_skeleton import plane_basis, principal_axis

SUFFIXES = (".ply", ".xyz", ".txt", ".csv", ".las")
#: fewest points a cloud must have
MIN_POINTS = 200
#: slab thickness in r_s
SLAB = 2.0
#: angle bins of a slab's contour
ANGLES = 72
#: a slab needs at least this share of its angle bins filled
MIN_FILLED = 0.5


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
        elif suffix == ".las":
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
    theta = np.linspace(-np.pi, np.pi, ANGLES, endpoint=False)
    rings, centres = [], []
    for k in range(n_slabs):
        p = points[slab == k] - mean
        pu, pv = p @ u, p @ v
        cu, cv = pu.mean(), pv.mean()
        ang = np.arctan2(pv - cv, pu - cu)
        b = np.minimum(((ang + np.pi) / (2 * np.pi) * ANGLES).astype(np.int64), ANGLES - 1)
        r = np.full(ANGLES, -np.inf)
        np.maximum.at(r, b, np.hypot(pu - cu, pv - cv))
        filled = np.isfinite(r)
        if filled.mean() < MIN_FILLED:
            raise InputError(source, "", f"slice {k + 1} of {n_slabs} along the cloud's axis has points at "
                             f"{int(filled.sum())} of {ANGLES} angles: not one log along a line, or a gap in the scan")
        r = np.interp(theta, theta[filled], r[filled], period=2 * np.pi)
        centres.append(mean + float(s[slab == k].mean()) * axis + cu * u + cv * v)
        rings.append(centres[-1] + r[:, None] * (np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v))
    # the end slabs hold the cut faces' points, which fill a section only partly where a cut is
    # not square to the axis: the ends take their neighbour's contour, moved to the cloud's ends
    for end, nxt, sk in ((0, 1, s.min()), (-1, -2, s.max())):
        shift = (sk - (centres[nxt] - mean) @ axis) * axis
        centres[end], rings[end] = centres[nxt] + shift, rings[nxt] + shift
    mesh = trimesh.Trimesh(*closed_tube(np.array(rings), centres[0], centres[-1]), process=False)
    if mesh.volume < 0:
        mesh.invert()
    return MeshInput(mesh, (f"lofted a surface through {len(rings)} slices of {len(points)} points",), source)


def closed_tube(rings: np.ndarray, start, end) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of the tube through ``rings`` (along, around, 3), each ring a
    closed loop, capped by fans about the points ``start`` and ``end`` (in the first and the
    last ring's plane)."""
    along, around = rings.shape[:2]
    vertices = np.vstack([rings.reshape(-1, 3), start, end])
    i = np.arange(along - 1)[:, None] * around
    j = np.arange(around)[None, :]
    a0, a1 = i + j, i + (j + 1) % around
    first, last = np.arange(around), (along - 1) * around + np.arange(around)
    n = along * around
    faces = [np.stack([a0, a1, a1 + around], -1).reshape(-1, 3), np.stack([a0, a1 + around, a0 + around], -1).reshape(-1, 3),
             np.stack([np.full(around, n), np.roll(first, -1), first], -1),
             np.stack([np.full(around, n + 1), last, np.roll(last, -1)], -1)]
    return vertices, np.concatenate(faces)
