"""The Blender add-on (docs/architecture.md "Blender add-on"; issue 6, item 5 and "Show"), headless with the
``bpy`` wheel.

Every bpy step runs in a subprocess (``bpy`` bundles its own ``pxr``, which must not meet
usd-core's in this interpreter). The extension is built with ``wooddecay addon build`` (plain
Python, checked against Blender's own extension builder), installed from the zip with Blender's ``extension install-file`` into a
throw-away user folder (BLENDER_USER_RESOURCES), enabled, and driven through its operator
``bpy.ops.import_scene.wooddecay``. The bakes are made here with the Python API.

These tests FAIL (never skip) when bpy is missing.
"""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import wooddecay as wd
from wooddecay import addon
from wooddecay.cli import main
from wooddecay.export.gltf import export_gltf
from wooddecay.export.usd import FIELD_STEP, export_usd
from wooddecay.export.wood_read import wood_at

from .conftest import cracking_frames

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parent.parent
#: the add-on's source, package data of wooddecay (wooddecay/blender_addon/)
ADDON_DIR = addon.SOURCE
MODULE = "bl_ext.user_default.wooddecay"
#: seconds one bpy subprocess may take
TIMEOUT = 300
#: the render test: brown rot must move the rotted end's mean colour (sRGB, 0..1) by more than
#: this (measured ~0.26) and by more than RATIO times what the sound end moves (measured ~0.03);
#: the rotted end must also get darker by more than DARKER in mean luminance (measured ~0.15)
MARGIN, RATIO, DARKER = 0.12, 3.0, 0.06
#: the bark crack render: bark with bark_crack = 1 must be darker than bark with 0 by more than
#: CRACK_DARKER in mean luminance (sRGB, 0..1); bark with bark_crack = 0 and bark without the
#: attribute (an older bake) may differ by at most SAME
CRACK_DARKER, SAME = 0.05, 0.002


