"""Render the rest-meshlet USD debug view (woodstock Fig. 10) of a log, cut open, to a PNG with ``bpy``.

Usage (a separate interpreter from wooddecay's own USD code: ``bpy`` bundles its own ``pxr``,
so usd-core's ``pxr`` must never be imported in this process)::

    wooddecay inspect samples/log.toml --meshlets-usd /tmp/log_meshlets.usdc
    python scripts/render_meshlets.py /tmp/log_meshlets.usdc docs/images/log-meshlets.png

Also works as ``blender -b -P scripts/render_meshlets.py -- MESHLETS.usd OUT.png [options]``.

The USD importer turns ``/World/<scene>/Meshlets`` into one Blender mesh whose primvars become
attributes of the same name: ``displayColor`` (face corners), ``element`` and ``faceKind`` (faces,
int) and ``ring`` (points, float). The cut-away is chosen per *element*, so whole meshlets go: an
element is removed where the mean of its face centres lies on the camera side of a plane through
the pith and the log's axis (``half``; ``quadrant`` also needs it above the pith), within a span
of the axis (default from 30 % of the length to the far end, so the intact end keeps its bark).
The removal is a geometry-nodes Delete Geometry on a face attribute written here; the same
modifier shrinks every meshlet a little towards its centre (Scale Elements on the connected face
islands, which are the meshlets' disjoint shells), so thin dark gaps outline the cells, and
shades the faces flat (smooth normals would round each shell into a pill).

The image holds two renders of the same view, side by side (or stacked): left coloured by element
(``displayColor``, the bark faces -- ``faceKind`` 0 -- darker), right by ring age (a colour ramp
on ``ring``, every other band of ``--ring-band`` years darker so the rings read as bands; the bark
faces brown), with captions and a ramp legend drawn by PIL.
Cycles on the CPU with few samples and the denoiser; the PNG is quantised if over ``--max-kb``.
"""
from __future__ import annotations

import argparse
import itertools
import math
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b -P: not on the path
from _render_common import (
    evaluated_positions,
    frame_camera,
    label_font,
    paste_panels,
    publish_png,
    view_direction,
)

# ring ramp (linear RGB, positions in [0, 1] of the oldest ring): pale pith -> deep outer rings
RING_RAMP = [
    (0.00, (0.98, 0.90, 0.45)),
    (0.30, (0.85, 0.45, 0.10)),
    (0.60, (0.45, 0.10, 0.18)),
    (1.00, (0.06, 0.05, 0.30)),
]
BARK_COLOR = (0.16, 0.09, 0.05)


def parse_args(argv=None):
    if argv is None:
        argv = sys.argv[1:]
        if "--" in argv:  # blender -b -P script -- args
            argv = argv[argv.index("--") + 1:]
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("usd", help="meshlets USD written by `wooddecay inspect --meshlets-usd`")
    ap.add_argument("png", help="output PNG")
    ap.add_argument("--engine", choices=["CYCLES", "EEVEE"], default="CYCLES",
                    help="CYCLES (CPU, default) or EEVEE")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--width", type=int, default=900, help="width of the whole image (both views)")
    ap.add_argument("--height", type=int, default=450, help="height of the whole image (both views)")
    ap.add_argument("--layout", choices=["side", "stacked"], default="side",
                    help="the two views side by side (default) or one above the other")
    ap.add_argument("--threads", type=int, default=2, help="render threads (0: all cores)")
    ap.add_argument("--cut", choices=["half", "quadrant", "none"], default="half",
                    help="remove the camera-facing half (a section through the axis), the "
                         "camera-facing upper quadrant, or nothing (default half)")
    ap.add_argument("--cut-from", type=float, default=0.3,
                    help="the cut starts at this fraction of the log's length (default 0.3)")
    ap.add_argument("--cut-to", type=float, default=1.0,
                    help="and ends at this fraction (default 1.0: the far end)")
    ap.add_argument("--gap", type=float, default=0.06,
                    help="shrink each meshlet by this fraction towards its centre (0: no gaps)")
    ap.add_argument("--smooth", dest="flat", action="store_false",
                    help="keep the imported smooth shading (default: flat faces)")
    ap.add_argument("--ring-band", type=float, default=5.0,
                    help="ring view: alternate the shade every this many years (0: plain ramp)")
    ap.add_argument("--azimuth", type=float, default=-40.0,
                    help="camera azimuth in degrees about +z, from the log's axis (+x)")
    ap.add_argument("--elevation", type=float, default=28.0, help="camera elevation in degrees")
    ap.add_argument("--lens", type=float, default=50.0, help="focal length in mm (36 mm sensor)")
    ap.add_argument("--no-labels", dest="labels", action="store_false",
                    help="no captions on the views")
    ap.add_argument("--max-kb", type=int, default=300,
                    help="quantise the PNG (PIL) if it is larger than this many KB; 0: never")
    return ap.parse_args(argv)


