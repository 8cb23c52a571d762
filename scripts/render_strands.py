"""Render the strand-group USD debug view (woodstock Fig. 3b) to a PNG with Blender's ``bpy``.

Usage (a separate interpreter from wooddecay's own USD code: ``bpy`` bundles its own ``pxr``,
so usd-core's ``pxr`` must never be imported in this process)::

    wooddecay inspect samples/tree.toml --strands-usd /tmp/tree_strands.usdc
    python scripts/render_strands.py /tmp/tree_strands.usdc docs/images/tree-strands.png

Also works as ``blender -b -P scripts/render_strands.py -- STRANDS.usd OUT.png [options]``.

The USD importer turns the ``BasisCurves`` prim into a Blender *Curves* object (not legacy
Curve data): each primvar becomes a point attribute of the same name (``displayColor``,
``tissue``, ``ring``) and the widths become the ``radius`` attribute, so Cycles and EEVEE draw
the strands as round tubes without any bevel. A geometry-nodes modifier cuts away the half (or
quadrant) of the lower stem that faces the camera by deleting those points, so heartwood and
sapwood show inside the bark; a material reads ``displayColor`` through an Attribute node. The
camera, on a 3/4 view, is fitted to the points of the whole tree.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b -P: not on the path
from _render_common import publish_png


def parse_args(argv=None):
    if argv is None:
        argv = sys.argv[1:]
        if "--" in argv:  # blender -b -P script -- args
            argv = argv[argv.index("--") + 1:]
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("usd", help="strands USD written by `wooddecay inspect --strands-usd`")
    ap.add_argument("png", help="output PNG")
    ap.add_argument("--engine", choices=["CYCLES", "EEVEE"], default="CYCLES",
                    help="CYCLES (CPU, default) or EEVEE (a rougher fallback: camera-facing strips)")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=640)
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    ap.add_argument("--no-cut", dest="cut", action="store_false",
                    help="no cut-away: show the bark all round")
    ap.add_argument("--cut", dest="cut_mode", choices=["half", "quadrant"], default="half",
                    help="cut away the camera-facing half (a section through the stem axis) "
                         "or quadrant of the lower tree (default half)")
    ap.add_argument("--cut-height", type=float, default=0.33,
                    help="cut-away up to this fraction of the tree's height (default 0.33)")
    ap.add_argument("--azimuth", type=float, default=-50.0, help="camera azimuth in degrees")
    ap.add_argument("--elevation", type=float, default=12.0, help="camera elevation in degrees")
    ap.add_argument("--max-kb", type=int, default=400,
                    help="quantise the PNG (PIL) if it is larger than this many KB; 0: never")
    return ap.parse_args(argv)


def strands_object(bpy):
    obs = [ob for ob in bpy.data.objects if ob.type in {"CURVES", "CURVE"}]
    if not obs:
        raise SystemExit("no curves found in the USD file")
    for ob in obs:
        if ob.name.startswith("Strands"):
            return ob
    return obs[0]


def world_bbox(ob):
    from mathutils import Vector

    corners = [ob.matrix_world @ Vector(c) for c in ob.bound_box]
    lo = Vector([min(c[i] for c in corners) for i in range(3)])
    hi = Vector([max(c[i] for c in corners) for i in range(3)])
    return lo, hi


def add_cutaway(bpy, ob, lo, hi, view_dir, height_fraction, mode="half"):
    """Geometry nodes: delete the points on the camera side of the stem below the cut height.

    The stem axis is taken through the mean of the lowest points. ``half``: a point is deleted
    where its horizontal offset from the axis points towards the camera (a section plane through
    the axis, seen face on). ``quadrant``: where the offset has a positive component along both
    horizontal axes at +-45 degrees of the view direction (a wedge with two faces).
    A strand crossing the cut loses its points there; Delete Geometry keeps the rest of the
    curve in one piece.
    """
    import numpy as np

    d = ob.data
    pos = np.empty(len(d.points) * 3, np.float32)
    d.attributes["position"].data.foreach_get("vector", pos)
    pos = pos.reshape(-1, 3)
    z_cut = lo.z + height_fraction * (hi.z - lo.z)
    base = pos[pos[:, 2] < lo.z + 0.05 * (hi.z - lo.z)]
    cx, cy = (base[:, 0].mean(), base[:, 1].mean()) if len(base) else ((lo.x + hi.x) / 2, (lo.y + hi.y) / 2)
    # the two horizontal half-axes at +-45 degrees of the view direction bound the quadrant
    az = math.atan2(view_dir.y, view_dir.x)
    if mode == "quadrant":
        a1 = (math.cos(az - math.pi / 4), math.sin(az - math.pi / 4))
        a2 = (math.cos(az + math.pi / 4), math.sin(az + math.pi / 4))
    else:
        a1 = a2 = (math.cos(az), math.sin(az))

    ng = bpy.data.node_groups.new("StrandCutaway", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, L = ng.nodes, ng.links
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    position = n.new("GeometryNodeInputPosition")
    sep = n.new("ShaderNodeSeparateXYZ")
    L.new(position.outputs[0], sep.inputs[0])

    def dot_axis(axis):
        # (x - cx) * ax + (y - cy) * ay > 0
        vm = n.new("ShaderNodeVectorMath")
        vm.operation = "DOT_PRODUCT"
        L.new(position.outputs[0], vm.inputs[0])
        vm.inputs[1].default_value = (axis[0], axis[1], 0.0)
        cmp = n.new("FunctionNodeCompare")
        cmp.data_type = "FLOAT"
        cmp.operation = "GREATER_THAN"
        L.new(vm.outputs["Value"], cmp.inputs[0])
        cmp.inputs[1].default_value = cx * axis[0] + cy * axis[1]
        return cmp.outputs[0]

    below = n.new("FunctionNodeCompare")
    below.data_type = "FLOAT"
    below.operation = "LESS_THAN"
    L.new(sep.outputs["Z"], below.inputs[0])
    below.inputs[1].default_value = z_cut
    and1 = n.new("FunctionNodeBooleanMath")
    and1.operation = "AND"
    L.new(dot_axis(a1), and1.inputs[0])
    L.new(dot_axis(a2), and1.inputs[1])
    and2 = n.new("FunctionNodeBooleanMath")
    and2.operation = "AND"
    L.new(and1.outputs[0], and2.inputs[0])
    L.new(below.outputs[0], and2.inputs[1])
    delete = n.new("GeometryNodeDeleteGeometry")
    delete.domain = "POINT"
    L.new(gin.outputs[0], delete.inputs["Geometry"])
    L.new(and2.outputs[0], delete.inputs["Selection"])
    L.new(delete.outputs[0], gout.inputs[0])
    mod = ob.modifiers.new("Cutaway", "NODES")
    mod.node_group = ng
    return z_cut


def tissue_material(bpy, attribute="displayColor"):
    mat = bpy.data.materials.new("StrandTissue")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes.get("Principled BSDF")
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = attribute
    links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.85
    if "Specular IOR Level" in bsdf.inputs:  # 4.x name
        bsdf.inputs["Specular IOR Level"].default_value = 0.25
    return mat


def point_positions(ob):
    """World positions of the object's points (evaluated: after the cut-away, if any)."""
    import numpy as np

    bpy = sys.modules["bpy"]
    ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    d = ev.data
    pos = np.empty(len(d.points) * 3, np.float32)
    d.attributes["position"].data.foreach_get("vector", pos)
    pos = pos.reshape(-1, 3).astype(np.float64)
    m = np.array(ob.matrix_world)
    return pos @ m[:3, :3].T + m[:3, 3]


