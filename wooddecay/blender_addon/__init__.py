"""Wood Decay: import wooddecay bakes into Blender with a fungal decay material.

A Blender 4.2+ extension (docs/architecture.md "Blender add-on"). File > Import > Wood Decay
(.usd/.usda/.usdc/.glb) imports a bake through Blender's own USD or glTF importer, renames the
glTF attributes to the USD primvar names and gives the meshes the "Wood Decay" material, whose
controls sit on one "Wood Decay" group node. Scripts can call the operator directly::

    bpy.ops.import_scene.wooddecay(filepath="bake/log/log.usdc")

Modules: :mod:`.importer` and :mod:`.shader` are plain Python (file formats, attribute names,
the material graph as data); :mod:`.blender_import` and :mod:`.material` do the Blender work;
this file holds the operator and the menu entry.
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import blender_import, importer

__all__ = ["IMPORT_SCENE_OT_wooddecay", "register", "unregister"]


class IMPORT_SCENE_OT_wooddecay(bpy.types.Operator, ImportHelper):
    """Import a wooddecay bake (USD or binary glTF) with the Wood Decay material"""

    bl_idname = "import_scene.wooddecay"
    bl_label = "Import Wood Decay"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default=importer.FILTER_GLOB, options={"HIDDEN"})
    assign_material: BoolProperty(
        name="Wood Decay Material",
        description="Give the imported meshes the Wood Decay material (else keep the file's preview material)",
        default=True,
    )

    def execute(self, context):
        try:
            report = blender_import.import_bake(self.filepath, assign_material=self.assign_material)
        except (ValueError, RuntimeError, OSError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        if not report["objects"]:
            self.report({"WARNING"}, f"{self.filepath}: no meshes imported")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Imported {len(report['objects'])} wood mesh(es) from {report['format'].upper()}"
                              + (f" with material {report['material']}" if report["material"] else ""))
        return {"FINISHED"}


def menu_func_import(self, context):
    self.layout.operator(IMPORT_SCENE_OT_wooddecay.bl_idname, text="Wood Decay (.usd/.usda/.usdc/.glb)")


def register():
    bpy.utils.register_class(IMPORT_SCENE_OT_wooddecay)
    bpy.types.TOPBAR_MT_file_import.append(menu_func_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_func_import)
    bpy.utils.unregister_class(IMPORT_SCENE_OT_wooddecay)