def load_pure(name: str):
    """A bpy-free module of the add-on (importer.py, shader.py) loaded from its file."""
    key = f"wooddecay_addon_{name}"
    if key not in sys.modules:
        spec = importlib.util.spec_from_file_location(key, ADDON_DIR / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[key] = module  # dataclasses look their module up
        spec.loader.exec_module(module)
    return sys.modules[key]


def run_blender(script: str, *args, user: Path, timeout: float = TIMEOUT) -> dict:
    """Run ``script`` in a bpy subprocess with Blender's user folder ``user``; the script writes
    its results as JSON to ``argv[1]``. Fails with the subprocess output on any error."""
    out = Path(tempfile.mkdtemp(dir=user)) / "result.json"
    proc = subprocess.run([sys.executable, "-c", script, str(out), *map(str, args)],
                          env=addon_env(user), capture_output=True, text=True, timeout=timeout)
    log = (proc.stdout + proc.stderr)[-6000:]
    assert proc.returncode == 0 and out.is_file(), f"bpy subprocess failed (exit {proc.returncode}):\n{log}"
    res = json.loads(out.read_text())
    assert "error" not in res, f"{res['error']}\n{log}"
    return res


def addon_env(user: Path) -> dict:
    return dict(os.environ) | {"BLENDER_USER_RESOURCES": str(user), "PYTHONUNBUFFERED": "1"}


# ----------------------------------------------------------------------------- bpy-side scripts

#: shared start of the bpy scripts: enable the installed extension, helpers, result writing.
#: (Classes left registered make the bpy module hang at exit, so the scripts disable the add-on
#: and leave through os._exit.)
PRELUDE = r'''
import json, math, os, sys, time, traceback
import numpy as np
import bpy, addon_utils

OUT = sys.argv[1]
MODULE = "bl_ext.user_default.wooddecay"
res = {}

def finish(code=0):
    try:
        addon_utils.disable(MODULE)
    except Exception:
        pass
    with open(OUT, "w") as f:
        json.dump(res, f)
    sys.stdout.flush(); sys.stderr.flush()
    os._exit(code)

def enable():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    res["found"] = sorted(m.__name__ for m in addon_utils.modules() if m.__name__.endswith("wooddecay"))
    addon_utils.enable(MODULE, default_set=True, handle_error=None)
    res["enabled"] = MODULE in bpy.context.preferences.addons
    res["operator"] = hasattr(bpy.types, "IMPORT_SCENE_OT_wooddecay")
    res["menu"] = any(getattr(f, "__module__", "").startswith(MODULE)
                      for f in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize())

def import_file(path):
    before = set(bpy.data.objects)
    result = bpy.ops.import_scene.wooddecay(filepath=path)
    return sorted((o for o in bpy.data.objects if o not in before and o.type == "MESH"), key=lambda o: o.name), result

def values(mesh, name):
    a = mesh.attributes[name]
    n = len(a.data)
    if a.data_type == "FLOAT_VECTOR":
        v = np.empty(3 * n, np.float32); a.data.foreach_get("vector", v); return v.reshape(n, 3)
    v = np.empty(n, np.float32 if a.data_type == "FLOAT" else np.int32); a.data.foreach_get("value", v)
    return v

def evaluated(ob, frame):
    bpy.context.scene.frame_set(frame)
    ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    me = ev.to_mesh()
    P = np.empty(3 * len(me.vertices), np.float32); me.vertices.foreach_get("co", P)
    out = {"P": P.reshape(-1, 3), **{k: values(me, k) for k in ("H_c", "H_l", "M") if k in me.attributes}}
    ev.to_mesh_clear()
    return out

def evaluated_all(obs, frame):
    """:func:`evaluated` of every object, concatenated, points in the world."""
    parts = []
    for ob in obs:
        e = evaluated(ob, frame)
        m = np.array(ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).matrix_world)
        e["P"] = e["P"] @ m[:3, :3].T + m[:3, 3]
        parts.append(e)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0] if all(k in p for p in parts)}

def setup_render(samples, threads, location, target, ortho_scale, size):
    """Orthographic camera at ``location`` looking at ``target``, a sun, a grey world, Cycles on
    the CPU without denoising, a transparent film, ``size`` = (width, height) pixels."""
    import mathutils
    sc = bpy.context.scene
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", ortho_scale
    sc.collection.objects.link(cam)
    cam.location = location
    cam.rotation_euler = (mathutils.Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    sc.camera = cam
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(50), 0.0, math.radians(-60))
    sc.collection.objects.link(sun)
    sc.world = bpy.data.worlds.new("world")
    sc.world.use_nodes = True
    sc.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1.0)
    r = sc.render
    r.engine = "CYCLES"
    sc.cycles.device, sc.cycles.samples, sc.cycles.use_denoising = "CPU", samples, False
    r.threads_mode, r.threads = "FIXED", threads
    r.resolution_x, r.resolution_y = size
    r.resolution_percentage = 100
    r.film_transparent = True
    sc.view_settings.view_transform = "Standard"
    r.image_settings.file_format, r.image_settings.color_mode = "PNG", "RGBA"

def render_still(path, shown):
    """Render to the PNG ``path`` with only the meshes in ``shown``; (pixels (h, w, 4) of the
    saved PNG, seconds)."""
    for o in bpy.data.objects:
        if o.type == "MESH":
            o.hide_render = o not in shown
    bpy.context.scene.render.filepath = path
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t
    img = bpy.data.images.load(path)
    w, h = img.size
    return np.array(img.pixels[:], dtype=np.float32).reshape(h, w, 4), seconds

def covered_columns(px):
    """First and one past the last image column the object covers."""
    cols = np.flatnonzero((px[..., 3] > 0.9).any(0))
    return int(cols.min()), int(cols.max()) + 1

def halves(px):
    """:func:`column_means` of the left and right half of what the object covers (a 2-pixel gap
    each side of the middle)."""
    x0, x1 = covered_columns(px)
    mid = (x0 + x1) // 2
    return column_means(px, {"left": (0, mid - 2), "right": (mid + 2, px.shape[1])})

def column_means(px, bounds):
    """Mean colour and pixel count of the covered pixels in each column range of ``bounds``."""
    cover = px[..., 3] > 0.9
    out = {"pixels": int(cover.sum())}
    for key, (a, b) in bounds.items():
        m = cover.copy(); m[:, :a] = False; m[:, b:] = False
        out[key] = px[m][:, :3].mean(0).tolist()
        out[key + "_pixels"] = int(m.sum())
    return out

def describe(mat):
    group = next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"), None) if mat and mat.use_nodes else None
    d = {"name": mat.name if mat else None, "group": None}
    if group is not None:
        d["group"] = group.node_tree.name
        d["group_nodes"] = len(group.node_tree.nodes)
        d["inputs"] = [s.name for s in group.inputs]
        d["outputs"] = [s.name for s in group.outputs]
        d["linked"] = {s.name: s.links[0].from_node.attribute_name for s in group.inputs
                       if s.is_linked and s.links[0].from_node.bl_idname == "ShaderNodeAttribute"}
        d["surface"] = any(l.from_node == group and l.to_node.bl_idname == "ShaderNodeOutputMaterial"
                           for l in mat.node_tree.links)
        images = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"]
        d["crack_map"] = sorted({(os.path.basename(n.image.filepath), n.interpolation, n.image.source,
                                  tuple(t.number for t in n.image.tiles)) for n in images if n.image})
        d["crack_map_uv"] = sorted({n.uv_map for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeUVMap"})
        d["frame_driver"] = [fc.driver.expression for fc in (mat.node_tree.animation_data.drivers
                             if mat.node_tree.animation_data else [])]
        d["bark_furrows"] = group.inputs["Bark Furrows"].default_value
    return d

try:
'''

INSPECT = PRELUDE + r'''
    usd, glb = sys.argv[2], sys.argv[3]
    enable()
    # USD
    obs, result = import_file(usd)
    sc = bpy.context.scene
    u = {"result": sorted(result), "objects": [o.name for o in obs], "frames": [sc.frame_start, sc.frame_end],
         "modifiers": [m.type for o in obs for m in o.modifiers]}
    ob = obs[0]
    u["attributes"] = {a.name: [a.domain, a.data_type] for a in ob.data.attributes if not a.name.startswith(".")}
    first, last = evaluated_all(obs, sc.frame_start), evaluated_all(obs, sc.frame_end)
    u["frame_start"] = {k: np.sort(v).tolist() for k, v in first.items() if k != "P"}
    u["frame_end"] = {k: np.sort(v).tolist() for k, v in last.items() if k != "P"}
    u["dP"] = float(np.abs(first["P"] - last["P"]).max())
    u["faceKind"] = sorted({k for o in obs if "faceKind" in o.data.attributes for k in values(o.data, "faceKind").tolist()}) or None
    u["material"] = [describe(s.material) for o in obs for s in o.material_slots]
    res["usd"] = u
    # glTF
    obs, result = import_file(glb)
    g = {"result": sorted(result), "objects": [o.name for o in obs]}
    g["attributes"] = sorted({a.name for o in obs for a in o.data.attributes if not a.name.startswith(".")})
    g["values"] = {k: np.sort(np.concatenate([values(o.data, k) for o in obs])).tolist()
                   for k in ("H_c", "H_l", "M", "ring", "faceKind", "bark_crack", "bark_crack_depth")
                   if all(k in o.data.attributes for o in obs)}
    if all("wood" in o.data.attributes for o in obs):
        W = np.concatenate([values(o.data, "wood") for o in obs])
        g["wood"] = W[np.lexsort(W.T[::-1])].tolist()
    g["material"] = [describe(s.material) for o in obs for s in o.material_slots]
    res["gltf"] = g
    # a glTF without _FACE_KIND and _RING (not from wooddecay's exporter)
    obs, result = import_file(sys.argv[4])
    mat = obs[0].material_slots[0].material
    f = describe(mat)
    f["result"] = sorted(result)
    group = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup")
    f["face_kind_default"] = group.inputs["Face Kind"].default_value
    f["bark_crack_default"] = group.inputs["Bark Crack"].default_value
    res["fallback"] = f
    res["materials"] = sorted(m.name for m in bpy.data.materials if m.users)
    res["groups"] = sorted(t.name for t in bpy.data.node_groups)
except Exception:
    res["error"] = traceback.format_exc()
    finish(1)
finish(0)
'''

RENDER = PRELUDE + r'''
    rot, sound, png_dir = sys.argv[2], sys.argv[3], sys.argv[4]
    samples, threads = int(sys.argv[5]), int(sys.argv[6])
    enable()
    logs = {"rot": import_file(rot)[0], "sound": import_file(sound)[0]}
    sc = bpy.context.scene
    sc.frame_set(sc.frame_end)  # the last frame of each bake (a cache holds its last sample)
    # above and in front of the root end (x = 0): it is on the left
    setup_render(samples, threads, (-0.35, -0.8, 0.5), (0.15, 0.0, 0.06), 0.36, (128, 128))
    res["seconds"] = {}
    for name in ("rot", "sound"):
        px, res["seconds"][name] = render_still(os.path.join(png_dir, f"{name}.png"), logs[name])
        x0, x1 = covered_columns(px)
        third = (x1 - x0) // 3
        res[name] = {"bbox": [x0, x1], **column_means(px, {"rotted_end": (x0, x0 + third),
                                                            "sound_end": (x1 - third, x1)})}
except Exception:
    res["error"] = traceback.format_exc()
    finish(1)
finish(0)
'''


CRACK_RENDER = PRELUDE + r'''
    crack, plain, png_dir = sys.argv[2], sys.argv[3], sys.argv[4]
    samples, threads = int(sys.argv[5]), int(sys.argv[6])
    enable()
    patches = {"crack": import_file(crack)[0], "plain": import_file(plain)[0]}
    res["materials"] = {k: describe(obs[0].material_slots[0].material) for k, obs in patches.items()}
    sc = bpy.context.scene
    sc.frame_set(sc.frame_end)
    setup_render(samples, threads, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.26, (128, 64))  # from above
    res["seconds"] = {}
    for name, obs in patches.items():
        px, res["seconds"][name] = render_still(os.path.join(png_dir, f"{name}.png"), obs)
        res[name] = halves(px)
except Exception:
    res["error"] = traceback.format_exc()
    finish(1)
finish(0)
'''


CRACK_MAP_RENDER = PRELUDE + r'''
    tiles, png_dir = sys.argv[2], sys.argv[3]
    samples, threads = int(sys.argv[4]), int(sys.argv[5])
    enable()
    obs = import_file(tiles)[0]
    res["material"] = describe(obs[0].material_slots[0].material)
    setup_render(samples, threads, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.26, (128, 64))  # from above
    for frame in (0, 1, 3):
        bpy.context.scene.frame_set(frame)
        res[frame] = halves(render_still(os.path.join(png_dir, f"frame{frame}.png"), obs)[0])
except Exception:
    res["error"] = traceback.format_exc()
    finish(1)
finish(0)
'''



EXPOSURE = PRELUDE + r"""
    enable()
    obs, result = import_file(sys.argv[2])
    res["modifiers"] = sorted({tuple(m.type for m in ob.modifiers) for ob in obs})
    res["faces"], res["points"] = [], []
    for frame in (0, 1, 2):
        bpy.context.scene.frame_set(frame)
        deps = bpy.context.evaluated_depsgraph_get()
        ev = [ob.evaluated_get(deps) for ob in obs]
        res["faces"].append(sum(len(e.data.polygons) for e in ev))
        res["points"].append(sum(len(e.data.vertices) for e in ev))
except Exception:
    res["error"] = traceback.format_exc()
    finish(1)
finish(0)
"""

# ----------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def addon_zip(tmp_path_factory) -> Path:
    """The extension zip, built through the CLI: ``wooddecay addon build -o DIR``."""
    out = tmp_path_factory.mktemp("addon_dist")
    result = CliRunner().invoke(main, ["addon", "build", "-o", str(out)])
    assert result.exit_code == 0, (result.output, result.exception)
    path = out / addon.zip_name()
    assert f"wrote {path}" in result.output
    return path


@pytest.fixture(scope="module")
def blender_user(tmp_path_factory, addon_zip) -> Path:
    """A throw-away Blender user folder with the extension installed from the zip."""
    user = tmp_path_factory.mktemp("blender_user")
    addon.install(addon_zip, user_resources=user, timeout=TIMEOUT)
    return user


@pytest.fixture(scope="module")
def bake(tmp_path_factory):
    """samples/tiny.toml, 4 days, 3 frames, coupled mechanics on the fixed schedule (so the
    points move every step): .usdc of all frames and .glb of the last, with the scene and frames."""
    out = tmp_path_factory.mktemp("tiny_bake")
    scene = wd.load_scene(ROOT / "samples" / "tiny.toml",
                          overrides={"time.days": 4, "time.frames": 3, "time.schedule": "fixed"})
    model = wd.build_model(scene)
    frames = list(wd.Simulation(model).run())
    mesh = wd.build_meshlets(model)
    usd = export_usd(out / "tiny.usdc", model, mesh, frames)
    glb = export_gltf(out / "tiny.glb", model, mesh, frames[-1])
    # the same GLB without the face kind, ring and bark crack attributes
    importer = load_pure("importer")
    doc, binary = importer.read_glb(Path(glb).read_bytes())
    drop = ("_FACE_KIND", "_RING", "_BARK_CRACK", "_BARK_DEPTH")
    for m in doc["meshes"]:
        for prim in m["primitives"]:
            prim["attributes"] = {k: v for k, v in prim["attributes"].items() if k not in drop}
    plain = out / "plain.glb"
    plain.write_bytes(importer.write_glb(doc, binary))
    return {"usd": Path(usd), "glb": Path(glb), "glb_plain": plain, "scene": scene, "frames": frames}


@pytest.fixture(scope="module")
def rot_usd(tmp_path_factory) -> Path:
    """samples/tiny.toml decayed for 1000 days (biology only; brown rot from the root end: H_c
    about 0.1-0.3 there, above 0.8 at the far end), two frames."""
    out = tmp_path_factory.mktemp("rot_bake")
    scene = wd.load_scene(ROOT / "samples" / "tiny.toml", overrides={"time.days": 1000, "time.frames": 2})
    model = wd.build_model(scene)
    frames = list(wd.Simulation(model, mechanics=False).run())
    mesh = wd.build_meshlets(model)
    return Path(export_usd(out / "rot.usdc", model, mesh, frames))


def bark_patches_usd(path: Path, crack: bool, bark_uv: bool = False) -> Path:
    """Two flat 10 x 10 cm patches of bark in the z = 0 plane, side by side along x, 1 cm apart,
    as a bake's ``/World/<scene>/Wood`` mesh (quads; faceKind 0; H_c, H_l, M = 1, 1, 0.3 and,
    with ``crack``, bark_crack and bark_crack_depth time-sampled at frames 0 and 1). Both patches
    have the same wood coordinates (the same bark texture); with ``crack`` the right one lies in
    a crack (bark_crack 1, depth 5 mm), the left one does not (0). With ``bark_uv`` the faces
    carry a face-varying ``barkUV``: the left patch in u 0.05-0.45, the right in 0.55-0.95 of the
    crack map, v 0.1-0.9."""
    from pxr import Sdf, UsdGeom, Vt

    from wooddecay.export import stage as stage_mod

    n, size, r = 10, 0.1, 0.1  # quads a side, patch size (m), bark radius (m)
    u = np.linspace(0.0, size, n + 1)
    X, Y = (a.ravel() for a in np.meshgrid(u, u - size / 2, indexing="ij"))
    ij = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quad = np.stack([ij[:-1, :-1], ij[1:, :-1], ij[1:, 1:], ij[:-1, 1:]], axis=-1).reshape(-1, 4)
    shift = size + 0.01
    P = np.concatenate([np.stack([X - shift, Y, 0 * X], 1), np.stack([X + 0.01, Y, 0 * X], 1)])
    faces = np.concatenate([quad, quad + len(X)])
    wood = np.tile(np.stack([np.full_like(X, r), Y / r, X], 1), (2, 1))  # (r, phi, s)
    side = np.repeat([0.0, 1.0], len(X))  # 0 left patch, 1 right patch

    stage, root = stage_mod.new_stage("bark")
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(1.0)
    mesh = UsdGeom.Mesh.Define(stage, f"{root}/Wood")
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4] * len(faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()))
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(P.astype(np.float32)))
    pv = UsdGeom.PrimvarsAPI(mesh)
    T = Sdf.ValueTypeNames
    pv.CreatePrimvar("wood", T.Float3Array, UsdGeom.Tokens.vertex).Set(
        Vt.Vec3fArray.FromNumpy(wood.astype(np.float32)))
    pv.CreatePrimvar("ring", T.FloatArray, UsdGeom.Tokens.vertex).Set(
        Vt.FloatArray.FromNumpy(np.zeros(len(P), np.float32)))
    pv.CreatePrimvar("faceKind", T.IntArray, UsdGeom.Tokens.uniform).Set(Vt.IntArray([0] * len(faces)))
    fields = {"H_c": np.ones_like(side), "H_l": np.ones_like(side), "M": np.full_like(side, 0.3)}
    if crack:
        fields |= {"bark_crack": side, "bark_crack_depth": 0.005 * side}
    if bark_uv:
        uv = np.stack([np.concatenate([0.05 + 0.4 * X / size, 0.55 + 0.4 * X / size]),
                       np.tile(0.1 + 0.8 * (Y + size / 2) / size, 2)], 1)
        pv.CreatePrimvar("barkUV", T.TexCoord2fArray, UsdGeom.Tokens.faceVarying).Set(
            Vt.Vec2fArray.FromNumpy(uv[faces.ravel()].astype(np.float32)))
    for name, values in fields.items():
        primvar = pv.CreatePrimvar(name, T.FloatArray, UsdGeom.Tokens.vertex)
        for frame in (0.0, 1.0):
            primvar.Set(Vt.FloatArray.FromNumpy(values.astype(np.float32)), frame)
    stage.GetRootLayer().Export(str(path))
    return path


