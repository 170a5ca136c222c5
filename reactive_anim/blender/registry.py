"""Every class the add-on registers, in order, the menu entries and the watchers. Adding an operator = one line."""

from __future__ import annotations

import bpy

from . import operators
from .bake import bake, bake_ops, worker
from .character import role_map
from .impacts import impact_ops, impacts, marker_sync
from .ui import overlay, panels, settings

CLASSES = (
    impacts.REACTIVE_ANIM_PG_impact,
    bake.REACTIVE_ANIM_PG_bake_state,
    settings.REACTIVE_ANIM_PG_scene,
    role_map.REACTIVE_ANIM_PG_role,
    operators.REACTIVE_ANIM_OT_import_bvh,
    impact_ops.REACTIVE_ANIM_OT_add_impact,
    impact_ops.REACTIVE_ANIM_OT_aim_impact,
    impact_ops.REACTIVE_ANIM_OT_jump_to_impact,
    impact_ops.REACTIVE_ANIM_OT_remove_impact,
    bake_ops.REACTIVE_ANIM_OT_bake,
    bake_ops.REACTIVE_ANIM_OT_preview,
    bake_ops.REACTIVE_ANIM_OT_accept_preview,
    bake_ops.REACTIVE_ANIM_OT_discard_preview,
    bake_ops.REACTIVE_ANIM_OT_clear_bake,
    role_map.REACTIVE_ANIM_OT_detect_roles,
    role_map.REACTIVE_ANIM_OT_role_preset,
    role_map.REACTIVE_ANIM_OT_clear_roles,
    panels.REACTIVE_ANIM_UL_impacts,
    panels.REACTIVE_ANIM_MT_reactions,
    panels.REACTIVE_ANIM_PT_main,
    panels.REACTIVE_ANIM_PT_impacts,
    panels.REACTIVE_ANIM_PT_bake,
    panels.REACTIVE_ANIM_PT_roles,
)

# Property groups attached to Blender's own types: (type, attribute, group, property kind).
# Registered after CLASSES.
PROPERTIES = (
    (bpy.types.TimelineMarker, "reactive_anim", impacts.REACTIVE_ANIM_PG_impact, bpy.props.PointerProperty),
    (bpy.types.Object, "reactive_anim_bake", bake.REACTIVE_ANIM_PG_bake_state, bpy.props.PointerProperty),
    (bpy.types.Scene, "reactive_anim", settings.REACTIVE_ANIM_PG_scene, bpy.props.PointerProperty),
    (bpy.types.Armature, "reactive_anim_roles", role_map.REACTIVE_ANIM_PG_role, bpy.props.CollectionProperty),
)

# Blender's menus that get an entry: (menu, draw function).
MENUS = (
    (bpy.types.TOPBAR_MT_file_import, operators.draw_import_entry),
    (bpy.types.VIEW3D_MT_object, panels.draw_menu_entry),
    (bpy.types.VIEW3D_MT_pose, panels.draw_menu_entry),
)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for owner, attribute, group, kind in PROPERTIES:
        setattr(owner, attribute, kind(type=group))
    for menu, entry in MENUS:
        menu.append(entry)
    marker_sync.register()
    overlay.register()


def unregister() -> None:
    worker.cancel_running()  # its modal operator is freed without being cancelled
    overlay.unregister()
    marker_sync.unregister()
    for menu, entry in reversed(MENUS):
        menu.remove(entry)
    for owner, attribute, _group, _kind in reversed(PROPERTIES):
        delattr(owner, attribute)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