def frame_camera(bpy, points, azimuth, elevation, aspect, lens=50.0, margin=1.05):
    """Perspective camera on a 3/4 view whose frustum holds all ``points`` (n, 3).

    The tree's bounding box would do, but its corners seen on a diagonal leave much empty
    space around a slender tree, so the frame is fitted to the points themselves.
    """
    import numpy as np
    from mathutils import Vector

    az, el = math.radians(azimuth), math.radians(elevation)
    v = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    fwd = -v
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    pr, pu, pv = points @ right, points @ up, points @ v
    # aim at the centre of the projected extent
    center = right * (pr.min() + pr.max()) / 2 + up * (pu.min() + pu.max()) / 2 + v * (pv.min() + pv.max()) / 2
    o = points - center
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = lens
    cam_data.sensor_fit = "AUTO"  # the 36 mm sensor spans the larger image side
    tan_big = cam_data.sensor_width / 2 / lens
    tan_w = tan_big * min(1.0, aspect)
    tan_h = tan_big / max(1.0, aspect)
    ov = o @ v
    dist = float(max((np.abs(o @ right) * margin / tan_w + ov).max(),
                     (np.abs(o @ up) * margin / tan_h + ov).max()))
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = Vector(center + v * dist)
    cam.rotation_euler = Vector(fwd).to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_start = max(0.01, dist / 1000)
    cam_data.clip_end = dist * 10
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam


