"""USD stage plumbing shared by the exporters: the stage conventions of DESIGN "USD stage" (Z up,
metres, default prim ``/World`` with one Xform per scene) and atomic writes.

A stage is exported to a hidden temporary file in the target folder that keeps the real
extension last (USD picks the format from the suffix), then renamed over the target, so a crash
never leaves a half file. A failed write raises :class:`~wooddecay.errors.InputError`.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError

SUFFIXES = (".usda", ".usdc", ".usd")


def prim_name(name: str) -> str:
    """A valid USD identifier for a scene name."""
    from pxr import Tf

    return Tf.MakeValidIdentifier(str(name) or "scene") or "scene"


def check_usd_path(path, what: str) -> Path:
    """``path`` as a Path after checking its suffix and that its folder exists."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(str(path), "", f"a {what} USD file must end in {', '.join(SUFFIXES)}")
    if not path.parent.is_dir():
        raise InputError(str(path), "", f"folder {path.parent} does not exist")
    return path


def new_stage(scene):
    """An in-memory stage with the conventions above; returns (stage, scene prim path)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    root = f"/World/{prim_name(scene.name)}"
    UsdGeom.Xform.Define(stage, root)
    return stage, root


def export_atomic(stage, path: Path, what: str) -> Path:
    """Write ``stage`` to ``path`` through a temporary file and a rename."""
    from pxr import Tf

    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        if not stage.GetRootLayer().Export(str(tmp)):
            raise OSError(f"USD could not write {tmp}")
        os.replace(tmp, path)
    except (OSError, Tf.ErrorException) as err:
        raise InputError(str(path), "", f"cannot write the {what} USD file: {err}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path