@pytest.fixture(scope="module")
def bark_patches(tmp_path_factory) -> dict:
    """:func:`bark_patches_usd` with the bark crack primvars ("crack") and without ("plain")."""
    out = tmp_path_factory.mktemp("bark_patches")
    return {k: bark_patches_usd(out / f"{k}.usda", k == "crack") for k in ("crack", "plain")}


@pytest.fixture(scope="module")
def imported(blender_user, bake) -> dict:
    """The installed add-on imports the USD and the GLB (one bpy subprocess)."""
    return run_blender(INSPECT, bake["usd"], bake["glb"], bake["glb_plain"], user=blender_user)


def usd_primvar(path: Path, name: str, frame: int) -> np.ndarray:
    """The primvar ``name`` of the whole wood at ``frame`` (every piece, indices resolved)."""
    from pxr import Usd

    return wood_at(Usd.Stage.Open(str(path)), float(frame))[name]


def glb_attribute(path: Path, name: str) -> np.ndarray:
    """All values of vertex attribute ``name`` over the GLB's primitives (float32 accessors)."""
    importer = load_pure("importer")
    doc, binary = importer.read_glb(path.read_bytes())
    arrays = []
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            arrays.append(decode(doc, binary, prim["attributes"][name]))
    return np.concatenate(arrays)