def meshlets_object(bpy):
    obs = [ob for ob in bpy.data.objects if ob.type == "MESH"]
    if not obs:
        raise SystemExit("no mesh found in the USD file")
    for ob in obs:
        if ob.name.startswith("Meshlets"):
            return ob
    return max(obs, key=lambda ob: len(ob.data.polygons))


def mesh_arrays(ob):
    """World vertex positions (n, 3), face centres (f, 3), face element (f,), face kind (f,)."""
    import numpy as np

    d = ob.data
    m = np.array(ob.matrix_world)
    pos = np.empty(len(d.vertices) * 3, np.float32)
    d.vertices.foreach_get("co", pos)
    pos = pos.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    cen = np.empty(len(d.polygons) * 3, np.float32)
    d.polygons.foreach_get("center", cen)
    cen = cen.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]

    def face_int(name, default):
        a = d.attributes.get(name) or d.attributes.get("primvars:" + name)
        if a is None or a.domain != "FACE":
            return np.full(len(d.polygons), default, np.int64)
        v = np.empty(len(d.polygons), np.int32)
        a.data.foreach_get("value", v)
        return v.astype(np.int64)

    element = face_int("element", -1)
    if (element < 0).all():  # no element primvar: every face its own "element"
        element = np.arange(len(d.polygons))
    return pos, cen, element, face_int("faceKind", 1)


def point_float(ob, name):
    import numpy as np

    d = ob.data
    a = d.attributes.get(name) or d.attributes.get("primvars:" + name)
    if a is None:
        return None, None
    v = np.empty(len(a.data), np.float32)
    a.data.foreach_get("value", v)
    return a.name, v


def log_frame(pos, ring):
    """The log's axis (unit, the longest box side), its span along it, and the pith (a point).

    The pith is the mean of the vertices in the youngest ring (the lowest ``ring`` values), so
    a section through it shows the rings symmetric; without ``ring`` the box centre is used.
    """
    import numpy as np

    lo, hi = pos.min(0), pos.max(0)
    k = int(np.argmax(hi - lo))
    axis = np.zeros(3)
    axis[k] = 1.0
    centre = (lo + hi) / 2
    if ring is not None and len(ring) == len(pos):
        young = ring <= ring.min() + 0.5
        pith = pos[young].mean(0)
        pith[k] = centre[k]
    else:
        pith = centre
    return axis, lo[k], hi[k], pith


def cut_selection(cen, element, axis, a0, a1, pith, view_dir, mode, t0, t1):
    """Boolean per face: the faces of the elements to remove (whole meshlets)."""
    import numpy as np

    ne = int(element.max()) + 1
    cnt = np.maximum(np.bincount(element, minlength=ne), 1)
    ec = np.stack([np.bincount(element, weights=cen[:, i], minlength=ne) for i in range(3)], 1) / cnt[:, None]
    rel = ec - pith
    t = rel @ axis
    # camera side: the view direction with its axis component removed
    side = np.asarray(view_dir, float) - (np.dot(view_dir, axis)) * axis
    side /= max(np.linalg.norm(side), 1e-12)
    span = a1 - a0
    sel = (t >= a0 - pith @ axis + t0 * span) & (t <= a0 - pith @ axis + t1 * span) & (rel @ side > 0)
    if mode == "quadrant":
        up = np.array([0.0, 0.0, 1.0]) - axis[2] * axis
        up /= max(np.linalg.norm(up), 1e-12)
        sel &= rel @ up > 0
    return sel[element]


