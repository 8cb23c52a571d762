"""What the meshlets' bark shows of the cracks: per-vertex crack primvars and grooves (docs/model.md §10).

A meshlet vertex on a bark face lies at (phi, s) of its branch (its rest ``wood`` coordinates), so
at flat coordinates of the sheet (:mod:`.sheet`). Its distance d to the nearest crack (the cracked
sheet edges, sampled every quarter edge) and that crack's width w there
(:func:`wooddecay.bark.cracks.widths`) give

* ``bark_crack`` = clip(1 - d / (w / 2 + r_s), 0, 1): 1 on the crack's centre line, 0 beyond its
  edge plus one strand radius (about the spacing of the meshlets' bark vertices, so that a crack
  between two vertices still shows; the shader draws the crack floor where it exceeds a level);
* ``bark_crack_depth`` = ``crack_depth`` w ``bark_crack``, at most the bark thickness: the
  V-shaped depth (woodification §5).

Grooves: where the crack is wider than ``groove_width`` the bark vertices move inwards by the
depth, along the mean normal of their bark faces (at most half the bark thickness, half r_s and
a quarter of the vertex's shortest edge, so no cell turns inside out and no face folds over). The offset is applied to the rest position before skinning, to every
copy of a shared vertex alike, so the meshlets stay closed and keep sharing their faces.
"""
from __future__ import annotations

from typing import cast

import numpy as np

from ..wood import BarkSetup, WoodModel
from ..meshlets.sweep import FACE_BARK
from ..bark.cracks import widths
from ..bark.sheet import branch_trees

#: crack samples per sheet edge
SAMPLES = 5


def bark_vertices(mesh) -> np.ndarray:
    """(V,) bool: the meshlet vertex is (a copy of) a vertex of a bark face."""
    shared = np.zeros(int(mesh.vertex_shared.max(initial=-1)) + 1, dtype=bool)
    shared[mesh.vertex_shared[mesh.faces[mesh.face_kind == FACE_BARK].ravel()]] = True
    return shared[mesh.vertex_shared]


def crack_samples(sheet, cracked: np.ndarray, w_v: np.ndarray):
    """Points along the cracked edges (flat coordinates), their branch and the width there."""
    ce = np.flatnonzero(cracked)
    t = np.linspace(0.0, 1.0, SAMPLES)
    a, b = sheet.edges[ce, 0], sheet.edges[ce, 1]
    br = sheet.vertex_branch[a]
    P = sheet.period[br]
    xa = (sheet.phi[a] % (2 * np.pi)) * P / (2 * np.pi)
    dphi = (sheet.phi[b] - sheet.phi[a] + np.pi) % (2 * np.pi) - np.pi
    x = xa[:, None] + t[None] * (dphi * P / (2 * np.pi))[:, None]
    y = sheet.s[a][:, None] + t[None] * (sheet.s[b] - sheet.s[a])[:, None]
    w = w_v[a][:, None] * (1 - t[None]) + w_v[b][:, None] * t[None]
    return np.stack([x.ravel(), y.ravel()], 1), np.repeat(br, SAMPLES), w.ravel()


def crack_fields(model: WoodModel, mesh, cracked: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(V,) ``bark_crack``, ``bark_crack_depth`` (m) and the crack width (m) at every meshlet
    vertex for the cracked sheet edges ``cracked`` (module docstring); zeros off the bark."""
    V = len(mesh.points)
    crack, depth, width = np.zeros(V), np.zeros(V), np.zeros(V)
    sheet, b = model.bark, model.bark_setup
    if sheet is None or not cracked.any():
        return crack, depth, width
    assert b is not None  # set together with the sheet
    w_v = widths(sheet, cracked, float(b.crack_width))
    pts, br, w = crack_samples(sheet, cracked, w_v)
    trees = branch_trees(sheet.period, br, pts)
    on = np.flatnonzero(bark_vertices(mesh))
    vb = model.branch[mesh.vertex_element[on]]
    P = sheet.period[vb]
    vxy = np.stack([(mesh.wood[on, 1] % (2 * np.pi)) * P / (2 * np.pi), mesh.wood[on, 2]], 1)
    for branch in np.unique(vb):
        if int(branch) not in trees:
            continue
        tree, rows, y0 = trees[int(branch)]
        sel = np.flatnonzero(vb == branch)
        q = np.stack([vxy[sel, 0] % sheet.period[branch], vxy[sel, 1] - y0], 1)
        d, k = tree.query(q)
        wk = w[rows[k]]
        c = np.clip(1.0 - d / (0.5 * wk + model.r_s), 0.0, 1.0)
        crack[on[sel]] = c
        width[on[sel]] = np.where(c > 0.0, wk, 0.0)
    depth = np.minimum(float(b.crack_depth) * width * crack, model.bark_thickness)
    return crack, depth, width


def groove_offsets(model: WoodModel, mesh, depth: np.ndarray, width: np.ndarray) -> np.ndarray:
    """(V, 3) rest-position offsets that cut the grooves (module docstring)."""
    out = np.zeros((len(mesh.points), 3))
    gw = float(cast(BarkSetup, model.bark_setup).groove_width) if model.bark is not None else 0.0
    cut = (width > gw) & (depth > 0.0) if gw > 0.0 else np.zeros(len(depth), dtype=bool)
    if not cut.any():
        return out
    F = mesh.faces[mesh.face_kind == FACE_BARK]
    P = mesh.points
    n = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])  # area-weighted, outward
    shared = mesh.vertex_shared
    acc = np.zeros((int(shared.max()) + 1, 3))
    for k in range(3):
        np.add.at(acc, shared[F[:, k]], n)
    normal = acc[shared]
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    # at most half the bark thickness and r_s, and a quarter of the shortest edge at the vertex,
    # so no face folds over
    E = mesh.faces.reshape(-1)
    nxt = np.roll(mesh.faces, -1, axis=1).reshape(-1)
    length = np.linalg.norm(P[nxt] - P[E], axis=1)
    shortest = np.full(len(acc), np.inf)
    np.minimum.at(shortest, shared[E], length)
    np.minimum.at(shortest, shared[nxt], length)
    cap = np.minimum(0.5 * min(model.bark_thickness, model.r_s), 0.25 * shortest[shared])
    out[cut] = -normal[cut] * np.minimum(depth[cut], cap[cut])[:, None]
    return out


def frame_bark(model: WoodModel, mesh, frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``bark_crack``, ``bark_crack_depth`` (V,) and the groove offsets (V, 3) of one
    :class:`~wooddecay.sim.driver.Frame` (zeros without a bark sheet)."""
    cracked = frame.bark.get("cracked")
    if cracked is None or model.bark is None:
        V = len(mesh.points)
        return np.zeros(V), np.zeros(V), np.zeros((V, 3))
    crack, depth, width = crack_fields(model, mesh, cracked)
    return crack, depth, groove_offsets(model, mesh, depth, width)
