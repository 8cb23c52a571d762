"""An artist's surface mesh -> a checked, closed ``trimesh.Trimesh`` in metres, placed where it
sat in its file (the ``[skeleton] mesh = "FILE"`` form and ``wooddecay init --from-mesh``).

Formats: OBJ, PLY, STL, glTF/GLB (trimesh; a glTF scene's node transforms are applied) and USD
(.usd, .usda, .usdc, .usdz through usd-core: every ``UsdGeom.Mesh`` prim in world space at the
default time, polygons fanned into triangles, scaled by the stage's ``metersPerUnit``). OBJ, PLY
and STL carry no units: they are read as metres unless ``scale`` says otherwise. The model is
z-up (as our USD stages; our glTF files are y-up by the glTF spec): glTF is turned from y-up, USD
from its stage's ``upAxis``, OBJ, PLY and STL are taken as z-up unless ``up = "y"`` (Blender
writes OBJ y-up by default).

trimesh's hole filling and winding repair walk the mesh's graph with networkx (a dependency for
that). Checks, each an :class:`~wooddecay.errors.InputError` naming the file (exit 2): unreadable or
unknown format, no triangles, non-finite coordinates, several disjoint bodies (unless
``largest``: the one of largest area is kept), a body that stays open after repair. Repairs
trimesh can make (merging duplicate vertices, dropping degenerate faces, filling holes, winding
the faces outwards) are made and reported in :attr:`MeshInput.repairs`.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wooddecay.errors import InputError

TRIMESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf")
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
SUFFIXES = TRIMESH_SUFFIXES + USD_SUFFIXES
#: (x, y, z) of a y-up file -> our z-up coordinates: the inverse of export.gltf's Z_TO_Y_UP
Y_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True, eq=False)
class MeshInput:
    """A closed, outward-wound triangle mesh in metres and what was repaired to make it so."""

    mesh: object  # trimesh.Trimesh
    repairs: tuple[str, ...]
    source: str


def _read_trimesh(path: Path):
    import trimesh

    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as err:  # trimesh raises many types for bad files
        raise InputError(str(path), "", f"cannot read the mesh: {err}") from None
    if not isinstance(loaded, trimesh.Trimesh):
        raise InputError(str(path), "", "holds no triangle mesh")
    up = "y" if path.suffix.lower() in (".glb", ".gltf") else None
    return np.asarray(loaded.vertices, float), np.asarray(loaded.faces, np.int64), up


def _read_usd(path: Path):
    """Every mesh prim of the stage in world space and metres, polygons fanned into triangles."""
    from pxr import Usd, UsdGeom

    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as err:  # pxr raises Tf.ErrorException
        raise InputError(str(path), "", f"cannot read the USD stage: {err}") from None
    if stage is None:
        raise InputError(str(path), "", "cannot read the USD stage")
    unit = UsdGeom.GetStageMetersPerUnit(stage)
    cache = UsdGeom.XformCache(Usd.TimeCode.Default())
    points, faces, offset = [], [], 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh) or UsdGeom.Imageable(prim).ComputeVisibility() == UsdGeom.Tokens.invisible:
            continue
        mesh = UsdGeom.Mesh(prim)
        p = np.asarray(mesh.GetPointsAttr().Get() or [], float).reshape(-1, 3)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], np.int64)
        index = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], np.int64)
        if len(p) == 0 or len(counts) == 0:
            continue
        if counts.min() < 3 or counts.sum() != len(index) or index.min(initial=0) < 0 or index.max(initial=0) >= len(p):
            raise InputError(str(path), str(prim.GetPath()), "face vertex counts and indices do not match its points")
        m = np.asarray(cache.GetLocalToWorldTransform(prim), float)  # row vectors: p' = p M
        p = p @ m[:3, :3] + m[3, :3]
        start = np.concatenate([[0], np.cumsum(counts)[:-1]])
        # a polygon of k corners fans into k - 2 triangles (start, start + j, start + j + 1)
        n_tri = counts - 2
        first = np.repeat(start, n_tri)
        j = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
        tri = np.stack([index[first], index[first + j], index[first + j + 1]], axis=1)
        points.append(p)
        faces.append(tri + offset)
        offset += len(p)
    if not points:
        raise InputError(str(path), "", "holds no visible UsdGeom.Mesh with faces")
    return np.concatenate(points) * unit, np.concatenate(faces), str(UsdGeom.GetStageUpAxis(stage)).lower()


def checked_path(path, source: str | None, what: str, suffixes) -> Path:
    """``path`` as a Path if it is a file with one of ``suffixes``; else a one-line error naming
    ``source`` (the scene key or option) or the path."""
    path = Path(path)
    where = source or str(path)
    if not path.is_file():
        raise InputError(where, "", f"{what} file '{path}' does not exist")
    if path.suffix.lower() not in suffixes:
        raise InputError(where, "", f"cannot read '{path.name}': the {what} formats are {', '.join(suffixes)}")
    return path


def load_mesh(path, scale: float = 1.0, largest: bool = False, source: str | None = None,
              up: str | None = None) -> MeshInput:
    """Read, check and repair the mesh at ``path`` (module docstring); coordinates times ``scale``,
    turned to z-up from ``up`` ("y" or "z"; by default the file's own: glTF y, USD its stage's,
    others z).

    ``source`` names the scene key in messages about a missing file or an unknown format."""
    import trimesh

    path = checked_path(path, source, "mesh", SUFFIXES)
    suffix = path.suffix.lower()
    vertices, faces, file_up = (_read_usd if suffix in USD_SUFFIXES else _read_trimesh)(path)
    name = str(path)
    if (up or file_up) == "y":
        vertices = vertices @ Y_TO_Z_UP.T
    if len(faces) == 0:
        raise InputError(name, "", "the mesh has no triangles")
    if len(vertices) < 4:
        raise InputError(name, "", f"the mesh has {len(vertices)} vertices: a closed body needs at least 4")
    if not np.isfinite(vertices).all():
        raise InputError(name, "", f"{int((~np.isfinite(vertices).all(axis=1)).sum())} vertices are not finite")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(name, "", "faces index vertices the mesh does not have")
    mesh = trimesh.Trimesh(vertices * float(scale), faces, process=False)
    repairs = []
    n_v, n_f = len(mesh.vertices), len(mesh.faces)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.vertices) < n_v:
        repairs.append(f"merged {n_v - len(mesh.vertices)} duplicate vertices")
    if len(mesh.faces) < n_f:
        repairs.append(f"dropped {n_f - len(mesh.faces)} degenerate or repeated faces")
    if len(mesh.faces) == 0:
        raise InputError(name, "", "the mesh has no triangles of non-zero area")
    bodies = mesh.split(only_watertight=False)
    if len(bodies) > 1:
        if not largest:
            raise InputError(name, "", f"the mesh has {len(bodies)} disjoint bodies; keep the largest with "
                             "--largest (skeleton.largest = true) or give one body")
        mesh = max(bodies, key=lambda b: b.area)
        repairs.append(f"kept the largest of {len(bodies)} bodies")
    if not mesh.is_watertight:
        n_f = len(mesh.faces)
        trimesh.repair.fill_holes(mesh)
        if not mesh.is_watertight:
            raise InputError(name, "", f"the mesh is open or not manifold ({int(len(mesh.faces))} faces) and "
                             "filling its holes did not close it")
        repairs.append(f"filled holes with {len(mesh.faces) - n_f} faces")
    if not mesh.is_winding_consistent or mesh.volume < 0.0:
        trimesh.repair.fix_normals(mesh)
        repairs.append("wound the faces outwards")
    if not mesh.volume > 0.0:
        raise InputError(name, "", "the mesh encloses no volume")
    return MeshInput(mesh, tuple(repairs), name)


def _closest_on_triangles(p, a, b, c):
    """Closest points on triangles (a, b, c) to points p, all (n, 3) (Ericson, Real-Time Collision
    Detection §5.1.5: the Voronoi regions of the vertices, edges and face)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
        out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    cases = [  # later cases override earlier ones where they apply
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t_bc[:, None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None]),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for mask, q in cases:
        out = np.where(mask[:, None], q, out)
    return out


