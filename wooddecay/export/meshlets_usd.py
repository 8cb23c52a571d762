"""Debug view of the rest meshlets as one USD Mesh (woodstock Fig. 10).

``write_meshlets_usd(path, model, mesh)`` writes ``/World/<scene>/Meshlets``: all meshlets as
disjoint closed shells of triangles (subdivisionScheme none), ``displayColor`` per face by element
(a hash colour, so neighbours differ), uniform int ``element`` and ``faceKind`` (0 bark, 1 side,
2 cap), vertex float ``ring``. Stage conventions and the atomic write: :mod:`.stage`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import stage as stage_mod


def element_colors(element: np.ndarray) -> np.ndarray:
    """A pseudo-random but fixed colour per element index (golden-ratio hue walk)."""
    h = (np.asarray(element, dtype=np.float64) * 0.6180339887498949) % 1.0
    k = (np.array([5.0, 3.0, 1.0])[None] + h[:, None] * 6.0) % 6.0
    rgb = 1.0 - np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0) * 0.65
    return rgb.astype(np.float32)


def write_meshlets_usd(path, model, mesh) -> Path:
    """Write the rest meshlets ``mesh`` to ``path`` (.usda, .usdc or .usd)."""
    from pxr import Gf, Sdf, UsdGeom, Vt

    path = stage_mod.check_usd_path(path, "meshlets")
    stage, root = stage_mod.new_stage(model.info.name)
    m = UsdGeom.Mesh.Define(stage, f"{root}/Meshlets")
    pts = np.ascontiguousarray(mesh.points, dtype=np.float32)
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
    m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(mesh.n_faces, 3, dtype=np.int32)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh.faces.astype(np.int32).ravel()))
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    if len(pts):
        m.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*pts.min(0).tolist()), Gf.Vec3f(*pts.max(0).tolist())]))
    pv = UsdGeom.PrimvarsAPI(m)
    pv.CreatePrimvar("element", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform).Set(
        Vt.IntArray.FromNumpy(mesh.face_element.astype(np.int32)))
    pv.CreatePrimvar("faceKind", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform).Set(
        Vt.IntArray.FromNumpy(mesh.face_kind.astype(np.int32)))
    pv.CreatePrimvar("ring", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex).Set(
        Vt.FloatArray.FromNumpy(mesh.ring.astype(np.float32)))
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.uniform).Set(
        Vt.Vec3fArray.FromNumpy(element_colors(mesh.face_element)))
    return stage_mod.export_atomic(stage, path, "meshlets")
