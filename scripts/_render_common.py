"""Helpers shared by the ``bpy`` render scripts (render_meshlets.py, render_bake.py, render_strands.py).

Camera fitting on a 3/4 view, world positions of an evaluated mesh and PNG size capping. Nothing
here imports ``bpy`` at module level (the scripts pass it in), nor wooddecay or usd-core's ``pxr``.

The scripts import this file by name: ``python scripts/X.py`` puts ``scripts/`` first on
``sys.path``; under ``blender -b -P scripts/X.py`` each script adds its own folder first.
"""
from __future__ import annotations

import math
import os


def evaluated_positions(bpy, ob, max_points=200_000):
    """World positions (n, 3) of ``ob``'s evaluated mesh (after its modifiers), thinned to at
    most about ``max_points``."""
    import numpy as np

    ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    d = ev.data
    pos = np.empty(len(d.vertices) * 3, np.float32)
    d.vertices.foreach_get("co", pos)
    pos = pos.reshape(-1, 3).astype(np.float64)
    if len(pos) > max_points:
        pos = pos[:: len(pos) // max_points + 1]
    m = np.array(ob.matrix_world)
    return pos @ m[:3, :3].T + m[:3, 3]


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


def frame_camera(bpy, points, v, aspect, lens=50.0, margin=1.04):
    """Perspective camera looking along ``-v`` whose frustum holds all ``points`` (n, 3); it is
    linked to the scene and made the scene camera, and returned.

    ``margin`` > 1 leaves room around the points (1.2: their extent fills 1/1.2 of the frame)."""
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
    for _ in range(3):
        o = points - center
        ov = o @ v
        dist = float(max((np.abs(o @ right) * margin / tan_w + ov).max(),
                         (np.abs(o @ up) * margin / tan_h + ov).max()))
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


def paste_panels(paths, layout="side"):
    """The panel PNGs at ``paths`` (all one size) in one RGB image, side by side (``side``) or
    one above the other (``stacked``); returns the image and the panels' (width, height)."""
    from PIL import Image

    ims = [Image.open(p).convert("RGB") for p in paths]
    w, h = ims[0].size
    n = len(ims)
    img = Image.new("RGB", (n * w, h) if layout == "side" else (w, n * h))
    for i, im in enumerate(ims):
        img.paste(im, (i * w, 0) if layout == "side" else (0, i * h))
    return img, (w, h)


def publish_png(tmp, out, max_kb):
    """Cap ``tmp`` at ``max_kb`` KB (:func:`shrink_png`), give it the umask's permissions (a
    temporary file may have been made 0600) and move it to ``out`` in one step."""
    shrink_png(tmp, max_kb)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, out)
