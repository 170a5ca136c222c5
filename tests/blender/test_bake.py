"""The bake and clear operators (blender/bake/bake.py) end to end: the sample walk imported, impact markers,
the sample library, real physics and search, the reacted action written; failures leave no trace."""

from __future__ import annotations

import re

import bpy
import numpy as np
import pytest

from reactive_anim.blender.bake import bake, bake_ops, resources
from reactive_anim.blender.character import action_io
from reactive_anim.blender.impacts import impacts
from reactive_anim.core.model import quat
from reactive_anim.core.model.classes import CLASS_SLUGS
from tests.support.actions import action_of, fcurves, keyframes
from tests.support.bake_scene import blend_snapshot, library_without_falls, walk_with_impacts
from tools.devkit.blender_types import armature_data, as_buffer
from tools.devkit.operators import addon_ops


def test_bake_writes_a_new_action_and_leaves_the_original_as_it_was(empty_scene):
    rig = walk_with_impacts(empty_scene)
    original = action_of(rig)
    keys_before = keyframes(original)
    markers_before = blend_snapshot()["markers"]
    walk = action_io.read_motion(rig)

    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}

    reacted = action_of(rig)
    assert reacted.name == "walk.reacted" and reacted != original
    assert original.use_fake_user and keyframes(original) == keys_before
    assert blend_snapshot()["markers"] == markers_before
    # keys on every frame of the reacted motion, on every curve
    first, last = round(reacted.frame_range[0]), round(reacted.frame_range[1])
    assert first == 1 and last >= 264  # the walk's frames at least (a reaction may play past its end)
    curves = fcurves(reacted)
    keyed = {(fc.data_path, fc.array_index) for fc in curves}
    quaternions = {
        (f'pose.bones["{b.name}"].rotation_quaternion', i) for b in armature_data(rig).bones for i in range(4)
    }
    assert quaternions | {('pose.bones["pelvis"].location', i) for i in range(3)} <= keyed
    for fc in curves:
        frames = np.empty(len(fc.keyframe_points) * 2, dtype=np.float32)
        fc.keyframe_points.foreach_get("co", as_buffer(frames))
        assert np.array_equal(frames[0::2], np.arange(first, last + 1)), fc.data_path
    # before the first impact (frame 41) the reacted motion is the walk; shortly after, it is not
    motion = action_io.read_motion(rig, reacted)
    before_hit = slice(0, 41)  # timeline frames 1-41
    assert np.abs(motion.global_positions()[before_hit] - walk.global_positions()[before_hit]).max() < 1e-5
    assert quat.angle_between(motion.local_rot[41:70], walk.local_rot[41:70]).max() > 0.1
    # the summary: one line per impact, overrides honoured, stored for the panel
    state = bake.bake_state(rig)
    assert state.original_action == original and state.reacted_action == reacted
    lines = state.summary.splitlines()
    assert len(lines) == 4 and "3 impacts baked into 'walk.reacted'" in lines[0]
    assert lines[1].startswith("frame 41 'hit_01' chest: step_forward (override), clip step_forward_")
    assert lines[2].startswith("frame 131 'hit_02' chest: sway_balance (override), clip sway_balance_")
    assert lines[3].startswith("frame 201 'hit_03' head: ") and lines[3].split()[4] in CLASS_SLUGS
    assert all(re.search(r", \d+ ms(; .+)?$", line) for line in lines[1:]), lines  # time, then any note


def test_clear_bake_restores_the_original(empty_scene):
    rig = walk_with_impacts(empty_scene)
    before = blend_snapshot()
    addon_ops.bake(armature_name="walk")
    assert "walk.reacted" in bpy.data.actions

    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}

    assert action_of(rig).name == "walk"
    assert "walk.reacted" not in bpy.data.actions
    after = blend_snapshot()
    assert after["actions"] == before["actions"] and after["markers"] == before["markers"]
    assert after["objects"]["walk"][:3] == before["objects"]["walk"][:3]
    with pytest.raises(RuntimeError, match=r"clear_bake.poll\(\) There are no baked reactions to clear"):
        addon_ops.clear_bake(armature_name="walk")