def glb_names(path: Path) -> list[str]:
    """The vertex attribute names of the GLB's primitives."""
    doc, _ = load_pure("importer").read_glb(path.read_bytes())
    return sorted({k for mesh in doc["meshes"] for prim in mesh["primitives"] for k in prim["attributes"]})


def decode(doc, binary, index) -> np.ndarray:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    stride = view.get("byteStride", 4 * n)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    raw = np.frombuffer(binary, dtype=np.uint8)[start:start + stride * (acc["count"] - 1) + 4 * n]
    raw = np.concatenate([raw, np.zeros(stride * acc["count"] - len(raw), np.uint8)])
    out = raw.reshape(acc["count"], stride)[:, :4 * n].copy().view(np.float32)
    return out[:, 0] if n == 1 else out


# ----------------------------------------------------------------------------- tests

def test_bpy_is_installed():
    """The Blender tests need the bpy wheel (pip install 'bpy==4.5.*'): fail, never skip."""
    assert importlib.util.find_spec("bpy") is not None, "bpy is missing: pip install -e '.[test]'"


def test_manifest():
    m = addon.manifest()
    assert m["schema_version"] == "1.0.0"
    assert m["id"] == "wooddecay" and m["type"] == "add-on"
    assert m["blender_version_min"] == "4.2.0"
    assert m["name"] and m["tagline"] and m["maintainer"]
    assert all(x.startswith("SPDX:") for x in m["license"])
    assert addon.manifest_errors(m) == []
    with open(ROOT / "pyproject.toml", "rb") as f:
        project = tomllib.load(f)["project"]
    assert m["version"] == project["version"], "keep the add-on and package versions equal"
    assert m["license"] == [f"SPDX:{project['license']}"], "keep the add-on and package licenses equal"


