"""Bake reactions into a new action, and clear a bake.

A bake reads the armature's action (action_io.read_motion) and its impact markers (impacts.py),
runs core.react.bake_reactions, and writes the reacted motion into a NEW action `<action>.reacted`,
assigned to the armature; it carries every channel of the original the reacted motion does not
decide (object keys, custom properties, bone scale, other bones: action_io.write_motion), so up to
the first impact it plays exactly as the original. The original action keeps a fake user and is
never modified; clearing the bake assigns it again and removes the reacted action. What a bake
replaced (the original action, its slot, the bones' rotation modes, which write_motion switches to
quaternions) is kept in a property group on the armature object, `Object.reactive_anim_bake`, with
the last bake's per-impact summary for the panel. Baking an armature that already plays its
reacted action bakes the original again (read in its rotation modes) and replaces the reacted
action. The motion is read and written with the object as at the action's first frame, wherever
the playhead is (`held_at_frame`).

A reaction often runs past the animation (a fall and a get-up after the walk has ended): a bake, a
preview and an accepted preview widen the scene's frame range to what the armature plays, so that
pressing play shows the whole reaction; clearing and discarding put back the range the animator had
(see "The scene's frame range" below).

A bake has three steps so that the UI never blocks: `prepare_bake` reads everything from the .blend
on the main thread into a BakeJob; `BakeJob.run` computes from that alone (numpy in, numpy out, no
bpy), so it may run in a worker thread; `commit_bake` writes the result on the main thread.
`bake_armature` does the three in a row (background mode, scripts, the command line).

Any failure leaves the file as it was: everything that can fail (markers, library, classifier,
reading, the core) runs before anything is created, and whatever the bake created is removed and
the assignment restored if writing fails. Errors name the marker, clip or file at fault.
"""

# Blender declares properties as annotations holding calls (`summary: StringProperty(...)`), which
# are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

import bpy
from bpy.props import IntVectorProperty, PointerProperty, StringProperty
from mathutils import Quaternion, Vector

from ...core.model.errors import BVHError, ImpactError, LibraryError, ReactiveAnimError, SkeletonError
from ...core.model.impact import Impact
from ...core.model.skeleton import Motion
from ...core.react import Baked, Reaction, ReactionClassifier, ReactionSettings, bake_reactions
from ...core.search.library import Library
from .. import compat
from ..character import action_io, role_map
from ..impacts import impacts
from ..ui import settings
from . import consumed, resources

REACTED_SUFFIX = ".reacted"
# The bake state a failed write puts back (the summary is only written after a bake succeeds).
_RESTORED_STATE = ("original_action", "reacted_action", "original_slot", "rotation_modes")

# progress(k, n, what): before impact k of n (what names its marker), and once with k == n, "done".
Progress = Callable[[int, int, str], None]


# ---------------------------------------------------------------------------------------------
# What a bake replaced, kept on the armature object


class REACTIVE_ANIM_PG_bake_state(bpy.types.PropertyGroup):
    """On the armature object: what the last bake replaced (so clear can restore it), its summary,
    and the preview waiting to be accepted or discarded (preview.py)."""

    original_action: PointerProperty(name="Original Action", type=bpy.types.Action)
    reacted_action: PointerProperty(name="Reacted Action", type=bpy.types.Action)
    original_slot: StringProperty(name="Original Slot", description="Identifier of the original action's slot")
    rotation_modes: StringProperty(name="Rotation Modes", description="JSON: bone name -> rotation mode before")
    summary: StringProperty(name="Last Bake", description="One line per impact of the last bake")
    rows: StringProperty(name="Last Bake Rows", description="JSON: per impact of the last bake, what the panel shows")
    fingerprint: StringProperty(name="Baked Impacts", description="The impacts the last bake (or preview) was made of")
    preview_object: PointerProperty(name="Preview Ghost", type=bpy.types.Object)
    preview_action: PointerProperty(name="Preview Action", type=bpy.types.Action)
    preview_result: StringProperty(name="Preview", description="JSON: what the preview becomes once accepted")
    muted: StringProperty(
        name="Switched Off", description="JSON: the constraints and drivers the bake consumed and muted (consumed.py)"
    )
    # A scene's name, not a pointer: an ID pointer would drag the whole scene along when the
    # character is appended into another file.
    range_scene: StringProperty(
        name="Extended Scene", description="The scene whose frame range the bake or preview widened; empty: none"
    )
    range_before: IntVectorProperty(
        name="Frame Range Before", size=4,
        description="That scene's frame start, end, preview start and end as the animator had them",
    )  # fmt: skip
    range_set: IntVectorProperty(
        name="Frame Range Set", size=4,
        description="The same four as the bake or preview set them; restored only while the scene still has these",
    )  # fmt: skip


