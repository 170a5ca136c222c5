"""The role map editor (blender/character/role_map.py): a rig whose bone names are not recognised cannot bake,
and says exactly which roles are missing; mapped in the editor (by hand or a preset), it bakes."""

from __future__ import annotations

import bpy
import pytest

from reactive_anim.blender.bake import bake
from reactive_anim.blender.character import role_map
from reactive_anim.blender.impacts import impacts
from reactive_anim.blender.ui import panels, settings
from reactive_anim.core.model.roles import ALL_ROLES, REQUIRED_ROLES, RIG_PRESETS
from tests.support.actions import action_of
from tests.support.bake_scene import walk_with_impacts
from tests.support.ui_recorder import draw
from tools.devkit.blender_types import armature_data
from tools.devkit.operators import addon_ops

SAMPLE = RIG_PRESETS["sample"]


def _renamed_rig(scene: bpy.types.Scene) -> tuple[bpy.types.Object, dict[str, str]]:
    """The sample walk with every bone renamed to an opaque name (the action follows the renames),
    and its role map in the new names."""
    rig = walk_with_impacts(scene)
    new = {}
    for k, bone in enumerate(list(armature_data(rig).bones)):
        old = bone.name
        bone.name = f"b{k:02d}"
        new[old] = bone.name
    for marker in scene.timeline_markers:
        impacts.impact_data(marker).bone = new[impacts.impact_data(marker).bone]
    return rig, {role: new[name] for role, name in SAMPLE.items()}


def test_an_unrecognised_rig_names_the_missing_roles_and_bakes_once_mapped(empty_scene):
    rig, mapping = _renamed_rig(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    before = set(bpy.data.actions.keys())

    with pytest.raises(RuntimeError, match=r"no joint found for the roles: pelvis, waist, .*wrist_r\. .*b00, b01"):
        addon_ops.bake(armature_name="walk")
    assert set(bpy.data.actions.keys()) == before
    assert set(role_map.missing_roles(rig)) == set(REQUIRED_ROLES)

    drawn = draw(panels.REACTIVE_ANIM_PT_roles, bpy.context)
    assert drawn.texts()[0].startswith("Missing: pelvis, waist, back, chest")
    role_map.set_roles(rig, {})  # the editor's rows, one per role, empty
    drawn = draw(panels.REACTIVE_ANIM_PT_roles, bpy.context)
    assert [name for kind, name, *_ in drawn.items if kind == "prop_search"] == ["bone"] * len(ALL_ROLES)
    for entry in role_map.role_entries(rig):
        entry.bone = mapping[entry.role]  # as the animator picks each bone in the panel
    assert role_map.missing_roles(rig) == []
    assert draw(panels.REACTIVE_ANIM_PT_roles, bpy.context).texts()[0] == "Every role has its bone"

    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}
    assert action_of(rig).name == "walk.reacted"
    assert "frame 41 'hit_01' b03: step_forward" in bake.bake_state(rig).summary


def test_detect_finds_the_sample_rig_and_keeps_what_was_mapped(empty_scene):
    rig = walk_with_impacts(empty_scene)
    role_map.set_roles(rig, {"chest": "spine.001"})  # the animator's choice wins
    assert addon_ops.detect_roles(armature_name="walk") == {"FINISHED"}
    found = role_map.role_overrides(rig)
    assert [e.role for e in role_map.role_entries(rig)] == list(ALL_ROLES)
    assert found["chest"] == "spine.001" and found["pelvis"] == "pelvis" and found["wrist_l"] == "hand.L"


def test_a_preset_maps_bones_behind_a_namespace(empty_scene):
    rig = walk_with_impacts(empty_scene)
    for bone in armature_data(rig).bones:
        bone.name = f"hero:{bone.name}"
    assert role_map.missing_roles(rig) == []  # the name reading skips namespaces already
    assert addon_ops.role_preset(armature_name="walk", preset="sample") == {"FINISHED"}
    assert role_map.role_overrides(rig)["hip_l"] == "hero:thigh.L"
    assert len(role_map.role_overrides(rig)) == len(SAMPLE)
    assert addon_ops.clear_roles(armature_name="walk") == {"FINISHED"}
    assert role_map.role_overrides(rig) == {}
    with pytest.raises(RuntimeError, match="has none of the rigify rig's bone names"):
        addon_ops.role_preset(armature_name="walk", preset="rigify")


def test_the_role_map_is_saved_with_the_armature(empty_scene, tmp_path):
    rig, mapping = _renamed_rig(empty_scene)
    role_map.set_roles(rig, mapping)
    path = tmp_path / "roles.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert role_map.role_overrides(bpy.data.objects["walk"]) == mapping


def test_the_role_check_follows_renamed_bones(empty_scene):
    """The panel's line is kept per rig (it draws on every mouse move): a renamed bone must show at
    once, and so must its name given back."""
    rig = walk_with_impacts(empty_scene)
    settings.scene_settings(empty_scene).character = rig
    assert role_map.check_roles(rig) == "Every role has its bone"
    armature_data(rig).bones[SAMPLE["knee_l"]].name = "opaque"
    assert role_map.check_roles(rig).startswith("Missing: ") and "knee_l" in role_map.check_roles(rig)
    armature_data(rig).bones["opaque"].name = SAMPLE["knee_l"]
    assert role_map.check_roles(rig) == "Every role has its bone"
