"""The crack map: the bark's cracks at texel resolution for the shader (woodification §5).

The meshlets' bark vertices lie a strand diameter apart around the wood and up to a rod element
apart along it, so per-vertex crack values (:mod:`.surface`) blur a crack a few millimetres wide
into a smudge. The crack map samples the cracks every ``h / TEXELS_PER_EDGE`` of the bark instead:
an atlas with one tile of rows per branch (row = s, column = phi; every tile spans the full width,
so phi wraps with the texture's repeat), each texel

* R: the frame at which the nearest crack opened there (frame index / 65535; 1 where no crack
  is): the shader shows it from that frame on, so one image serves the whole animation;
* G: the V-profile 1 - d / w of that crack (d the distance to its centre line, w its width there,
  :func:`wooddecay.bark.cracks.widths` of the last frame): above 1/2 inside the crack, as
  ``bark_crack`` is (the shader draws the crack floor from there);
* B: 0 (reserved).

``bark_uv`` gives every face corner its (u, v) in the atlas: u = phi / (2 pi), unwrapped from the
face's first corner so a face across phi = +-pi does not stretch over the whole width, and v the
texel row of its s in its branch's tile.
"""
from __future__ import annotations

import numba
import numpy as np

from .cracks import widths
from .sheet import branch_trees
from .surface import SAMPLES, crack_samples

#: texels per sheet edge length
TEXELS_PER_EDGE = 4
NEVER = 65535


def _tiles(sheet, texel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per branch its lowest s, first row and number of rows in the atlas (0 without a sheet)."""
    nb = len(sheet.period)
    s0, count = np.zeros(nb), np.zeros(nb, dtype=np.int64)
    for b in range(nb):
        on = sheet.vertex_branch == b
        if on.any():
            s0[b] = sheet.s[on].min()
            count[b] = int(np.ceil((sheet.s[on].max() - s0[b]) / texel)) + 1
    return s0, np.concatenate([[0], np.cumsum(count)[:-1]]), count


def open_frames(frames) -> np.ndarray | None:
    """(E,) first frame index at which each sheet edge is cracked (NEVER if never)."""
    out = None
    for fr in frames:
        cracked = fr.bark.get("cracked")
        if cracked is None:
            return None
        if out is None:
            out = np.full(len(cracked), NEVER, dtype=np.int64)
        out[(out == NEVER) & cracked] = fr.index
    return out


def crack_map(model, frames) -> np.ndarray | None:
    """(H, W, 3) uint16 crack map of the bake's ``frames`` (module docstring); None without a
    bark sheet."""
    sheet = model.bark
    opened = open_frames(frames) if sheet is not None else None
    if opened is None:
        return None
    texel = sheet.h / TEXELS_PER_EDGE
    s0, first, count = _tiles(sheet, texel)
    H, W = int(count.sum()), int(np.ceil(sheet.period.max() / texel))
    out = np.zeros((H, W, 3), dtype=np.uint16)
    out[..., 0] = NEVER
    cracked = opened < NEVER
    if not cracked.any():
        return out
    w_v = widths(sheet, cracked, float(model.bark_setup["crack_width"]))
    pts, br, w = crack_samples(sheet, cracked, w_v)
    edge = np.repeat(np.flatnonzero(cracked), SAMPLES)
    trees = branch_trees(sheet.period, br, pts)
    for b, (tree, rows, y0) in trees.items():
        nrow = int(count[b])
        r, c = np.meshgrid(np.arange(nrow), np.arange(W), indexing="ij")
        P = sheet.period[b]
        q = np.stack([(c.ravel() + 0.5) / W * P, s0[b] + r.ravel() * texel - y0], 1)
        # a texel farther than the widest crack from every sample is 0 whichever is nearest
        d, k = tree.query(np.stack([q[:, 0] % P, np.clip(q[:, 1], 0.0, None)], 1),
                          distance_upper_bound=float(w[rows].max()), workers=numba.get_num_threads())
        near = k < len(rows)
        g = np.zeros(len(q))
        g[near] = np.clip(1.0 - d[near] / np.maximum(w[rows[k[near]]], 1e-12), 0.0, 1.0)
        tile = out[first[b]:first[b] + nrow].reshape(-1, 3)
        inside = g > 0.0
        tile[inside, 0] = opened[edge[rows[k[inside]]]]
        tile[:, 1] = np.round(g * NEVER).astype(np.uint16)
    return out


def bark_uv(model, mesh, faces: np.ndarray) -> np.ndarray:
    """(len(faces) * 3, 2) atlas coordinates of every corner of ``faces`` (module docstring;
    (0, 0) where the model has no bark sheet)."""
    sheet = model.bark
    if sheet is None:
        return np.zeros((3 * len(faces), 2))
    texel = sheet.h / TEXELS_PER_EDGE
    s0, first, count = _tiles(sheet, texel)
    H = int(count.sum())
    corner = faces.ravel()
    b = model.branch[mesh.vertex_element[corner]]
    u = (mesh.wood[corner, 1] / (2 * np.pi)).reshape(-1, 3)
    u[:, 1:] = u[:, :1] + (u[:, 1:] - u[:, :1] + 0.5) % 1.0 - 0.5
    v = (first[b] + (mesh.wood[corner, 2] - s0[b]) / texel + 0.5) / max(H, 1)
    return np.stack([u.ravel(), 1.0 - v], 1)