def test_addon_build_zip(addon_zip):
    """``wooddecay addon build`` writes <id>-<version>.zip: the manifest and the add-on modules
    at the top, no caches."""
    names = zipfile.ZipFile(addon_zip).namelist()
    for f in ("blender_manifest.toml", "__init__.py", "importer.py", "shader.py", "material.py",
              "blender_import.py"):
        assert f in names
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]


def test_addon_build_is_blenders_zip(addon_zip, tmp_path):
    """The zip ``wooddecay addon build`` makes without Blender holds the files, with the same
    bytes, that Blender's ``extension build`` puts in its zip, and Blender's ``extension
    validate`` accepts it."""
    theirs = addon.blender_build(tmp_path / "blender", timeout=TIMEOUT)
    assert theirs.name == addon_zip.name
    with zipfile.ZipFile(addon_zip) as ours, zipfile.ZipFile(theirs) as blender:
        assert sorted(ours.namelist()) == sorted(blender.namelist())
        for name in blender.namelist():
            assert ours.read(name) == blender.read(name), name
    addon.validate(addon_zip, timeout=TIMEOUT)


def test_addon_build_needs_no_bpy(tmp_path):
    """``wooddecay addon build`` in a Python where ``bpy`` cannot be imported (as from a wheel
    installed without the render extra)."""
    code = ("import sys; sys.modules['bpy'] = None\n"
            "from wooddecay.cli import main\n"
            "main(['addon', 'build', '-o', sys.argv[1]])")
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True,
                          timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert zipfile.ZipFile(tmp_path / addon.zip_name()).read("blender_manifest.toml") == \
        (ADDON_DIR / "blender_manifest.toml").read_bytes()


def test_pure_modules_have_no_bpy():
    """importer.py and shader.py are plain Python (the glTF-Blender-IO split)."""
    for name in ("importer", "shader"):
        text = (ADDON_DIR / f"{name}.py").read_text()
        assert "import bpy" not in text
        load_pure(name)


def test_importer_helpers():
    importer = load_pure("importer")
    assert importer.file_format("a/b.USDC") == "usd" and importer.file_format("x.usda") == "usd"
    assert importer.file_format("x.usd") == "usd" and importer.file_format("x.glb") == "gltf"
    with pytest.raises(ValueError):
        importer.file_format("x.obj")
    plan = dict(importer.rename_plan(["_H_c", "_H_l", "_M", "_WOOD", "position", "M"]))
    assert plan == {"_H_c": "H_c", "_H_l": "H_l", "_WOOD": "wood"}  # "M" taken: "_M" stays
    # the bark crack attributes get the USD primvar names the material reads
    plan = dict(importer.rename_plan(["_BARK_CRACK", "_BARK_DEPTH", "_FACE_KIND"]))
    assert plan == {"_BARK_CRACK": "bark_crack", "_BARK_DEPTH": "bark_crack_depth", "_FACE_KIND": "faceKind"}
    shader = load_pure("shader")
    assert set(importer.RENAMES.values()) == {s.attribute for s in shader.DATA}, "a renamed attribute nothing reads"


def test_glb_split_keeps_the_bytes(bake, tmp_path):
    """The workaround for Blender's glTF importer (mixed custom attribute types) rewrites only
    the JSON: the split scalars read exactly the vector's values."""
    importer = load_pure("importer")
    fixed = tmp_path / "fixed.glb"
    split = importer.prepare_glb(bake["glb"], fixed)
    assert split == {"_WOOD": ["_WOOD.0", "_WOOD.1", "_WOOD.2"]}
    assert importer.read_glb(fixed.read_bytes())[1] == importer.read_glb(bake["glb"].read_bytes())[1]
    wood = glb_attribute(bake["glb"], "_WOOD")
    comps = np.stack([glb_attribute(fixed, c) for c in split["_WOOD"]], axis=1)
    np.testing.assert_array_equal(wood, comps)
    np.testing.assert_array_equal(glb_attribute(fixed, "_H_c"), glb_attribute(bake["glb"], "_H_c"))
    assert importer.join_plan(split, ["_WOOD.0", "_WOOD.1", "_WOOD.2"]) == [("wood", split["_WOOD"])]


