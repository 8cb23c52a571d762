"""The crack map: the bark's cracks at texel resolution for the shader (woodification §5), one
tile per frame.

The meshlets' bark vertices lie a strand diameter apart around the wood and up to a rod element
apart along it, so per-vertex crack values (:mod:`.surface`) blur a crack a few millimetres wide
into a smudge. The crack map samples the cracks every ``h / TEXELS_PER_EDGE`` of the bark instead:
an atlas with one band of rows per branch (row = s, column = phi; every band spans the full width,
so phi wraps around the branch), each texel the V-profile 1 - d / w of the nearest crack open at
that frame (d the distance to its centre line, w its width there,
:func:`wooddecay.bark.cracks.widths` of the frame's cracks): above 1/2 inside the crack, as
``bark_crack`` is (the shader draws the crack floor from there), 0 off every crack.

Frame k's atlas is UDIM tile 1001 + k (``<stem>_bark.<UDIM>.png``; the shader reads tile k at
frame k), so a frame shows the cracks and widths of that frame alone, whatever the bake's length:
a crack's ends taper while it grows and a crack that opens later does not hide an earlier one
nearby. UDIM numbers :data:`MAX_TILES` tiles; a bake of more frames keeps the first
``MAX_TILES - 1`` and its last in the last tile.

``bark_uv`` gives every face corner its (u, v) in the atlas: u = phi / (2 pi), unwrapped from the
face's first corner so a face across phi = +-pi does not stretch over the whole width, and v the
texel row of its s in its branch's band.
"""
from __future__ import annotations

import numba
import numpy as np

from ..wood import WoodModel
from ..bark.cracks import widths
from ..bark.sheet import branch_trees
from .bark_surface import crack_samples

#: texels per sheet edge length
TEXELS_PER_EDGE = 4
#: UDIM tiles 1001-2000
MAX_TILES = 1000
#: UDIM number of frame 0's tile
FIRST_TILE = 1001


def file_name(stem: str, tile: int | None = None) -> str:
    """The crack map's file beside ``<stem>.usdc``: tile ``tile`` (frame ``tile``'s), or with
    ``tile`` None the UDIM pattern (``<stem>_bark.<UDIM>.png``, as USD and Blender name a set)."""
    return f"{stem}_bark.{'<UDIM>' if tile is None else FIRST_TILE + tile}.png"


def tile_number(name: str, stem: str) -> int | None:
    """The UDIM number of the file ``name`` if it is a tile of ``<stem>``'s crack map
    (:func:`file_name`), else None."""
    prefix = f"{stem}_bark."
    middle = name[len(prefix):-4] if name.startswith(prefix) and name.endswith(".png") else ""
    return int(middle) if middle.isdigit() else None


def _branch_rows(sheet, texel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per branch its lowest s, first row and number of rows in the atlas (0 without a sheet)."""
    nb = len(sheet.period)
    s0, count = np.zeros(nb), np.zeros(nb, dtype=np.int64)
    for b in range(nb):
        on = sheet.vertex_branch == b
        if on.any():
            s0[b] = sheet.s[on].min()
            count[b] = int(np.ceil((sheet.s[on].max() - s0[b]) / texel)) + 1
    return s0, np.concatenate([[0], np.cumsum(count)[:-1]]), count


def crack_maps(model: WoodModel, frames) -> list[np.ndarray] | None:
    """Per frame of ``frames`` (at most :data:`MAX_TILES`: module docstring) the (H, W) uint16
    crack map (the V-profile x 65535); None without a bark sheet or without the frames' cracks."""
    sheet = model.bark
    if sheet is None:
        return None
    cracked = [fr.bark.get("cracked") for fr in frames]
    if any(c is None for c in cracked):
        return None
    if len(cracked) > MAX_TILES:
        cracked = cracked[:MAX_TILES - 1] + cracked[-1:]
    texel = sheet.h / TEXELS_PER_EDGE
    rows = _branch_rows(sheet, texel)
    tiles, last = [], None
    for c in cracked:
        if last is None or not np.array_equal(c, last[0]):
            last = (c, _profile(model, c, texel, rows))
        tiles.append(last[1])
    return tiles


def _profile(model: WoodModel, cracked: np.ndarray, texel: float, rows) -> np.ndarray:
    """(H, W) uint16 V-profile of the nearest of the cracked sheet edges ``cracked`` per texel
    (``rows``: :func:`_branch_rows`)."""
    sheet, setup = model.bark, model.bark_setup
    assert sheet is not None and setup is not None  # the texture is made only with a sheet
    s0, first, count = rows
    H, W = int(count.sum()), int(np.ceil(sheet.period.max() / texel))
    out = np.zeros((H, W), dtype=np.uint16)
    if not cracked.any():
        return out
    w_v = widths(sheet, cracked, float(setup.crack_width))
    pts, br, w = crack_samples(sheet, cracked, w_v)
    for b, (tree, rows, y0) in branch_trees(sheet.period, br, pts).items():
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
        out[first[b]:first[b] + nrow] = np.round(g * 65535.0).astype(np.uint16).reshape(nrow, W)
    return out


def bark_uv(model: WoodModel, mesh, faces: np.ndarray) -> np.ndarray:
    """(len(faces) * 3, 2) atlas coordinates of every corner of ``faces`` (module docstring;
    (0, 0) where the model has no bark sheet)."""
    sheet = model.bark
    if sheet is None:
        return np.zeros((3 * len(faces), 2))
    texel = sheet.h / TEXELS_PER_EDGE
    s0, first, count = _branch_rows(sheet, texel)
    H = int(count.sum())
    corner = faces.ravel()
    b = model.branch[mesh.vertex_element[corner]]
    u = (mesh.wood[corner, 1] / (2 * np.pi)).reshape(-1, 3)
    u[:, 1:] = u[:, :1] + (u[:, 1:] - u[:, :1] + 0.5) % 1.0 - 0.5
    v = (first[b] + (mesh.wood[corner, 2] - s0[b]) / texel + 0.5) / max(H, 1)
    return np.stack([u.ravel(), 1.0 - v], 1)