def set_face_attr(ob, name, values, kind="BOOLEAN"):
    d = ob.data
    if name in d.attributes:
        d.attributes.remove(d.attributes[name])
    a = d.attributes.new(name, kind, "FACE")
    a.data.foreach_set("value", values)


def add_cut_and_gaps(bpy, ob, gap, flat=True):
    """Geometry nodes: delete the faces flagged ``cutAway``, shrink each shell by ``gap``, flat shading."""
    ng = bpy.data.node_groups.new("MeshletCutaway", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, L = ng.nodes, ng.links
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    flag = n.new("GeometryNodeInputNamedAttribute")
    flag.data_type = "BOOLEAN"
    flag.inputs["Name"].default_value = "cutAway"
    delete = n.new("GeometryNodeDeleteGeometry")
    delete.domain = "FACE"
    L.new(gin.outputs[0], delete.inputs["Geometry"])
    L.new(flag.outputs["Attribute"], delete.inputs["Selection"])
    out = delete.outputs[0]
    if gap > 0:
        # face islands = the meshlets' disjoint shells, scaled about their own centres
        scale = n.new("GeometryNodeScaleElements")
        scale.domain = "FACE"
        scale.scale_mode = "UNIFORM"
        scale.inputs["Scale"].default_value = 1.0 - gap
        L.new(out, scale.inputs["Geometry"])
        out = scale.outputs[0]
    if flat:
        # flat faces: smooth normals round each closed shell into a pill and blur the cells
        shade = n.new("GeometryNodeSetShadeSmooth")
        shade.inputs["Shade Smooth"].default_value = False
        L.new(out, shade.inputs["Geometry"])
        out = shade.outputs[0]
    L.new(out, gout.inputs[0])
    mod = ob.modifiers.new("Cutaway", "NODES")
    mod.node_group = ng


def _bsdf(mat):
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Roughness"].default_value = 0.8
    if "Specular IOR Level" in bsdf.inputs:  # 4.x name
        bsdf.inputs["Specular IOR Level"].default_value = 0.2
    return bsdf


def _with_bark(mat, color_socket, bark_attr, replace=False):
    """On the bark faces, darken ``color_socket`` (or replace it by the bark colour); returns the new socket."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bark = nodes.new("ShaderNodeAttribute")
    bark.attribute_type = "GEOMETRY"
    bark.attribute_name = bark_attr
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MIX" if replace else "MULTIPLY"
    links.new(bark.outputs["Fac"], mix.inputs["Factor"])
    links.new(color_socket, mix.inputs[6])  # A (colour)
    mix.inputs[7].default_value = (*BARK_COLOR, 1.0) if replace else (0.3, 0.3, 0.3, 1.0)  # B
    return mix.outputs[2]  # Result (colour)


def element_material(bpy, color_attr, bark_attr):
    mat = bpy.data.materials.new("MeshletElement")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = _bsdf(mat)
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = color_attr
    links.new(_with_bark(mat, attr.outputs["Color"], bark_attr), bsdf.inputs["Base Color"])
    return mat


def ring_material(bpy, ring_attr, ring_max, band, bark_attr):
    mat = bpy.data.materials.new("MeshletRing")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = _bsdf(mat)
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = ring_attr
    norm = nodes.new("ShaderNodeMath")
    norm.operation = "DIVIDE"
    norm.use_clamp = True
    links.new(attr.outputs["Fac"], norm.inputs[0])
    norm.inputs[1].default_value = max(ring_max, 1e-6)
    ramp = nodes.new("ShaderNodeValToRGB")
    el = ramp.color_ramp.elements
    while len(el) < len(RING_RAMP):
        el.new(0.5)
    for e, (p, c) in zip(el, RING_RAMP):
        e.position, e.color = p, (*c, 1.0)
    links.new(norm.outputs[0], ramp.inputs["Fac"])
    color = ramp.outputs["Color"]
    if band > 0:
        # shade = 1 on even bands of `band` years, 0.45 on odd ones
        div = nodes.new("ShaderNodeMath")
        div.operation = "DIVIDE"
        links.new(attr.outputs["Fac"], div.inputs[0])
        div.inputs[1].default_value = band
        fl = nodes.new("ShaderNodeMath")
        fl.operation = "FLOOR"
        links.new(div.outputs[0], fl.inputs[0])
        mod = nodes.new("ShaderNodeMath")
        mod.operation = "FLOORED_MODULO"
        links.new(fl.outputs[0], mod.inputs[0])
        mod.inputs[1].default_value = 2.0
        mix = nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.blend_type = "MULTIPLY"
        links.new(mod.outputs[0], mix.inputs["Factor"])
        links.new(color, mix.inputs[6])
        mix.inputs[7].default_value = (0.45, 0.45, 0.45, 1.0)
        color = mix.outputs[2]
    links.new(_with_bark(mat, color, bark_attr, replace=True), bsdf.inputs["Base Color"])
    return mat


def setup_render(bpy, args, width, height):
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "8"
    r.image_settings.compression = 100
    r.film_transparent = False
    r.use_persistent_data = True  # the second view reuses the synced mesh and BVH
    if args.threads:
        r.threads_mode, r.threads = "FIXED", args.threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    if args.engine == "CYCLES":
        r.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = args.samples
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.max_bounces = 3
        scene.cycles.use_denoising = True
        try:
            scene.cycles.denoiser = "OPENIMAGEDENOISE"
        except TypeError:
            scene.cycles.use_denoising = False
    else:
        r.engine = "BLENDER_EEVEE_NEXT"
        scene.eevee.taa_render_samples = args.samples


def add_lights(bpy, v):
    from mathutils import Vector

    scene = bpy.context.scene
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = math.radians(8)
    ob = bpy.data.objects.new("Sun", sun)
    # from above, a little to the side of the camera
    d = Vector((v[0] * 0.7 - v[1] * 0.4, v[1] * 0.7 + v[0] * 0.4, 1.0)).normalized()
    ob.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(ob)
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.62, 0.68, 0.75, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world


def _srgb(c):
    return tuple(round(255 * (12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055))
                 for x in c)


def compose(paths, out, layout, labels, ring_min, ring_max, band):
    """Paste the panel PNGs side by side or stacked; captions and a ring legend if ``labels``."""
    from PIL import ImageDraw

    img, (w, h) = paste_panels(paths, layout)
    if labels:
        draw = ImageDraw.Draw(img)
        font = label_font(15)
        ink = (25, 28, 34)
        caps = ["coloured by element (bark darker)",
                f"coloured by ring age ({band:g}-year bands)" if band > 0 else "coloured by ring age"]
        for i, cap in enumerate(caps):
            x0, y0 = (i * w, 0) if layout == "side" else (0, i * h)
            draw.text((x0 + 10, y0 + 8), cap, fill=ink, font=font)
        # ring legend: the ramp as a bar, bottom left of the ring view
        x0, y0 = (w, 0) if layout == "side" else (0, h)
        bw, bh = min(160, w // 3), 9
        bx, by = x0 + 10, y0 + h - 34
        for i in range(bw):
            t = i / (bw - 1)
            col = _srgb(RING_RAMP[-1][1])
            for (p0, c0), (p1, c1) in itertools.pairwise(RING_RAMP):
                if p0 <= t <= p1:
                    f = (t - p0) / max(p1 - p0, 1e-9)
                    col = _srgb([a + (b - a) * f for a, b in zip(c0, c1)])
                    break
            draw.line([(bx + i, by), (bx + i, by + bh)], fill=col)
        draw.rectangle([bx - 1, by - 1, bx + bw, by + bh], outline=ink)
        draw.text((bx, by + bh + 3), "0", fill=ink, font=font)
        txt = f"{ring_max:.0f} years"
        tw = draw.textlength(txt, font=font)
        draw.text((bx + bw - tw, by + bh + 3), txt, fill=ink, font=font)
        # a swatch for the bark
        draw.rectangle([bx + bw + 14, by - 1, bx + bw + 24, by + bh], fill=_srgb(BARK_COLOR),
                       outline=ink)
        draw.text((bx + bw + 29, by - 4), "bark", fill=ink, font=font)
    img.save(out, optimize=True)


def main(argv=None) -> None:
    args = parse_args(argv)
    t0 = time.perf_counter()
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    res = bpy.ops.wm.usd_import(filepath=os.path.abspath(args.usd))
    if "FINISHED" not in res:
        raise SystemExit(f"USD import failed: {res}")
    ob = meshlets_object(bpy)
    bpy.context.view_layer.update()
    names = {a.name for a in ob.data.attributes}
    color_attr = next((n for n in ("displayColor", "primvars:displayColor", "Col", "color") if n in names),
                      "displayColor")
    ring_attr, ring = point_float(ob, "ring")
    pos, cen, element, kind = mesh_arrays(ob)
    axis, a0, a1, pith = log_frame(pos, ring)
    v = view_direction(axis, args.azimuth, args.elevation)

    if args.cut != "none":
        sel = cut_selection(cen, element, axis, a0, a1, pith, v, args.cut, args.cut_from, args.cut_to)
    else:
        sel = np.zeros(len(cen), bool)
    set_face_attr(ob, "cutAway", sel)
    set_face_attr(ob, "bark", (kind == 0).astype(np.float32), "FLOAT")
    add_cut_and_gaps(bpy, ob, args.gap, args.flat)
    n_cut = len(np.unique(element[sel]))

    if args.layout == "side":
        pw, ph = args.width // 2, args.height
    else:
        pw, ph = args.width, args.height // 2
    setup_render(bpy, args, pw, ph)
    bpy.context.view_layer.update()
    frame_camera(bpy, evaluated_positions(bpy, ob), v, pw / ph, lens=args.lens)
    add_lights(bpy, v)
    ring_lo = float(ring.min()) if ring is not None else 0.0
    ring_hi = float(ring.max()) if ring is not None else 1.0
    mats = [element_material(bpy, color_attr, "bark")]
    if ring_attr is not None:
        mats.append(ring_material(bpy, ring_attr, ring_hi, args.ring_band, "bark"))
    else:
        print("render_meshlets: no `ring` attribute, both views coloured by element", file=sys.stderr)
        mats.append(mats[0])

    out = os.path.abspath(args.png)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmpdir = tempfile.mkdtemp(prefix=".render-", dir=os.path.dirname(out))
    panels = [os.path.join(tmpdir, f"view{i}.png") for i in range(2)]
    tmp = os.path.join(tmpdir, "out.png")
    t_render = 0.0
    try:
        for mat, path in zip(mats, panels):
            ob.data.materials.clear()
            ob.data.materials.append(mat)
            bpy.context.scene.render.filepath = path
            t1 = time.perf_counter()
            bpy.ops.render.render(write_still=True)
            t_render += time.perf_counter() - t1
        compose(panels, tmp, args.layout, args.labels, ring_lo, ring_hi, args.ring_band)
        publish_png(tmp, out, args.max_kb)
    finally:
        for p in panels + [tmp]:
            if os.path.exists(p):
                os.unlink(p)
        os.rmdir(tmpdir)
    print(f"render_meshlets: {out} ({os.path.getsize(out) // 1024} KB, {args.width}x{args.height}, "
          f"{args.engine}, {len(ob.data.polygons)} faces, {int(element.max()) + 1} elements, "
          f"{n_cut} cut away, render {t_render:.1f} s, total {time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
