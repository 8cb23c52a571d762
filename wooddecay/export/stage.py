"""USD stage plumbing shared by the exporters: the stage conventions of docs/architecture.md "USD stage" (Z up,
metres, default prim ``/World`` with one Xform per scene) and atomic writes.

Stages are written with :mod:`wooddecay.atomic` (temporary file and rename; a failed write raises
:class:`~wooddecay.errors.InputError`).
"""
from __future__ import annotations

from pathlib import Path

from ..atomic import check_output, replace_with

SUFFIXES = (".usda", ".usdc", ".usd")


def prim_name(name: str) -> str:
    """A valid USD identifier for a scene name."""
    from pxr import Tf

    return Tf.MakeValidIdentifier(str(name) or "scene") or "scene"


def check_usd_path(path, what: str) -> Path:
    """``path`` as a Path after checking its suffix and that its folder exists."""
    return check_output(path, SUFFIXES, f"{what} USD")


def new_stage(name: str):
    """An in-memory stage with the conventions above for the scene called ``name``; returns
    (stage, scene prim path)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    root = f"/World/{prim_name(name)}"
    UsdGeom.Xform.Define(stage, root)
    return stage, root


def export_atomic(stage, path: Path, what: str) -> Path:
    """Write ``stage`` to ``path`` through a temporary file and a rename."""
    from pxr import Tf

    def write(tmp: Path) -> None:
        try:
            ok = stage.GetRootLayer().Export(str(tmp))
        except Tf.ErrorException as err:
            raise OSError(str(err).strip().splitlines()[-1]) from None
        if not ok:
            raise OSError(f"USD could not write {tmp}")
    return replace_with(path, write, f"{what} USD")
