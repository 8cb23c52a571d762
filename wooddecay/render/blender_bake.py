"""Render a wooddecay bake with the Wood Decay add-on's material to a PNG with Blender's ``bpy``.

Usage (a separate interpreter from wooddecay's own USD code: ``bpy`` bundles its own ``pxr``,
so usd-core's ``pxr`` must never be imported in this process)::

    wooddecay bake samples/log.toml -o /tmp/log_bake
    python scripts/render_bake.py /tmp/log_bake/log.usdc docs/images/log-late.png --frame 23

(``scripts/render_bake.py`` runs this file; from Python, :func:`wooddecay.render.render_bake`.)

The add-on is used as Blender users get it: its extension zip is built from ``wooddecay/blender_addon/``
(``wooddecay.addon.build``, the zip Blender's extension builder makes) and installed with Blender's
``extension install-file`` into a user folder of wooddecay's cache (``BLENDER_USER_RESOURCES``,
:func:`wooddecay.addon.installed`: built once per add-on source), both in a subprocess of this
Python (which imports wooddecay, hence usd-core's ``pxr``); this process
then enables it and imports the bake through its operator, ``bpy.ops.import_scene.wooddecay``,
which gives the meshes the "Wood Decay" material (driven by the H_c, H_l, M, wood, ring and
faceKind attributes). Run inside a Blender binary (``blender -b -P wooddecay/render/blender_bake.py --
BAKE OUT.png [options]``) the extension must already be installed and enabled there.

The picture: the bake at ``--frame`` (default its last; a USD bake plays back through a
MeshSequenceCache, a .glb holds the last frame only) on a grey ground plane under a sun and a
grey sky, seen by one perspective camera per ``--azimuth`` (degrees about +z from the log's
axis, the longest side of its bounding box, pointing to +x), each fitted to the mesh (or to
``--fit-box``, so that renders of two bakes share their camera) on a 3/4 view. A log has two cut ends and a view shows one, so by default there are two views side by
side, both from -y with x = 0 on the left: -145 looks at the x = 0 end (the sample log's root
end, where its brown rot enters), -35 at the far end. Each view is captioned with the mean
H_c and H_l (cellulose, lignin left) of the end it faces, and a footer gives the simulated day
and the mass loss from the ``summary.json`` that ``wooddecay bake`` writes beside the USD.
Cycles on the CPU with few samples and the denoiser; the PNG is quantised if over ``--max-kb``.
"""
from __future__ import annotations

import importlib
import os
import subprocess
import sys
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b -P: not on the path
import blender_common as common

#: the extension's module once installed into the user repository
MODULE = "bl_ext.user_default.wooddecay"
GROUND_COLOR = (0.42, 0.42, 0.40)
SKY_COLOR = (0.70, 0.72, 0.75)

#: run in a subprocess: print the user folder with the extension installed (built once, cached)
INSTALL = """\
from wooddecay import addon
print(addon.installed())
"""


def parse_args(argv=None):
    ap = common.render_parser(__doc__, "bake written by `wooddecay bake` (.usdc/.usda/.usd, or .glb)")
    ap.add_argument("--frame", type=int, default=None, help="frame to show (default: the bake's last)")
    common.add_size_args(ap, 24, 640, 360, views="all views")
    common.add_threads_arg(ap, 2)
    ap.add_argument("--azimuth", type=float, nargs="+", default=[-145.0, -35.0], metavar="DEG",
                    help="camera azimuths in degrees about +z from the log's axis (+x), one view "
                         "each (default -145 -35: the x = 0 end, then the far end, both from -y)")
    common.add_layout_arg(ap, "the views")
    common.add_camera_args(ap, 28.0, lens=50.0)
    ap.add_argument("--margin", type=float, default=1.08, help="room around the log in each view (1: tight)")
    ap.add_argument("--fit-box", type=float, nargs=6, default=None, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
                    help="fit the cameras and the ground to this box (m) instead of the shown mesh, so renders "
                         "of different bakes or frames share one camera")
    ap.add_argument("--source", default=None, metavar="MESH",
                    help="also render this mesh (OBJ, PLY and STL z-up, glTF/GLB, USD: the one the bake's skeleton "
                         "was built from) in plain wood grey through the same cameras into OUT_source.png; the "
                         "cameras then hold both")
    ap.add_argument("--no-ground", dest="ground", action="store_false", help="no ground plane")
    common.add_labels_arg(ap, "no captions (near end's mean H_c and H_l; day and mass loss from the "
                              "bake's summary.json)")
    args = common.parse_render_args(ap, argv, max_kb=250)
    if not os.path.isfile(args.usd):
        ap.error(f"no such file: {args.usd}")
    if args.source is not None and not os.path.isfile(args.source):
        ap.error(f"no such file: {args.source}")
    return args


