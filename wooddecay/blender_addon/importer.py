"""Format helpers of the Wood Decay importer, with no ``bpy`` (docs/architecture.md "Blender add-on").

The Blender side (:mod:`.blender_import`) imports a bake through Blender's own USD or glTF
importer; this module holds what does not need Blender, so it can be read and tested alone
(the split of glTF-Blender-IO: ``io/`` format code, ``blender/`` Blender code):

* :func:`file_format`: ``"usd"`` or ``"gltf"`` from the file name;
* :data:`RENAMES` and :func:`rename_plan`: the glTF custom attributes ``_H_c``, ``_H_l``,
  ``_M``, ``_WOOD``, ``_RING``, ``_FACE_KIND``, ``_BARK_CRACK``, ``_BARK_DEPTH`` become ``H_c``,
  ``H_l``, ``M``, ``wood``, ``ring``, ``faceKind``, ``bark_crack``, ``bark_crack_depth``, the
  names of the USD primvars, so one material serves both formats;
* :func:`split_custom_vectors`: a workaround for Blender's glTF importer (4.2 to 5.0), which
  fails with ``ValueError: all the input array dimensions ...`` when a primitive has custom
  attributes of different types (``_WOOD`` VEC3 beside the SCALAR ``_H_c``; it pairs the
  attributes with their buffers through a ``set``, KhronosGroup/glTF-Blender-IO#2658). The GLB
  is rewritten (JSON chunk only) so that each custom VECn attribute becomes n SCALAR attributes
  reading the same bytes through a strided buffer view; :func:`join_plan` says how to put them
  back together after the import.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

USD_SUFFIXES = (".usd", ".usda", ".usdc")
GLTF_SUFFIXES = (".glb",)
SUFFIXES = USD_SUFFIXES + GLTF_SUFFIXES
#: file browser filter of the import operator
FILTER_GLOB = ";".join(f"*{s}" for s in SUFFIXES)

#: glTF custom attribute -> USD primvar name (the attribute names the material reads)
RENAMES = {
    "_H_c": "H_c",
    "_H_l": "H_l",
    "_M": "M",
    "_WOOD": "wood",
    "_RING": "ring",
    "_FACE_KIND": "faceKind",
    "_BARK_CRACK": "bark_crack",
    "_BARK_DEPTH": "bark_crack_depth",
}
#: the decay fields every wooddecay mesh carries (vertex attributes in both formats)
FIELDS = ("H_c", "H_l", "M")
#: faceKind values (USD uniform int primvar; glTF ``_FACE_KIND`` as float)
BARK, SIDE, CAP = 0, 1, 2

GLB_MAGIC = 0x46546C67  # b"glTF"
CHUNK_JSON, CHUNK_BIN = 0x4E4F534A, 0x004E4942
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
#: separator between a split vector attribute's name and its component index
SPLIT_SEP = "."


def file_format(path) -> str:
    """``"usd"`` for .usd/.usda/.usdc, ``"gltf"`` for .glb; ValueError otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix in USD_SUFFIXES:
        return "usd"
    if suffix in GLTF_SUFFIXES:
        return "gltf"
    raise ValueError(f"{path}: not a wooddecay bake (expected one of {', '.join(SUFFIXES)})")


def rename_plan(names) -> list[tuple[str, str]]:
    """(old, new) pairs that turn the glTF attribute names among ``names`` into the USD ones;
    a pair is left out when ``new`` is already taken."""
    names = set(names)
    return [(old, new) for old, new in RENAMES.items() if old in names and new not in names]


def read_glb(data: bytes) -> tuple[dict, bytes]:
    """(JSON document, BIN chunk) of a binary glTF; ValueError when it is not one."""
    if len(data) < 20:
        raise ValueError("not a binary glTF (too short)")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != GLB_MAGIC or version != 2:
        raise ValueError("not a binary glTF 2.0 file")
    doc, binary, pos = None, b"", 12
    while pos + 8 <= min(length, len(data)):
        size, kind = struct.unpack_from("<II", data, pos)
        chunk = data[pos + 8:pos + 8 + size]
        if kind == CHUNK_JSON:
            doc = json.loads(chunk.decode("utf-8"))
        elif kind == CHUNK_BIN and not binary:
            binary = bytes(chunk)
        pos += 8 + size
    if doc is None:
        raise ValueError("binary glTF without a JSON chunk")
    return doc, binary


