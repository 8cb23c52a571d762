"""The baked USD stage (docs/architecture.md "USD stage": the contract between bake, the add-on and CI).

``export_usd(path, model, mesh, frames)`` writes:

* stage metadata: Z up, metersPerUnit 1, defaultPrim ``/World``, timeCodesPerSecond = ``time.fps``,
  start/end time codes = the first and last frame index, customLayerData (``format_version``: the
  stage's format :data:`FORMAT`, wooddecay version, scene name, seed, hash of the resolved scene,
  days per frame, frame days);
* ``/World/<scene>/Wood``: one Mesh of all meshlets as disjoint closed shells (triangles,
  subdivisionScheme none, static ``faceVertexIndices``), ``points`` and ``extent`` time-sampled (the skinned
  meshlets of :mod:`wooddecay.meshlets.skin`); vertex primvars H_c, H_l, M, R_w, R_b, C
  (time-sampled, interpolated with the skinning weights), ``bark_crack`` and ``bark_crack_depth``
  (time-sampled, :mod:`wooddecay.export.bark_surface`; the bark's grooves are in ``points``), the
  face-varying ``barkUV`` into the crack map, one UDIM tile per frame ``<stem>_bark.<UDIM>.png``
  written beside the stage (:mod:`wooddecay.export.bark_texture`; customLayerData ``bark_texture`` names
  the set, tiles of an earlier bake there are removed) and ``displayColor`` (a rot preview, see
  :func:`wooddecay.export.colors.rot_color`); static ``wood`` (float3 rest wood-local r, phi, s)
  and ``ring``; uniform int ``element``, ``tissue``, ``faceKind`` (0 bark, 1 side, 2 cap),
  ``exposedFrame`` (the time code from which the face shows) and time-sampled ``piece`` (the
  connected component of the face's element);
* faces between meshlets that hold together for the whole bake are left out
  (:func:`wooddecay.meshlets.visibility.exposure`: side faces across a connection that never
  breaks or between neighbours that stay in one piece, caps across a strand link never cut, none
  next to dwindling wood). A face that a later frame exposes is a hole (``holeIndices``,
  time-sampled where the hidden set changes; not authored when nothing is ever hidden) until that
  frame, so a frame shows the faces of its own state whatever the bake's length; the add-on drops
  them by ``exposedFrame``;
* ``/World/<scene>/Looks/Wood``: a UsdPreviewSurface whose diffuseColor reads ``displayColor``
  through a UsdPrimvarReader_float3, so any USD viewer shows the rot.

Written atomically (:func:`wooddecay.export.stage.export_atomic`).

Readers (``wooddecay diff``, ``wooddecay inspect BAKE_DIR``) check a stage's format with
:func:`stage_format` / :func:`check_bake_format`: a stage without ``format_version`` was baked
before the key existed and is format 1; one of a newer format than this wooddecay reads is refused
in one line (:class:`~wooddecay.errors.InputError`, exit 2).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import bark_surface as surface
from . import bark_texture as texture
from ..errors import InputError
from ..meshlets import skin as skin_mod
from ..meshlets.visibility import NEVER, exposure
from ..sim.state import FIELDS
from . import stage as stage_mod
from .colors import rot_color
from .png import write_png16

#: the bark's vertex primvars (:mod:`wooddecay.export.bark_surface`)
BARK_PRIMVARS = ("bark_crack", "bark_crack_depth")

#: The baked stage's format, written as customLayerData ``format_version``. A change to what the
#: stage holds or means (a prim, primvar or metadata key renamed, removed or reinterpreted) bumps it
#: and is listed in CHANGELOG.md; readers refuse a stage of a newer format.
FORMAT = 1
#: the oldest stage format this wooddecay reads
FORMAT_MIN = 1
#: the format of a stage baked before ``format_version`` existed
FORMAT_UNDECLARED = 1
FORMAT_KEY = "format_version"


def stage_format(custom_layer_data, file) -> int:
    """The format of a baked stage from its root layer's ``custom_layer_data`` (a mapping):
    ``format_version``, or :data:`FORMAT_UNDECLARED` for a stage baked before the key existed.
    Raises :class:`~wooddecay.errors.InputError` (one line: ``file``, the key and the formats this
    wooddecay reads) for a newer format or a value that is not a whole number."""
    from ..version import __version__

    value = dict(custom_layer_data or {}).get(FORMAT_KEY, FORMAT_UNDECLARED)
    allowed = f"formats [{FORMAT_MIN}, {FORMAT}]"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(str(file), f"customLayerData.{FORMAT_KEY}",
                         f"expected a whole number in [{FORMAT_MIN}, {FORMAT}], got {value!r:.40}")
    if value > FORMAT:
        raise InputError(str(file), f"customLayerData.{FORMAT_KEY}",
                         f"stage format {int(value)} is newer than wooddecay {__version__} reads ({allowed}); "
                         "upgrade wooddecay to read this stage")
    if value < FORMAT_MIN:
        raise InputError(str(file), f"customLayerData.{FORMAT_KEY}",
                         f"stage format {int(value)} is older than wooddecay {__version__} reads ({allowed})")
    return int(value)


def check_bake_format(folder) -> None:
    """:func:`stage_format` of every USD stage directly in the bake folder ``folder`` (its layer
    metadata only; a file USD cannot open is left to the reader that opens it)."""
    from pxr import Sdf, Tf

    folder = Path(folder)
    if not folder.is_dir():
        return
    for p in sorted(folder.iterdir()):
        if p.suffix.lower() not in stage_mod.SUFFIXES or p.name.startswith(".") or not p.is_file():
            continue
        try:
            layer = Sdf.Layer.OpenAsAnonymous(str(p), True)
        except Tf.ErrorException:
            continue
        if layer is not None:
            stage_format(layer.customLayerData, p)


def crack_map_files(path) -> list[Path]:
    """The crack map's files beside the stage ``path`` (its UDIM tiles and the single image older
    bakes wrote), in tile order."""
    path = Path(path)
    if not path.parent.is_dir():
        return []
    tiles = {p: texture.tile_number(p.name, path.stem) for p in path.parent.iterdir()}
    single = path.with_name(f"{path.stem}_bark.png")
    return ([p for k, p in sorted((k, p) for p, k in tiles.items() if k is not None)]
            + ([single] if single.exists() else []))


def export_usd(path, model, mesh, frames, version: str = "") -> Path:
    """Write the baked stage (module docstring) for ``frames`` (a list of
    :class:`wooddecay.sim.driver.Frame`) to ``path`` (.usda, .usdc or .usd)."""
    from pxr import Gf, Sdf, UsdGeom, UsdShade, Vt

    path = stage_mod.check_usd_path(path, "baked")
    frames = list(frames)
    stage, root = stage_mod.new_stage(model.info.name)
    stage.SetStartTimeCode(float(frames[0].index))
    stage.SetEndTimeCode(float(frames[-1].index))
    stage.SetTimeCodesPerSecond(float(model.time.fps))
    stage.SetFramesPerSecond(float(model.time.fps))
    days = [float(f.t_days) for f in frames]
    stage.GetRootLayer().customLayerData = {
        FORMAT_KEY: FORMAT, "wooddecay_version": version, "scene": model.info.name, "seed": int(model.info.seed),
        "scene_hash": model.info.hash,
        "days_per_frame": float(model.time.days) / max(int(model.time.frames) - 1, 1),
        "frame_days": Vt.DoubleArray(days),
    }
    link = skin_mod.links(model, mesh)
    first = exposure(model, mesh, frames)
    keep = first != NEVER
    index = np.array([f.index for f in frames], dtype=np.int32)
    shown_from = index[first[keep]]
    faces = mesh.faces[keep]
    used, inv = np.unique(faces, return_inverse=True)
    faces = inv.reshape(-1, 3)
    fe = mesh.face_element[keep]

    wood = UsdGeom.Mesh.Define(stage, f"{root}/Wood")
    wood.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    wood.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
    wood.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()))
    pv = UsdGeom.PrimvarsAPI(wood)
    T = Sdf.ValueTypeNames
    pv.CreatePrimvar("wood", T.Float3Array, UsdGeom.Tokens.vertex).Set(
        Vt.Vec3fArray.FromNumpy(mesh.wood[used].astype(np.float32)))
    pv.CreatePrimvar("ring", T.FloatArray, UsdGeom.Tokens.vertex).Set(
        Vt.FloatArray.FromNumpy(mesh.ring[used].astype(np.float32)))
    for old in crack_map_files(path):
        old.unlink()
    tiles = texture.crack_maps(model, frames)
    if tiles is not None:
        for k, tile in enumerate(tiles):
            write_png16(path.with_name(texture.file_name(path.stem, k)), tile, "bark crack map")
        stage.GetRootLayer().customLayerData = {**stage.GetRootLayer().customLayerData,
                                                "bark_texture": texture.file_name(path.stem)}
        pv.CreatePrimvar("barkUV", T.TexCoord2fArray, UsdGeom.Tokens.faceVarying).Set(
            Vt.Vec2fArray.FromNumpy(texture.bark_uv(model, mesh, mesh.faces[keep]).astype(np.float32)))
    for name, values in (("element", fe), ("tissue", model.tissue[fe]), ("faceKind", mesh.face_kind[keep]),
                         ("exposedFrame", shown_from)):
        pv.CreatePrimvar(name, T.IntArray, UsdGeom.Tokens.uniform).Set(
            Vt.IntArray.FromNumpy(np.asarray(values, dtype=np.int32)))
    piece = pv.CreatePrimvar("piece", T.IntArray, UsdGeom.Tokens.uniform)
    fields = {f: pv.CreatePrimvar(f, T.FloatArray, UsdGeom.Tokens.vertex) for f in FIELDS + BARK_PRIMVARS}
    color = wood.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
    points, extent = wood.CreatePointsAttr(), wood.CreateExtentAttr()
    held = 0  # faces hidden at the last sample of holeIndices; no sample while none is hidden
    for fr in frames:
        t = float(fr.index)
        hidden = np.flatnonzero(shown_from > fr.index).astype(np.int32)
        if len(hidden) != held:  # the hidden set only shrinks
            wood.CreateHoleIndicesAttr().Set(Vt.IntArray.FromNumpy(hidden), t)
            held = len(hidden)
        crack, depth, offset = surface.frame_bark(model, mesh, fr)
        P, F = skin_mod.frame_arrays(model, mesh, link, fr, offset)
        P, F = P[used].astype(np.float32), F[used].astype(np.float32)
        points.Set(Vt.Vec3fArray.FromNumpy(P), t)
        extent.Set(Vt.Vec3fArray([Gf.Vec3f(*P.min(0).tolist()), Gf.Vec3f(*P.max(0).tolist())]), t)
        for k, f in enumerate(FIELDS):
            fields[f].Set(Vt.FloatArray.FromNumpy(np.ascontiguousarray(F[:, k])), t)
        for f, v in zip(BARK_PRIMVARS, (crack, depth)):
            fields[f].Set(Vt.FloatArray.FromNumpy(v[used].astype(np.float32)), t)
        ix = {f: k for k, f in enumerate(FIELDS)}
        color.Set(Vt.Vec3fArray.FromNumpy(rot_color(F[:, ix["H_c"]], F[:, ix["H_l"]], F[:, ix["M"]])), t)
        comp = fr.mech["component"][fe] if fr.mech else np.zeros(len(fe))
        piece.Set(Vt.IntArray.FromNumpy(comp.astype(np.int32)), t)

    UsdGeom.Scope.Define(stage, f"{root}/Looks")
    mat = UsdShade.Material.Define(stage, f"{root}/Looks/Wood")
    surf = UsdShade.Shader.Define(stage, f"{root}/Looks/Wood/PreviewSurface")
    surf.CreateIdAttr("UsdPreviewSurface")
    reader = UsdShade.Shader.Define(stage, f"{root}/Looks/Wood/RotColor")
    reader.CreateIdAttr("UsdPrimvarReader_float3")
    reader.CreateInput("varname", T.String).Set("displayColor")
    reader.CreateOutput("result", T.Float3)
    surf.CreateInput("diffuseColor", T.Color3f).ConnectToSource(reader.ConnectableAPI(), "result")
    surf.CreateInput("roughness", T.Float).Set(0.8)
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(wood.GetPrim()).Bind(mat)
    return stage_mod.export_atomic(stage, path, "baked")
