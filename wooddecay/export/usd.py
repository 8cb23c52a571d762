"""The baked USD stage (docs/architecture.md "USD stage": the contract between bake, the add-on and CI).

``export_usd(path, model, mesh, frames)`` writes format 2 (:data:`FORMAT`):

* stage metadata: Z up, metersPerUnit 1, defaultPrim ``/World``, timeCodesPerSecond = ``time.fps``,
  start/end time codes = the first and last frame index, customLayerData (``format_version``,
  wooddecay version, scene name, seed, hash of the resolved scene, days per frame, frame days,
  ``point_tolerance`` and ``field_step``), the scene's description as the root layer's documentation;
* ``/World/<scene>/Wood``: an Xform of one Mesh ``piece_<id>`` per piece of the last frame, its
  meshlets as disjoint closed shells (triangles, subdivisionScheme none, static topology). What a
  frame changes is written only where it changed (:mod:`wooddecay.export.tracks`): the piece's
  ``xformOp:transform`` where it moved as a rigid body, its local ``points`` and ``extent`` where it
  changed shape (every written point within ``point_tolerance`` of the skinned meshlets of
  :mod:`wooddecay.meshlets.skin`); the vertex primvars H_c, H_l, M, R_w, R_b, C (interpolated with
  the skinning weights) and ``bark_crack`` as indices into a static table of values ``field_step``
  apart, ``bark_crack_depth`` into one ``point_tolerance`` apart (:mod:`wooddecay.export.bark_surface`;
  the bark's grooves are in ``points``), ``displayColor`` into a palette of the rot preview colours
  the bake uses (:func:`wooddecay.export.colors.rot_color`), indices written where one changed; the
  face-varying ``barkUV`` into the crack map, one UDIM tile per frame ``<stem>_bark.<UDIM>.png``
  written beside the stage (:mod:`wooddecay.export.bark_texture`; customLayerData ``bark_texture``
  names the set, tiles of an earlier bake there are removed); static ``wood`` (float3 rest
  wood-local r, phi, s), ``ring``, ``vertex`` (the vertex's index in the whole wood) and ``rest``
  (point3f: the as-built meshlets before the rods settled, in the piece's space at the first
  frame, whose transform carries it to the world); uniform int
  ``face`` (the face's index in the whole wood), ``element``, ``tissue``, ``faceKind`` (0 bark, 1
  side, 2 cap), ``exposedFrame`` (the time code from which the face shows) and time-sampled
  ``piece`` (the connected component of the face's element). An attribute that changes has a
  sample at every frame (a repeated value is stored once), one that never does only a default;
* faces between meshlets that hold together for the whole bake are left out
  (:func:`wooddecay.meshlets.visibility.exposure`: side faces across a connection that never
  breaks or between neighbours that stay in one piece, caps across a strand link never cut, none
  next to dwindling wood). A face that a later frame exposes is a hole of its piece
  (``holeIndices``; not authored when nothing is ever hidden) until that frame, so a frame shows the
  faces of its own state whatever the bake's length; the add-on drops them by ``exposedFrame``;
* ``/World/<scene>/Looks/Wood``: a UsdPreviewSurface whose diffuseColor reads ``displayColor``
  through a UsdPrimvarReader_float3, bound to the Wood Xform, so any USD viewer shows the rot.

Written atomically (:func:`wooddecay.export.stage.export_atomic`).

Readers (``wooddecay diff``, ``wooddecay inspect BAKE_DIR``) check a stage's format with
:func:`stage_format` / :func:`check_bake_format`: a stage without ``format_version`` was baked
before the key existed and is format 1 (one Mesh ``/World/<scene>/Wood`` with every value at every
frame; :func:`wooddecay.export.wood_read.wood_at` reads both); one of a newer format than this
wooddecay reads is refused in one line (:class:`~wooddecay.errors.InputError`, exit 2).
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
from .tracks import PoseTrack, changed, piece_max

#: the bark's vertex primvars (:mod:`wooddecay.export.bark_surface`)
BARK_PRIMVARS = ("bark_crack", "bark_crack_depth")

#: The baked stage's format, written as customLayerData ``format_version``. A change to what the
#: stage holds or means (a prim, primvar or metadata key renamed, removed or reinterpreted) bumps it
#: and is listed in CHANGELOG.md; readers refuse a stage of a newer format.
FORMAT = 2
#: the oldest stage format this wooddecay reads
FORMAT_MIN = 1
#: the format of a stage baked before ``format_version`` existed
FORMAT_UNDECLARED = 1
FORMAT_KEY = "format_version"
#: the defaults of ``[export] point_tolerance`` (m) and ``field_step`` (the schema's, which a test
#: holds equal: the exporters sit below the scene)
POINT_TOLERANCE = 2e-4
FIELD_STEP = 2e-3
#: levels of H_c, H_l and M in the displayColor palette (a preview: 1/63 of the rot, 1/7 of the moisture)
PALETTE = (64, 64, 8)


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


def _piece_runs(key: np.ndarray):
    """(order, start): ``key`` sorted stably into runs of one piece each (piece k's items are
    ``order[start[k]:start[k + 1]]``)."""
    order = np.argsort(key, kind="stable")
    return order, np.searchsorted(key[order], np.arange(int(key.max(initial=-1)) + 2))


def _matrix(R, c):
    """The row-vector USD matrix of world = R local + c."""
    from pxr import Gf

    m = np.eye(4)
    m[:3, :3], m[3, :3] = R.T, c
    return Gf.Matrix4d(*m.ravel().tolist())


def export_usd(path, model, mesh, frames, version: str = "", point_tolerance: float = POINT_TOLERANCE,
               field_step: float = FIELD_STEP) -> Path:
    """Write the baked stage (module docstring) for ``frames`` (a list of
    :class:`wooddecay.sim.driver.Frame`) to ``path`` (.usda, .usdc or .usd); the tolerances are
    ``[export]``'s."""
    from pxr import Gf, Sdf, UsdGeom, UsdShade, Vt

    path = stage_mod.check_usd_path(path, "baked")
    frames = list(frames)
    tol_x, step_f = float(point_tolerance), float(field_step)
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
        "frame_days": Vt.DoubleArray(days), "point_tolerance": tol_x, "field_step": step_f,
    }
    stage.GetRootLayer().documentation = model.info.description
    link = skin_mod.links(model, mesh)
    first = exposure(model, mesh, frames)
    keep = first != NEVER
    index = np.array([f.index for f in frames], dtype=np.int32)
    shown_from = index[first[keep]]
    used, inv = np.unique(mesh.faces[keep], return_inverse=True)
    faces = inv.reshape(-1, 3)
    fe = mesh.face_element[keep]
    final = frames[-1].mech["component"] if frames[-1].mech else np.zeros(model.n_elements, dtype=np.int64)
    ids, vpiece = np.unique(final[mesh.vertex_element[used]], return_inverse=True)
    vorder, vstart = _piece_runs(vpiece)
    forder, fstart = _piece_runs(vpiece[faces[:, 0]])
    rank = np.empty_like(vorder)
    rank[vorder] = np.arange(len(vorder))
    local = rank[faces[forder]] - vstart[vpiece[faces[forder, 0]]][:, None]
    fe, shown_from = fe[forder], shown_from[forder]

    T = Sdf.ValueTypeNames
    wood = UsdGeom.Xform.Define(stage, f"{root}/Wood")
    for old in crack_map_files(path):
        old.unlink()
    tiles = texture.crack_maps(model, frames)
    uv = None
    if tiles is not None:
        for k, tile in enumerate(tiles):
            write_png16(path.with_name(texture.file_name(path.stem, k)), tile, "bark crack map")
        stage.GetRootLayer().customLayerData = {**stage.GetRootLayer().customLayerData,
                                                "bark_texture": texture.file_name(path.stem)}
        uv = texture.bark_uv(model, mesh, mesh.faces[keep]).astype(np.float32).reshape(-1, 3, 2)[forder]
    static_v = {"wood": (T.Float3Array, mesh.wood[used][vorder].astype(np.float32), Vt.Vec3fArray),
                "ring": (T.FloatArray, mesh.ring[used][vorder].astype(np.float32), Vt.FloatArray),
                "vertex": (T.IntArray, vorder.astype(np.int32), Vt.IntArray)}
    static_f = {"face": forder, "element": fe, "tissue": model.tissue[fe], "faceKind": mesh.face_kind[keep][forder],
                "exposedFrame": shown_from}
    prims: list[tuple] = []
    for k, piece in enumerate(ids.tolist()):
        vs, fs = slice(vstart[k], vstart[k + 1]), slice(fstart[k], fstart[k + 1])
        m = UsdGeom.Mesh.Define(stage, f"{root}/Wood/piece_{piece}")
        m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(fs.stop - fs.start, 3, dtype=np.int32)))
        m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(local[fs].astype(np.int32).ravel()))
        pv = UsdGeom.PrimvarsAPI(m)
        for name, (kind, values, vt) in static_v.items():
            pv.CreatePrimvar(name, kind, UsdGeom.Tokens.vertex).Set(vt.FromNumpy(np.ascontiguousarray(values[vs])))
        for name, values in static_f.items():
            pv.CreatePrimvar(name, T.IntArray, UsdGeom.Tokens.uniform).Set(
                Vt.IntArray.FromNumpy(np.asarray(values[fs], dtype=np.int32)))
        if uv is not None:
            pv.CreatePrimvar("barkUV", T.TexCoord2fArray, UsdGeom.Tokens.faceVarying).Set(
                Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(uv[fs].reshape(-1, 2))))
        tabled = {f: pv.CreatePrimvar(f, T.FloatArray, UsdGeom.Tokens.vertex) for f in FIELDS + BARK_PRIMVARS}
        tabled["displayColor"] = m.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
        attrs = {"xform": m.AddTransformOp(), "points": m.CreatePointsAttr(), "extent": m.CreateExtentAttr(),
                 "piece": pv.CreatePrimvar("piece", T.IntArray, UsdGeom.Tokens.uniform).GetAttr(),
                 "holeIndices": m.CreateHoleIndicesAttr()}
        attrs.update((f, p.CreateIndicesAttr()) for f, p in tabled.items())
        prims.append((vs, fs, attrs, {name: [] for name in attrs}, tabled, pv))

    columns = FIELDS + BARK_PRIMVARS
    step = np.array([step_f] * (len(FIELDS) + 1) + [tol_x])  # bark_crack_depth is a length
    lo = np.array([min(float(f.fields[c].min(initial=0.0)) for f in frames) for c in FIELDS] + [0.0, 0.0])
    hi = np.array([max(float(f.fields[c].max(initial=0.0)) for f in frames) for c in FIELDS]
                  + [1.0, float(model.bark_thickness)])
    k_lo, k_hi = np.floor(lo / step).astype(np.int64), np.ceil(hi / step).astype(np.int64)
    tables = [Vt.FloatArray.FromNumpy((np.arange(k_lo[j], k_hi[j] + 1) * step[j]).astype(np.float32))
              for j in range(len(columns))]
    ix = {f: j for j, f in enumerate(columns)}
    colour = [ix[f] for f in ("H_c", "H_l", "M")]
    for *_, tabled, _ in prims:
        for f, table in zip(columns, tables):
            tabled[f].Set(table)
    track: PoseTrack | None = None
    level: np.ndarray = np.zeros(0, dtype=np.int64)
    held_piece: np.ndarray = np.zeros(0, dtype=np.int32)
    prev = frames[0].index
    for fr in frames:
        crack, depth, offset = surface.frame_bark(model, mesh, fr)
        P, F = skin_mod.frame_arrays(model, mesh, link, fr, offset)
        X = P[used][vorder]
        values = np.concatenate([F[used], crack[used][:, None], depth[used][:, None]], 1)[vorder]
        now = np.clip(np.rint(values / step).astype(np.int64), k_lo, k_hi) - k_lo
        comp = (fr.mech["component"][fe] if fr.mech else np.zeros(len(fe))).astype(np.int32)
        hidden = shown_from > fr.index
        if track is None:
            track, level, held_piece = PoseTrack(X, vstart), now, comp.copy()
            rest = mesh.points[used][vorder] - track.c[track.piece]
            pose = shape = regroup = hidden_now = np.ones(len(ids), dtype=bool)
            fresh = np.ones((len(ids), len(columns)), dtype=bool)
        else:
            pose, shape = track.update(X, tol_x)
            fresh = changed(now, level, vstart, 0)
            level = now
            regroup = piece_max((comp != held_piece).astype(np.float64), fstart) > 0
            held_piece = comp
            hidden_now = piece_max((hidden != (shown_from > prev)).astype(np.float64), fstart) > 0
        prev = fr.index
        tint = fresh[:, colour].any(1)
        cell = [np.rint(values[:, j] * (n - 1)).clip(0, n - 1).astype(np.int64) for j, n in zip(colour, PALETTE)]
        swatch = ((cell[0] * PALETTE[1] + cell[1]) * PALETTE[2] + cell[2]).astype(np.int32)
        for k, (vs, fs, attrs, samples, *_) in enumerate(prims):
            def put(name, make, new):
                samples[name].append(make() if new or not samples[name] else samples[name][-1])
            L = track.L[vs].astype(np.float32)
            put("xform", lambda: _matrix(track.R[k], track.c[k]), pose[k])
            put("points", lambda: Vt.Vec3fArray.FromNumpy(L), shape[k])
            put("extent", lambda: Vt.Vec3fArray([Gf.Vec3f(*L.min(0).tolist()), Gf.Vec3f(*L.max(0).tolist())]),
                shape[k])
            for j, f in enumerate(columns):
                put(f, lambda: Vt.IntArray.FromNumpy(level[vs, j].astype(np.int32)), fresh[k, j])
            put("displayColor", lambda: swatch[vs], tint[k])
            put("piece", lambda: Vt.IntArray.FromNumpy(held_piece[fs]), regroup[k])
            put("holeIndices", lambda: Vt.IntArray.FromNumpy(np.flatnonzero(hidden[fs]).astype(np.int32)),
                hidden_now[k])

    swatches = np.unique(np.concatenate([s for _, _, _, samples, *_ in prims for s in samples["displayColor"]]))
    grid = np.unravel_index(swatches, PALETTE)
    palette = Vt.Vec3fArray.FromNumpy(rot_color(*(g / (n - 1.0) for g, n in zip(grid, PALETTE))))
    for vs, _, attrs, samples, tabled, pv in prims:
        pv.CreatePrimvar("rest", T.Point3fArray, UsdGeom.Tokens.vertex).Set(
            Vt.Vec3fArray.FromNumpy(rest[vs].astype(np.float32)))
        tabled["displayColor"].Set(palette)
        made: dict[int, object] = {}
        samples["displayColor"] = [made.setdefault(id(s), Vt.IntArray.FromNumpy(
            np.searchsorted(swatches, s).astype(np.int32))) for s in samples["displayColor"]]
        for name, values in samples.items():
            if len({id(v) for v in values}) == 1:
                if name != "holeIndices" or len(values[0]):
                    attrs[name].Set(values[0])
            else:
                for fr, v in zip(frames, values):
                    attrs[name].Set(v, float(fr.index))

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