#: importers of --source meshes by suffix: operator path and its arguments (OBJ, PLY and STL keep
#: their coordinates: z-up, as wooddecay reads them)
SOURCE_IMPORT = {".obj": ("wm.obj_import", {"forward_axis": "Y", "up_axis": "Z"}),
                 ".ply": ("wm.ply_import", {"forward_axis": "Y", "up_axis": "Z"}),
                 ".stl": ("wm.stl_import", {"forward_axis": "Y", "up_axis": "Z"}),
                 ".glb": ("import_scene.gltf", {}), ".gltf": ("import_scene.gltf", {}),
                 ".usd": ("wm.usd_import", {}), ".usda": ("wm.usd_import", {}), ".usdc": ("wm.usd_import", {})}
SOURCE_COLOR = (0.46, 0.38, 0.30)


def import_source(bpy, path):
    """The --source mesh's objects, in a plain wood-grey material, and their world vertices."""
    import numpy as np

    suffix = os.path.splitext(path)[1].lower()
    if suffix not in SOURCE_IMPORT:
        raise SystemExit(f"render_bake: cannot import --source {path}: the formats are {', '.join(SOURCE_IMPORT)}")
    before = set(bpy.data.objects)
    op, kwargs = SOURCE_IMPORT[suffix]
    group, name = op.split(".")
    getattr(getattr(bpy.ops, group), name)(filepath=os.path.abspath(path), **kwargs)
    obs = [ob for ob in bpy.data.objects if ob not in before and ob.type == "MESH"]
    mat, bsdf = common.principled_material(bpy, "Source", 0.7)
    bsdf.inputs["Base Color"].default_value = (*SOURCE_COLOR, 1.0)
    pts = []
    for ob in obs:
        ob.data.materials.clear()
        ob.data.materials.append(mat)
        m = np.array(ob.matrix_world)
        co = np.array([v.co[:] for v in ob.data.vertices])
        pts.append(co @ m[:3, :3].T + m[:3, 3])
    return obs, np.concatenate(pts) if pts else np.zeros((0, 3))


def addon_user_folder():
    """Blender user resources with the extension installed: ``$WOODDECAY_ADDON_USER`` where the
    caller passes it (:func:`wooddecay.render.render_bake`), else :func:`wooddecay.addon.installed`
    in a subprocess (it imports usd-core's ``pxr``)."""
    if os.environ.get("WOODDECAY_ADDON_USER"):
        return os.environ["WOODDECAY_ADDON_USER"]
    proc = subprocess.run([sys.executable, "-c", INSTALL], check=False, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"render_bake: could not build and install the add-on:\n{(proc.stdout + proc.stderr)[-4000:]}")
    return proc.stdout.strip().splitlines()[-1]