def test_two_bakes_give_identical_keyframes_and_a_rebake_replaces_the_first(empty_scene):
    rig = walk_with_impacts(empty_scene)
    original_keys = keyframes(action_of(rig))
    addon_ops.bake(armature_name="walk")
    first = keyframes(action_of(rig))

    addon_ops.bake(armature_name="walk")  # bakes the original again, replaces walk.reacted
    assert sorted(a.name for a in bpy.data.actions) == ["walk", "walk.reacted"]
    assert action_of(rig).name == "walk.reacted"
    assert keyframes(action_of(rig)) == first
    assert keyframes(bpy.data.actions["walk"]) == original_keys

    addon_ops.clear_bake(armature_name="walk")
    addon_ops.bake(armature_name="walk")
    assert keyframes(action_of(rig)) == first


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("missing library", r"reaction library not found: .*nowhere"),
        ("broken library", r"clip 'step_forward_1.bvh': unknown reaction class 'kick'"),
        ("missing model", r"classifier model not found: .*missing\.onnx"),
        ("marker on a missing bone", r"impact marker 'hit_02' at frame 131 is on bone 'tail', which armature 'walk'"),
        ("marker outside the animation", r"impact marker 'hit_03' at frame 300 is outside the animation's frames"),
        ("class the library lacks", r"marker 'hit_02' at frame 131: the library has no clips of class 'sway_balance'"),
        ("no markers", r"bake.poll\(\) Add an impact first"),
        ("no armature", r"there is no armature called 'runner'"),
    ],
)
def test_a_failed_bake_leaves_no_trace(empty_scene, tmp_path, case, expected):
    rig = walk_with_impacts(empty_scene)
    options = {"armature_name": "walk"}
    marker = {m.name: m for m in empty_scene.timeline_markers}
    if case == "missing library":
        options["library_path"] = str(tmp_path / "nowhere")
    elif case == "broken library":
        (tmp_path / "library.toml").write_text('[[clip]]\nfile = "step_forward_1.bvh"\nclass = "kick"\n')
        options["library_path"] = str(tmp_path)
    elif case == "missing model":
        options["model_path"] = str(tmp_path / "missing.onnx")
    elif case == "marker on a missing bone":
        impacts.impact_data(marker["hit_02"]).bone = "tail"  # as if the bone had been renamed
    elif case == "marker outside the animation":
        marker["hit_03"].frame = 300
    elif case == "class the library lacks":  # fails inside the core, after the first impact is made
        options["library_path"] = str(library_without_falls(tmp_path))
    elif case == "no markers":
        for m in list(empty_scene.timeline_markers):
            impacts.remove_impact(empty_scene, m)
    elif case == "no armature":
        options["armature_name"] = "runner"
    before = blend_snapshot()

    with pytest.raises(RuntimeError, match=expected):
        addon_ops.bake(**options)

    assert blend_snapshot() == before
    assert action_of(rig).name == "walk" and "walk.reacted" not in bpy.data.actions


def test_a_failed_rebake_keeps_the_previous_bake(empty_scene):
    rig = walk_with_impacts(empty_scene)
    addon_ops.bake(armature_name="walk")
    before = blend_snapshot()
    impacts.impact_data(empty_scene.timeline_markers["hit_01"]).bone = "tail"
    with pytest.raises(RuntimeError, match="impact marker 'hit_01' at frame 41 is on bone 'tail'"):
        addon_ops.bake(armature_name="walk")
    impacts.impact_data(empty_scene.timeline_markers["hit_01"]).bone = "chest"
    assert blend_snapshot() == before
    assert action_of(rig).name == "walk.reacted"


def test_bake_is_one_undo_step(empty_scene):
    rig = walk_with_impacts(empty_scene)
    bpy.ops.ed.undo_push(message="impacts added")
    before = blend_snapshot()
    assert "UNDO" in bake_ops.REACTIVE_ANIM_OT_bake.bl_options
    # as a button calls it: through invoke (synchronous in background mode), pushing an undo step
    assert addon_ops.bake("INVOKE_DEFAULT", True, armature_name="walk") == {"FINISHED"}
    assert action_of(rig).name == "walk.reacted"

    bpy.ops.ed.undo()

    rig = bpy.data.objects["walk"]  # undo reloads the data: old references are stale
    assert action_of(rig).name == "walk" and "walk.reacted" not in bpy.data.actions
    assert blend_snapshot() == before
    bpy.ops.ed.redo()
    assert action_of(bpy.data.objects["walk"]).name == "walk.reacted"


def test_default_library_and_cache_locations():
    """The sample library is found from a checkout; the cache is never inside the library folder."""
    library = resources.default_library_path()
    assert library is not None and (library / "library.toml").is_file()
    cache = resources.library_cache_dir()
    assert cache is not None and cache.is_dir() and library not in cache.parents
    assert resources.default_model_path().name == "reaction_classifier.onnx"
