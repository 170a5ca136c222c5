"""The scene's frame range after a bake or a preview (blender/bake/bake.py, preview.py): it covers the
reacted action, so pressing play shows the whole reaction; it never shrinks a range the animator
set wider; undo, Clear Reactions and Discard Preview put back the animator's range."""

from __future__ import annotations

import bpy
import pytest

from reactive_anim.blender.bake import bake
from reactive_anim.blender.character import bvh_import
from reactive_anim.blender.impacts import impacts
from tests.support.actions import action_of
from tests.support.bake_scene import WALK
from tools.devkit.operators import addon_ops

WALK_RANGE = (1, 264)  # the sample walk's keys, the range its import sets
FROM_THE_RIGHT = (1.0, 0.0, 0.0)


@pytest.fixture
def rig(empty_scene) -> bpy.types.Object:
    """The sample walk with a hard hit on the hips near its end: it falls and gets up, long after
    the walk's last frame."""
    armature = bvh_import.import_bvh(bpy.context, WALK)
    impacts.add_impact(empty_scene, armature, "pelvis", 206, FROM_THE_RIGHT, 350.0, "fall_side_knees")
    assert _frame_range(empty_scene) == WALK_RANGE
    return armature


def _frame_range(scene: bpy.types.Scene) -> tuple[int, int]:
    return scene.frame_start, scene.frame_end


def _keys(action: bpy.types.Action) -> tuple[int, int]:
    first, last = action.curve_frame_range
    return round(first), round(last)


def _reacted_keys(rig: bpy.types.Object) -> tuple[int, int]:
    first, last = _keys(action_of(rig))
    assert action_of(rig).name == "walk.reacted" and first == 1 and last > 400  # the fall and get-up
    return first, last


def test_a_bake_extends_the_range_to_the_whole_reaction_and_says_so(empty_scene, rig):
    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}

    first, last = _reacted_keys(rig)
    assert _frame_range(empty_scene) == (first, last)
    head = bake.bake_state(rig).summary.splitlines()[0]
    assert head.endswith(f"; scene frame range extended to {first}-{last}")
    assert "preview range" not in head  # the scene does not use one

    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}
    assert _frame_range(empty_scene) == WALK_RANGE


def test_the_bakes_last_step_extends_the_range_and_reports_it(empty_scene, rig):
    """commit_bake is the last step of both the modal and the synchronous operator: what they report."""
    job = bake.prepare_bake(empty_scene, rig)
    result = bake.commit_bake(job, job.run(), 0.0)

    assert _frame_range(empty_scene) == result.frame_range == _reacted_keys(rig)
    assert result.summary().splitlines()[0].endswith(f"scene frame range extended to 1-{result.frame_range[1]}")


def test_a_range_set_wider_is_never_shrunk(empty_scene, rig):
    empty_scene.frame_start, empty_scene.frame_end = 0, 2000
    addon_ops.bake(armature_name="walk")
    assert _frame_range(empty_scene) == (0, 2000)
    assert "frame range" not in bake.bake_state(rig).summary
    addon_ops.clear_bake(armature_name="walk")
    assert _frame_range(empty_scene) == (0, 2000)

    empty_scene.frame_start, empty_scene.frame_end = 0, 100  # wider at the start only
    addon_ops.bake(armature_name="walk")
    assert _frame_range(empty_scene) == (0, _reacted_keys(rig)[1])
    addon_ops.clear_bake(armature_name="walk")
    assert _frame_range(empty_scene) == (0, 100)


def test_a_preview_range_in_use_is_extended_too(empty_scene, rig):
    empty_scene.use_preview_range = True
    empty_scene.frame_preview_start, empty_scene.frame_preview_end = 150, 250

    addon_ops.bake(armature_name="walk")

    first, last = _reacted_keys(rig)
    assert (empty_scene.frame_preview_start, empty_scene.frame_preview_end) == (first, last)
    assert _frame_range(empty_scene) == (first, last)
    assert (
        bake.bake_state(rig)
        .summary.splitlines()[0]
        .endswith(f"scene frame range extended to {first}-{last}; preview range extended to {first}-{last}")
    )
    addon_ops.clear_bake(armature_name="walk")
    assert (empty_scene.frame_preview_start, empty_scene.frame_preview_end) == (150, 250)
    assert _frame_range(empty_scene) == WALK_RANGE