def test_shader_graph_is_complete():
    """Every group input is declared and used; the graph only reads existing nodes."""
    shader = load_pure("shader")
    g = shader.wood_decay_graph()
    users = g.users()
    assert set(users) == {s.name for s in shader.INPUTS}, "the graph reads an undeclared input"
    assert not [k for k, n in users.items() if n == 0], "an input that nothing reads"
    for node in g.nodes:
        for ref in node.refs():
            if isinstance(ref, shader.Out):
                assert 0 <= ref.node < len(g.nodes)
    assert set(g.outputs) == {s.name for s in shader.OUTPUTS}
    names = {s.name for s in shader.CONTROLS}
    for control in ("Base Color", "Ring Contrast", "Brown Rot Strength", "White Rot Strength",
                    "Moisture Darkening", "Bark Color", "Crack Color", "Crack Width", "Crack Roughness"):
        assert control in names
    # the bark cracks: two attribute inputs whose defaults (older bakes) are "no crack", and a
    # near-black crack floor
    data = {s.name: s for s in shader.DATA}
    assert data["Bark Crack"].attribute == "bark_crack" and data["Crack Depth"].attribute == "bark_crack_depth"
    assert data["Bark Crack"].default == 0.0 and data["Crack Depth"].default == 0.0
    controls = {s.name: s for s in shader.CONTROLS}
    assert max(controls["Crack Color"].default) < 0.05
    assert 0.0 < controls["Crack Width"].default < 1.0


def test_extension_installs_and_enables(imported, blender_user):
    """Installed from the zip into the user repository; enabling registers the operator and the
    File > Import menu entry."""
    assert (blender_user / "extensions" / "user_default" / "wooddecay" / "blender_manifest.toml").is_file()
    assert imported["found"] == [MODULE]
    assert imported["enabled"] and imported["operator"] and imported["menu"]


def test_usd_import_attributes(imported, bake):
    u = imported["usd"]
    assert u["result"] == ["FINISHED"] and len(u["objects"]) == 1
    attrs = u["attributes"]
    for name in ("H_c", "H_l", "M", "R_w", "R_b", "C", "ring"):
        assert attrs[name] == ["POINT", "FLOAT"], name
    assert attrs["wood"] == ["POINT", "FLOAT_VECTOR"]
    for name in ("faceKind", "element", "tissue", "piece"):
        assert attrs[name] == ["FACE", "INT"], name
    assert set(u["faceKind"]) <= {0, 1, 2} and 0 in u["faceKind"]
    m = bake["scene"].moisture
    for frame in ("frame_start", "frame_end"):
        v = u[frame]
        assert 0.0 <= min(v["H_c"]) and max(v["H_c"]) <= 1.0
        assert 0.0 <= min(v["H_l"]) and max(v["H_l"]) <= 1.0
        # moisture is held in [M_2, M_1] (kg/kg; 0.1 and 1 here) by the moisture model (Eq. 15)
        assert m["M_2"] - 1e-5 <= min(v["M"]) and max(v["M"]) <= m["M_1"] + 1e-5


def test_usd_frames_differ_over_time(imported, bake):
    """Blender's USD import plays the bake back (MeshSequenceCache): the fields it shows at the
    first and last frame are the stage's time samples, and they differ."""
    u = imported["usd"]
    assert u["frames"] == [0, len(bake["frames"]) - 1]
    assert "MESH_SEQUENCE_CACHE" in u["modifiers"]
    for frame, key in ((0, "frame_start"), (u["frames"][1], "frame_end")):
        for name in ("H_c", "M"):
            np.testing.assert_allclose(u[key][name], np.sort(usd_primvar(bake["usd"], name, frame)), atol=1e-6)
    dH = np.abs(np.subtract(u["frame_end"]["H_c"], u["frame_start"]["H_c"])).max()
    dM = np.abs(np.subtract(u["frame_end"]["M"], u["frame_start"]["M"])).max()
    assert dH > 1e-4 and dM > 1e-4, (dH, dM)
    assert u["dP"] > 0.0, "points do not move between frames"


def test_gltf_import_attributes(imported, bake):
    """glTF attributes are renamed to the USD names, none is left behind, values match the file."""
    g = imported["gltf"]
    assert g["result"] == ["FINISHED"] and g["objects"]
    for name in ("H_c", "H_l", "M", "wood", "ring", "faceKind"):
        assert name in g["attributes"], name
    assert not [a for a in g["attributes"] if a.startswith("_")], g["attributes"]
    v = g["values"]
    assert 0.0 <= v["H_c"][0] and v["H_c"][-1] <= 1.0 and 0.0 <= v["H_l"][0] and v["H_l"][-1] <= 1.0
    m = bake["scene"].moisture
    assert m["M_2"] - 1e-5 <= v["M"][0] and v["M"][-1] <= m["M_1"] + 1e-5
    pairs = [("H_c", "_H_c"), ("H_l", "_H_l"), ("M", "_M"), ("ring", "_RING")]
    # the bark crack attributes, where the exporter writes them
    present = set(glb_names(bake["glb"]))
    pairs += [(name, gname) for name, gname in (("bark_crack", "_BARK_CRACK"), ("bark_crack_depth", "_BARK_DEPTH"))
              if gname in present]
    for name, gname in pairs:
        np.testing.assert_allclose(v[name], np.sort(glb_attribute(bake["glb"], gname)), atol=1e-6)
    W = glb_attribute(bake["glb"], "_WOOD")
    np.testing.assert_allclose(g["wood"], W[np.lexsort(W.T[::-1])], atol=1e-6)
    # the glTF holds the last frame: the field values of the stage's last frame, which writes them
    # on a table of export.field_step
    np.testing.assert_allclose([v["H_c"][0], v["H_c"][-1]], [imported["usd"]["frame_end"]["H_c"][0],
                                                            imported["usd"]["frame_end"]["H_c"][-1]],
                               atol=FIELD_STEP / 2 + 1e-6)


