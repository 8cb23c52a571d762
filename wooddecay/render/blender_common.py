"""Helpers shared by the ``bpy`` render scripts (blender_bake.py here, scripts/render_meshlets.py and
scripts/render_strands.py).

Their common command-line options, importing a USD file and finding its object, reading point
positions and attributes, the render settings, a sun and a plain sky, node-tree building blocks
(a material around a Principled BSDF, a geometry-nodes modifier), camera fitting on a 3/4 view,
rendering one or more views into a PNG (captions, size capping) and the exit under the ``bpy``
wheel. Nothing here imports ``bpy`` at module level (the scripts pass it in), nor wooddecay or
usd-core's ``pxr``.

The scripts import this file by name (``import blender_common``): each puts this folder first on
``sys.path``, as ``blender -b -P`` does not.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

#: background colour of the worlds of render_strands.py and render_meshlets.py (linear RGB)
SKY_BLUE = (0.62, 0.68, 0.75)
#: colour of the captions drawn on the pictures
INK = (25, 28, 34)

# -- command line -------------------------------------------------------------------------------


def render_parser(doc, usd_help, engine_help=None):
    """A parser described by the first paragraph of ``doc`` with the positional ``usd`` and
    ``png`` and, if ``engine_help`` is given, ``--engine`` (CYCLES or EEVEE)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("usd", help=usd_help)
    ap.add_argument("png", help="output PNG")
    if engine_help:
        ap.add_argument("--engine", choices=["CYCLES", "EEVEE"], default="CYCLES", help=engine_help)
    return ap


def add_size_args(ap, samples, width, height, views=None):
    """``--samples``, ``--width`` and ``--height``; ``views`` ("both views"): what the whole image
    holds, for the help of the last two."""
    ap.add_argument("--samples", type=int, default=samples)
    ap.add_argument("--width", type=int, default=width, help=views and f"width of the whole image ({views})")
    ap.add_argument("--height", type=int, default=height, help=views and f"height of the whole image ({views})")


def add_threads_arg(ap, default):
    ap.add_argument("--threads", type=int, default=default, help="render threads (0: all cores)")


def add_layout_arg(ap, views):
    """``--layout``: ``views`` ("the views") side by side or stacked."""
    ap.add_argument("--layout", choices=["side", "stacked"], default="side",
                    help=f"{views} side by side (default) or one above the other")


def add_camera_args(ap, elevation, azimuth=None, azimuth_help=None, lens=None):
    """``--azimuth`` (one, if ``azimuth`` is given), ``--elevation`` and ``--lens`` (if given)."""
    if azimuth is not None:
        ap.add_argument("--azimuth", type=float, default=azimuth, help=azimuth_help)
    ap.add_argument("--elevation", type=float, default=elevation, help="camera elevation in degrees")
    if lens is not None:
        ap.add_argument("--lens", type=float, default=lens, help="focal length in mm (36 mm sensor)")


def add_labels_arg(ap, help):
    ap.add_argument("--no-labels", dest="labels", action="store_false", help=help)


def parse_render_args(ap, argv, max_kb):
    """Add ``--max-kb`` (default ``max_kb``, last in the help) and parse ``argv``, by default the
    command line's arguments (those after ``--`` under ``blender -b -P script -- args``)."""
    ap.add_argument("--max-kb", type=int, default=max_kb,
                    help="quantise the PNG (PIL) if it is larger than this many KB; 0: never")
    if argv is None:
        argv = sys.argv[1:]
        if "--" in argv:  # blender -b -P script -- args
            argv = argv[argv.index("--") + 1:]
    return ap.parse_args(argv)