def bake_state(armature: bpy.types.Object) -> REACTIVE_ANIM_PG_bake_state:
    """The armature's bake state (registered as `Object.reactive_anim_bake`)."""
    return cast(REACTIVE_ANIM_PG_bake_state, armature.reactive_anim_bake)  # pyright: ignore[reportAttributeAccessIssue]


def is_baked(armature: bpy.types.Object) -> bool:
    """The armature plays the reacted action of its last bake."""
    state = bake_state(armature)
    adt = armature.animation_data
    return bool(state.reacted_action and state.original_action and adt and adt.action == state.reacted_action)


def source_action(armature: bpy.types.Object) -> bpy.types.Action:
    """The action a bake reads: the original when the armature plays its reacted action, else the assigned one."""
    if is_baked(armature):
        return bake_state(armature).original_action
    action = armature.animation_data.action if armature.animation_data else None
    if action is None:
        raise SkeletonError(settings.no_action_message(armature))
    return action


def source_slot(armature: bpy.types.Object) -> str:
    """Identifier of the slot the armature plays its source action through (Blender 4.4+), whose
    channels a bake carries; "" in 4.2 or with none assigned."""
    if is_baked(armature):
        return bake_state(armature).original_slot
    slot = compat.assigned_slot(armature.animation_data) if armature.animation_data is not None else None
    return slot.identifier if slot is not None else ""


def impacts_fingerprint(scene: bpy.types.Scene, armature_name: str) -> str:
    """A short digest of the armature's impact markers (frame, bone, push, reaction): the panel
    compares it with the last bake's to say the bake is out of date."""
    parts = []
    for marker in impacts.impact_markers(scene, armature_name):
        p = impacts.impact_data(marker)
        parts.append(f"{p.uid} {marker.frame} {p.bone} {tuple(p.direction)} {p.strength} {p.reaction}")
    return hashlib.sha1("\n".join(parts).encode()).hexdigest()[:16]


# ---------------------------------------------------------------------------------------------
# Results


@dataclass(frozen=True)
class BakeResult:
    """One armature's bake: the actions, the markers (name, frame) in impact order, one Reaction each."""

    armature: str
    original_action: str
    reacted_action: str
    frame_range: tuple[int, int]  # the reacted action's keys, inclusive
    markers: list[tuple[str, int]]
    reactions: list[Reaction]
    classifier_note: str
    seconds: float
    range_note: str = ""  # how the bake widened the scene's frame range, if it did

    def impact_lines(self) -> list[str]:
        """One line per impact: frame, marker, bone, class (and how it was chosen), clip, cost, ms."""
        return [_impact_line(name, frame, r) for (name, frame), r in zip(self.markers, self.reactions, strict=True)]

    def summary(self) -> str:
        head = (
            f"'{self.armature}': {len(self.reactions)} impacts baked into '{self.reacted_action}' "
            f"(frames {self.frame_range[0]}-{self.frame_range[1]}) in {self.seconds:.2f} s; {self.classifier_note}"
        )
        return with_range_note("\n".join([head, *self.impact_lines()]), self.range_note)

    def rows(self) -> str:
        """Per impact, as JSON for the panel: marker, frame, bone, class, how chosen, clip, cost."""
        return json.dumps(
            [
                {
                    "marker": name,
                    "frame": frame,
                    "bone": r.impact.bone,
                    "class": r.reaction_class,
                    "chosen_by": _chosen_by(r),
                    "clip": r.clip,
                    "then": r.chained or "",
                    "cost": round(r.cost, 2),
                    "accepted": r.accepted,
                    "note": r.note,
                }
                for (name, frame), r in zip(self.markers, self.reactions, strict=True)
            ]
        )


