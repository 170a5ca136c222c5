"""The bake and clear operators (blender/bake.py) end to end: the sample walk imported, impact markers,
the sample library, real physics and search, the reacted action written; failures leave no trace."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

from reactive_anim.blender import action_io, bake, bvh_import, impacts
from reactive_anim.core import quat
from reactive_anim.core.classes import CLASS_SLUGS
from tests.support.actions import fcurves, keyframes

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "sample_clips" / "walk.bvh"  # 264 frames at 60 fps, keys on frames 1-264
FORWARD = (0.0, -1.0, 0.0)  # the sample walk walks along -Y: a push from behind


def _walk_with_impacts(scene: bpy.types.Scene) -> bpy.types.Object:
    """The sample walk with three impacts: two forced classes and one the pipeline chooses."""
    rig = bvh_import.import_bvh(bpy.context, WALK)
    impacts.add_impact(scene, rig, "chest", 41, FORWARD, 120.0, "step_forward")
    impacts.add_impact(scene, rig, "chest", 131, (0.0, 1.0, 0.0), 60.0, "sway_balance")
    impacts.add_impact(scene, rig, "head", 201, (1.0, 0.0, 0.0), 80.0)
    return rig


def _snapshot() -> dict:
    """Everything a failed bake must leave as it was: actions and their keys, assignments, markers,
    rotation modes and the bake state."""
    objects = {}
    for ob in bpy.data.objects:
        adt = ob.animation_data
        slot = getattr(adt, "action_slot", None) if adt else None
        state = bake.bake_state(ob)
        objects[ob.name] = (
            adt.action.name if adt and adt.action else None,
            slot.identifier if slot is not None else None,
            tuple(pb.rotation_mode for pb in ob.pose.bones) if ob.pose else (),
            tuple(str(getattr(state, k)) for k in ("original_action", "reacted_action", "rotation_modes", "summary")),
        )
    markers = []
    for m in bpy.context.scene.timeline_markers:
        p = impacts.impact_data(m)
        markers.append((m.name, m.frame, p.armature, p.bone, tuple(p.direction), p.strength, p.reaction, p.uid))
    actions = {a.name: (a.use_fake_user, keyframes(a)) for a in bpy.data.actions}
    return {"objects": objects, "markers": markers, "actions": actions}


def test_bake_writes_a_new_action_and_leaves_the_original_as_it_was(empty_scene):
    rig = _walk_with_impacts(empty_scene)
    original = rig.animation_data.action
    keys_before = keyframes(original)
    markers_before = _snapshot()["markers"]
    walk = action_io.read_motion(rig)

    assert bpy.ops.reactive_anim.bake(armature_name="walk") == {"FINISHED"}

    reacted = rig.animation_data.action
    assert reacted.name == "walk.reacted" and reacted != original
    assert original.use_fake_user and keyframes(original) == keys_before
    assert _snapshot()["markers"] == markers_before
    # keys on every frame of the reacted motion, on every curve
    first, last = round(reacted.frame_range[0]), round(reacted.frame_range[1])
    assert first == 1 and last > 264
    curves = fcurves(reacted)
    keyed = {(fc.data_path, fc.array_index) for fc in curves}
    quaternions = {(f'pose.bones["{b.name}"].rotation_quaternion', i) for b in rig.data.bones for i in range(4)}
    assert quaternions | {('pose.bones["pelvis"].location', i) for i in range(3)} <= keyed
    for fc in curves:
        frames = np.empty(len(fc.keyframe_points) * 2, dtype=np.float32)
        fc.keyframe_points.foreach_get("co", frames)
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
    assert all(line.endswith(" ms") for line in lines[1:])


def test_clear_bake_restores_the_original(empty_scene):
    rig = _walk_with_impacts(empty_scene)
    before = _snapshot()
    bpy.ops.reactive_anim.bake(armature_name="walk")
    assert "walk.reacted" in bpy.data.actions

    assert bpy.ops.reactive_anim.clear_bake(armature_name="walk") == {"FINISHED"}

    assert rig.animation_data.action.name == "walk"
    assert "walk.reacted" not in bpy.data.actions
    after = _snapshot()
    assert after["actions"] == before["actions"] and after["markers"] == before["markers"]
    assert after["objects"]["walk"][:3] == before["objects"]["walk"][:3]
    with pytest.raises(RuntimeError, match="armature 'walk' has no baked reactions to clear"):
        bpy.ops.reactive_anim.clear_bake(armature_name="walk")


def test_two_bakes_give_identical_keyframes_and_a_rebake_replaces_the_first(empty_scene):
    rig = _walk_with_impacts(empty_scene)
    original_keys = keyframes(rig.animation_data.action)
    bpy.ops.reactive_anim.bake(armature_name="walk")
    first = keyframes(rig.animation_data.action)

    bpy.ops.reactive_anim.bake(armature_name="walk")  # bakes the original again, replaces walk.reacted
    assert sorted(a.name for a in bpy.data.actions) == ["walk", "walk.reacted"]
    assert rig.animation_data.action.name == "walk.reacted"
    assert keyframes(rig.animation_data.action) == first
    assert keyframes(bpy.data.actions["walk"]) == original_keys

    bpy.ops.reactive_anim.clear_bake(armature_name="walk")
    bpy.ops.reactive_anim.bake(armature_name="walk")
    assert keyframes(rig.animation_data.action) == first


def _library_without_falls(folder: Path) -> Path:
    """A library of the sample steps only (absolute paths), so a forced fall has nothing to play."""
    lines = [
        f'[[clip]]\nfile = "{REPO / "sample_clips" / f"step_forward_{k}.bvh"}"\nclass = "step_forward"\n'
        for k in (1, 2, 3)
    ]
    toml = folder / "steps.toml"
    toml.write_text("\n".join(lines), encoding="utf-8")
    return toml


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("missing library", r"reaction library not found: .*nowhere"),
        ("broken library", r"clip 'step_forward_1.bvh': unknown reaction class 'kick'"),
        ("missing model", r"classifier model not found: .*missing\.onnx"),
        ("marker on a missing bone", r"impact marker 'hit_02' at frame 131 is on bone 'tail', which armature 'walk'"),
        ("marker outside the animation", r"impact marker 'hit_03' at frame 300 is outside the animation's frames"),
        ("class the library lacks", r"marker 'hit_02' at frame 131: the library has no clips of class 'sway_balance'"),
        ("no markers", r"armature 'walk' has no impact markers"),
        ("no armature", r"there is no armature called 'runner'"),
    ],
)
def test_a_failed_bake_leaves_no_trace(empty_scene, tmp_path, case, expected):
    rig = _walk_with_impacts(empty_scene)
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
        options["library_path"] = str(_library_without_falls(tmp_path))
    elif case == "no markers":
        for m in list(empty_scene.timeline_markers):
            impacts.remove_impact(empty_scene, m)
    elif case == "no armature":
        options["armature_name"] = "runner"
    before = _snapshot()

    with pytest.raises(RuntimeError, match=expected):
        bpy.ops.reactive_anim.bake(**options)

    assert _snapshot() == before
    assert rig.animation_data.action.name == "walk" and "walk.reacted" not in bpy.data.actions


def test_a_failed_rebake_keeps_the_previous_bake(empty_scene):
    rig = _walk_with_impacts(empty_scene)
    bpy.ops.reactive_anim.bake(armature_name="walk")
    before = _snapshot()
    impacts.impact_data(empty_scene.timeline_markers["hit_01"]).bone = "tail"
    with pytest.raises(RuntimeError, match="impact marker 'hit_01' at frame 41 is on bone 'tail'"):
        bpy.ops.reactive_anim.bake(armature_name="walk")
    impacts.impact_data(empty_scene.timeline_markers["hit_01"]).bone = "chest"
    assert _snapshot() == before
    assert rig.animation_data.action.name == "walk.reacted"


def test_bake_is_one_undo_step_and_poll_explains_itself(empty_scene):
    assert {"REGISTER", "UNDO"} <= bake.REACTIVE_ANIM_OT_bake.bl_options
    assert {"REGISTER", "UNDO"} <= bake.REACTIVE_ANIM_OT_clear_bake.bl_options
    assert not bpy.ops.reactive_anim.bake.poll()  # an empty file has no armature
    _walk_with_impacts(empty_scene)
    assert bpy.ops.reactive_anim.bake.poll()


def test_default_library_and_cache_locations():
    """The sample library is found from a checkout; the cache is never inside the library folder."""
    library = bake.default_library_path()
    assert library is not None and (library / "library.toml").is_file()
    cache = bake.library_cache_dir()
    assert cache.is_dir() and library not in cache.parents
    assert bake.default_model_path().name == "reaction_classifier.onnx"
