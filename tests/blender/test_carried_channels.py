"""The reacted action carries every channel of the original the bake does not change (object keys,
bone custom properties, bone scale, bones outside the skeleton), keys and settings as they are, so
that up to the first impact it plays exactly like the original; the character travels and turns as
it did, whatever frame the playhead was on at bake time. (Before, the reacted action held only the
skeleton's rotations and root location: the character froze where the playhead stood.)"""

from __future__ import annotations

from typing import Any

import bpy
import numpy as np
import pytest
from mathutils import Matrix

from reactive_anim.blender import compat
from reactive_anim.blender.bake import bake
from reactive_anim.blender.character import action_io
from reactive_anim.blender.impacts import impacts
from reactive_anim.core.model.skeleton import Motion
from tests.support.actions import action_of, fcurves, keyframes, values_before
from tests.support.bake_scene import walk_with_impacts
from tools.devkit.blender_types import armature_data, as_buffer
from tools.devkit.operators import addon_ops

FIRST_IMPACT = 41  # walk_with_impacts' first marker
SKELETON_ROTATIONS = ("rotation_quaternion", "rotation_euler", "rotation_axis_angle")


def _curve(fc: bpy.types.FCurve) -> tuple:
    """Everything a carried F-curve must keep, read key by key (not the way the copy is made)."""
    keys = [
        (
            k.co[:], k.handle_left[:], k.handle_right[:], k.handle_left_type, k.handle_right_type,
            k.interpolation, k.easing, k.type, k.back, k.amplitude, k.period,
        )
        for k in fc.keyframe_points
    ]  # fmt: skip
    modifiers = [
        (
            m.type,
            {p.identifier: _plain(getattr(m, p.identifier)) for p in m.bl_rna.properties if not p.is_readonly},
            [(c.frame, c.min, c.max) for c in getattr(m, "control_points", ())],
        )
        for m in fc.modifiers
    ]
    settings = (fc.extrapolation, fc.mute, fc.hide, fc.lock, fc.color_mode, fc.color[:], fc.auto_smoothing)
    samples = [s.co[:] for s in fc.sampled_points]
    return keys, fc.group.name if fc.group else None, settings, modifiers, samples


def _plain(value: Any) -> Any:
    return tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value


def _curves(action: bpy.types.Action) -> dict[tuple[str, int], tuple]:
    return {(fc.data_path, fc.array_index): _curve(fc) for fc in fcurves(action)}


def _keyed(action: bpy.types.Action, path: str) -> list[bpy.types.FCurve]:
    return [fc for fc in fcurves(action) if fc.data_path == path]


# ---------------------------------------------------------------------------------------------
# The sample walk with everything the bake must carry


def _add_bones(rig: bpy.types.Object) -> None:
    """'prop' held in the right hand (a child of hand.R: part of the skeleton, which takes every bone
    under the root) and 'ik_target', a root bone of its own (outside the skeleton, as IK targets and
    props at the armature's origin are)."""
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    bones = armature_data(rig).edit_bones
    hand = bones["hand.R"]
    prop = bones.new("prop")
    prop.head, prop.tail, prop.parent = hand.tail, hand.tail + hand.vector * 0.8, hand
    target = bones.new("ik_target")
    target.head, target.tail = (0.3, 0.2, 0.1), (0.3, 0.2, 0.3)
    bpy.ops.object.mode_set(mode="OBJECT")


def _key(owner: Any, path: str, frames_values: list[tuple[int, Any]], index: int = -1, group: str = "") -> None:
    for frame, value in frames_values:
        if path.startswith("["):
            owner[path[2:-2]] = value
        else:
            setattr(owner, path, value)
        owner.keyframe_insert(path, index=index, frame=frame, group=group)