def _chosen_by(r: Reaction) -> str:
    if r.impact.reaction is not None:
        return "override"
    if r.going_down:
        return "going down at C: a fall"
    if r.probabilities:
        return f"classifier, p={r.probabilities.get(r.reaction_class, 0.0):.2f}"
    return "whole-library search"


def _impact_line(name: str, frame: int, r: Reaction) -> str:
    over = "" if r.accepted else " (over the search threshold)"
    then = f", then {r.chained}" if r.chained else ""
    note = f"; {r.note}" if r.note else ""  # e.g. the library lacks the class the push called for
    return (
        f"frame {frame} '{name}' {r.impact.bone}: {r.reaction_class} ({_chosen_by(r)}), clip {r.clip}{then}, "
        f"cost {r.cost:.1f}{over}, {r.timings.get('total', 0.0) * 1000:.0f} ms{note}"
    )


# ---------------------------------------------------------------------------------------------
# Prepare (main thread), run (any thread), commit (main thread)


@dataclass(frozen=True)
class BakeJob:
    """Everything a bake reads from the .blend, read on the main thread. `run` computes from this
    alone, so it may run in a worker thread while the animator keeps working."""

    armature: str
    scene: str  # the scene whose markers it reads, and whose frame range the result widens
    source_action: str
    first_frame: int
    markers: list[tuple[str, int]]  # (name, frame) in impact order
    labels: list[str]  # how errors name each marker
    impacts: list[Impact]
    motion: Motion
    library: Library
    classifier: ReactionClassifier | None
    classifier_note: str
    settings: ReactionSettings | None
    fingerprint: str

    def run(self, progress: Progress | None = None, cancel: Callable[[], bool] | None = None) -> Baked:
        """The core bake (no bpy); an error raised while an impact is made is prefixed with its marker.
        cancel() returning True stops it with core.errors.Cancelled."""
        tracker = _MarkerProgress(self.labels, progress)
        try:
            return bake_reactions(
                self.motion, self.impacts, self.library, self.classifier, self.settings, progress=tracker, cancel=cancel
            )
        except ReactiveAnimError as exc:
            if tracker.current is None:
                raise
            kind = LibraryError if isinstance(exc, BVHError) else type(exc)  # BVHError's arguments differ
            raise kind(f"{tracker.current}: {exc}") from exc


class _MarkerProgress:
    """bake_reactions' progress callback: remembers which marker's impact is being made, and passes
    the marker's label on. The impacts are in frame order already, so bake_reactions' stable sort
    keeps them in the markers' order and its index names the marker."""

    def __init__(self, labels: list[str], progress: Progress | None) -> None:
        self.labels = labels
        self.progress = progress
        self.current: str | None = None

    def __call__(self, k: int, n: int, step: str) -> None:
        self.current = self.labels[k] if k < n else None
        if self.progress is not None:
            self.progress(k, n, self.current or step)