def test_undo_of_the_bake_restores_the_range(empty_scene, rig):
    bpy.ops.ed.undo_push(message="impact added")
    # as a button calls it: through invoke (synchronous in background mode), pushing an undo step
    assert addon_ops.bake("INVOKE_DEFAULT", True, armature_name="walk") == {"FINISHED"}
    extended = _frame_range(bpy.context.scene)
    assert extended[1] > WALK_RANGE[1]

    bpy.ops.ed.undo()
    assert _frame_range(bpy.context.scene) == WALK_RANGE  # undo reloads the data: no stale references
    assert action_of(bpy.data.objects["walk"]).name == "walk"

    bpy.ops.ed.redo()
    assert _frame_range(bpy.context.scene) == extended


def test_clear_leaves_a_range_the_animator_changed_since(empty_scene, rig):
    addon_ops.bake(armature_name="walk")
    empty_scene.frame_end = 600

    addon_ops.clear_bake(armature_name="walk")

    assert _frame_range(empty_scene) == (1, 600)
    assert bake.bake_state(rig).range_scene == ""  # nothing left to restore


def test_a_rebake_refits_and_clear_still_restores_the_animators_range(empty_scene, rig):
    addon_ops.bake(armature_name="walk")
    extended = _frame_range(empty_scene)
    addon_ops.bake(armature_name="walk")
    assert _frame_range(empty_scene) == extended
    assert bake.bake_state(rig).summary.splitlines()[0].endswith(f"extended to {extended[0]}-{extended[1]}")

    addon_ops.clear_bake(armature_name="walk")
    assert _frame_range(empty_scene) == WALK_RANGE


def test_a_preview_extends_the_range_and_discard_restores_it(empty_scene, rig):
    assert addon_ops.preview(armature_name="walk") == {"FINISHED"}

    ghost_keys = _keys(bpy.data.actions["walk.preview"])
    assert ghost_keys[1] > 400 and _frame_range(empty_scene) == ghost_keys
    assert rig.animation_data.action.name == "walk"  # the character is not changed

    assert addon_ops.discard_preview(armature_name="walk") == {"FINISHED"}
    assert _frame_range(empty_scene) == WALK_RANGE

    addon_ops.preview(armature_name="walk")
    empty_scene.frame_start = 10  # the animator changes the range: discard leaves it
    addon_ops.discard_preview(armature_name="walk")
    assert _frame_range(empty_scene) == (10, ghost_keys[1])


def test_an_accepted_preview_keeps_the_range_says_so_and_clears_like_a_bake(empty_scene, rig):
    addon_ops.preview(armature_name="walk")
    empty_scene.frame_end = 300  # the animator narrows it again: accepting extends it once more

    assert addon_ops.accept_preview(armature_name="walk") == {"FINISHED"}

    first, last = _reacted_keys(rig)
    assert _frame_range(empty_scene) == (first, last)
    assert bake.bake_state(rig).summary.splitlines()[0].endswith(f"; scene frame range extended to {first}-{last}")
    addon_ops.clear_bake(armature_name="walk")
    assert _frame_range(empty_scene) == (1, 300)


def test_a_bake_over_a_preview_fits_the_bake_and_clear_restores(empty_scene, rig):
    addon_ops.preview(armature_name="walk")
    addon_ops.bake(armature_name="walk")  # discards the preview

    assert "walk.preview" not in bpy.data.actions
    assert _frame_range(empty_scene) == _reacted_keys(rig)
    addon_ops.clear_bake(armature_name="walk")
    assert _frame_range(empty_scene) == WALK_RANGE


def test_the_range_and_what_restores_it_survive_save_and_reload(empty_scene, rig, tmp_path):
    addon_ops.bake(armature_name="walk")
    extended = _frame_range(empty_scene)
    path = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)

    bpy.ops.wm.open_mainfile(filepath=str(path))

    assert _frame_range(bpy.context.scene) == extended
    assert addon_ops.clear_bake(armature_name="walk") == {"FINISHED"}
    assert _frame_range(bpy.context.scene) == WALK_RANGE
