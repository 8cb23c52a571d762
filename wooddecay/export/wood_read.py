"""The baked wood of a stage of any format, as one mesh in the bake's own order (docs/architecture.md
"USD stage"): what ``wooddecay diff`` compares across formats and the tests read.

:func:`wood_at` returns, for one time code, the world ``points`` (V, 3), the ``faces`` (F, 3) over
them and every primvar of the wood, flattened (indexed primvars resolved) and ordered as the bake
numbers vertices and faces:

* format 1: the single Mesh ``/World/<scene>/Wood``, in its own order;
* format 2: the Mesh of each piece under the Xform ``/World/<scene>/Wood``, its points carried to
  the world by its transform, its vertices and faces put in place by its ``vertex`` and ``face``
  primvars (which are then left out, as format 1 has none).

``holeIndices`` become a per-face bool ``hole``; ``rest`` (format 2) is carried to the world by
the piece's transform at the first frame. Values are float64 (ints stay ints).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError


def wood_meshes(stage, file="") -> list:
    """The wood's Mesh prims: the one Mesh of format 1 or the pieces of format 2."""
    root = stage.GetDefaultPrim()
    scenes = list(root.GetChildren()) if root else []
    wood = next((c.GetChild("Wood") for c in scenes if c.GetChild("Wood")), None)
    if wood is None:
        raise InputError(str(file), "/World/<scene>/Wood", "not a wooddecay bake: the stage has no wood")
    if wood.GetTypeName() == "Mesh":
        return [wood]
    return [c for c in wood.GetChildren() if c.GetTypeName() == "Mesh"]


def wood_at(stage, time: float, file="") -> dict[str, np.ndarray]:
    """The whole wood at ``time`` (module docstring)."""
    from pxr import Usd, UsdGeom

    t = Usd.TimeCode(time)
    parts: dict[str, list] = {}
    n_v = n_f = 0
    for prim in wood_meshes(stage, file):
        mesh = UsdGeom.Mesh(prim)
        local = np.asarray(mesh.GetPointsAttr().Get(t), dtype=np.float64).reshape(-1, 3)
        m = np.asarray(mesh.ComputeLocalToWorldTransform(t))
        faces = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(t), dtype=np.int64).reshape(-1, 3)
        hole = np.zeros(len(faces), dtype=bool)
        hole[np.asarray(mesh.GetHoleIndicesAttr().Get(t) or [], dtype=np.int64)] = True
        per = {"vertex": {"points": local @ m[:3, :3] + m[3, :3]}, "uniform": {"hole": hole}, "faceVarying": {}}
        first = np.asarray(mesh.ComputeLocalToWorldTransform(Usd.TimeCode(stage.GetStartTimeCode())))
        for pv in UsdGeom.PrimvarsAPI(prim).GetPrimvars():
            v = pv.ComputeFlattened(t)
            kind = {"varying": "vertex"}.get(pv.GetInterpolation(), pv.GetInterpolation())
            if v is not None and kind in per:
                v = np.asarray(v)
                per[kind][pv.GetPrimvarName()] = v.astype(np.float64) if v.dtype.kind == "f" else v
        if "rest" in per["vertex"]:  # in the piece's space at the first frame
            per["vertex"]["rest"] = per["vertex"]["rest"] @ first[:3, :3] + first[3, :3]
        vertex = per["vertex"].pop("vertex", np.arange(n_v, n_v + len(local)))
        face = per["uniform"].pop("face", np.arange(n_f, n_f + len(faces)))
        per["uniform"]["faces"] = vertex[faces]
        corner = (3 * face[:, None] + np.arange(3)).ravel()
        for kind, where in (("vertex", vertex), ("uniform", face), ("faceVarying", corner)):
            for name, v in per[kind].items():
                parts.setdefault(name, []).append((where, v))
        n_v += len(local)
        n_f += len(faces)
    out = {}
    for name, chunks in parts.items():
        where = np.concatenate([w for w, _ in chunks])
        out[name] = np.concatenate([v for _, v in chunks])[np.argsort(where, kind="stable")]
    return out