def prepare_bake(
    scene: bpy.types.Scene,
    armature: bpy.types.Object,
    library: Library | str | Path | None = None,
    model_path: str | Path | None = None,
    settings: ReactionSettings | None = None,
    classifier: tuple[ReactionClassifier | None, str] | None = None,
) -> BakeJob:
    """Read what the armature's bake needs; raises a ReactiveAnimError naming the marker, clip or
    file at fault. Changes nothing in the .blend. Arguments as bake_armature's."""
    if not isinstance(armature.data, bpy.types.Armature):
        raise SkeletonError(f"object '{armature.name}' is not an armature")
    if armature.library is not None:  # what a bake writes on it would not be saved
        raise SkeletonError(
            f"'{armature.name}' is linked from '{bpy.path.basename(armature.library.filepath)}': "
            "make a library override (Object > Library Override > Make) to bake it"
        )
    if armature.mode == "EDIT":
        raise SkeletonError(f"armature '{armature.name}' is in Edit Mode; leave it to bake")
    _check_scale(armature)
    source = source_action(armature)
    if not action_io.has_keyframes(source):
        raise SkeletonError(
            f"action '{source.name}' has no keyframes: key the motion, or assign the action that has it"
        )
    first, last = round(source.frame_range[0]), round(source.frame_range[1])
    markers = impacts.impact_markers(scene, armature.name)
    if not markers:
        raise ImpactError(f"armature '{armature.name}' has no impact markers to react to")
    impact_list = impacts.read_impacts(scene, armature, (first, last))
    opened = library if isinstance(library, Library) else resources.open_library(library)
    model, note = classifier if classifier is not None else resources.open_classifier(model_path)
    # a rebake reads the original as it played; the object as at the first frame, wherever the playhead is
    state = bake_state(armature)
    with consumed.active_while(armature, state.muted), _original_rotation_modes(armature), held_at_frame(first):
        impact_list = _turned_as_at(first, armature, impact_list)
        motion = action_io.read_motion(armature, source, (first, last))
    role_map.apply_character_roles(armature, motion.skeleton)
    labels = [impacts.marker_label(m) for m in markers]
    for label, impact in zip(labels, impact_list, strict=True):
        if impact.bone not in motion.skeleton.names:
            raise ImpactError(f"{label} is on bone '{impact.bone}', which is not part of the animated skeleton")
    return BakeJob(
        armature=armature.name,
        scene=scene.name,
        source_action=source.name,
        first_frame=first,
        markers=[(m.name, m.frame) for m in markers],
        labels=labels,
        impacts=impact_list,
        motion=motion,
        library=opened,
        classifier=model,
        classifier_note=note,
        settings=settings,
        fingerprint=impacts_fingerprint(scene, armature.name),
    )


@contextmanager
def _original_rotation_modes(armature: bpy.types.Object) -> Iterator[None]:
    """While a rebake reads the original: the bones in the rotation modes the original keys (the
    bake switched the skeleton's to quaternions; Euler keys read in quaternion mode read nothing)."""
    state = bake_state(armature)
    if not (is_baked(armature) and state.rotation_modes):
        yield
        return
    now = {pose_bone.name: pose_bone.rotation_mode for pose_bone in armature.pose.bones}
    restore_rotation_modes(armature, json.loads(state.rotation_modes))
    try:
        yield
    finally:
        restore_rotation_modes(armature, now)


@contextmanager
def held_at_frame(frame: int) -> Iterator[None]:
    """The scene at `frame` while the body runs, its playhead put back afterwards.

    A bake reads the motion, and writes the reacted one, with the armature's object placed as at the
    action's first frame: motions are measured in the object's axes (action_io), and a keyed or
    parented object turns from frame to frame. Read and written at the same frame, the result is
    the same whatever frame the playhead was on, and the object's own keys, carried into the
    reacted action, move it as they moved the original."""
    scene = bpy.context.scene
    playhead = scene.frame_current, scene.frame_subframe
    scene.frame_set(frame)
    try:
        yield
    finally:
        scene.frame_set(playhead[0], subframe=playhead[1])


def _turned_as_at(first: int, armature: bpy.types.Object, impact_list: list[Impact]) -> list[Impact]:
    """The impacts with their world pushes as the character, read as at frame `first`, feels them:
    a push that lands after the object has turned (a keyed rotation, a turning parent) is turned
    back by the object's turn since then. Leaves the scene at `first`."""
    scene = bpy.context.scene

    def rotation(frame: int) -> Quaternion:
        scene.frame_set(frame)
        return armature.matrix_world.to_3x3().normalized().to_quaternion()

    at = {frame: rotation(frame) for frame in sorted({first + round(i.frame) for i in impact_list})}
    start = rotation(first)
    turned = []
    for impact in impact_list:
        now = at[first + round(impact.frame)]
        if now != start:  # unturned, the push is left exactly as typed
            turned_back = start @ now.inverted() @ Vector(impact.direction)
            impact = replace(impact, direction=(turned_back.x, turned_back.y, turned_back.z))
        turned.append(impact)
    return turned


ZERO_SCALE = 1e-6  # an object axis scaled below this is taken as flattened to nothing