@pytest.mark.parametrize("fmt", ["usd", "gltf"])
def test_material_has_wood_decay_group(imported, bake, fmt):
    """Every imported mesh gets the Wood Decay material: its group node holds the controls and
    reads the attributes through Attribute nodes; the file's preview material is gone."""
    mats = imported[fmt]["material"]
    assert mats
    attributes = set(imported[fmt]["attributes"])
    for d in mats:
        assert d["name"].startswith("Wood Decay") and d["group"] == "Wood Decay", d
        assert d["surface"]
        linked = {"H_c": "H_c", "H_l": "H_l", "M": "M", "Wood": "wood", "Ring": "ring", "Face Kind": "faceKind"}
        # the bark crack inputs read their attributes where the bake has them; a USD bake's Bark
        # Crack comes from its crack map instead (barkUV into the UDIM tile of the current frame,
        # one tile per frame of the bake, by the frame driver)
        linked |= {k: a for k, a in (("Bark Crack", "bark_crack"), ("Crack Depth", "bark_crack_depth"))
                   if a in attributes}
        if fmt == "usd":
            linked.pop("Bark Crack")
            png = Path(bake["usd"]).stem + "_bark.<UDIM>.png"
            assert d["crack_map"] == [[png, "Linear", "TILED", [1001 + k for k in range(len(bake["frames"]))]]]
            assert d["crack_map_uv"] == ["barkUV"] and d["frame_driver"] == ["frame"]
            assert d["bark_furrows"] < 1.0
        else:
            assert d["crack_map"] == [] and d["bark_furrows"] == 1.0
        assert d["linked"] == linked
        for control in ("Brown Rot Strength", "White Rot Strength", "Moisture Darkening", "Ring Contrast",
                        "Base Color", "Bark Color"):
            assert control in d["inputs"]
        assert d["outputs"][:1] == ["BSDF"] and d["group_nodes"] > 50
    # one shader group serves both imports; the USD's mesh has the exposure modifier's group too
    assert imported["groups"] == ["Wood Decay", "Wood Decay Exposure"]
    assert not [m for m in imported["materials"] if not m.startswith("Wood Decay")]


def test_gltf_without_face_kind_falls_back(imported):
    """Without a face kind (or ring, or bark cracks) the material still builds: those group
    inputs stay unlinked, Face Kind keeps its default 1 (wood, no bark) and Bark Crack its 0."""
    f = imported["fallback"]
    assert f["result"] == ["FINISHED"] and f["group"] == "Wood Decay"
    assert f["linked"] == {"H_c": "H_c", "H_l": "H_l", "M": "M", "Wood": "wood"}
    assert f["face_kind_default"] == 1.0 and f["bark_crack_default"] == 0.0


@pytest.mark.slow
def test_render_rotted_and_sound_wood_differ(blender_user, bake, rot_usd, tmp_path):
    """128x128 Cycles render (CPU, 16 samples, 2 threads) of the tiny log after 4 days (sound)
    and after 1000 days of brown rot from the root end, same view: the root end (left third of
    the log in the image) changes colour by more than MARGIN and gets darker; the far end, which
    the rot has barely reached, changes far less."""
    res = run_blender(RENDER, rot_usd, bake["usd"], tmp_path, 16, 2, user=blender_user)
    rot, sound = res["rot"], res["sound"]
    for r in (rot, sound):
        assert r["pixels"] > 2000 and r["rotted_end_pixels"] > 400 and r["sound_end_pixels"] > 400, r
    d_rotted = float(np.linalg.norm(np.subtract(rot["rotted_end"], sound["rotted_end"])))
    d_sound = float(np.linalg.norm(np.subtract(rot["sound_end"], sound["sound_end"])))
    luma = np.array([0.2126, 0.7152, 0.0722])
    darker = float(luma @ np.subtract(sound["rotted_end"], rot["rotted_end"]))
    print(f"render seconds {res['seconds']}; rotted end moved {d_rotted:.3f}, sound end {d_sound:.3f}, "
          f"rotted end darker by {darker:.3f} (sRGB)")
    assert d_rotted > MARGIN, (d_rotted, rot, sound)
    assert d_rotted > RATIO * d_sound, (d_rotted, d_sound)
    assert darker > DARKER, darker


@pytest.mark.slow
def test_render_bark_cracks_are_darker(blender_user, bark_patches, tmp_path):
    """128x64 Cycles render (CPU, 16 samples, 2 threads) from above of two patches of bark with
    the same texture, the right one in a crack (bark_crack 1), the left one not (0): the right one
    is darker by more than CRACK_DARKER in mean luminance. The same patches without the bark
    crack primvars (an older bake) render as the uncracked one did, and alike on both sides."""
    res = run_blender(CRACK_RENDER, bark_patches["crack"], bark_patches["plain"], tmp_path, 16, 2, user=blender_user)
    assert res["materials"]["crack"]["linked"]["Bark Crack"] == "bark_crack"
    assert res["materials"]["crack"]["linked"]["Crack Depth"] == "bark_crack_depth"
    assert "Bark Crack" not in res["materials"]["plain"]["linked"]
    crack, plain = res["crack"], res["plain"]
    for r in (crack, plain):
        assert r["left_pixels"] > 1500 and r["right_pixels"] > 1500, r
    luma = np.array([0.2126, 0.7152, 0.0722])
    darker = float(luma @ np.subtract(crack["left"], crack["right"]))
    same = float(np.abs(np.subtract(crack["left"], plain["left"])).max())
    sides = float(luma @ np.subtract(plain["left"], plain["right"]))
    print(f"render seconds {res['seconds']}; cracked bark darker by {darker:.3f} (sRGB luminance "
          f"{luma @ crack['left']:.3f} -> {luma @ crack['right']:.3f}); uncracked vs no attribute {same:.4f}; "
          f"left vs right without cracks {sides:+.4f}")
    assert darker > CRACK_DARKER, (darker, crack)
    assert same <= SAME, (same, crack, plain)
    assert abs(sides) < CRACK_DARKER / 4, (sides, plain)