def exit_now(code):
    """Flush stdout and stderr and leave with ``code`` through ``os._exit``: with the ``bpy``
    wheel a process that enabled an add-on hangs at exit, even once it is disabled again (see
    tests/test_addon.py)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


# -- scene and data -----------------------------------------------------------------------------


def import_usd(bpy, path):
    """Start from an empty factory scene and import the USD file at ``path`` (Blender's importer)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    res = bpy.ops.wm.usd_import(filepath=os.path.abspath(path))
    if "FINISHED" not in res:
        raise SystemExit(f"USD import failed: {res}")


def find_object(bpy, types, prefix, what, fallback):
    """The first object of one of ``types`` whose name starts with ``prefix``, else
    ``fallback(objects of those types)``; exits if there is none (``what``: for the message)."""
    obs = [ob for ob in bpy.data.objects if ob.type in types]
    if not obs:
        raise SystemExit(f"no {what} found in the USD file")
    for ob in obs:
        if ob.name.startswith(prefix):
            return ob
    return fallback(obs)


def color_attribute(data):
    """The name the USD importer gave the ``displayColor`` primvar among ``data``'s attributes."""
    names = {a.name for a in data.attributes}
    return next((n for n in ("displayColor", "primvars:displayColor", "Col", "color") if n in names),
                "displayColor")


def vectors(seq, prop):
    """The 3-vector property ``prop`` of every item of the bpy collection ``seq``, (n, 3) float32."""
    import numpy as np

    a = np.empty(len(seq) * 3, np.float32)
    seq.foreach_get(prop, a)
    return a.reshape(-1, 3)


def attribute_values(attr, dtype="float32"):
    """The values (n,) of the scalar attribute ``attr``."""
    import numpy as np

    v = np.empty(len(attr.data), dtype)
    attr.data.foreach_get("value", v)
    return v


def local_positions(data):
    """Object-space positions (n, 3), float32, of a mesh's vertices or a Curves object's points."""
    if hasattr(data, "vertices"):
        return vectors(data.vertices, "co")
    return vectors(data.attributes["position"].data, "vector")


def to_world(ob, pos):
    """The object-space points ``pos`` (n, 3) of ``ob`` in world space."""
    import numpy as np

    m = np.array(ob.matrix_world)
    return pos @ m[:3, :3].T + m[:3, 3]


def evaluated_positions(bpy, ob, max_points=200_000):
    """World positions (n, 3) of ``ob``'s evaluated mesh or curves (after its modifiers), thinned
    to at most about ``max_points`` (None: all)."""
    import numpy as np

    pos = local_positions(ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).data).astype(np.float64)
    if max_points and len(pos) > max_points:
        pos = pos[:: len(pos) // max_points + 1]
    return to_world(ob, pos)


def log_axis(lo, hi):
    """Unit vector along the longest side of the box ``lo``..``hi`` (positive direction)."""
    import numpy as np

    axis = np.zeros(3)
    axis[int(np.argmax(hi - lo))] = 1.0
    return axis


# -- render settings, lights, nodes -------------------------------------------------------------


def setup_render(bpy, width, height, samples, threads, engine="CYCLES", max_bounces=4, persistent=False):
    """An 8-bit RGB PNG of ``width`` x ``height``, the Standard view transform, ``threads`` (0:
    all cores); Cycles on the CPU with ``samples``, ``max_bounces`` and the denoiser, or EEVEE
    (``engine``); ``persistent``: later renders reuse the synced scene. Returns the scene."""
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "8"
    r.image_settings.compression = 100
    r.film_transparent = False
    r.use_persistent_data = persistent
    if threads:
        r.threads_mode, r.threads = "FIXED", threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    if engine == "CYCLES":
        r.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = samples
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.max_bounces = max_bounces
        scene.cycles.use_denoising = True
        try:
            scene.cycles.denoiser = "OPENIMAGEDENOISE"
        except TypeError:
            scene.cycles.use_denoising = False
    else:
        r.engine = "BLENDER_EEVEE_NEXT"
        scene.eevee.taa_render_samples = samples
    return scene


def add_sun_and_sky(bpy, energy, angle, sky, strength):
    """A sun of ``energy`` and ``angle`` degrees (aim it with :func:`aim_sun`) and a world of the
    plain colour ``sky`` (linear RGB) at ``strength``; returns the sun's object."""
    scene = bpy.context.scene
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = energy
    sun.angle = math.radians(angle)
    ob = bpy.data.objects.new("Sun", sun)
    scene.collection.objects.link(ob)
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*sky, 1.0)
    bg.inputs["Strength"].default_value = strength
    scene.world = world
    return ob


