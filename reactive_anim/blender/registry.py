"""Every class the add-on registers, in order, and the menu entries. Adding an operator = one line."""

from __future__ import annotations

import bpy

from . import operators, panels

CLASSES = (
    operators.REACTIVE_ANIM_OT_import_bvh,
    panels.REACTIVE_ANIM_PT_main,
)


def _menu_import(self: bpy.types.Menu, context: bpy.types.Context) -> None:
    self.layout.operator(operators.REACTIVE_ANIM_OT_import_bvh.bl_idname, text="Mocap for Reactions (.bvh)")


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(_menu_import)


def unregister() -> None:
    bpy.types.TOPBAR_MT_file_import.remove(_menu_import)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