def _character(scene: bpy.types.Scene) -> bpy.types.Object:
    """The sample walk (three impacts, the first at frame 41) whose action also keys: the object's
    location and turn (it travels 3 m and turns 0.4 rad), an integer property of the object, an
    IK/FK switch on hand.R, the scale of chest (whose neck and shoulders are not connected to it),
    head and the prop, the prop's Euler rotation, and a target bone outside the skeleton with
    modifiers, linear extrapolation, easing and other key types."""
    rig = walk_with_impacts(scene)
    _add_bones(rig)
    pose = rig.pose.bones
    pose["prop"].rotation_mode = pose["ik_target"].rotation_mode = "XYZ"
    _key(rig, "location", [(1, (0.0, 0.0, 0.0)), (120, (0.2, -1.4, 0.0)), (264, (0.5, -3.0, 0.0))])
    _key(rig, "rotation_euler", [(1, (0.0, 0.0, 0.0)), (264, (0.0, 0.0, 0.4))], index=2)
    _key(rig, '["weapon"]', [(1, 0), (200, 3)])
    _key(pose["hand.R"], '["ik_fk"]', [(1, 0.0), (30, 0.0), (120, 1.0)])
    _key(pose["chest"], "scale", [(1, (1.0, 1.0, 1.0)), (20, (1.15, 1.1, 1.15)), (40, (1.0, 1.0, 1.0))])
    _key(pose["head"], "scale", [(1, (1.0, 1.0, 1.0)), (25, (1.3, 1.3, 1.3))])
    _key(pose["prop"], "scale", [(1, (1.0, 1.0, 1.0)), (60, (2.0, 0.5, 2.0))])
    _key(pose["prop"], "rotation_euler", [(1, (0.0, 0.0, 0.0)), (90, (0.5, 0.2, -0.3))])
    _key(pose["ik_target"], "location", [(1, (0.0, 0.0, 0.0)), (50, (0.1, -0.4, 0.2)), (100, (0.0, -0.8, 0.0))])
    _key(pose["ik_target"], "rotation_euler", [(1, (0.0, 0.0, 0.0)), (40, (0.3, 0.0, 1.0))])
    action = action_of(rig)
    loc_x, loc_y, loc_z = _keyed(action, 'pose.bones["ik_target"].location')
    loc_x.extrapolation = "LINEAR"
    loc_y.keyframe_points[1].interpolation, loc_y.keyframe_points[1].easing = "BACK", "EASE_IN"
    loc_y.keyframe_points[1].back = 2.5
    loc_y.keyframe_points[0].interpolation, loc_y.keyframe_points[0].period = "ELASTIC", 3.0
    loc_y.keyframe_points[2].type = "BREAKDOWN"
    noise = loc_z.modifiers.new("NOISE")
    assert isinstance(noise, bpy.types.FModifierNoise)
    noise.strength, noise.scale, noise.phase = 0.2, 7.0, 1.5
    rot_x = _keyed(action, 'pose.bones["ik_target"].rotation_euler')[0]
    cycles = rot_x.modifiers.new("CYCLES")
    assert isinstance(cycles, bpy.types.FModifierCycles)
    cycles.mode_after = "REPEAT_OFFSET"
    rot_x.keyframe_points[1].handle_left_type = "VECTOR"
    return rig


def _decided(path: str, skeleton: list[str]) -> bool:
    """The channels the bake writes: the rotation (any mode) and location of a skeleton bone."""
    return any(
        path in (f'pose.bones["{name}"].{prop}', f"pose.bones['{name}'].{prop}")
        for name in skeleton
        for prop in (*SKELETON_ROTATIONS, "location")
    )


def _played(rig: bpy.types.Object, frames: range) -> dict[str, np.ndarray]:
    """What the armature shows at each frame: the object's world matrix, every pose bone's world
    matrix (scale included) and the two custom properties."""
    scene = bpy.context.scene
    pose_bones = rig.pose.bones
    buffer = np.empty(len(pose_bones) * 16, dtype=np.float32)
    played: dict[str, list] = {"object": [], "bones": [], "ik_fk": [], "weapon": []}
    for frame in frames:
        scene.frame_set(frame)
        pose_bones.foreach_get("matrix", as_buffer(buffer))
        world = np.array(rig.matrix_world)
        played["object"].append(world)
        played["bones"].append(world @ buffer.reshape(-1, 4, 4).transpose(0, 2, 1))
        played["ik_fk"].append(pose_bones["hand.R"]["ik_fk"])
        played["weapon"].append(rig["weapon"])
    return {key: np.array(values) for key, values in played.items()}


# ---------------------------------------------------------------------------------------------
# The bake