def aim_sun(sun, v, along, side, up):
    """Light from ``along`` * ``v`` (towards the camera), ``side`` * ``v`` turned 90 degrees
    anticlockwise about +z (negative: clockwise) and ``up`` * +z."""
    from mathutils import Vector

    d = Vector((v[0] * along - v[1] * side, v[1] * along + v[0] * side, up)).normalized()
    sun.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()


def principled_material(bpy, name, roughness, specular=None):
    """A new node material ``name`` and its Principled BSDF, given ``roughness`` and, if given
    (Blender 4.x), ``specular`` as the Specular IOR Level."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Roughness"].default_value = roughness
    if specular is not None and "Specular IOR Level" in bsdf.inputs:  # 4.x name
        bsdf.inputs["Specular IOR Level"].default_value = specular
    return mat, bsdf


def attribute_node(mat, name):
    """A new Attribute node in ``mat`` reading the geometry attribute ``name``."""
    attr = mat.node_tree.nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = name
    return attr


def add_nodes_modifier(bpy, ob, name, build):
    """A geometry-nodes modifier "Cutaway" on ``ob`` with a new node tree ``name`` of one geometry
    input and output, between which ``build(tree, input geometry socket)`` puts its nodes and
    returns the output geometry socket."""
    ng = bpy.data.node_groups.new(name, "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    ng.links.new(build(ng, gin.outputs[0]), gout.inputs[0])
    mod = ob.modifiers.new("Cutaway", "NODES")
    mod.node_group = ng
    return mod


def delete_geometry(ng, geometry, selection, domain):
    """A Delete Geometry node in ``ng`` removing the ``domain`` elements of the socket ``geometry``
    where the socket ``selection`` is true; returns its geometry output."""
    delete = ng.nodes.new("GeometryNodeDeleteGeometry")
    delete.domain = domain
    ng.links.new(geometry, delete.inputs["Geometry"])
    ng.links.new(selection, delete.inputs["Selection"])
    return delete.outputs[0]


# -- camera ---------------------------------------------------------------------------------------


def view_direction(axis, azimuth, elevation):
    """Unit vector from the subject towards the camera: ``azimuth`` degrees about +z from the
    horizontal part of ``axis`` (+x if it has none), ``elevation`` degrees above the ground."""
    import numpy as np

    az, el = math.radians(azimuth), math.radians(elevation)
    a = np.asarray(axis, float).copy()
    a[2] = 0.0
    if np.linalg.norm(a) < 1e-9:
        a = np.array([1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.array([-a[1], a[0], 0.0])  # a rotated by +90 degrees about z
    h = math.cos(az) * a + math.sin(az) * b
    return math.cos(el) * h + np.array([0.0, 0.0, math.sin(el)])


def frame_camera(bpy, points, v, aspect, lens=50.0, margin=1.04, recentre=True):
    """Perspective camera looking along ``-v`` whose frustum holds all ``points`` (n, 3); it is
    linked to the scene and made the scene camera, and returned.

    ``margin`` > 1 leaves room around the points (1.2: their extent fills 1/1.2 of the frame).
    The camera aims at the centre of the points' box in view space; ``recentre`` then moves it
    (three times) onto the centre of their projection, which the nearer points would otherwise
    push off centre."""
    import numpy as np
    from mathutils import Vector

    v = np.asarray(v, float) / np.linalg.norm(v)
    fwd = -v
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    pr, pu, pv = points @ right, points @ up, points @ v
    center = right * (pr.min() + pr.max()) / 2 + up * (pu.min() + pu.max()) / 2 + v * (pv.min() + pv.max()) / 2
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = lens
    cam_data.sensor_fit = "AUTO"  # the 36 mm sensor spans the larger image side
    tan_big = cam_data.sensor_width / 2 / lens
    tan_w = tan_big * min(1.0, aspect)
    tan_h = tan_big / max(1.0, aspect)
    # the nearer points subtend more: iterate on the distance, then re-centre on the projection
    dist = 0.0
    for _ in range(3 if recentre else 1):
        o = points - center
        ov = o @ v
        dist = float(max((np.abs(o @ right) * margin / tan_w + ov).max(),
                         (np.abs(o @ up) * margin / tan_h + ov).max()))
        if not recentre:
            break
        eye = center + v * dist
        rel = points - eye
        depth = -(rel @ v)
        sx, sy = (rel @ right) / depth, (rel @ up) / depth
        cx, cy = (sx.min() + sx.max()) / 2, (sy.min() + sy.max()) / 2
        center = center + (right * cx + up * cy) * dist
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = Vector(center + v * dist)
    cam.rotation_euler = Vector(fwd).to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_start = max(0.01, dist / 1000)
    cam_data.clip_end = dist * 10
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    return cam


# -- pictures -------------------------------------------------------------------------------------


def panel_size(width, height, n, layout):
    """(width, height) of each of ``n`` views in a ``width`` x ``height`` image, side by side
    (``side``) or stacked."""
    return (width // n, height) if layout == "side" else (width, height // n)


def render_views(bpy, png, n, max_kb, view=None, compose=None):
    """Render ``n`` stills, each after ``view(i)`` (if given) has set up the scene for it, into
    panel PNGs in a temporary folder beside ``png``; ``compose(panels, path)`` writes the picture
    from them (None: the one panel is the picture), which :func:`publish_png` caps at ``max_kb``
    and moves to ``png``. Returns the picture's absolute path and the seconds spent rendering."""
    out = os.path.abspath(png)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmpdir = tempfile.mkdtemp(prefix=".render-", dir=os.path.dirname(out))
    panels = [os.path.join(tmpdir, f"view{i}.png") for i in range(n)]
    tmp = os.path.join(tmpdir, "out.png")
    t_render = 0.0
    try:
        for i, path in enumerate(panels):
            if view is not None:
                view(i)
            bpy.context.scene.render.filepath = path
            t1 = time.perf_counter()
            bpy.ops.render.render(write_still=True)
            t_render += time.perf_counter() - t1
        if compose is not None:
            compose(panels, tmp)
        publish_png(panels[0] if compose is None else tmp, out, max_kb)
    finally:
        for p in panels + [tmp]:
            if os.path.exists(p):
                os.unlink(p)
        os.rmdir(tmpdir)
    return out, t_render


