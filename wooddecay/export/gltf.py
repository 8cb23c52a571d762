"""One baked frame as binary glTF 2.0 (docs/architecture.md "glTF"; woodstock §8.3, exported meshlets).

``export_gltf(path, model, mesh, frame)`` writes a ``.glb`` of one
:class:`wooddecay.sim.driver.Frame` (the CLI passes the last by default):

* one node per connected piece (``frame.mech["component"]`` of the face's element; one piece
  without mechanics), each node a mesh of one triangle primitive, node ``translation`` = the
  centre of the piece's bounding box (vertex positions are relative to it, so each piece imports
  as an object with its origin at its centre), node ``extras.piece`` = the component id;
* the faces the USD stage shows at this frame (:func:`wooddecay.meshlets.visibility.visible_faces`
  given this frame), skinned the same way (:func:`wooddecay.meshlets.skin.frame_arrays`);
* vertex attributes ``POSITION``, ``NORMAL``, ``COLOR_0`` (the rot preview colour of
  :func:`wooddecay.export.colors.rot_color`, so a plain glTF viewer shows the rot, as ``displayColor``
  does in USD) and the application-specific ``_H_c``, ``_H_l``, ``_M`` (FLOAT SCALAR), ``_WOOD``
  (VEC3, rest wood-local r, phi, s), ``_RING`` (ring age) and ``_FACE_KIND`` (0 bark, 1 side,
  2 cap, as a float: glTF has no per-face attributes, but every vertex here belongs to faces of
  one kind, see below), ``_BARK_CRACK`` and ``_BARK_DEPTH`` (the bark's cracks,
  :mod:`wooddecay.export.bark_surface`; its grooves are in ``POSITION``);
* normals: a meshlet vertex is split into one copy per facet group it touches (face kind and
  neighbour element: the bark, each side wall, each cap), and each copy gets the area-weighted
  normal of its group's faces. Walls stay sharp, curved bark stays smooth, and the vertex count
  stays ~1/6 of flat (3 vertices per triangle) normals;
* glTF is Y up: points and normals are turned from the model's Z up by (x, y, z) -> (x, z, -y),
  which Blender's glTF importer turns back;
* one ``pbrMetallicRoughness`` material (white base colour times ``COLOR_0``, roughness 0.8);
  ``asset.extras``: wooddecay version, scene name, seed, scene hash, frame index, day and the
  scene's description.

Plain numpy + struct + json (the container is small; see docs/decisions.md, "glTF"). Written
atomically: a hidden temporary file in the target folder, then ``os.replace``.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from ..wood import WoodModel
from ..atomic import check_output, write_bytes
from . import bark_surface as surface
from ..meshlets import skin as skin_mod
from ..meshlets.visibility import visible_faces
from ..sim.state import FIELDS
from .colors import rot_color
from .tracks import piece_max, rigid_fit

SUFFIXES = (".glb",)
GLB_MAGIC, GLB_VERSION = 0x46546C67, 2  # b"glTF"
CHUNK_JSON, CHUNK_BIN = 0x4E4F534A, 0x004E4942  # b"JSON", b"BIN\0"
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
TRIANGLES = 4
#: glTF (Y up) from the model's Z up: (x, y, z) -> (x, z, -y)
Z_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def check_glb_path(path) -> Path:
    """``path`` as a Path after checking its suffix and that its folder exists."""
    return check_output(path, SUFFIXES, "glTF (binary .glb)")


def split_vertices(faces, face_kind, face_neighbour):
    """Split every vertex into one copy per facet group (face kind, neighbour) using it.

    Returns (source vertex of each copy (U,), faces over the copies (F, 3), group of each copy's
    faces: kind (U,))."""
    g_nb = face_neighbour.astype(np.int64) + 1
    n_groups = int(g_nb.max(initial=0)) + 1
    group = face_kind.astype(np.int64) * n_groups + g_nb
    n_all = 3 * n_groups
    keys = faces.astype(np.int64) * n_all + group[:, None]
    uniq, inv = np.unique(keys.ravel(), return_inverse=True)
    return uniq // n_all, inv.reshape(-1, 3), (uniq % n_all) // n_groups


def vertex_normals(points, faces, n_vertices):
    """Unit area-weighted vertex normals; a vertex whose faces have no area gets +Y."""
    a, b, c = (points[faces[:, k]] for k in range(3))
    fn = np.cross(b - a, c - a)  # |fn| = 2 area
    acc = np.stack([np.bincount(faces.ravel(), weights=np.repeat(fn[:, k], 3), minlength=n_vertices)
                    for k in range(3)], axis=1)
    length = np.linalg.norm(acc, axis=1)
    bad = ~(length > 1e-30)
    acc[bad] = (0.0, 1.0, 0.0)
    length[bad] = 1.0
    return acc / length[:, None]


class _Bin:
    """The binary chunk: one bufferView (4-byte aligned) and one accessor per array."""

    def __init__(self):
        self.parts, self.size = [], 0
        self.views, self.accessors = [], []

    def add(self, array, kind: str, target: int | None, minmax: bool = False) -> int:
        """An accessor of ``array`` in a view of its own (``target`` None: animation data)."""
        array = np.ascontiguousarray(array)
        ctype = {np.dtype(np.float32): FLOAT, np.dtype(np.uint16): UNSIGNED_SHORT,
                 np.dtype(np.uint32): UNSIGNED_INT}[array.dtype]
        data = array.astype(array.dtype.newbyteorder("<"), copy=False).tobytes()
        view = {"buffer": 0, "byteOffset": self.size, "byteLength": len(data)}
        self.views.append(view if target is None else view | {"target": target})
        pad = (-len(data)) % 4
        self.parts.append(data + b"\0" * pad)
        self.size += len(data) + pad
        acc = {"bufferView": len(self.views) - 1, "componentType": ctype, "count": int(len(array)),
               "type": kind}
        if minmax:
            flat = array.reshape(len(array), -1)
            acc["min"] = [float(v) for v in flat.min(axis=0)]
            acc["max"] = [float(v) for v in flat.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def bytes(self) -> bytes:
        return b"".join(self.parts)


def glb_bytes(doc: dict, binary: bytes) -> bytes:
    """The GLB container: 12-byte header, JSON chunk (space padded), BIN chunk (zero padded)."""
    js = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    js += b" " * ((-len(js)) % 4)
    binary += b"\0" * ((-len(binary)) % 4)
    total = 12 + 8 + len(js) + (8 + len(binary) if binary else 0)
    out = [struct.pack("<III", GLB_MAGIC, GLB_VERSION, total), struct.pack("<II", len(js), CHUNK_JSON), js]
    if binary:
        out += [struct.pack("<II", len(binary), CHUNK_BIN), binary]
    return b"".join(out)


def _motion(model: WoodModel, mesh, link, frames, src, vorder, vstart, local):
    """Per frame of ``frames`` and per piece, the rotation (K, 4) quaternion (x, y, z, w) and the
    translation (K, 3) (Y up) that carry the piece's mesh ``local`` (its vertices ``src[vorder]``
    less its node translation, in runs ``vstart``) closest to its skinned points at that frame
    (:func:`wooddecay.export.tracks.rigid_fit`)."""
    from scipy.spatial.transform import Rotation

    quats: list[np.ndarray] = []
    moves: list[np.ndarray] = []
    for fr in frames:
        _, _, offset = surface.frame_bark(model, mesh, fr)
        P, _ = skin_mod.frame_arrays(model, mesh, link, fr, offset)
        R, c, _ = rigid_fit(local, P[src[vorder]] @ Z_TO_Y_UP.T, vstart)
        q = Rotation.from_matrix(R).as_quat()
        if quats:  # the shorter way round from the frame before
            q *= np.where(np.einsum("ki,ki->k", q, quats[-1]) < 0, -1.0, 1.0)[:, None]
        quats.append(q)
        moves.append(c)
    return np.stack(quats), np.stack(moves)


def gltf_document(model: WoodModel, mesh, frame, version: str = "", link=None, frames=(),
                  point_tolerance: float = 0.0) -> tuple[dict, bytes]:
    """The glTF JSON document and its binary buffer for ``frame`` (module docstring), animated over
    ``frames`` when given (pieces whose pose moves a point by more than ``point_tolerance``)."""
    if link is None:
        link = skin_mod.links(model, mesh)
    mech = frame.mech or None
    keep = np.flatnonzero(visible_faces(model, mesh, frame))
    crack, depth, offset = surface.frame_bark(model, mesh, frame)
    P, F = skin_mod.frame_arrays(model, mesh, link, frame, offset)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(F))):
        raise ValueError(f"frame {frame.index}: non-finite points or fields, nothing to export")
    component = mech["component"] if mech else np.zeros(model.n_elements, dtype=np.int64)

    src, faces, kind = split_vertices(mesh.faces[keep], mesh.face_kind[keep], mesh.face_neighbour[keep])
    points = P[src] @ Z_TO_Y_UP.T
    normals = vertex_normals(points, faces, len(src))
    ix = {f: k for k, f in enumerate(FIELDS)}
    fields = F[src]
    vpiece = component[mesh.vertex_element[src]]
    fpiece = vpiece[faces[:, 0]]

    # contiguous vertex and face ranges per piece
    vorder = np.argsort(vpiece, kind="stable")
    rank = np.empty_like(vorder)
    rank[vorder] = np.arange(len(vorder))
    faces = rank[faces]
    forder = np.argsort(fpiece, kind="stable")
    faces, fpiece = faces[forder], fpiece[forder]
    pieces, vstart = np.unique(vpiece[vorder], return_index=True)
    vstart = np.append(vstart, len(vorder))
    fstart = np.append(np.searchsorted(fpiece, pieces), len(fpiece))

    f32 = np.float32
    cols = {
        "_H_c": fields[:, ix["H_c"]], "_H_l": fields[:, ix["H_l"]], "_M": fields[:, ix["M"]],
        "_WOOD": mesh.wood[src], "_RING": mesh.ring[src], "_FACE_KIND": kind,
        "_BARK_CRACK": crack[src], "_BARK_DEPTH": depth[src],
    }
    color = rot_color(fields[:, ix["H_c"]], fields[:, ix["H_l"]], fields[:, ix["M"]])
    buf = _Bin()
    nodes, meshes = [], []
    name = str(model.info.name) or "scene"
    for k, piece in enumerate(pieces.tolist()):
        vs = vorder[vstart[k]:vstart[k + 1]]
        tri = faces[fstart[k]:fstart[k + 1]] - vstart[k]
        lo, hi = points[vs].min(axis=0), points[vs].max(axis=0)
        centre = 0.5 * (lo + hi)
        attrs = {
            "POSITION": buf.add((points[vs] - centre).astype(f32), "VEC3", ARRAY_BUFFER, minmax=True),
            "NORMAL": buf.add(normals[vs].astype(f32), "VEC3", ARRAY_BUFFER),
            "COLOR_0": buf.add(color[vs].astype(f32), "VEC3", ARRAY_BUFFER),
        }
        for attr, values in cols.items():
            values = values[vs]
            attrs[attr] = buf.add(values.astype(f32), "VEC3" if values.ndim == 2 else "SCALAR", ARRAY_BUFFER)
        itype = np.uint16 if len(vs) <= 0xFFFF else np.uint32  # 0xFFFF is the restart value
        indices = buf.add(tri.astype(itype).ravel(), "SCALAR", ELEMENT_ARRAY_BUFFER)
        meshes.append({"name": f"{name}_piece_{piece}", "primitives": [
            {"attributes": attrs, "indices": indices, "mode": TRIANGLES, "material": 0}]})
        nodes.append({"name": f"{name}_piece_{piece}", "mesh": k,
                      "translation": [float(v) for v in centre], "extras": {"piece": int(piece)}})

    animation = None
    if len(frames) > 1 and nodes:
        centre = np.array([n["translation"] for n in nodes])
        piece_of = np.repeat(np.arange(len(nodes)), np.diff(vstart))
        local = points[vorder] - centre[piece_of]
        quat, move = _motion(model, mesh, link, frames, src, vorder, vstart, local)
        reach = piece_max(np.linalg.norm(local, axis=1), vstart)
        angle = 2.0 * np.arccos(np.clip(np.abs(quat[..., 3]), 0.0, 1.0))
        moving = np.flatnonzero((np.linalg.norm(move - centre, axis=2) + angle * reach).max(0) > point_tolerance)
        if len(moving):
            times = np.array([f.index for f in frames], dtype=np.float32) / np.float32(model.time.fps)
            t_in = buf.add(times, "SCALAR", None, minmax=True)
            samplers, channels = [], []
            for k in moving.tolist():
                for path, values, kind in (("translation", move[:, k], "VEC3"), ("rotation", quat[:, k], "VEC4")):
                    out = buf.add(values.astype(f32), kind, None)
                    samplers.append({"input": t_in, "output": out, "interpolation": "LINEAR"})
                    channels.append({"sampler": len(samplers) - 1, "target": {"node": k, "path": path}})
            animation = {"name": f"{name}_pieces", "samplers": samplers, "channels": channels}

    binary = buf.bytes()
    doc = {
        "asset": {"version": "2.0", "generator": "wooddecay",
                  "extras": {"wooddecay_version": version, "scene": name, "seed": int(model.info.seed),
                             "scene_hash": model.info.hash, "frame": int(frame.index),
                             "t_days": float(frame.t_days), "description": model.info.description}},
        "scene": 0,
        "scenes": [{"name": name, "nodes": list(range(len(nodes)))} if nodes else {"name": name}],
        "materials": [{"name": "Wood", "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}}],
    }
    if nodes:
        doc.update(nodes=nodes, meshes=meshes, accessors=buf.accessors, bufferViews=buf.views,
                   buffers=[{"byteLength": len(binary)}])
    if animation:
        doc["animations"] = [animation]
    return doc, binary


def export_gltf(path, model, mesh, frame, version: str = "", link=None, frames=(),
                point_tolerance: float = 0.0) -> Path:
    """Write ``frame`` (a :class:`wooddecay.sim.driver.Frame`) as a binary glTF to ``path``
    (.glb), its pieces animated over ``frames`` (module docstring); ``link`` (from
    :func:`wooddecay.meshlets.skin.links`) may be passed to reuse it."""
    path = check_glb_path(path)
    doc, binary = gltf_document(model, mesh, frame, version=version, link=link, frames=frames,
                                point_tolerance=point_tolerance)
    return write_bytes(path, glb_bytes(doc, binary), "glTF")
