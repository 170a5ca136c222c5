"""The animator's side: 3D View > Sidebar (N) > Reactions, and a Reactions menu (so every
operator is in F3 search too).

The panel: the character, the library and model, the scene's impacts as a list (a UIList over the
scene's timeline markers, showing the character's impact markers in frame order), the active
impact's fields to edit, then Bake / Preview / Accept / Discard / Clear and the last bake's
summary, or the progress of the bake being computed.
"""

from __future__ import annotations

import json
from typing import Any, cast

import bpy

from .. import operators
from ..bake import bake, bake_ops, preview, worker
from ..character import role_map
from ..impacts import impact_ops, impacts
from . import settings


def button(
    layout: bpy.types.UILayout,
    operator: type[bpy.types.Operator],
    text: str | None = None,
    icon: str = "NONE",
    emboss: bool = True,
    targets: dict[str, str] | None = None,
) -> None:
    """An operator button whose targets (armature name, marker uid) are set, so it acts on them and
    not on whatever is active when clicked."""
    label = operator.bl_label if text is None else text
    properties = layout.operator(operator.bl_idname, text=label, icon=cast(Any, icon), emboss=emboss)
    for name, value in (targets or {}).items():
        setattr(properties, name, value)


class REACTIVE_ANIM_UL_impacts(bpy.types.UIList):
    """The character's impact markers, in frame order: name, frame, bone, strength, reaction."""

    def draw_item(
        self,
        context: bpy.types.Context,
        layout: bpy.types.UILayout,
        data: Any,
        item: Any,
        icon: int | None,
        active_data: Any,
        active_property: str | None,
        index: int | None = 0,
        flt_flag: int | None = 0,
    ) -> None:
        marker = item
        props = impacts.impact_data(marker)
        row = layout.row(align=True)
        row.prop(marker, "name", text="", emboss=False, icon="MARKER_HLT" if marker.select else "MARKER")
        row.label(text=f"{marker.frame}")
        row.label(text=props.bone)
        row.label(text=f"{props.strength:.0f} N·s")
        row.label(text="auto" if props.reaction == impacts.AUTO else props.reaction.replace("_", " "))
        button(
            row,
            impact_ops.REACTIVE_ANIM_OT_jump_to_impact,
            text="",
            icon="TIME",
            emboss=False,
            targets={"uid": props.uid},
        )

    def filter_items(self, context: bpy.types.Context, data: Any, property: str) -> tuple[list[int], list[int]]:
        markers = getattr(data, property)
        character = settings.panel_character(context)
        flags = [
            self.bitflag_filter_item
            if impacts.is_impact_marker(m) and (character is None or impacts.character_name(m) == character.name)
            else 0
            for m in markers
        ]
        order = bpy.types.UI_UL_list.sort_items_helper([(k, m.frame) for k, m in enumerate(markers)], lambda e: e[1])
        return flags, order


class REACTIVE_ANIM_PT_main(bpy.types.Panel):
    """The Reactions sidebar tab."""

    bl_idname = "REACTIVE_ANIM_PT_main"
    bl_label = "Reactions"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Reactions"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        scene = context.scene
        scene_settings = settings.scene_settings(scene)
        layout.prop(scene_settings, "character")
        character = settings.panel_character(context)
        if character is None:
            layout.label(text="Pick the character, or select an armature", icon="INFO")
            layout.operator(operators.REACTIVE_ANIM_OT_import_bvh.bl_idname, icon="IMPORT")
            return
        action = bake.bake_state(character).original_action or (
            character.animation_data.action if character.animation_data else None
        )
        if action is None:
            layout.label(text=f"'{character.name}' has no action: import a BVH", icon="ERROR")
            layout.operator(operators.REACTIVE_ANIM_OT_import_bvh.bl_idname, icon="IMPORT")
            return
        layout.label(text=f"Motion: {action.name}", icon="ACTION")


class _CharacterPanel:
    """A Reactions subpanel, shown once there is a character."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Reactions"
    bl_parent_id = REACTIVE_ANIM_PT_main.bl_idname

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return settings.panel_character(context) is not None


class REACTIVE_ANIM_PT_impacts(_CharacterPanel, bpy.types.Panel):
    """The impact list and the active impact's fields."""

    bl_idname = "REACTIVE_ANIM_PT_impacts"
    bl_label = "Impacts"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        scene = context.scene
        character = settings.panel_character(context)
        assert character is not None
        row = layout.row()
        row.template_list(
            REACTIVE_ANIM_UL_impacts.__name__, "", scene, "timeline_markers", settings.scene_settings(scene),
            "active_impact", rows=4,
        )  # fmt: skip
        side = row.column(align=True)
        button(
            side, impact_ops.REACTIVE_ANIM_OT_add_impact, text="", icon="ADD", targets={"armature_name": character.name}
        )
        side.operator(impact_ops.REACTIVE_ANIM_OT_remove_impact.bl_idname, text="", icon="REMOVE")
        side.separator()
        side.operator(impact_ops.REACTIVE_ANIM_OT_jump_to_impact.bl_idname, text="", icon="TIME")
        side.operator(impact_ops.REACTIVE_ANIM_OT_aim_impact.bl_idname, text="", icon="VIEW_CAMERA")
        marker = settings.active_impact_marker(scene, character.name)
        if marker is None:
            layout.label(text="Pose mode: select the bone that is hit, then +", icon="INFO")
            return
        props = impacts.impact_data(marker)
        col = layout.column()
        col.use_property_split = True
        col.prop(marker, "frame")
        data = character.data
        if isinstance(data, bpy.types.Armature):
            col.prop_search(props, "bone", data, "bones")
        col.prop(props, "direction")
        button(col, impact_ops.REACTIVE_ANIM_OT_aim_impact, icon="VIEW_CAMERA", targets={"uid": props.uid})
        col.prop(props, "strength")
        col.prop(props, "reaction")


