"""The import operator and add-on registration on the real Blender."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

import reactive_anim
from reactive_anim.blender.character import action_io, bvh_import
from reactive_anim.core.model import quat
from tests.support.actions import action_of
from tests.support.mocap import require_mocap
from tools.devkit.blender_types import armature_data
from tools.devkit.operators import addon_ops

MALFORMED = Path(__file__).resolve().parents[1] / "data" / "malformed"
WALK = Path(__file__).resolve().parents[2] / "sample_clips" / "walk.bvh"


def test_import_builds_armature_with_quaternion_action_at_file_rate():
    path = require_mocap("cmu_iclone/002_03.bvh")
    result = addon_ops.import_bvh(filepath=str(path), armature_name="runner")
    assert result == {"FINISHED"}
    rig = bpy.data.objects["runner"]
    assert rig.type == "ARMATURE" and len(armature_data(rig).bones) == 101
    action = action_of(rig)
    assert action.use_fake_user
    assert {pb.rotation_mode for pb in rig.pose.bones} == {"QUATERNION"}
    scene = bpy.context.scene
    assert scene.render.fps / scene.render.fps_base == pytest.approx(60.0, rel=1e-3)
    assert action.frame_range[:] == (1.0, 86.0)
    # metres, not centimetres: the rest pose spans about 1.3 m between its lowest and highest bone heads
    heads = [rig.matrix_world @ b.head_local for b in armature_data(rig).bones]
    assert 1.0 < max(h.z for h in heads) - min(h.z for h in heads) < 2.1


@pytest.mark.parametrize(
    "name", ["truncated_motion_last_line.bvh", "unknown_channel.bvh", "unbalanced_extra_brace.bvh"]
)
def test_malformed_file_is_refused_and_leaves_nothing_behind(name):
    path = MALFORMED / name
    assert path.is_file(), f"corpus file {name} is missing"
    before = (len(bpy.data.objects), len(bpy.data.armatures), len(bpy.data.actions))
    with pytest.raises(RuntimeError, match=rf"{name}, line \d+"):
        addon_ops.import_bvh(filepath=str(path))
    assert (len(bpy.data.objects), len(bpy.data.armatures), len(bpy.data.actions)) == before


def test_import_selects_the_rig_and_fits_the_scene_to_the_motion():
    bpy.context.scene.frame_end = 50
    addon_ops.import_bvh(filepath=str(WALK))
    rig = bpy.data.objects["walk"]
    assert bpy.context.view_layer.objects.active == rig and rig.select_get()
    assert action_of(rig).name == "walk" and bpy.context.scene.frame_end == 264


def test_the_same_file_twice_makes_two_rigs_each_playing_its_own_action():
    """Blender renames the second rig; its action still plays on it (its own slot in Blender 4.4+)."""
    first = bvh_import.import_bvh(bpy.context, WALK)
    second = bvh_import.import_bvh(bpy.context, WALK)
    assert second.name == "walk.001" and second.animation_data.action != first.animation_data.action
    motions = [action_io.read_motion(rig, evaluate=True) for rig in (first, second)]
    assert np.abs(motions[0].global_positions() - motions[1].global_positions()).max() < 1e-6
    assert quat.angle_between(motions[1].local_rot[:, 1:], quat.identity()).max() > 0.3  # it moves


def test_import_from_edit_mode_of_another_object():
    mesh = bpy.data.objects.new("box", bpy.data.meshes.new("box"))
    bpy.context.collection.objects.link(mesh)
    bpy.context.view_layer.objects.active = mesh
    bpy.ops.object.mode_set(mode="EDIT")
    assert addon_ops.import_bvh(filepath=str(WALK)) == {"FINISHED"}
    assert bpy.data.objects["walk"].mode == "OBJECT" and mesh.mode == "OBJECT"


def test_a_joint_name_blender_cannot_hold_is_refused_and_leaves_nothing_behind(tmp_path):
    path = tmp_path / "long_name.bvh"
    path.write_text(WALK.read_text().replace("JOINT spine.001", "JOINT " + "s" * 64, 1))
    before = (len(bpy.data.objects), len(bpy.data.armatures), len(bpy.data.actions))
    with pytest.raises(RuntimeError, match="longer than the 63 bytes a Blender bone name holds"):
        addon_ops.import_bvh(filepath=str(path))
    assert (len(bpy.data.objects), len(bpy.data.armatures), len(bpy.data.actions)) == before


def test_unit_override_scales_the_character():
    path = require_mocap("cmu/90_18.bvh")
    addon_ops.import_bvh(filepath=str(path), unit="cmu", armature_name="metres")
    addon_ops.import_bvh(filepath=str(path), unit="in", armature_name="inches")
    tall = armature_data(bpy.data.objects["metres"]).bones["Head"].head_local.length
    short = armature_data(bpy.data.objects["inches"]).bones["Head"].head_local.length
    assert tall / short == pytest.approx(1 / 0.45, rel=1e-5)


def test_register_unregister_twice_in_one_process():
    """The session fixture registered the add-on; cycle it twice more and end registered."""
    for _ in range(2):
        reactive_anim.unregister()
        assert not hasattr(bpy.types, "REACTIVE_ANIM_OT_import_bvh")
        reactive_anim.register()
        assert hasattr(bpy.types, "REACTIVE_ANIM_OT_import_bvh")
    assert addon_ops.import_bvh.poll()
