"""Sidebar UI (3D View > N panel > Reactions)."""

from __future__ import annotations

import bpy

from . import operators


class REACTIVE_ANIM_PT_main(bpy.types.Panel):
    bl_idname = "REACTIVE_ANIM_PT_main"
    bl_label = "Reactions"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Reactions"

    def draw(self, context: bpy.types.Context) -> None:
        col = self.layout.column(align=True)
        col.operator(operators.REACTIVE_ANIM_OT_import_bvh.bl_idname, icon="IMPORT")
