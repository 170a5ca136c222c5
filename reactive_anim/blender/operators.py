"""Operators. Each names its targets in properties, so it runs the same from a button, a script or headless."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from ..core.errors import ReactiveAnimError
from . import bvh_import

UNIT_ITEMS = (
    ("auto", "Automatic", "Guess from the skeleton's size (centimetres, inches, metres, CMU units)"),
    ("m", "Metres", ""),
    ("cm", "Centimetres", ""),
    ("mm", "Millimetres", ""),
    ("in", "Inches", ""),
    ("cmu", "CMU units", "The CMU database's unit, 1/0.45 inch"),
)


class REACTIVE_ANIM_OT_import_bvh(bpy.types.Operator, ImportHelper):
    """Import a BVH motion capture file as a character ready for reactions"""

    bl_idname = "reactive_anim.import_bvh"
    bl_label = "Import Mocap (BVH)"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".bvh"
    filter_glob: StringProperty(default="*.bvh", options={"HIDDEN"})
    unit: EnumProperty(name="Units", items=UNIT_ITEMS, default="auto")
    up_axis: EnumProperty(
        name="Up Axis",
        items=(("Y", "Y up", "Most BVH files"), ("Z", "Z up", "Files exported Z up")),
        default="Y",
    )
    armature_name: StringProperty(name="Armature Name", description="Name for the new armature (default: the file's name)")

    def execute(self, context):
        try:
            armature = bvh_import.import_bvh(
                context, self.filepath, unit=self.unit, up=self.up_axis, name=self.armature_name
            )
        except ReactiveAnimError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        action = armature.animation_data.action
        self.report({"INFO"}, f"Imported '{armature.name}' with action '{action.name}' ({len(armature.data.bones)} bones)")
        return {"FINISHED"}