def test_every_channel_the_bake_does_not_change_is_carried(empty_scene):
    rig = _character(empty_scene)
    source = action_of(rig)
    before = _curves(source)
    skeleton = action_io.armature_skeleton(rig).names
    assert "prop" in skeleton and "ik_target" not in skeleton  # a child of the hand is baked; a root of its own is not

    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}

    reacted = action_of(rig)
    after = _curves(reacted)
    carried = {channel for channel in before if not _decided(channel[0], skeleton)}
    assert {path for path, _ in carried} == {
        "location",
        "rotation_euler",
        '["weapon"]',
        'pose.bones["hand.R"]["ik_fk"]',
        'pose.bones["chest"].scale',
        'pose.bones["head"].scale',
        'pose.bones["prop"].scale',
        'pose.bones["ik_target"].location',
        'pose.bones["ik_target"].rotation_euler',
    }
    for channel in carried:
        assert after[channel] == before[channel], channel
    # the bake's own channels: a quaternion and (root) location on every frame; no Euler left for the prop
    first, last = round(reacted.frame_range[0]), round(reacted.frame_range[1])
    assert not _keyed(reacted, 'pose.bones["prop"].rotation_euler')
    for name in skeleton:
        for fc in _keyed(reacted, f'pose.bones["{name}"].rotation_quaternion'):
            assert len(fc.keyframe_points) == last - first + 1
    assert all(_decided(path, skeleton) for path, _ in set(after) - carried)
    # the original is untouched; the prop and the target keep their rotation modes as the bake needs them
    assert _curves(source) == before
    assert rig.pose.bones["prop"].rotation_mode == "QUATERNION" and rig.pose.bones["ik_target"].rotation_mode == "XYZ"
    # Blender 4.4+: one slot, the one the armature plays, holding every curve
    if hasattr(reacted, "slots"):
        layered = compat.layered(reacted)
        assert len(layered.slots) == 1 and compat.layered(rig.animation_data).action_slot == layered.slots[0]
        bag = layered.layers[0].strips[0].channelbag(layered.slots[0])
        assert len(bag.fcurves) == len(after)


def test_before_the_first_impact_the_reacted_action_plays_as_the_original(empty_scene):
    rig = _character(empty_scene)
    frames = range(1, 265)
    original = _played(rig, frames)
    skeleton = action_io.armature_skeleton(rig).names
    empty_scene.frame_set(150)

    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}

    reacted = _played(rig, frames)
    before_hit = slice(0, FIRST_IMPACT - 1)  # frames 1-40
    np.testing.assert_allclose(reacted["bones"][before_hit], original["bones"][before_hit], rtol=0, atol=1e-5)
    # what the bake does not change plays as before at every frame: the object, its properties, the target bone
    for key in ("object", "ik_fk", "weapon"):
        np.testing.assert_array_equal(reacted[key], original[key], err_msg=key)
    target = rig.pose.bones.find("ik_target")
    np.testing.assert_allclose(reacted["bones"][:, target], original["bones"][:, target], rtol=0, atol=1e-6)
    # ... and the reaction does change the skeleton after the first impact
    baked = [rig.pose.bones.find(name) for name in skeleton]
    assert (
        np.abs(reacted["bones"][FIRST_IMPACT + 5 :, baked] - original["bones"][FIRST_IMPACT + 5 :, baked]).max() > 0.05
    )


def test_the_character_travels_as_before_whatever_frame_the_playhead_was_on(empty_scene):
    rig = _character(empty_scene)
    frames = [1, 40, 41, 100, 200, 264]
    original = _played(rig, range(1, 265))["object"]
    assert np.abs(original[-1][:3, 3] - original[0][:3, 3]).max() > 2.9  # it travels

    empty_scene.frame_set(1)
    addon_ops.bake(armature_name="walk")
    first = keyframes(action_of(rig))
    played = _played(rig, range(1, 265))["object"]
    np.testing.assert_array_equal(played, original)
    for frame in frames:  # the world position, frame by frame
        empty_scene.frame_set(frame)
        assert rig.matrix_world.translation[:] == tuple(original[frame - 1][:3, 3])

    empty_scene.frame_set(230)  # a rebake from elsewhere (the reacted action plays while it reads)
    addon_ops.bake(armature_name="walk")
    assert keyframes(action_of(rig)) == first
    addon_ops.clear_bake(armature_name="walk")
    empty_scene.frame_set(97, subframe=0.5)  # the object half-way through its travel and turn
    addon_ops.bake(armature_name="walk")
    assert keyframes(action_of(rig)) == first
    assert (empty_scene.frame_current, empty_scene.frame_subframe) == (97, 0.5)  # the playhead put back