def shrink_png(path, max_kb):
    """Quantise the PNG at ``path`` in place (PIL: 256, then 128, then 64 colours) until it is
    at most ``max_kb`` KB; nothing if it already is, or if ``max_kb`` is 0."""
    if not max_kb or os.path.getsize(path) <= max_kb * 1024:
        return
    from PIL import Image

    for colors in (256, 128, 64):
        img = Image.open(path).convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT,
                                                      dither=Image.Dither.NONE)
        img.save(path, optimize=True)
        if os.path.getsize(path) <= max_kb * 1024:
            return


def label_font(size=15):
    """PIL's default font at ``size`` pixels (its bitmap font on Pillow < 10.1)."""
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def panel_origin(i, size, layout):
    """Top left corner of panel ``i`` of ``size`` (width, height) in a picture of ``layout``."""
    w, h = size
    return (i * w, 0) if layout == "side" else (0, i * h)


def paste_panels(paths, layout="side"):
    """The panel PNGs at ``paths`` (all one size) in one RGB image, side by side (``side``) or
    one above the other (``stacked``); returns the image and the panels' (width, height)."""
    from PIL import Image

    ims = [Image.open(p).convert("RGB") for p in paths]
    size = ims[0].size
    w, h = size
    img = Image.new("RGB", (len(ims) * w, h) if layout == "side" else (w, len(ims) * h))
    for i, im in enumerate(ims):
        img.paste(im, panel_origin(i, size, layout))
    return img, size


def caption_panels(img, size, layout, captions, font_size):
    """Draw ``captions`` in :data:`INK` at the top left of the panels of ``img`` (see
    :func:`paste_panels`); returns the ``ImageDraw`` and the font, for more."""
    from PIL import ImageDraw

    draw = ImageDraw.Draw(img)
    font = label_font(font_size)
    for i, cap in enumerate(captions):
        x0, y0 = panel_origin(i, size, layout)
        draw.text((x0 + 10, y0 + 8), cap, fill=INK, font=font)
    return draw, font


def publish_png(tmp, out, max_kb):
    """Cap ``tmp`` at ``max_kb`` KB (:func:`shrink_png`), give it the umask's permissions (a
    temporary file may have been made 0600) and move it to ``out`` in one step."""
    shrink_png(tmp, max_kb)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, out)