def _check_scale(armature: bpy.types.Object) -> None:
    """Refuse a world transform the bake cannot read: an axis scaled to zero (by the armature or a
    parent) or a mirror (a negative determinant), naming the objects whose scale does it."""
    bpy.context.view_layer.update()  # the transform as it stands now, as read_motion reads it
    matrix = armature.matrix_world.to_3x3()
    chain = [armature]
    while chain[-1].parent is not None:
        chain.append(chain[-1].parent)
    if min(column.length for column in matrix.col) < ZERO_SCALE:
        culprits = [ob for ob in chain if min(abs(v) for v in ob.scale) < ZERO_SCALE]
        raise SkeletonError(
            f"armature '{armature.name}' has a zero scale ({_scales(culprits or [armature])}): "
            "give it a scale above 0 on every axis to bake it"
        )
    if matrix.determinant() < 0:
        culprits = [ob for ob in chain if ob.scale[0] * ob.scale[1] * ob.scale[2] < 0]
        raise SkeletonError(
            f"armature '{armature.name}' is mirrored by a negative scale ({_scales(culprits or [armature])}), "
            "which the bake does not support: apply the scale (Object > Apply > Scale) or un-mirror it to bake it"
        )


def _scales(objects: list[bpy.types.Object]) -> str:
    return ", ".join(f"'{ob.name}' scale ({', '.join(f'{v:g}' for v in ob.scale)})" for ob in objects)


def job_result(job: BakeJob, baked: Baked, reacted_action: str, seconds: float) -> BakeResult:
    return BakeResult(
        armature=job.armature,
        original_action=job.source_action,
        reacted_action=reacted_action,
        frame_range=(job.first_frame, job.first_frame + baked.motion.num_frames - 1),
        markers=job.markers,
        reactions=baked.reactions,
        classifier_note=job.classifier_note,
        seconds=seconds,
    )


def job_target(job: BakeJob) -> tuple[bpy.types.Object, bpy.types.Action]:
    """The job's armature and source action, checked unchanged since prepare_bake (the animator may
    have worked on while the bake ran in the background), and its scene still there."""
    if job.scene not in bpy.data.scenes:
        raise ReactiveAnimError(f"scene '{job.scene}' was removed while the bake ran; bake again")
    armature = settings.armature_named(job.armature)
    source = source_action(armature)
    if source.name != job.source_action:
        raise SkeletonError(
            f"armature '{job.armature}' now plays '{source.name}', not '{job.source_action}' as when the bake began; "
            "bake again"
        )
    return armature, source


def commit_bake(job: BakeJob, baked: Baked, seconds: float) -> BakeResult:
    """Write the reacted motion as `<action>.reacted`, assign it and widen the scene's frame range
    to it (main thread). The range ignores a pending preview: the bake supersedes it."""
    armature, source = job_target(job)
    name, slot = source.name + REACTED_SUFFIX, source_slot(armature)

    def write() -> bpy.types.Action:
        with held_at_frame(job.first_frame):  # where prepare_bake read it
            return action_io.write_motion(
                armature, baked.motion, name, job.first_frame, carry_from=source, carry_slot=slot
            )

    reacted = assign_reacted(armature, source, write)
    switch_off_consumed(armature, baked.motion.skeleton.names)
    note = extend_frame_range(bpy.data.scenes[job.scene], armature, with_preview=False)
    result = replace(job_result(job, baked, reacted.name, seconds), range_note=note)
    record_result(armature, result.summary(), result.rows(), job.fingerprint)
    return result


def switch_off_consumed(armature: bpy.types.Object, bones: Sequence[str]) -> None:
    """Mute the constraints and drivers of the keyed bones, whose effect the reacted keys already
    hold (consumed.py); those a previous bake muted stay muted and listed, for Clear."""
    state = bake_state(armature)
    items = consumed.from_json(state.muted) + consumed.consumed(armature, bones)
    consumed.set_muted(armature, items, True)
    state.muted = consumed.to_json(items)


def record_result(armature: bpy.types.Object, summary: str, rows: str, fingerprint: str) -> None:
    state = bake_state(armature)
    state.summary, state.rows, state.fingerprint = summary, rows, fingerprint