def test_a_push_lands_as_the_turned_character_feels_it(empty_scene):
    """The bake reads the character as at the action's first frame; a push that lands once the
    object has turned (its rotation keyed) is turned back with it: the same reactions as on a
    character that never turns, pushed the same way relative to its body."""
    rig = walk_with_impacts(empty_scene)
    plain = bake.bake_armature(empty_scene, rig)
    plain_keys = _key_values(action_of(rig))
    bake.clear_bake(rig)

    _key(rig, "rotation_euler", [(1, (0.0, 0.0, 0.0)), (264, (0.0, 0.0, 0.9))], index=2)  # the walk's keys: 1-264
    for point in _keyed(action_of(rig), "rotation_euler")[0].keyframe_points:
        point.interpolation = "LINEAR"  # turned 0.9 * (frame - 1) / 263 at each frame
    for marker in impacts.impact_markers(empty_scene, rig.name):
        data = impacts.impact_data(marker)
        data.direction = Matrix.Rotation(0.9 * (marker.frame - 1) / 263, 3, "Z") @ data.direction
    turned = bake.bake_armature(empty_scene, rig)

    assert [(r.clip, r.reaction_class) for r in turned.reactions] == [
        (r.clip, r.reaction_class) for r in plain.reactions
    ]
    # The last push, turned back by a keyed turn, carries its round-off into the simulation, which
    # amplifies it (test_placement): its cost by up to 0.05, its keys by a few cm; before it, 1e-3.
    np.testing.assert_allclose([r.cost for r in turned.reactions], [r.cost for r in plain.reactions], atol=0.1)
    turned_keys = _key_values(action_of(rig))
    last_push = max(marker.frame for marker in impacts.impact_markers(empty_scene, rig.name))
    for channel, values in plain_keys.items():
        difference = values_before(turned_keys[channel], last_push) - values_before(values, last_push)
        assert np.abs(difference).max(initial=0.0) < 1e-3, channel


def _key_values(action: bpy.types.Action) -> dict[tuple[str, int], np.ndarray]:
    values = {}
    for fc in fcurves(action):
        co = np.empty(2 * len(fc.keyframe_points), dtype=np.float32)
        fc.keyframe_points.foreach_get("co", as_buffer(co))
        values[(fc.data_path, fc.array_index)] = co
    return values


# ---------------------------------------------------------------------------------------------
# write_motion, on each action API


def _two_bone_rig() -> bpy.types.Object:
    data = bpy.data.armatures.new("rig")
    rig = bpy.data.objects.new("rig", data)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    root = data.edit_bones.new("root")
    root.head, root.tail = (0, 0, 1), (0, 0, 1.5)
    arm = data.edit_bones.new("arm")
    arm.head, arm.tail, arm.parent = (0, 0.1, 1.5), (0.4, 0.1, 1.6), root
    bpy.ops.object.mode_set(mode="OBJECT")
    return rig


def _new_fcurve(action: bpy.types.Action, slot: Any, path: str, index: int = 0) -> bpy.types.FCurve:
    """A curve made by hand in the action (in the slot's channel bag, Blender 4.4+)."""
    if not hasattr(action, "layers"):
        return action.fcurves.new(path, index=index)
    return compat.layered(action).layers[0].strips[0].channelbag(slot).fcurves.new(path, index=index)


