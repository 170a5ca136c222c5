"""The armature builder on the real Blender: Blender's own importer's rig, bone for bone."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

from reactive_anim.blender.character import action_io, armature_build, bvh_import
from reactive_anim.core.model.errors import SkeletonError
from reactive_anim.core.model.skeleton import Skeleton
from tests.support.mocap import require_mocap
from tools.devkit.blender_bvh import import_with_blender
from tools.devkit.blender_types import armature_data

WALK = Path(__file__).resolve().parents[2] / "sample_clips" / "walk.bvh"
# CMU cgspeed (joints with zero OFFSETs: bones Blender lengthens), Bandai Namco (every joint
# translated, End Sites at their joints), the iClone CC rig (101 joints, twist and face bones).
FILES = [
    "cmu/90_18.bvh",
    "bandai_namco/dataset-2/dataset-2_walk-turn-left_normal_001.bvh",
    "cmu_iclone/007_01.bvh",
]


def _file(relative: str) -> Path:
    """The file to import; skips where this Blender's importer is not the reference."""
    if relative.startswith("cmu/") and bpy.app.version < (4, 5):
        pytest.skip(
            "Blender 4.2's importer measures a bone with several children from the wrong point, "
            "which lengthens CMU's Spine1 and hands (fixed in 4.5; we follow 4.5)"
        )
    return WALK if relative == "walk" else require_mocap(relative)


@pytest.mark.parametrize("relative", ["walk", *FILES])
def test_rest_pose_is_blenders_importers(relative):
    """Same heads, tails and rest matrices (so the same rolls) as Blender's importer, except leaves
    the file gives no length in a centimetre file: Blender lengthens those to exactly 1 mm and its
    float rounding then decides whether to lengthen them again along their parent."""
    path = _file(relative)
    ours = bvh_import.import_bvh(bpy.context, path, name="ours")
    theirs = import_with_blender(bpy.context, path)
    our_bones, their_bones = armature_data(ours).bones, armature_data(theirs).bones
    assert [b.name for b in our_bones] == [b.name for b in their_bones]
    undecided = []
    for bone in our_bones:
        other = their_bones[bone.name]
        assert (bone.head_local - other.head_local).length < 1e-5, bone.name
        same = (bone.tail_local - other.tail_local).length < 1e-5
        if same:
            assert np.abs(np.array(bone.matrix_local) - np.array(other.matrix_local)).max() < 1e-5, bone.name
        else:
            undecided.append(bone)
    assert all(not b.children and abs(b.length - 1e-3) < 1e-6 for b in undecided), [b.name for b in undecided]
    assert len(undecided) <= len(our_bones) // 4


@pytest.mark.parametrize("relative", ["walk", "cmu/90_18.bvh"])
def test_blenders_action_plays_the_same_on_our_rig(relative):
    """Same rest pose, same keys: the action Blender's importer made moves our rig as ours does."""
    path = _file(relative)
    ours = bvh_import.import_bvh(bpy.context, path, name="ours")
    theirs = import_with_blender(bpy.context, path)
    own = action_io.read_motion(ours, evaluate=True)
    borrowed = action_io.read_motion(ours, theirs.animation_data.action, evaluate=True)
    assert np.abs(borrowed.global_positions() - own.global_positions()).max() < 1e-5


def _chain(offsets: list[tuple[float, float, float]], end_site: tuple[float, float, float]) -> Skeleton:
    names = [f"b{j}" for j in range(len(offsets))]
    return Skeleton(names, np.arange(len(offsets)) - 1, np.array(offsets), {len(offsets) - 1: np.array(end_site)})


def _build(skeleton: Skeleton, **options) -> bpy.types.Object:
    return armature_build.build_armature(
        bpy.context, skeleton, "rig", file_axes=options.pop("file_axes", np.eye(3)), file_unit=0.01, **options
    )


def test_a_bone_without_length_is_lengthened_as_blender_does():
    """A root at its child's head points up the file's Y a tenth of a file unit; a leaf whose End
    Site is at its head likewise."""
    rig = _build(_chain([(0, 0, 1), (0, 0, 0), (0.3, 0, 0)], end_site=(0, 0, 0)))
    bones = armature_data(rig).bones
    assert np.allclose((bones["b0"].tail_local - bones["b0"].head_local)[:], (0, 0.001, 0), atol=1e-7)
    assert np.allclose(bones["b1"].tail_local[:], bones["b2"].head_local[:], atol=1e-7)
    assert np.allclose((bones["b2"].tail_local - bones["b2"].head_local)[:], (0, 0.001, 0), atol=1e-7)


def test_roll_is_zero_in_the_file_axes():
    """Bones made in the file's axes with zero roll, then turned: a Y-up file's bones have zero roll
    in Y-up axes, so a bone along the file's X keeps its Z axis along the file's Z (Blender's -Y)."""
    y_up = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # a Y-up file's axes in Blender's: (x, y, z) -> (x, -z, y)
    rig = _build(_chain([(0, 0, 1), (0.2, 0, 0)], end_site=(0.2, 0, 0)), file_axes=y_up)
    arm = np.array(armature_data(rig).bones["b1"].matrix_local)[:3, :3]
    assert np.allclose(arm[:, 1], (1, 0, 0), atol=1e-6)  # along X
    assert np.allclose(arm[:, 2], y_up[:, 2], atol=1e-6)  # Z along the file's Z


def test_connects_children_at_their_parents_tail_unless_translated():
    skeleton = _chain([(0, 0, 1), (0, 0, 0.5), (0, 0.1, 0.4), (0, 0, 0.3)], end_site=(0, 0, 0.1))
    rig = _build(skeleton, translated_joints={2})
    assert [b.use_connect for b in armature_data(rig).bones] == [False, True, False, True]


def test_a_name_too_long_for_blender_is_refused_before_anything_is_made():
    skeleton = _chain([(0, 0, 1), (0, 0, 0.5)], end_site=(0, 0, 0.1))
    skeleton.names[1] = "x" * 64
    before = (len(bpy.data.objects), len(bpy.data.armatures))
    with pytest.raises(SkeletonError, match="longer than the 63 bytes"):
        _build(skeleton)
    assert (len(bpy.data.objects), len(bpy.data.armatures)) == before