def write_glb(doc: dict, binary: bytes) -> bytes:
    """A binary glTF of ``doc`` and ``binary`` (chunks padded to 4 bytes)."""
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * (-len(js) % 4)
    out = [struct.pack("<II", len(js), CHUNK_JSON), js]
    if binary:
        binary = binary + b"\0" * (-len(binary) % 4)
        out += [struct.pack("<II", len(binary), CHUNK_BIN), binary]
    body = b"".join(out)
    return struct.pack("<III", GLB_MAGIC, 2, 12 + len(body)) + body


def _custom_types(doc: dict) -> list[set[str]]:
    """Accessor types of the custom attributes, per primitive."""
    acc = doc.get("accessors", [])
    return [{acc[i]["type"] for k, i in prim.get("attributes", {}).items() if k.startswith("_")}
            for mesh in doc.get("meshes", []) for prim in mesh.get("primitives", [])]


def needs_split(doc: dict) -> bool:
    """True when a primitive mixes custom attribute types (what trips Blender's importer)."""
    return any(len(types) > 1 for types in _custom_types(doc))


def split_custom_vectors(doc: dict) -> dict[str, list[str]]:
    """Rewrite ``doc`` in place: each custom VECn attribute ``_X`` of each primitive becomes
    SCALAR attributes ``_X.0`` ... ``_X.{n-1}`` over the same bytes (new accessors with a byte
    offset per component into a new buffer view with the vector's stride). Returns
    ``{"_X": ["_X.0", ...]}``. Sparse accessors and views that already have a stride other than
    the packed one are left alone."""
    acc, views = doc.get("accessors", []), doc.get("bufferViews", [])
    done: dict[int, list[int]] = {}  # vector accessor -> its component accessors
    split: dict[str, list[str]] = {}
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            attrs = prim.get("attributes", {})
            for name, ia in list(attrs.items()):
                a = acc[ia]
                n = COMPONENTS.get(a["type"], 0)
                if not name.startswith("_") or n < 2 or "sparse" in a or "bufferView" not in a:
                    continue
                size = COMPONENT_BYTES[a["componentType"]]
                view = views[a["bufferView"]]
                stride = view.get("byteStride", n * size)
                if stride != n * size and "byteStride" in view:
                    continue
                if ia not in done:
                    new_view = {k: v for k, v in view.items() if k != "target"} | {"byteStride": stride}
                    views.append(new_view)
                    iv = len(views) - 1
                    comps = []
                    for c in range(n):
                        comp = {"bufferView": iv, "byteOffset": a.get("byteOffset", 0) + c * size,
                                "componentType": a["componentType"], "count": a["count"], "type": "SCALAR"}
                        if "normalized" in a:
                            comp["normalized"] = a["normalized"]
                        if "min" in a and "max" in a:
                            comp["min"], comp["max"] = [a["min"][c]], [a["max"][c]]
                        acc.append(comp)
                        comps.append(len(acc) - 1)
                    done[ia] = comps
                del attrs[name]
                names = [f"{name}{SPLIT_SEP}{c}" for c in range(n)]
                attrs.update(zip(names, done[ia]))
                split[name] = names
    return split


def prepare_glb(src, dst) -> dict[str, list[str]] | None:
    """When ``src`` trips Blender's glTF importer (:func:`needs_split`), write a fixed copy to
    ``dst`` and return its split attributes; otherwise write nothing and return None. Files with
    external resources (a ``uri`` that is not a data URI) are left alone."""
    doc, binary = read_glb(Path(src).read_bytes())
    if not needs_split(doc):
        return None
    external = [x for key in ("buffers", "images") for x in doc.get(key, [])
                if "uri" in x and not str(x["uri"]).startswith("data:")]
    if external:
        return None
    split = split_custom_vectors(doc)
    Path(dst).write_bytes(write_glb(doc, binary))
    return split


def join_plan(split: dict[str, list[str]], names) -> list[tuple[str, list[str]]]:
    """(final name, component attribute names) for each split vector whose components are all
    among ``names``; the final name is the glTF name renamed by :data:`RENAMES`."""
    names = set(names)
    return [(RENAMES.get(vec, vec), comps) for vec, comps in split.items() if all(c in names for c in comps)]