def view_direction(azimuth, elevation):
    from mathutils import Vector

    az, el = math.radians(azimuth), math.radians(elevation)
    return Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)))


def setup_render(bpy, args):
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = args.width, args.height, 100
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "8"
    r.image_settings.compression = 100
    r.film_transparent = False
    if args.threads:
        r.threads_mode, r.threads = "FIXED", args.threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    if args.engine == "CYCLES":
        r.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = args.samples
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.max_bounces = 4
        scene.cycles.use_denoising = True
        try:
            scene.cycles.denoiser = "OPENIMAGEDENOISE"
        except TypeError:
            scene.cycles.use_denoising = False
        scene.cycles_curves.shape = "THICK"
    else:
        r.engine = "BLENDER_EEVEE_NEXT"
        r.hair_type = "STRIP"  # camera-facing strips of the curve radius (default: 1 px lines)
        scene.eevee.taa_render_samples = args.samples


def add_lights(bpy, view_dir):
    from mathutils import Vector

    scene = bpy.context.scene
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.5
    sun.angle = math.radians(5)
    ob = bpy.data.objects.new("Sun", sun)
    # from above, a little to the side of the camera
    d = Vector((view_dir.x * 0.6 - view_dir.y * 0.5, view_dir.y * 0.6 + view_dir.x * 0.5, 1.1)).normalized()
    ob.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(ob)
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.62, 0.68, 0.75, 1.0)
    bg.inputs["Strength"].default_value = 0.9
    scene.world = world


def main(argv=None) -> None:
    args = parse_args(argv)
    t0 = time.perf_counter()
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    res = bpy.ops.wm.usd_import(filepath=os.path.abspath(args.usd))
    if "FINISHED" not in res:
        raise SystemExit(f"USD import failed: {res}")
    ob = strands_object(bpy)
    if ob.type == "CURVE":  # older importers: legacy curve data, give it a bevel
        ob.data.bevel_depth = 0.004
        ob.data.bevel_resolution = 1
        attr_name = "displayColor"
    else:
        names = {a.name for a in ob.data.attributes}
        attr_name = next((n for n in ("displayColor", "primvars:displayColor", "Col", "color")
                          if n in names), "displayColor")
    bpy.context.view_layer.update()
    lo, hi = world_bbox(ob)
    setup_render(bpy, args)
    view_dir = view_direction(args.azimuth, args.elevation)
    if args.cut and ob.type == "CURVES":
        add_cutaway(bpy, ob, lo, hi, view_dir, args.cut_height, args.cut_mode)
    if ob.type == "CURVES":
        frame_camera(bpy, point_positions(ob), args.azimuth, args.elevation, args.width / args.height)
    else:
        corners = [[x, y, z] for x in (lo.x, hi.x) for y in (lo.y, hi.y) for z in (lo.z, hi.z)]
        import numpy as np
        frame_camera(bpy, np.array(corners), args.azimuth, args.elevation, args.width / args.height)
    mat = tissue_material(bpy, attr_name)
    ob.data.materials.clear()
    ob.data.materials.append(mat)
    add_lights(bpy, view_dir)

    out = os.path.abspath(args.png)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", prefix=".render-", dir=os.path.dirname(out))
    os.close(fd)
    try:
        bpy.context.scene.render.filepath = tmp
        t1 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        t_render = time.perf_counter() - t1
        publish_png(tmp, out, args.max_kb)  # mkstemp made it 0600
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    print(f"render_strands: {out} ({os.path.getsize(out) // 1024} KB, {args.width}x{args.height}, "
          f"{args.engine}, render {t_render:.1f} s, total {time.perf_counter() - t0:.1f} s, "
          f"colour attribute {attr_name!r})")


if __name__ == "__main__":
    main()
