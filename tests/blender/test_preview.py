"""Preview before committing (blender/bake/preview.py): the reacted motion on a ghost sharing the
character's armature data; Discard leaves no trace, Accept equals a direct bake."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from reactive_anim.blender.bake import bake, preview
from reactive_anim.blender.character import action_io
from reactive_anim.blender.ui import settings
from tests.support.actions import action_of, keyframes
from tests.support.bake_scene import blend_snapshot, summary_without_times, walk_with_impacts
from tools.devkit.operators import addon_ops


def test_preview_plays_on_a_ghost_and_leaves_the_character_alone(empty_scene):
    rig = walk_with_impacts(empty_scene)
    before = blend_snapshot()
    modes = [pb.rotation_mode for pb in rig.pose.bones]

    assert addon_ops.preview(armature_name="walk") == {"FINISHED"}

    ghost = bpy.data.objects["walk.preview"]
    assert ghost.data == rig.data and ghost.show_in_front and ghost.display_type == "WIRE" and ghost.hide_select
    assert ghost.users_collection == rig.users_collection
    assert action_of(ghost).name == "walk.preview"
    assert action_of(rig).name == "walk"
    assert [pb.rotation_mode for pb in rig.pose.bones] == modes
    assert blend_snapshot()["actions"]["walk"] == before["actions"]["walk"]
    # the ghost moves as the reaction does: same before the first impact, apart after it
    walk = action_io.read_motion(rig)
    ghost_motion = action_io.read_motion(ghost)
    assert np.abs(ghost_motion.global_positions()[:40] - walk.global_positions()[:40]).max() < 1e-5
    assert np.abs(ghost_motion.global_positions()[60:100] - walk.global_positions()[60:100]).max() > 0.05
    with pytest.raises(RuntimeError, match=r"clear_bake.poll\(\) There are no baked reactions"):
        addon_ops.clear_bake(armature_name="walk")


def test_preview_then_discard_leaves_the_file_unchanged(empty_scene):
    walk_with_impacts(empty_scene)
    before = blend_snapshot()
    objects, actions = set(bpy.data.objects.keys()), set(bpy.data.actions.keys())

    addon_ops.preview(armature_name="walk")
    assert addon_ops.discard_preview(armature_name="walk") == {"FINISHED"}

    assert set(bpy.data.objects.keys()) == objects and set(bpy.data.actions.keys()) == actions
    assert blend_snapshot() == before
    with pytest.raises(RuntimeError, match=r"discard_preview.poll\(\) There is no preview to discard"):
        addon_ops.discard_preview(armature_name="walk")


def test_preview_then_accept_equals_a_direct_bake(empty_scene):
    rig = walk_with_impacts(empty_scene)
    addon_ops.bake(armature_name="walk")
    direct = blend_snapshot()
    direct_keys = keyframes(action_of(rig))
    direct_state = bake.bake_state(rig)
    direct_summary, direct_rows = direct_state.summary, direct_state.rows
    addon_ops.clear_bake(armature_name="walk")

    addon_ops.preview(armature_name="walk")
    assert addon_ops.accept_preview(armature_name="walk") == {"FINISHED"}

    assert "walk.preview" not in bpy.data.objects and "walk.preview" not in bpy.data.actions
    assert action_of(rig).name == "walk.reacted"
    assert keyframes(action_of(rig)) == direct_keys
    state = bake.bake_state(rig)
    assert state.rows == direct_rows
    assert summary_without_times(state.summary) == summary_without_times(direct_summary)
    accepted = blend_snapshot()
    for snapshot in (accepted, direct):  # the measured times differ
        name, slot, modes, _bake_fields, collections = snapshot["objects"]["walk"]
        snapshot["objects"]["walk"] = (name, slot, modes, collections)
    assert accepted == direct
    # and it clears like a bake
    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}
    assert action_of(rig).name == "walk"


def test_a_bake_replaces_a_pending_preview_and_a_second_preview_replaces_the_first(empty_scene):
    walk_with_impacts(empty_scene)
    addon_ops.preview(armature_name="walk")
    addon_ops.preview(armature_name="walk")
    assert [ob.name for ob in bpy.data.objects] == ["walk", "walk.preview"]
    assert sorted(bpy.data.actions.keys()) == ["walk", "walk.preview"]
    addon_ops.bake(armature_name="walk")
    assert [ob.name for ob in bpy.data.objects] == ["walk"]
    assert sorted(bpy.data.actions.keys()) == ["walk", "walk.reacted"]
    assert not preview.has_preview(bpy.data.objects["walk"])


def test_a_refused_accept_keeps_the_preview_and_discard_still_removes_it(empty_scene):
    rig = walk_with_impacts(empty_scene)
    addon_ops.preview(armature_name="walk")
    rig.animation_data.action = bpy.data.actions.new("other")  # the character changed meanwhile

    with pytest.raises(RuntimeError, match="now plays 'other', not 'walk' as when the preview was made"):
        addon_ops.accept_preview(armature_name="walk")

    assert "walk.preview" in bpy.data.objects and "walk.preview" in bpy.data.actions
    assert preview.has_preview(rig)
    assert addon_ops.discard_preview(armature_name="walk") == {"FINISHED"}
    assert "walk.preview" not in bpy.data.objects and "walk.preview" not in bpy.data.actions


def test_the_ghost_is_never_taken_for_the_character(empty_scene):
    walk_with_impacts(empty_scene)
    addon_ops.preview(armature_name="walk")
    ghost = bpy.data.objects["walk.preview"]
    assert not settings.is_character(ghost)
    assert settings.armatures_with_action() == [bpy.data.objects["walk"]]
    bpy.context.view_layer.objects.active = None
    assert settings.target_armature(bpy.context, "") == bpy.data.objects["walk"]  # the only character
    assert addon_ops.accept_preview() == {"FINISHED"}  # no name: the character, not its ghost


def test_a_duplicated_character_never_removes_what_its_original_uses(empty_scene):
    rig = walk_with_impacts(empty_scene)
    addon_ops.bake(armature_name="walk")
    copy = rig.copy()  # as Shift+D: the bake state (with its pointers) is copied too
    copy.animation_data.action = action_of(rig).copy()
    empty_scene.collection.objects.link(copy)

    assert addon_ops.clear_bake(armature_name=copy.name) == {"FINISHED"}

    assert action_of(rig).name == "walk.reacted"  # the original keeps its bake
    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}
    assert action_of(rig).name == "walk"
