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

import itertools
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "wooddecay", "render"))
import blender_common as common

# ring ramp (linear RGB, positions in [0, 1] of the oldest ring): pale pith -> deep outer rings
RING_RAMP = [
    (0.00, (0.98, 0.90, 0.45)),
    (0.30, (0.85, 0.45, 0.10)),
    (0.60, (0.45, 0.10, 0.18)),
    (1.00, (0.06, 0.05, 0.30)),
]
BARK_COLOR = (0.16, 0.09, 0.05)


def parse_args(argv=None):
    ap = common.render_parser(__doc__, "meshlets USD written by `wooddecay inspect --meshlets-usd`",
                              "CYCLES (CPU, default) or EEVEE")
    common.add_size_args(ap, 16, 900, 450, views="both views")
    common.add_layout_arg(ap, "the two views")
    common.add_threads_arg(ap, 2)
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
    common.add_camera_args(ap, 28.0, azimuth=-40.0, lens=50.0,
                           azimuth_help="camera azimuth in degrees about +z, from the log's axis (+x)")
    common.add_labels_arg(ap, "no captions on the views")
    return common.parse_render_args(ap, argv, max_kb=300)


def _attribute(d, name):
    """The attribute ``name`` of the mesh data ``d`` (or ``primvars:name``), or None."""
    return d.attributes.get(name) or d.attributes.get("primvars:" + name)


def mesh_arrays(ob):
    """World vertex positions (n, 3), face centres (f, 3), face element (f,), face kind (f,)."""
    import numpy as np

    d = ob.data
    pos = common.to_world(ob, common.local_positions(d).astype(np.float64))
    cen = common.to_world(ob, common.vectors(d.polygons, "center").astype(np.float64))

    def face_int(name, default):
        a = _attribute(d, name)
        if a is None or a.domain != "FACE":
            return np.full(len(d.polygons), default, np.int64)
        return common.attribute_values(a, np.int32).astype(np.int64)

    element = face_int("element", -1)
    if (element < 0).all():  # no element primvar: every face its own "element"
        element = np.arange(len(d.polygons))
    return pos, cen, element, face_int("faceKind", 1)


def point_float(ob, name):
    a = _attribute(ob.data, name)
    if a is None:
        return None, None
    return a.name, common.attribute_values(a)


def log_frame(pos, ring):
    """The log's axis (unit, the longest box side), its span along it, and the pith (a point).

    The pith is the mean of the vertices in the youngest ring (the lowest ``ring`` values), so
    a section through it shows the rings symmetric; without ``ring`` the box centre is used.
    """
    import numpy as np

    lo, hi = pos.min(0), pos.max(0)
    axis = common.log_axis(lo, hi)
    k = int(np.argmax(axis))
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
    def build(ng, geometry):
        n, L = ng.nodes, ng.links
        flag = n.new("GeometryNodeInputNamedAttribute")
        flag.data_type = "BOOLEAN"
        flag.inputs["Name"].default_value = "cutAway"
        out = common.delete_geometry(ng, geometry, flag.outputs["Attribute"], "FACE")
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
        return out

    common.add_nodes_modifier(bpy, ob, "MeshletCutaway", build)


def _material(bpy, name, attribute):
    """A material ``name`` and its Principled BSDF, with an Attribute node reading ``attribute``."""
    mat, bsdf = common.principled_material(bpy, name, 0.8, 0.2)
    return mat, bsdf, common.attribute_node(mat, attribute)


def _math(mat, operation, a, b=None, clamp=False):
    """A Math node ``operation`` of the socket ``a`` and the value ``b`` (clamped to [0, 1] if
    ``clamp``); returns its result."""
    node = mat.node_tree.nodes.new("ShaderNodeMath")
    node.operation = operation
    if clamp:
        node.use_clamp = True
    mat.node_tree.links.new(a, node.inputs[0])
    if b is not None:
        node.inputs[1].default_value = b
    return node.outputs[0]


def _mix(mat, blend, factor, a, b):
    """A colour Mix node ``blend`` of the socket ``a`` and the colour ``b`` by the socket
    ``factor``; returns its result."""
    mix = mat.node_tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = blend
    mat.node_tree.links.new(factor, mix.inputs["Factor"])
    mat.node_tree.links.new(a, mix.inputs[6])  # A (colour)
    mix.inputs[7].default_value = (*b, 1.0)  # B
    return mix.outputs[2]  # Result (colour)


def _with_bark(mat, color_socket, bark_attr, replace=False):
    """On the bark faces, darken ``color_socket`` (or replace it by the bark colour); returns the new socket."""
    bark = common.attribute_node(mat, bark_attr)
    return _mix(mat, "MIX" if replace else "MULTIPLY", bark.outputs["Fac"], color_socket,
                BARK_COLOR if replace else (0.3, 0.3, 0.3))


def element_material(bpy, color_attr, bark_attr):
    mat, bsdf, attr = _material(bpy, "MeshletElement", color_attr)
    mat.node_tree.links.new(_with_bark(mat, attr.outputs["Color"], bark_attr), bsdf.inputs["Base Color"])
    return mat


