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

import math
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "wooddecay", "render"))
import blender_common as common


def parse_args(argv=None):
    ap = common.render_parser(__doc__, "strands USD written by `wooddecay inspect --strands-usd`",
                              "CYCLES (CPU, default) or EEVEE (a rougher fallback: camera-facing strips)")
    common.add_size_args(ap, 16, 480, 640)
    common.add_threads_arg(ap, 0)
    ap.add_argument("--no-cut", dest="cut", action="store_false",
                    help="no cut-away: show the bark all round")
    ap.add_argument("--cut", dest="cut_mode", choices=["half", "quadrant"], default="half",
                    help="cut away the camera-facing half (a section through the stem axis) "
                         "or quadrant of the lower tree (default half)")
    ap.add_argument("--cut-height", type=float, default=0.33,
                    help="cut-away up to this fraction of the tree's height (default 0.33)")
    common.add_camera_args(ap, 12.0, azimuth=-50.0, azimuth_help="camera azimuth in degrees")
    return common.parse_render_args(ap, argv, max_kb=400)


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
    pos = common.local_positions(ob.data)
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

    def build(ng, geometry):
        n, L = ng.nodes, ng.links
        position = n.new("GeometryNodeInputPosition")
        sep = n.new("ShaderNodeSeparateXYZ")
        L.new(position.outputs[0], sep.inputs[0])

        def compare(a, operation, b):
            cmp = n.new("FunctionNodeCompare")
            cmp.data_type = "FLOAT"
            cmp.operation = operation
            L.new(a, cmp.inputs[0])
            cmp.inputs[1].default_value = b
            return cmp.outputs[0]

        def dot_axis(axis):
            # (x - cx) * ax + (y - cy) * ay > 0
            vm = n.new("ShaderNodeVectorMath")
            vm.operation = "DOT_PRODUCT"
            L.new(position.outputs[0], vm.inputs[0])
            vm.inputs[1].default_value = (axis[0], axis[1], 0.0)
            return compare(vm.outputs["Value"], "GREATER_THAN", cx * axis[0] + cy * axis[1])

        def both(a, b):
            node = n.new("FunctionNodeBooleanMath")
            node.operation = "AND"
            L.new(a, node.inputs[0])
            L.new(b, node.inputs[1])
            return node.outputs[0]

        below = compare(sep.outputs["Z"], "LESS_THAN", z_cut)
        return common.delete_geometry(ng, geometry, both(both(dot_axis(a1), dot_axis(a2)), below), "POINT")

    common.add_nodes_modifier(bpy, ob, "StrandCutaway", build)
    return z_cut


def tissue_material(bpy, attribute="displayColor"):
    mat, bsdf = common.principled_material(bpy, "StrandTissue", 0.85, 0.25)
    mat.node_tree.links.new(common.attribute_node(mat, attribute).outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def main(argv=None) -> None:
    args = parse_args(argv)
    t0 = time.perf_counter()
    import bpy
    from mathutils import Vector

    common.import_usd(bpy, args.usd)
    ob = common.find_object(bpy, {"CURVES", "CURVE"}, "Strands", "curves", lambda obs: obs[0])
    if ob.type == "CURVE":  # older importers: legacy curve data, give it a bevel
        ob.data.bevel_depth = 0.004
        ob.data.bevel_resolution = 1
        attr_name = "displayColor"
    else:
        attr_name = common.color_attribute(ob.data)
    bpy.context.view_layer.update()
    lo, hi = world_bbox(ob)
    scene = common.setup_render(bpy, args.width, args.height, args.samples, args.threads, args.engine)
    if args.engine == "CYCLES":
        scene.cycles_curves.shape = "THICK"
    else:
        scene.render.hair_type = "STRIP"  # camera-facing strips of the curve radius (default: 1 px lines)
    v = common.view_direction((1.0, 0.0, 0.0), args.azimuth, args.elevation)  # azimuth from +x
    view_dir = Vector(v)
    if args.cut and ob.type == "CURVES":
        add_cutaway(bpy, ob, lo, hi, view_dir, args.cut_height, args.cut_mode)
    # fitted to the points: the tree's box seen on a diagonal leaves much room round a slender tree
    if ob.type == "CURVES":
        points = common.evaluated_positions(bpy, ob, max_points=None)  # after the cut-away, if any
    else:
        import numpy as np
        points = np.array([[x, y, z] for x in (lo.x, hi.x) for y in (lo.y, hi.y) for z in (lo.z, hi.z)])
    common.frame_camera(bpy, points, v, args.width / args.height, margin=1.05, recentre=False)
    mat = tissue_material(bpy, attr_name)
    ob.data.materials.clear()
    ob.data.materials.append(mat)
    sun = common.add_sun_and_sky(bpy, 3.5, 5, common.SKY_BLUE, 0.9)
    common.aim_sun(sun, view_dir, 0.6, 0.5, 1.1)  # from above, a little to the side of the camera

    out, t_render = common.render_views(bpy, args.png, 1, args.max_kb)
    print(f"render_strands: {out} ({os.path.getsize(out) // 1024} KB, {args.width}x{args.height}, "
          f"{args.engine}, render {t_render:.1f} s, total {time.perf_counter() - t0:.1f} s, "
          f"colour attribute {attr_name!r})")


if __name__ == "__main__":
    main()