def add_ground(bpy, z, size):
    """A square plane of side ``size`` at height ``z`` with a matt grey material."""
    mesh = bpy.data.meshes.new("Ground")
    h = size / 2
    mesh.from_pydata([(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new("Ground", mesh)
    mat, bsdf = common.principled_material(bpy, "Ground", 0.95)
    bsdf.inputs["Base Color"].default_value = (*GROUND_COLOR, 1.0)
    mesh.materials.append(mat)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def evaluated_fields(bpy, obs, names):
    """World positions (n, 3) of the evaluated meshes' points and their float point attributes
    ``names`` (those present on every mesh), all meshes concatenated."""
    import numpy as np

    depsgraph = bpy.context.evaluated_depsgraph_get()
    pos, fields = [], {n: [] for n in names}
    for ob in obs:
        d = ob.evaluated_get(depsgraph).data
        pos.append(common.to_world(ob, common.local_positions(d).astype(np.float64)))
        for n in names:
            a = d.attributes.get(n)
            if a is not None and a.domain == "POINT" and a.data_type == "FLOAT":
                fields[n].append(common.attribute_values(a))
    return np.concatenate(pos), {n: np.concatenate(v) for n, v in fields.items() if len(v) == len(obs)}


def bake_summary(path, frame):
    """(days, mass loss) of ``frame`` (None: the last) from the summary.json that ``wooddecay
    bake`` writes next to its outputs, or None."""
    import json

    summary = os.path.join(os.path.dirname(os.path.abspath(path)), "summary.json")
    try:
        with open(summary) as f:
            doc = json.load(f)
        rows = doc["frames"]
        row = rows[-1] if frame is None else next(r for r in rows if r["frame"] == frame)
        return float(row["t_days"]), float(row["mass_loss"])
    except (OSError, ValueError, KeyError, IndexError, StopIteration, TypeError):
        return None


def end_caption(pos, fields, axis, v):
    """A caption for the view along ``-v``: the log's end nearer the camera with the mean H_c and
    H_l of the points within 2 % of the length from it (both ends on a view from the side)."""
    import numpy as np

    k = int(np.argmax(axis))
    t = pos[:, k]
    lo, hi = float(t.min()), float(t.max())
    c = float(np.dot(v, axis))
    ends = [lo, hi] if abs(c) < 0.2 else [lo] if c < 0 else [hi]
    parts = []
    for end in ends:
        near = np.abs(t - end) <= 0.02 * (hi - lo)
        vals = [f"{n} {fields[n][near].mean():.2f}" for n in ("H_c", "H_l") if n in fields]
        text = f"{'xyz'[k]} = {round(end, 2) + 0.0:g} m" + (" end" if len(ends) == 1 else "")  # + 0.0: no "-0"
        parts.append(text + (": " + ", ".join(vals) if vals else ""))
    return "; ".join(parts)


def compose(paths, out, layout, captions, footer):
    """The views in one image (side by side or stacked), a caption on each and a footer."""
    img, size = common.paste_panels(paths, layout)
    draw, font = common.caption_panels(img, size, layout, captions, 14)
    if footer:
        draw.text((10, img.size[1] - 24), footer, fill=common.INK, font=font)
    img.save(out, optimize=True)


class BadFile(Exception):
    """An input file that cannot be rendered: one line, exit status 2."""


def render(bpy, args, t0):
    import numpy as np

    before = set(bpy.data.objects)
    try:
        res = bpy.ops.import_scene.wooddecay(filepath=os.path.abspath(args.usd))
    except RuntimeError as err:  # the importer reported an error: a file it cannot read
        reason = str(err).strip().splitlines()[0].replace("Error: ", "")
        raise BadFile(f"render_bake: {args.usd}: not a readable bake ({reason})") from None
    if "FINISHED" not in res:
        raise SystemExit(f"render_bake: the Wood Decay import failed: {res}")
    obs = [ob for ob in bpy.data.objects if ob not in before and ob.type == "MESH"]
    scene = bpy.context.scene
    # USD: the frames play back through a MeshSequenceCache; glTF holds the last frame only
    animated = any(m.type == "MESH_SEQUENCE_CACHE" for ob in obs for m in ob.modifiers)
    if animated:
        frame = scene.frame_end if args.frame is None else args.frame
        scene.frame_set(frame)
    else:
        if args.frame is not None:
            print("render_bake: the file holds one frame (the bake's last); --frame ignored", file=sys.stderr)
        frame = None
    bpy.context.view_layer.update()
    pos, fields = evaluated_fields(bpy, obs, ("H_c", "H_l"))
    source, source_pts = import_source(bpy, args.source) if args.source else ([], np.zeros((0, 3)))
    if args.fit_box is None:
        framed = np.concatenate([pos, source_pts])
    else:
        box = np.reshape(args.fit_box, (2, 3))
        framed = np.array([[box[i, 0], box[j, 1], box[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    lo, hi = framed.min(0), framed.max(0)
    axis = common.log_axis(lo, hi)
    n = len(args.azimuth)
    pw, ph = common.panel_size(args.width, args.height, n, args.layout)
    # persistent: later views reuse the synced mesh and BVH
    common.setup_render(bpy, pw, ph, args.samples, args.threads, persistent=True)
    if args.ground:
        add_ground(bpy, float(lo[2]), 40.0 * float(np.max(hi - lo)))
    sun = common.add_sun_and_sky(bpy, 3.5, 6, SKY_COLOR, 0.8)  # aimed per view
    captions = []

    def view(i):
        v = common.view_direction(axis, args.azimuth[i], args.elevation)
        common.frame_camera(bpy, framed, v, pw / ph, lens=args.lens, margin=args.margin)
        common.aim_sun(sun, v, 0.6, -0.5, 1.2)  # from above, behind the camera's left shoulder
        captions.append(end_caption(pos, fields, axis, v))

    def picture(panels, path):
        summary = bake_summary(args.usd, frame)
        footer = (f"day {summary[0]:g}, mass loss {100 * summary[1]:.1f} %; " if summary else "") + \
            "H_c, H_l: cellulose, lignin left (1 sound, 0 gone)"
        if args.labels:
            compose(panels, path, args.layout, captions, footer)
        else:
            common.paste_panels(panels, args.layout)[0].save(path, optimize=True)

    for ob in source:
        ob.hide_render = True
    out, t_render = common.render_views(bpy, args.png, n, args.max_kb, view, picture)
    if source:
        for ob in source:
            ob.hide_render = False
        for ob in obs:
            ob.hide_render = True
        stem, ext = os.path.splitext(args.png)
        shown, t_source = common.render_views(bpy, f"{stem}_source{ext}", n, args.max_kb, view,
                                              lambda panels, path: common.paste_panels(panels, args.layout)[0].save(path))
        t_render += t_source
        print(f"render_bake: {shown} (the source mesh {args.source}, the same cameras)")
    hc = fields.get("H_c")
    hc_text = f"H_c {hc.min():.3f}..{hc.max():.3f}" if hc is not None else "no H_c"
    shown = "last" if frame is None else frame
    print(f"render_bake: {out} ({os.path.getsize(out) // 1024} KB, {args.width}x{args.height}, "
          f"frame {shown}, {len(obs)} mesh(es), {hc_text}, {n} view(s) of {args.samples} samples, "
          f"render {t_render:.1f} s, total {time.perf_counter() - t0:.1f} s)")
    for cap in captions[:n]:
        print(f"  {cap}")


def main(argv=None) -> int:
    """Returns the exit status. With the ``bpy`` wheel the caller must leave through ``os._exit``
    (the add-on's classes make the module hang at exit even once disabled, see tests/test_addon.py)."""
    args = parse_args(argv)
    t0 = time.perf_counter()
    in_blender = "bpy" in sys.modules  # blender -b -P: Blender is already up, with its own add-ons
    if not in_blender:
        os.environ["BLENDER_USER_RESOURCES"] = addon_user_folder()  # read when bpy starts
    enabled = False
    try:
        import bpy

        addon_utils = importlib.import_module("addon_utils")  # on sys.path once bpy is up

        if not in_blender:
            bpy.ops.wm.read_factory_settings(use_empty=True)
            addon_utils.enable(MODULE, default_set=True, handle_error=None)
            enabled = True
        else:
            bpy.ops.wm.read_homefile(use_empty=True)
        if not hasattr(bpy.types, "IMPORT_SCENE_OT_wooddecay"):
            raise SystemExit("render_bake: the Wood Decay add-on is not enabled (install its zip: "
                             "`wooddecay addon build`)")
        render(bpy, args, t0)
        return 0
    except BadFile as exc:
        print(exc, file=sys.stderr)
        return 2
    except SystemExit as exc:
        print(exc, file=sys.stderr)
        return 1
    except Exception:  # noqa: BLE001 - report any error, then still disable the add-on
        traceback.print_exc()
        return 1
    finally:
        if enabled:
            addon_utils.disable(MODULE)


if __name__ == "__main__":
    common.exit_now(main())
