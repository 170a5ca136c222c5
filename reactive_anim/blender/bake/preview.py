"""Preview before committing: the reacted motion plays on a ghost of the character while the
character keeps its own action; Accept makes the preview the bake (no recomputation), Discard
removes every trace.

The ghost is a second armature object sharing the character's armature data (so it has the same
bones and rest pose, and costs no copy), drawn in front of everything as wire with tinted bones,
not selectable. Its action `<action>.preview` is written on the ghost, so the character's bones,
rotation modes and action are untouched until Accept. What the preview needs to become a bake is
kept in the character's bake state (bake.py): the ghost, the action, and a JSON record of the
result (summary, per-impact rows, the impacts it was made from, the bones it keys, the source).
Showing or accepting a preview widens the scene's frame range to it, discarding it restores the
range (bake.extend_frame_range).
"""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Any, cast

import bpy

from ...core.model.errors import ReactiveAnimError, SkeletonError
from ...core.react import Baked
from .. import compat
from ..character import action_io
from ..ui import settings
from . import bake

PREVIEW_SUFFIX = ".preview"
GHOST_BONE_COLOUR = "THEME09"  # a light tint in every default theme, unlike the character's own bones


def has_preview(armature: bpy.types.Object) -> bool:
    state = bake.bake_state(armature)
    return state.preview_action is not None or state.preview_object is not None


def show_preview(job: bake.BakeJob, baked: Baked, seconds: float) -> bake.BakeResult:
    """Play the bake's result on a ghost of the job's armature (replacing an earlier preview), the
    scene's frame range widened to it."""
    armature, source = bake.job_target(job)
    discard_preview(armature)
    ghost = action = None
    try:
        with bake.held_at_frame(job.first_frame):  # placed and written as a bake writes (bake.commit_bake)
            ghost = _make_ghost(armature)
            action = action_io.write_motion(
                ghost,
                baked.motion,
                source.name + PREVIEW_SUFFIX,
                job.first_frame,
                carry_from=source,  # the character's other channels, as the bake carries them
                carry_slot=bake.source_slot(armature),
            )
        bake.assign_action(ghost, action)
    except BaseException:
        if action is not None:
            bpy.data.actions.remove(action)
        if ghost is not None:
            bpy.data.objects.remove(ghost)
        raise
    result = bake.job_result(job, baked, source.name + bake.REACTED_SUFFIX, seconds)
    state = bake.bake_state(armature)
    state.preview_object, state.preview_action = ghost, action
    state.preview_result = json.dumps(
        {
            "summary": result.summary(),  # without the range note: accepting adds its own
            "rows": result.rows(),
            "fingerprint": job.fingerprint,
            "source": source.name,
            "bones": list(baked.motion.skeleton.names),
        }
    )
    return replace(result, range_note=bake.extend_frame_range(bpy.data.scenes[job.scene], armature))


def _make_ghost(armature: bpy.types.Object) -> bpy.types.Object:
    """A second object on the same armature data, where the character is, drawn in front as wire."""
    ghost = bpy.data.objects.new(armature.name + PREVIEW_SUFFIX, armature.data)
    ghost[settings.GHOST_TAG] = armature.name  # never taken for a character (settings.is_character)
    ghost.parent = armature.parent
    ghost.parent_type = armature.parent_type
    ghost.parent_bone = armature.parent_bone
    ghost.matrix_parent_inverse = armature.matrix_parent_inverse.copy()
    ghost.matrix_basis = armature.matrix_basis.copy()
    collections = armature.users_collection or (bpy.context.scene.collection,)
    for collection in collections:
        collection.objects.link(ghost)
    bpy.context.view_layer.update()  # builds the ghost's pose
    ghost.show_in_front = True
    ghost.display_type = "WIRE"
    ghost.hide_select = True
    ghost.hide_render = True
    ghost.animation_data_create()
    for pose_bone in ghost.pose.bones:
        cast(Any, pose_bone).color.palette = GHOST_BONE_COLOUR  # PoseBone.color: Blender 4.0+
        pose_bone.rotation_mode = armature.pose.bones[pose_bone.name].rotation_mode  # for carried rotations
    return ghost


def accept_preview(armature: bpy.types.Object, scene: bpy.types.Scene) -> str:
    """Make the preview the armature's bake, exactly as a bake would have left it (the scene's frame
    range covering it); returns the reacted action's name. Raises ReactiveAnimError, changing
    nothing, if there is no preview or the character changed since (another action, bones gone)."""
    state = bake.bake_state(armature)
    action = state.preview_action
    if action is None:
        raise ReactiveAnimError(f"armature '{armature.name}' has no preview to accept")
    record = json.loads(state.preview_result)
    source = bake.source_action(armature)
    if source.name != record["source"]:
        raise SkeletonError(
            f"armature '{armature.name}' now plays '{source.name}', not '{record['source']}' as when the preview "
            "was made; preview again"
        )
    missing = [name for name in record["bones"] if name not in armature.pose.bones]
    if missing:
        raise SkeletonError(f"armature '{armature.name}' no longer has the bones {', '.join(missing)}; preview again")

    def take_preview() -> bpy.types.Action:
        for bone_name in record["bones"]:
            armature.pose.bones[bone_name].rotation_mode = "QUATERNION"  # as write_motion leaves a bake
        for slot in compat.slots(action):  # 4.4+: the slot is named after the ghost
            slot.name_display = armature.name
        return action

    reacted = bake.assign_reacted(armature, source, take_preview, owned=False)
    bake.switch_off_consumed(armature, record["bones"])
    state.preview_action = None  # the action belongs to the bake now
    _remove_ghost(state)
    summary = bake.with_range_note(record["summary"], bake.extend_frame_range(scene, armature))
    bake.record_result(armature, summary, record["rows"], record["fingerprint"])
    return reacted.name


def discard_preview(armature: bpy.types.Object) -> bool:
    """Remove the preview's ghost and action; False if there was none. A duplicated character shares
    its original's preview pointers: what another object still uses is left alone."""
    state = bake.bake_state(armature)
    if not has_preview(armature):
        return False
    action = state.preview_action
    state.preview_action = None
    _remove_ghost(state)
    if action is not None and action.users == 0:
        bpy.data.actions.remove(action)
    bake.restore_frame_range(armature)
    return True


def _remove_ghost(state: bake.REACTIVE_ANIM_PG_bake_state) -> None:
    """Forget the ghost; remove it unless another character's state still points at it."""
    ghost = state.preview_object
    state.preview_object = None
    state.preview_result = ""
    if ghost is not None and ghost.users == len(ghost.users_collection):  # only its collections left
        bpy.data.objects.remove(ghost)
