"""Blender side of the importer: a wooddecay bake through Blender's own USD or glTF importer,
then the attributes renamed and the Wood Decay material assigned (docs/architecture.md "Blender add-on").

USD (``bpy.ops.wm.usd_import``): the mesh keeps the primvar names (H_c, H_l, M, R_w, R_b, C,
wood, ring, bark_crack, bark_crack_depth; faceKind, element, tissue, piece per face); points and
the time-sampled primvars play back through the MeshSequenceCache modifier Blender adds, and a
geometry-nodes modifier after it drops the faces a crack has not yet exposed (``exposedFrame``). glTF
(``bpy.ops.import_scene.gltf``): one object per piece with ``_H_c``, ``_H_l``, ``_M``, ``_WOOD``,
``_RING``, ``_FACE_KIND``, ``_BARK_CRACK``, ``_BARK_DEPTH``, renamed here to the USD names
(:data:`.importer.RENAMES`) so one material serves both.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import bpy

from . import importer, material
from .shader import DATA


def _new(collection, before):
    return [x for x in collection if x not in before]


def import_usd(filepath: str, own_material: bool) -> None:
    """Run Blender's USD importer (the scene's frame range set from the stage; its preview
    material skipped when the Wood Decay material replaces it)."""
    result = bpy.ops.wm.usd_import(filepath=filepath, set_frame_range=True, import_materials=not own_material)
    if "FINISHED" not in result:
        raise RuntimeError(f"Blender's USD importer could not read {filepath}")


def import_gltf(filepath: str) -> dict[str, list[str]]:
    """Run Blender's glTF importer; returns the vector attributes split by the importer
    workaround (:func:`.importer.prepare_glb`) so they can be joined back."""
    split = None
    with tempfile.TemporaryDirectory(prefix="wooddecay_") as tmp:
        fixed = os.path.join(tmp, Path(filepath).name)
        try:
            split = importer.prepare_glb(filepath, fixed)
        except (OSError, ValueError, KeyError):
            split = None  # let Blender's importer report what is wrong with the file
        result = bpy.ops.import_scene.gltf(filepath=fixed if split else filepath)
    if "FINISHED" not in result:
        raise RuntimeError(f"Blender's glTF importer could not read {filepath}")
    return split or {}


def join_vectors(mesh, split: dict[str, list[str]]) -> None:
    """Put split vector attributes back together (``_WOOD.0``.. -> ``wood``)."""
    import numpy as np

    for name, comps in importer.join_plan(split, [a.name for a in mesh.attributes]):
        if name in mesh.attributes:
            continue
        n = len(mesh.attributes[comps[0]].data)
        cols = []
        for c in comps:
            v = np.empty(n, dtype=np.float32)
            mesh.attributes[c].data.foreach_get("value", v)
            cols.append(v)
        domain = mesh.attributes[comps[0]].domain
        data_type = "FLOAT_VECTOR" if len(cols) == 3 else "FLOAT2" if len(cols) == 2 else "FLOAT_COLOR"
        target = mesh.attributes.new(name, data_type, domain)
        key = "color" if data_type == "FLOAT_COLOR" else "vector"
        target.data.foreach_set(key, np.stack(cols, axis=1).ravel())
        for c in comps:
            mesh.attributes.remove(mesh.attributes[c])


def rename_attributes(mesh) -> list[tuple[str, str]]:
    """glTF names -> USD names on ``mesh`` (see :func:`.importer.rename_plan`)."""
    plan = importer.rename_plan([a.name for a in mesh.attributes])
    for old, new in plan:
        mesh.attributes[old].name = new
    return plan


#: the geometry-nodes group that hides each face before its ``exposedFrame``, and its tag
EXPOSURE_GROUP = "Wood Decay Exposure"
EXPOSURE_TAG = "wooddecay_exposure"


def exposure_group():
    """The node group (made once per file; found by its tag): Delete Geometry of the faces (and
    their edges; the points stay, so the point count is that of the mesh cache at every frame)
    whose ``exposedFrame`` lies after the scene's frame, so a crack's faces show from the frame it
    opens and the normals at a frame are those of its own surface (the stage's time-sampled
    ``holeIndices``, which Blender's USD importer does not read). The scene's frame is the
    stage's time code, as the mesh cache reads it without a frame offset."""
    for tree in bpy.data.node_groups:
        if tree.bl_idname == "GeometryNodeTree" and tree.get(EXPOSURE_TAG) == 1:
            return tree
    group = bpy.data.node_groups.new(EXPOSURE_GROUP, "GeometryNodeTree")
    group[EXPOSURE_TAG] = 1
    group.is_modifier = True
    group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = group.nodes, group.links

    def node(kind, x, y):
        made = nodes.new(kind)
        made.location = (x, y)
        return made

    given, result = node("NodeGroupInput", -600, 0), node("NodeGroupOutput", 400, 0)
    shown = node("GeometryNodeInputNamedAttribute", -600, -200)
    shown.data_type = "FLOAT"
    shown.inputs["Name"].default_value = "exposedFrame"
    time = node("GeometryNodeInputSceneTime", -600, -400)
    half = node("ShaderNodeMath", -400, -400)
    half.operation = "ADD"
    half.inputs[1].default_value = 0.5
    later = node("FunctionNodeCompare", -200, -250)
    later.data_type, later.operation = "FLOAT", "GREATER_THAN"
    drop = node("GeometryNodeDeleteGeometry", 100, 0)
    drop.domain, drop.mode = "FACE", "EDGE_FACE"
    links.new(time.outputs["Frame"], half.inputs[0])
    links.new(shown.outputs["Attribute"], later.inputs["A"])
    links.new(half.outputs["Value"], later.inputs["B"])
    links.new(given.outputs["Geometry"], drop.inputs["Geometry"])
    links.new(later.outputs["Result"], drop.inputs["Selection"])
    links.new(drop.outputs["Geometry"], result.inputs["Geometry"])
    return group


def hide_unexposed(ob) -> None:
    """Add the :func:`exposure_group` modifier to ``ob`` (after its mesh cache) if its mesh has
    ``exposedFrame``."""
    if "exposedFrame" in ob.data.attributes:
        ob.modifiers.new(EXPOSURE_GROUP, "NODES").node_group = exposure_group()


def import_bake(filepath: str, assign_material: bool = True) -> dict:
    """Import ``filepath`` (.usd/.usda/.usdc/.glb) and dress it. Returns a report:
    ``objects`` (names of the imported meshes), ``format``, ``material`` (name or None),
    ``attributes`` (the attribute names the material reads)."""
    fmt = importer.file_format(filepath)
    objects_before, materials_before = set(bpy.data.objects), set(bpy.data.materials)
    split = {}
    if fmt == "usd":
        import_usd(filepath, assign_material)
    else:
        split = import_gltf(filepath)
    new_objects = _new(bpy.data.objects, objects_before)
    meshes = [ob for ob in new_objects if ob.type == "MESH"]
    for data in {ob.data for ob in meshes}:
        join_vectors(data, split)
        rename_attributes(data)
    names = set()
    for ob in meshes:
        names.update(a.name for a in ob.data.attributes)
        hide_unexposed(ob)
    report = {"format": fmt, "objects": [ob.name for ob in meshes], "material": None,
              "attributes": sorted(n for n in names if n in {s.attribute for s in DATA})}
    if assign_material and meshes:
        crack_map = os.path.splitext(filepath)[0] + f"_bark.{material.UDIM_FIRST}.png"
        names.update(uv.name for ob in meshes for uv in ob.data.uv_layers)
        mat = material.build_material(names, crack_map=crack_map if os.path.exists(crack_map) else None)
        for data in {ob.data for ob in meshes}:
            data.materials.clear()
            data.materials.append(mat)
        for old in _new(bpy.data.materials, materials_before):
            if old is not mat and old.users == 0:
                bpy.data.materials.remove(old)
        report["material"] = mat.name
    return report