def bake_armature(
    scene: bpy.types.Scene,
    armature: bpy.types.Object,
    library: Library | str | Path | None = None,
    model_path: str | Path | None = None,
    settings: ReactionSettings | None = None,
    progress: Progress | None = None,
    classifier: tuple[ReactionClassifier | None, str] | None = None,
) -> BakeResult:
    """Bake the armature's impact markers into `<action>.reacted`, assigned; the original untouched.

    library: a loaded Library, or its folder / .toml ("" or None: the bundled sample library).
    model_path: the classifier model ("" or None: the shipped one if present). classifier: an
    already opened (classifier, note) from resources.open_classifier, which then replaces model_path.
    Raises a ReactiveAnimError naming the marker, clip or file at fault, leaving everything as it was.
    """
    start = time.perf_counter()
    job = prepare_bake(scene, armature, library, model_path, settings, classifier)
    baked = job.run(progress)
    return commit_bake(job, baked, time.perf_counter() - start)


# ---------------------------------------------------------------------------------------------
# Assigning a reacted action, and undoing it


def assign_reacted(
    armature: bpy.types.Object, source: bpy.types.Action, make: Callable[[], bpy.types.Action], owned: bool = True
) -> bpy.types.Action:
    """Assign the reacted action `make()` returns; on any failure restore what was there (and remove
    the action if `owned`: made for this call). Replaces the previous bake's action, takes its name."""
    adt = armature.animation_data
    assert adt is not None  # source_action found an action on it
    state = bake_state(armature)
    rebake = is_baked(armature)
    modes = {pb.name: pb.rotation_mode for pb in armature.pose.bones}
    saved_action, saved_slot = adt.action, compat.assigned_slot(adt)
    saved_state = {key: getattr(state, key) for key in _RESTORED_STATE}
    previous = state.reacted_action if rebake else None
    name = source.name + REACTED_SUFFIX
    created = None
    try:
        created = make()
        _assign(adt, created, None)
        if not rebake:
            state.original_slot = saved_slot.identifier if saved_slot is not None else ""
            state.rotation_modes = json.dumps(modes)
        state.original_action = source
        state.reacted_action = created
    except BaseException:
        if created is not None and owned:
            bpy.data.actions.remove(created)
        _assign(adt, saved_action, saved_slot)
        restore_rotation_modes(armature, modes)
        for key, value in saved_state.items():
            setattr(state, key, value)
        raise
    # Past the point of failure: retire the previous bake's action (unless a duplicate of the
    # character plays it) and take its name.
    if previous is not None and previous.users == 0:
        bpy.data.actions.remove(previous)
    created.name = name
    source.use_fake_user = True
    return created


def assign_action(ob: bpy.types.Object, action: bpy.types.Action) -> None:
    """Play `action` on the object (through its first object slot in Blender 4.4+)."""
    _assign(ob.animation_data or ob.animation_data_create(), action, None)


def _assign(adt: bpy.types.AnimData, action: bpy.types.Action | None, slot: Any) -> None:
    """Play `action` through `slot` (4.4+; a slot identifier or a slot; default its first object slot)."""
    adt.action = action
    if action is None or not compat.has_slots(adt):
        return
    if slot is None or isinstance(slot, str):
        slot = compat.object_slot(action, slot or "")
    compat.assign_slot(adt, slot)


def restore_rotation_modes(armature: bpy.types.Object, modes: dict[str, str]) -> None:
    for bone_name, mode in modes.items():
        pose_bone = armature.pose.bones.get(bone_name)
        if pose_bone is not None:
            pose_bone.rotation_mode = cast(Any, mode)  # a mode Blender itself reported


def clear_bake(armature: bpy.types.Object) -> str:
    """Assign the original action again, remove the reacted one, restore the rotation modes.

    Returns the original action's name; raises ReactiveAnimError if the armature has no bake.
    """
    state = bake_state(armature)
    original, reacted = state.original_action, state.reacted_action
    if original is None or reacted is None:
        raise ReactiveAnimError(f"armature '{armature.name}' has no baked reactions to clear")
    adt = armature.animation_data or armature.animation_data_create()
    if adt.action == reacted:
        _assign(adt, original, state.original_slot or None)
    state.reacted_action = None
    if reacted.users == 0:  # a duplicate of the character may still play it
        bpy.data.actions.remove(reacted)
    if state.rotation_modes:
        restore_rotation_modes(armature, json.loads(state.rotation_modes))
    consumed.set_muted(armature, consumed.from_json(state.muted), False)
    state.original_action = None
    for key in ("original_slot", "rotation_modes", "summary", "rows", "fingerprint", "muted"):
        setattr(state, key, "")
    restore_frame_range(armature)
    return original.name


