"""The Reactions sidebar, its impact list and its menu, drawn in every state the animator meets:
no character, a character with impacts, a bake (up to date or not), a preview, a bake running.
Background mode draws no UI, so the draw functions run against tests/support/ui_recorder, which
checks every call against Blender's RNA (functions, keywords, icons, properties, operators)."""

from __future__ import annotations

import time

import bpy

from reactive_anim.blender.bake import bake, worker
from reactive_anim.blender.ui import panels, settings
from tests.support.bake_scene import walk_with_impacts
from tests.support.ui_recorder import Recorder, draw, draw_item, filter_items
from tools.devkit.operators import addon_ops

UILST_FLT_ITEM = 1 << 30  # UIList.bitflag_filter_item in Blender's source (RNA reports no default)


def _all_panels(context: bpy.types.Context) -> Recorder:
    recorded = Recorder()
    for panel in (panels.REACTIVE_ANIM_PT_main, panels.REACTIVE_ANIM_PT_impacts, panels.REACTIVE_ANIM_PT_bake):
        recorded.items += draw(panel, context).items
    return recorded


def test_without_a_character_the_panel_says_what_to_do(empty_scene):
    drawn = _all_panels(bpy.context)
    assert "Pick the character, or select an armature" in drawn.texts()
    assert drawn.operators() == ["reactive_anim.import_bvh"]


def test_a_character_with_impacts(empty_scene):
    rig = walk_with_impacts(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    settings.scene_settings(empty_scene).active_impact = 1  # hit_02

    drawn = _all_panels(bpy.context)

    assert "Motion: walk" in drawn.texts()
    assert ("template_list", "REACTIVE_ANIM_UL_impacts", "timeline_markers") in drawn.items
    assert [name for kind, name, *_ in drawn.items if kind in ("prop", "prop_search")] == [
        "character",
        "frame",
        "bone",
        "direction",
        "strength",
        "reaction",
        "library_path",
        "model_path",
    ]
    buttons = {item[1]: item[2] for item in drawn.items if item[0] == "operator"}
    assert buttons["reactive_anim.bake"] == {"armature_name": "walk"}
    assert buttons["reactive_anim.preview"] == {"armature_name": "walk"}
    assert buttons["reactive_anim.add_impact"] == {"armature_name": "walk"}
    assert "reactive_anim.clear_bake" not in buttons and "reactive_anim.accept_preview" not in buttons


def test_after_a_bake_the_panel_shows_each_impact_and_says_when_it_is_out_of_date(empty_scene):
    rig = walk_with_impacts(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    addon_ops.bake(armature_name="walk")

    texts = _all_panels(bpy.context).texts()
    assert "41 hit_01 (chest): step_forward" in texts and "131 hit_02 (chest): sway_balance" in texts
    assert any(t.strip().startswith("step_forward_") and "override" in t for t in texts)
    assert "The impacts changed since this bake" not in texts
    assert "reactive_anim.clear_bake" in _all_panels(bpy.context).operators()

    empty_scene.timeline_markers["hit_03"].frame = 210
    assert "The impacts changed since this bake" in _all_panels(bpy.context).texts()
    state = bake.bake_state(rig)
    assert state.fingerprint != bake.impacts_fingerprint(empty_scene, "walk")


def test_a_preview_offers_accept_and_discard(empty_scene):
    rig = walk_with_impacts(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    addon_ops.preview(armature_name="walk")
    drawn = _all_panels(bpy.context)
    assert {"reactive_anim.accept_preview", "reactive_anim.discard_preview"} <= set(drawn.operators())
    assert "Preview" in drawn.texts() and "41 hit_01 (chest): step_forward" in drawn.texts()


def test_a_running_bake_shows_its_progress_instead_of_the_buttons(empty_scene):
    rig = walk_with_impacts(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    background = worker.BackgroundBake(bake.prepare_bake(empty_scene, rig)).start()
    try:
        while background.progress.done < 1 and not background.poll():
            time.sleep(0.001)
        drawn = draw(panels.REACTIVE_ANIM_PT_bake, bpy.context)
    finally:
        background.cancel()
    assert drawn.operators() == []
    assert any(t.startswith("Reactions on 'walk': impact ") for t in drawn.texts())


def test_the_impact_list_shows_the_characters_impacts_in_frame_order(empty_scene):
    rig = walk_with_impacts(empty_scene)
    empty_scene.timeline_markers.new("camera cut", frame=5)  # an ordinary marker: hidden
    empty_scene.timeline_markers["hit_01"].frame = 250  # now the last impact
    settings.scene_settings(empty_scene).character = rig
    ui_list = type("List", (), {"bitflag_filter_item": UILST_FLT_ITEM})()

    flags, order = filter_items(panels.REACTIVE_ANIM_UL_impacts, ui_list, bpy.context, empty_scene, "timeline_markers")

    markers = list(empty_scene.timeline_markers)
    shown = [m.name for m, flag in zip(markers, flags, strict=True) if flag]
    assert sorted(shown) == ["hit_01", "hit_02", "hit_03"]
    by_position = sorted(range(len(markers)), key=lambda k: order[k])
    assert [markers[k].name for k in by_position if flags[k]] == ["hit_02", "hit_03", "hit_01"]
    row = draw_item(panels.REACTIVE_ANIM_UL_impacts, ui_list, bpy.context, empty_scene, markers[1], 1)
    assert ("prop", "name") in row.items and ("label", "131") in row.items and ("label", "chest") in row.items
    assert row.operators() == ["reactive_anim.jump_to_impact"]


def test_the_menu_lists_every_operator(empty_scene):
    drawn = draw(panels.REACTIVE_ANIM_MT_reactions, bpy.context)
    assert drawn.operators() == [cls.bl_idname for cls in panels.MENU_OPERATORS]