def ring_material(bpy, ring_attr, ring_max, band, bark_attr):
    mat, bsdf, attr = _material(bpy, "MeshletRing", ring_attr)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    norm = _math(mat, "DIVIDE", attr.outputs["Fac"], max(ring_max, 1e-6), clamp=True)
    ramp = nodes.new("ShaderNodeValToRGB")
    el = ramp.color_ramp.elements
    while len(el) < len(RING_RAMP):
        el.new(0.5)
    for e, (p, c) in zip(el, RING_RAMP):
        e.position, e.color = p, (*c, 1.0)
    links.new(norm, ramp.inputs["Fac"])
    color = ramp.outputs["Color"]
    if band > 0:
        # shade = 1 on even bands of `band` years, 0.45 on odd ones
        years = _math(mat, "FLOOR", _math(mat, "DIVIDE", attr.outputs["Fac"], band))
        odd = _math(mat, "FLOORED_MODULO", years, 2.0)
        color = _mix(mat, "MULTIPLY", odd, color, (0.45, 0.45, 0.45))
    links.new(_with_bark(mat, color, bark_attr, replace=True), bsdf.inputs["Base Color"])
    return mat


def _srgb(c):
    return tuple(round(255 * (12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055))
                 for x in c)


def compose(paths, out, layout, labels, ring_min, ring_max, band):
    """Paste the panel PNGs side by side or stacked; captions and a ring legend if ``labels``."""
    img, (w, h) = common.paste_panels(paths, layout)
    if labels:
        caps = ["coloured by element (bark darker)",
                f"coloured by ring age ({band:g}-year bands)" if band > 0 else "coloured by ring age"]
        draw, font = common.caption_panels(img, (w, h), layout, caps, 15)
        # ring legend: the ramp as a bar, bottom left of the ring view
        x0, y0 = common.panel_origin(1, (w, h), layout)
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
        draw.rectangle([bx - 1, by - 1, bx + bw, by + bh], outline=common.INK)
        draw.text((bx, by + bh + 3), "0", fill=common.INK, font=font)
        txt = f"{ring_max:.0f} years"
        tw = draw.textlength(txt, font=font)
        draw.text((bx + bw - tw, by + bh + 3), txt, fill=common.INK, font=font)
        # a swatch for the bark
        draw.rectangle([bx + bw + 14, by - 1, bx + bw + 24, by + bh], fill=_srgb(BARK_COLOR),
                       outline=common.INK)
        draw.text((bx + bw + 29, by - 4), "bark", fill=common.INK, font=font)
    img.save(out, optimize=True)


def main(argv=None) -> None:
    args = parse_args(argv)
    t0 = time.perf_counter()
    import bpy
    import numpy as np

    common.import_usd(bpy, args.usd)
    ob = common.find_object(bpy, {"MESH"}, "Meshlets", "mesh",
                            lambda obs: max(obs, key=lambda ob: len(ob.data.polygons)))
    bpy.context.view_layer.update()
    color_attr = common.color_attribute(ob.data)
    ring_attr, ring = point_float(ob, "ring")
    pos, cen, element, kind = mesh_arrays(ob)
    axis, a0, a1, pith = log_frame(pos, ring)
    v = common.view_direction(axis, args.azimuth, args.elevation)

    if args.cut != "none":
        sel = cut_selection(cen, element, axis, a0, a1, pith, v, args.cut, args.cut_from, args.cut_to)
    else:
        sel = np.zeros(len(cen), bool)
    set_face_attr(ob, "cutAway", sel)
    set_face_attr(ob, "bark", (kind == 0).astype(np.float32), "FLOAT")
    add_cut_and_gaps(bpy, ob, args.gap, args.flat)
    n_cut = len(np.unique(element[sel]))

    pw, ph = common.panel_size(args.width, args.height, 2, args.layout)
    # persistent: the second view reuses the synced mesh and BVH
    common.setup_render(bpy, pw, ph, args.samples, args.threads, args.engine, max_bounces=3, persistent=True)
    bpy.context.view_layer.update()
    common.frame_camera(bpy, common.evaluated_positions(bpy, ob), v, pw / ph, lens=args.lens)
    sun = common.add_sun_and_sky(bpy, 3.0, 8, common.SKY_BLUE, 1.0)
    common.aim_sun(sun, v, 0.7, 0.4, 1.0)  # from above, a little to the side of the camera
    ring_lo = float(ring.min()) if ring is not None else 0.0
    ring_hi = float(ring.max()) if ring is not None else 1.0
    mats = [element_material(bpy, color_attr, "bark")]
    if ring_attr is not None:
        mats.append(ring_material(bpy, ring_attr, ring_hi, args.ring_band, "bark"))
    else:
        print("render_meshlets: no `ring` attribute, both views coloured by element", file=sys.stderr)
        mats.append(mats[0])

    def show(i):
        ob.data.materials.clear()
        ob.data.materials.append(mats[i])

    out, t_render = common.render_views(
        bpy, args.png, 2, args.max_kb, show,
        lambda panels, path: compose(panels, path, args.layout, args.labels, ring_lo, ring_hi, args.ring_band))
    print(f"render_meshlets: {out} ({os.path.getsize(out) // 1024} KB, {args.width}x{args.height}, "
          f"{args.engine}, {len(ob.data.polygons)} faces, {int(element.max()) + 1} elements, "
          f"{n_cut} cut away, render {t_render:.1f} s, total {time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