def surface_closest(mesh, points, edge: float, candidates: int = 24) -> np.ndarray:
    """(n, 3) closest point on the surface of ``mesh`` to each of ``points`` (n, 3): the mesh is
    subdivided to edges of at most ``edge`` and the closest point taken exactly on the
    ``candidates`` triangles whose centroids are nearest (a KD-tree; the closest point's triangle
    has its centroid within ``edge`` of it)."""
    from scipy.spatial import cKDTree
    from trimesh.remesh import subdivide_to_size

    v, f = subdivide_to_size(mesh.vertices, mesh.faces, max_edge=edge, max_iter=20)
    tri = v[f]
    k = min(candidates, len(tri))
    _, idx = cKDTree(tri.mean(axis=1)).query(points, k=k)
    idx = idx.reshape(len(points), k)
    p = np.repeat(points, k, axis=0)
    t = tri[idx.ravel()]
    q = _closest_on_triangles(p, t[:, 0], t[:, 1], t[:, 2]).reshape(len(points), k, 3)
    best = np.linalg.norm(q - points[:, None], axis=2).argmin(axis=1)
    return q[np.arange(len(points)), best]


def surface_distance(mesh, points, edge: float, candidates: int = 24) -> np.ndarray:
    """Distance (m) from each of ``points`` (n, 3) to the surface of ``mesh`` (:func:`surface_closest`)."""
    return np.linalg.norm(points - surface_closest(mesh, points, edge, candidates), axis=1)