class REACTIVE_ANIM_PT_bake(_CharacterPanel, bpy.types.Panel):
    """Bake, preview, accept, discard, clear; the progress of a running bake; the last bake's summary."""

    bl_idname = "REACTIVE_ANIM_PT_bake"
    bl_label = "Bake"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        character = settings.panel_character(context)
        assert character is not None
        running = worker.running()
        if running is not None:
            progress = running.progress
            layout.progress(factor=progress.fraction, text=progress.text(running.job.armature))
            return
        row = layout.row(align=True)
        row.scale_y = 1.4
        on = {"armature_name": character.name}
        button(row, bake_ops.REACTIVE_ANIM_OT_bake, icon="REC", targets=on)
        button(row, bake_ops.REACTIVE_ANIM_OT_preview, icon="GHOST_ENABLED", targets=on)
        state = bake.bake_state(character)
        if preview.has_preview(character):
            row = layout.row(align=True)
            button(row, bake_ops.REACTIVE_ANIM_OT_accept_preview, icon="CHECKMARK", targets=on)
            button(row, bake_ops.REACTIVE_ANIM_OT_discard_preview, icon="X", targets=on)
            _draw_rows(layout, "Preview", json.loads(state.preview_result)["rows"])
        if state.reacted_action is not None:
            button(layout, bake_ops.REACTIVE_ANIM_OT_clear_bake, icon="TRASH", targets=on)
            if state.fingerprint != bake.impacts_fingerprint(context.scene, character.name):
                layout.label(text="The impacts changed since this bake", icon="ERROR")
            _draw_rows(layout, "Last bake", state.rows)
        with_settings = layout.column()
        with_settings.use_property_split = True
        scene_settings = settings.scene_settings(context.scene)
        with_settings.prop(scene_settings, "library_path", placeholder="bundled sample library")
        with_settings.prop(scene_settings, "model_path", placeholder="shipped classifier")


class REACTIVE_ANIM_PT_roles(_CharacterPanel, bpy.types.Panel):
    """Which bone plays each joint role, for rigs whose names are not recognised."""

    bl_idname = "REACTIVE_ANIM_PT_roles"
    bl_label = "Character Roles"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        character = settings.panel_character(context)
        assert character is not None
        status = role_map.check_roles(character)
        layout.label(text=status, icon="CHECKMARK" if status.startswith("Every") else "ERROR")
        on = {"armature_name": character.name}
        row = layout.row(align=True)
        button(row, role_map.REACTIVE_ANIM_OT_detect_roles, icon="VIEWZOOM", targets=on)
        row.operator_menu_enum(role_map.REACTIVE_ANIM_OT_role_preset.bl_idname, "preset", text="Preset")
        button(row, role_map.REACTIVE_ANIM_OT_clear_roles, text="", icon="X", targets=on)
        data = character.data
        if not isinstance(data, bpy.types.Armature):
            return
        column = layout.column(align=True)
        for entry in role_map.role_entries(character):
            column.prop_search(entry, "bone", data, "bones", text=entry.role.replace("_", " "))


def _draw_rows(layout: bpy.types.UILayout, title: str, rows_json: str) -> None:
    """Per impact: marker and frame, class and how it was chosen, clip and cost."""
    if not rows_json:
        return
    box = layout.box()
    box.label(text=title)
    for row in json.loads(rows_json):
        col = box.column(align=True)
        over = "" if row["accepted"] else ", over the threshold"
        col.label(text=f"{row['frame']} {row['marker']} ({row['bone']}): {row['class']}", icon="MARKER")
        then = f" then {row['then']}" if row["then"] else ""
        col.label(text=f"    {row['clip']}{then}, cost {row['cost']:.1f}{over}; {row['chosen_by']}")
        if row.get("note"):  # rows saved before notes existed have none
            col.label(text=f"    {row['note']}", icon="INFO")


# Every operator, in the order the Reactions menu lists them.
MENU_OPERATORS = (
    operators.REACTIVE_ANIM_OT_import_bvh,
    impact_ops.REACTIVE_ANIM_OT_add_impact,
    impact_ops.REACTIVE_ANIM_OT_aim_impact,
    impact_ops.REACTIVE_ANIM_OT_jump_to_impact,
    impact_ops.REACTIVE_ANIM_OT_remove_impact,
    bake_ops.REACTIVE_ANIM_OT_preview,
    bake_ops.REACTIVE_ANIM_OT_accept_preview,
    bake_ops.REACTIVE_ANIM_OT_discard_preview,
    bake_ops.REACTIVE_ANIM_OT_bake,
    bake_ops.REACTIVE_ANIM_OT_clear_bake,
    role_map.REACTIVE_ANIM_OT_detect_roles,
    role_map.REACTIVE_ANIM_OT_role_preset,
    role_map.REACTIVE_ANIM_OT_clear_roles,
)


class REACTIVE_ANIM_MT_reactions(bpy.types.Menu):
    """Every Reactions operator, in the Object and Pose menus (and so in F3 search)."""

    bl_idname = "REACTIVE_ANIM_MT_reactions"
    bl_label = "Reactions"

    def draw(self, context: bpy.types.Context) -> None:
        for operator in MENU_OPERATORS:
            self.layout.operator(operator.bl_idname)


def draw_menu_entry(self: bpy.types.Menu, context: bpy.types.Context) -> None:
    self.layout.menu(REACTIVE_ANIM_MT_reactions.bl_idname)
