"""Every class the add-on registers, in order, and the menu entries. Adding an operator = one line."""

from __future__ import annotations

import bpy

from . import bake, impacts, operators, panels

CLASSES = (
    impacts.REACTIVE_ANIM_PG_impact,
    bake.REACTIVE_ANIM_PG_bake_state,
    operators.REACTIVE_ANIM_OT_import_bvh,
    impacts.REACTIVE_ANIM_OT_add_impact,
    bake.REACTIVE_ANIM_OT_bake,
    bake.REACTIVE_ANIM_OT_clear_bake,
    panels.REACTIVE_ANIM_PT_main,
)

# Property groups attached to Blender's own types: (type, attribute, group). Registered after CLASSES.
PROPERTIES = (
    (bpy.types.TimelineMarker, "reactive_anim", impacts.REACTIVE_ANIM_PG_impact),
    (bpy.types.Object, "reactive_anim_bake", bake.REACTIVE_ANIM_PG_bake_state),
)


def _menu_import(self: bpy.types.Menu, context: bpy.types.Context) -> None:
    self.layout.operator(operators.REACTIVE_ANIM_OT_import_bvh.bl_idname, text="Mocap for Reactions (.bvh)")


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for owner, attribute, group in PROPERTIES:
        setattr(owner, attribute, bpy.props.PointerProperty(type=group))
    bpy.types.TOPBAR_MT_file_import.append(_menu_import)


def unregister() -> None:
    bpy.types.TOPBAR_MT_file_import.remove(_menu_import)
    for owner, attribute, _group in reversed(PROPERTIES):
        delattr(owner, attribute)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