def test_write_motion_carries_curves_with_every_setting(empty_scene):
    rig = _two_bone_rig()
    _key(rig.pose.bones["arm"], "rotation_quaternion", [(1, (1.0, 0.0, 0.0, 0.0)), (5, (0.9, 0.3, 0.1, 0.0))])
    _key(rig, "location", [(1, (0.0, 0.0, 0.0)), (9, (1.0, 2.0, 0.0))])
    _key(rig, '["count"]', [(1, 0), (10, 3)])  # an integer: Blender rounds it between keys
    _key(rig.pose.bones["root"], "scale", [(1, (1.0, 1.0, 1.0)), (4, (1.2, 1.2, 1.2))], group="root")
    action = action_of(rig)
    slot = getattr(rig.animation_data, "action_slot", None)
    x, y, z = _keyed(action, "location")
    generator = x.modifiers.new("GENERATOR")
    assert isinstance(generator, bpy.types.FModifierGenerator)
    generator.poly_order, generator.use_additive = 2, True
    generator.coefficients = (0.5, 0.25, -0.1)
    envelope = y.modifiers.new("ENVELOPE")
    assert isinstance(envelope, bpy.types.FModifierEnvelope)
    envelope.reference_value = 0.5
    envelope.control_points.add(3.0)
    envelope.control_points.foreach_set("min", [-1.0])  # in bulk, as action_io._copy_settings sets them
    envelope.control_points.foreach_set("max", [2.0])
    stepped = y.modifiers.new("STEPPED")
    assert isinstance(stepped, bpy.types.FModifierStepped)
    stepped.frame_step, stepped.use_restricted_range, stepped.frame_start, stepped.frame_end = 2.0, True, 2.0, 7.0
    limits = z.modifiers.new("LIMITS")
    assert isinstance(limits, bpy.types.FModifierLimits)
    limits.use_max_y, limits.max_y = True, 0.4
    wave = z.modifiers.new("FNGENERATOR")
    assert isinstance(wave, bpy.types.FModifierFunctionGenerator)
    wave.function_type = "SIN"
    z.mute, z.lock, z.hide, z.color_mode, z.color = True, True, True, "AUTO_RAINBOW", (0.2, 0.4, 0.6)
    sampled = _keyed(action, 'pose.bones["root"].scale')[2]
    sampled.convert_to_samples(1, 6)
    offset = sampled.modifiers.new("GENERATOR")
    assert isinstance(offset, bpy.types.FModifierGenerator)
    offset.use_additive, offset.coefficients = True, (0.1, 0.02)
    ungrouped = _new_fcurve(action, slot, "delta_location", 1)
    ungrouped.keyframe_points.insert(2.0, 0.3)
    quoted = _new_fcurve(action, slot, "pose.bones['arm'].location", 0)  # decided by the motion, however quoted
    quoted.keyframe_points.insert(2.0, 0.3)
    if slot is not None:  # Blender 4.4+: another object's slot in the same action is not the armature's
        other = bpy.data.objects.new("other", None)
        bpy.context.scene.collection.objects.link(other)
        other.animation_data_create().action = action
        _key(other, "scale", [(1, (1.0, 1.0, 1.0)), (3, (2.0, 2.0, 2.0))])
        assert len(compat.layered(action).slots) == 2
    before = {c: v for c, v in _curves(action).items() if not _decided(c[0], ["root", "arm"])}
    carried_paths = {"location", '["count"]', 'pose.bones["root"].scale', "delta_location"}
    assert {path for path, _ in before} == carried_paths | ({"scale"} if slot is not None else set())
    motion = action_io.read_motion(rig, frame_range=(1, 10), evaluate=True)

    written = action_io.write_motion(
        rig, motion, "carried", carry_from=action, carry_slot=slot.identifier if slot is not None else ""
    )

    after = {c: v for c, v in _curves(written).items() if not _decided(c[0], ["root", "arm"])}
    assert after.keys() == {c for c in before if c[0] in carried_paths}
    for channel, curve in after.items():
        assert curve == before[channel], channel
    assert after[("delta_location", 1)][1] is None  # ungrouped stays ungrouped
    assert after[('pose.bones["root"].scale', 0)][1] == "root"  # a curve stays in its group
    assert not _keyed(written, "pose.bones['arm'].location")
    assert len(after[('pose.bones["root"].scale', 2)][4]) == 5  # the samples, frames 1-5
    # played on the armature, the copy evaluates as the original (the integer rounded as Blender rounds it)
    values = {}
    for played in (action, written):
        bake.assign_action(rig, played)
        values[played.name] = []
        for frame in range(13):
            for subframe in (0.0, 0.5):
                empty_scene.frame_set(frame, subframe=subframe)
                values[played.name].append(
                    (rig["count"], *rig.location, *rig.delta_location, *rig.pose.bones["root"].scale)
                )
    assert values["carried"] == values[action.name]


def test_write_motion_leaves_nothing_behind_when_carrying_fails(empty_scene, monkeypatch):
    rig = _two_bone_rig()
    _key(rig, "location", [(1, (0.0, 0.0, 0.0)), (9, (1.0, 2.0, 0.0))])
    _key(rig.pose.bones["arm"], "rotation_quaternion", [(1, (1.0, 0.0, 0.0, 0.0)), (5, (0.9, 0.3, 0.1, 0.0))])
    motion: Motion = action_io.read_motion(rig)

    def broken(*_args: Any) -> None:
        raise RuntimeError("copy failed")

    monkeypatch.setattr(action_io, "_copy_fcurve", broken)
    with pytest.raises(RuntimeError, match="copy failed"):
        action_io.write_motion(rig, motion, "carried", carry_from=rig.animation_data.action)
    assert "carried" not in bpy.data.actions