# ---------------------------------------------------------------------------------------------
# The scene's frame range
#
# The range the animator set is kept in the bake state (range_before) with the range a bake or
# preview made of it (range_set). Every change fits the scene to the animator's range widened by
# what the armature plays (its reacted action, its preview's): the range never shrinks below the
# animator's, a rebake refits it, and once nothing plays it is the animator's range again. A scene
# whose range is no longer range_set was changed by the animator since: that range is theirs.

FrameRange = tuple[int, int, int, int]  # frame_start, frame_end, frame_preview_start, frame_preview_end
_RANGE_FIELDS = ("frame_start", "frame_end", "frame_preview_start", "frame_preview_end")


def extend_frame_range(scene: bpy.types.Scene, armature: bpy.types.Object, with_preview: bool = True) -> str:
    """Widen the scene's frame range (and its preview range, if the scene uses it) to cover what the
    armature plays, so pressing play shows the whole reaction. with_preview=False leaves out a
    pending preview (a bake supersedes it). Call it before the operator returns, so that the change
    is part of its undo step. Returns the summary's note on how the range differs from the
    animator's, "" if it does not."""
    state = bake_state(armature)
    ours = state.range_scene == scene.name and _scene_range(scene) == tuple(state.range_set)
    before = cast(FrameRange, tuple(state.range_before)) if ours else _scene_range(scene)
    return _fit_frame_range(scene, armature, before, with_preview)


def restore_frame_range(armature: bpy.types.Object) -> None:
    """After Clear Reactions or Discard Preview: fit the scene to the animator's range and what the
    armature still plays; the animator's range itself when nothing does. A range changed since the
    bake or preview set it is left alone."""
    state = bake_state(armature)
    scene = bpy.data.scenes.get(state.range_scene) if state.range_scene else None
    if scene is not None and _scene_range(scene) == tuple(state.range_set):
        _fit_frame_range(scene, armature, cast(FrameRange, tuple(state.range_before)), with_preview=True)
    else:
        state.range_scene = ""


def with_range_note(summary: str, note: str) -> str:
    """A bake summary with the frame range note at the end of its first line."""
    head, newline, lines = summary.partition("\n")
    return f"{head}; {note}{newline}{lines}" if note else summary


def _scene_range(scene: bpy.types.Scene) -> FrameRange:
    return cast(FrameRange, tuple(getattr(scene, name) for name in _RANGE_FIELDS))


def _fit_frame_range(scene: bpy.types.Scene, armature: bpy.types.Object, before: FrameRange, with_preview: bool) -> str:
    """Set the scene's range to `before` widened by the keys of what the armature plays, record it
    (or forget the record when nothing widens it), and return the note for the summary."""
    state = bake_state(armature)
    playing = [state.reacted_action] if is_baked(armature) else []
    if with_preview and state.preview_action is not None:
        playing.append(state.preview_action)
    start, end, preview_start, preview_end = before
    for action in playing:
        first, last = (round(frame) for frame in action.curve_frame_range)  # the keys, whatever range is set
        start, end = min(start, first), max(end, last)
        if scene.use_preview_range:
            preview_start, preview_end = min(preview_start, first), max(preview_end, last)
    fitted = (start, end, preview_start, preview_end)
    # Each start before its end: Blender pushes the end along when a start passes it, and the
    # end's own write then sets it.
    for name, value in zip(_RANGE_FIELDS, fitted, strict=True):
        if getattr(scene, name) != value:
            setattr(scene, name, value)
    if fitted == before:
        state.range_scene = ""
        return ""
    state.range_scene, state.range_before, state.range_set = scene.name, before, fitted
    notes = []
    if fitted[:2] != before[:2]:
        notes.append(f"scene frame range extended to {start}-{end}")
    if fitted[2:] != before[2:]:
        notes.append(f"preview range extended to {preview_start}-{preview_end}")
    return "; ".join(notes)