@pytest.mark.slow
def test_render_crack_map_tile_of_each_frame(blender_user, tmp_path):
    """128x64 Cycles render from above of two patches of bark (no per-vertex crack attributes)
    whose barkUV puts the left one on the left half of the crack map and the right one on its
    right half; tile 1001 (frame 0) has no crack, tile 1002 (frame 1) a crack over its right half.
    Frame 0 renders both patches alike, frame 1 the right one darker by more than CRACK_DARKER,
    and frame 3, past the last tile, as frame 1."""
    from wooddecay.export.png import write_png16

    usd = bark_patches_usd(tmp_path / "tiles.usda", crack=False, bark_uv=True)
    cracked = np.zeros((16, 32), np.uint16)
    cracked[:, 16:] = 65535
    write_png16(tmp_path / "tiles_bark.1001.png", np.zeros_like(cracked))
    write_png16(tmp_path / "tiles_bark.1002.png", cracked)
    res = run_blender(CRACK_MAP_RENDER, usd, tmp_path, 16, 2, user=blender_user)
    assert res["material"]["crack_map"] == [["tiles_bark.<UDIM>.png", "Linear", "TILED", [1001, 1002]]]
    luma = np.array([0.2126, 0.7152, 0.0722])
    darker = {f: float(luma @ np.subtract(res[str(f)]["left"], res[str(f)]["right"])) for f in (0, 1, 3)}
    held = float(np.abs(np.subtract(res["1"]["right"], res["3"]["right"])).max())
    print(f"right patch darker than the left by {darker} (sRGB luminance) at frames 0, 1, 3; frame 3 against 1 {held:.4f}")
    assert abs(darker[0]) < CRACK_DARKER / 4, darker
    assert darker[1] > CRACK_DARKER and darker[3] > CRACK_DARKER, darker
    assert held <= SAME, held


def test_faces_show_from_their_exposed_frame(blender_user, bake, tmp_path):
    """The tiny bake with cracks opening over its frames: the imported mesh shows at each frame
    the faces whose ``exposedFrame`` it has reached (the stage's holes at that frame), after its
    mesh cache, and keeps the cache's points."""
    from pxr import Usd, UsdGeom

    model = wd.build_model(bake["scene"])
    usd = export_usd(tmp_path / "tiny.usdc", model, wd.build_meshlets(model), cracking_frames(model, bake["frames"]))
    stage = Usd.Stage.Open(str(usd))
    wood = wood_at(stage, 0.0)
    shown = wood["exposedFrame"]
    res = run_blender(EXPOSURE, usd, user=blender_user)
    assert all(mods[-1] == "NODES" for mods in res["modifiers"])
    assert ["MESH_SEQUENCE_CACHE", "NODES"] in res["modifiers"]
    expected = [int(np.count_nonzero(shown <= k)) for k in (0, 1, 2)]
    print(f"faces shown at frames 0, 1, 2: {res['faces']} (stage {expected})")
    assert res["faces"] == expected and expected[0] < expected[1] < expected[2]
    assert res["points"] == [len(wood["points"])] * 3


@pytest.mark.slow
def test_render_source_mesh_through_the_same_cameras(bake, tmp_path):
    """render_bake --source: the mesh a bake was built from, rendered in plain grey beside the
    bake's picture with the cameras fitted to both: two pictures of one size, each showing an
    object (pixels away from the sky's colour), different from each other."""
    import trimesh
    from PIL import Image

    from wooddecay import render

    lo, hi = np.min(bake["frames"][0].mech["x"], axis=0), np.max(bake["frames"][0].mech["x"], axis=0)
    box = trimesh.creation.box(extents=hi - lo)
    box.apply_translation((lo + hi) / 2)
    source = tmp_path / "source.obj"
    box.export(source)
    png = tmp_path / "tiny.png"
    render.render_bake(bake["usd"], png, frame=None, options=("--width", "128", "--height", "72", "--samples", "4",
                                                              "--azimuth", "-145", "--no-labels", "--max-kb", "0",
                                                              "--source", str(source)))
    pictures = [np.asarray(Image.open(p).convert("RGB"), float) for p in (png, tmp_path / "tiny_source.png")]
    assert pictures[0].shape == pictures[1].shape == (72, 128, 3)
    for pic in pictures:
        assert np.mean(np.linalg.norm(pic - pic[0, 0], axis=-1) > 30) > 0.02
    assert np.mean(np.abs(pictures[0] - pictures[1])) > 2.0


def test_installed_extension_is_built_once_per_add_on_source(tmp_path, monkeypatch):
    """wooddecay.addon.installed: the user folder renders use, built and installed once per
    content of the add-on's source (a second call builds nothing), again when a file changes;
    no half-built folder is left."""
    import shutil

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    source = tmp_path / "blender_addon"
    shutil.copytree(ADDON_DIR, source, ignore=shutil.ignore_patterns("__pycache__"))
    first = addon.installed(source)
    assert (first / "extensions" / "user_default" / "wooddecay" / "blender_manifest.toml").is_file()
    with monkeypatch.context() as m:
        m.setattr(addon, "build", lambda *a, **k: pytest.fail("built again"))
        assert addon.installed(source) == first
    (source / "material.py").write_text((source / "material.py").read_text() + "\n# changed\n")
    other = addon.installed(source)
    assert other != first and "# changed" in (other / "extensions" / "user_default" / "wooddecay" / "material.py").read_text()
    assert sorted(p.name.startswith(".build-") for p in (tmp_path / "cache" / "wooddecay" / "addon").iterdir()) == [False, False]


@pytest.mark.blender
def test_render_of_a_file_that_is_no_bake_is_one_line_exit_2(tmp_path):
    """render_bake over a file the add-on cannot read: exit 2, its last line names the file and
    why, no picture."""
    from wooddecay import render

    bad = tmp_path / "bad.usdc"
    bad.write_bytes(b"not a USD file")
    proc = subprocess.run([sys.executable, str(render.BLENDER_BAKE), str(bad), str(tmp_path / "x.png")],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr[-2000:]
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith(f"render_bake: {bad}: not a readable bake"), last
    assert not (tmp_path / "x.png").exists()
