"""Operators. Each names its targets in properties, so it runs the same from a button, a script or headless."""

# Blender declares operator properties as annotations holding calls (`unit: EnumProperty(...)`),
# which are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

from typing import TYPE_CHECKING

import bpy
from bpy.props import EnumProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from ..core.model.errors import ReactiveAnimError
from .character import bvh_import

if TYPE_CHECKING:
    from bpy._typing.rna_enums import OperatorReturnItems  # fake-bpy-module's name for the result set

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
    armature_name: StringProperty(
        name="Armature Name", description="Name for the new armature (default: the file's name)", options={"SKIP_SAVE"}
    )

    if TYPE_CHECKING:
        filepath: str  # ImportHelper's property (the bpy type stubs leave it out)

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        try:
            armature = bvh_import.import_bvh(
                context, self.filepath, unit=self.unit, up=self.up_axis, name=self.armature_name
            )
        except ReactiveAnimError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        data, action = armature.data, armature.animation_data.action
        assert isinstance(data, bpy.types.Armature) and action is not None  # import_bvh made both
        self.report({"INFO"}, f"Imported '{armature.name}' with action '{action.name}' ({len(data.bones)} bones)")
        return {"FINISHED"}


def draw_import_entry(self: bpy.types.Menu, context: bpy.types.Context) -> None:
    """File > Import > Mocap for Reactions (.bvh)."""
    self.layout.operator(REACTIVE_ANIM_OT_import_bvh.bl_idname, text="Mocap for Reactions (.bvh)")
