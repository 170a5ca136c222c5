"""Bake reactions into a new action, and clear a bake (DESIGN.md, "The Blender layer").

A bake reads the armature's action (action_io.read_motion) and its impact markers (impacts.py),
runs core.react.bake_reactions, and writes the reacted motion into a NEW action `<action>.reacted`,
assigned to the armature. The original action keeps a fake user and is never modified; clearing
the bake assigns it again and removes the reacted action. What a bake replaced (the original
action, its slot, the bones' rotation modes, which write_motion switches to quaternions) is kept
in a property group on the armature object, `Object.reactive_anim_bake`, with the last bake's
per-impact summary for the panel. Baking an armature that already plays its reacted action bakes
the original again and replaces the reacted action.

Any failure leaves the file as it was: everything that can fail (markers, library, classifier,
reading, the core) runs before anything is created, and whatever the bake created is removed and
the assignment restored if writing fails. Errors name the marker, clip or file at fault.

This is the synchronous bake (background mode, scripts, the command line); the modal version with
a worker thread comes with the UI.
"""

# Blender declares properties as annotations holding calls (`armature_name: StringProperty(...)`),
# which are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import bpy
from bpy.props import PointerProperty, StringProperty

from ..core.classifier import load_classifier
from ..core.errors import BVHError, ClassifierError, ImpactError, LibraryError, ReactiveAnimError, SkeletonError
from ..core.impact import Impact
from ..core.library import Library, load_library
from ..core.react import Baked, Reaction, ReactionClassifier, ReactionSettings, bake_reactions
from ..core.skeleton import Motion
from . import action_io, impacts

if TYPE_CHECKING:
    from bpy._typing.rna_enums import OperatorReturnItems  # fake-bpy-module's name for the result set

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # reactive_anim/ (or the installed extension's folder)
REACTED_SUFFIX = ".reacted"
WHOLE_LIBRARY = "impacts without an override search the whole library"
# The bake state a failed write puts back (the summary is only written after a bake succeeds).
_RESTORED_STATE = ("original_action", "reacted_action", "original_slot", "rotation_modes")

# progress(k, n, what): before impact k of n (what names its marker), and once with k == n, "done".
Progress = Callable[[int, int, str], None]


# ---------------------------------------------------------------------------------------------
# Where things are: the library, the classifier model, the library cache


def default_library_path() -> Path | None:
    """The bundled sample library: `<package>/sample_library` in an extension that ships one, else
    the repository's `sample_clips/` when running from a checkout; None if neither exists."""
    for candidate in (PACKAGE_DIR / "sample_library", PACKAGE_DIR.parent / "sample_clips"):
        if (candidate / "library.toml").is_file():
            return candidate
    return None


def default_model_path() -> Path:
    """The shipped classifier model (it may not exist yet: the bake then searches the whole library)."""
    return PACKAGE_DIR / "models" / "reaction_classifier.onnx"


def library_cache_dir() -> Path:
    """Where compiled libraries are cached; the one place that decides it.

    Never inside the library folder, which may be read-only (an installed extension, a shared
    drive): the extension's user folder when running as an installed extension, else Blender's
    user data folder (which follows BLENDER_USER_RESOURCES, so tests stay out of the user's own).
    """
    package = (__package__ or "").rpartition(".")[0]  # "bl_ext.<repo>.reactive_anim" or "reactive_anim"
    if package.startswith("bl_ext."):
        return Path(bpy.utils.extension_path_user(package, path="library_cache", create=True))
    return Path(bpy.utils.user_resource("DATAFILES", path="reactive_anim/library_cache", create=True))


def open_library(path: str | Path | None = None) -> Library:
    """The compiled library at `path` (folder or .toml; "" or None: the bundled sample library)."""
    if not path:
        found = default_library_path()
        if found is None:
            raise LibraryError(
                f"no reaction library was given and none is bundled (looked for {PACKAGE_DIR / 'sample_library'} "
                f"and {PACKAGE_DIR.parent / 'sample_clips'}); choose a library folder"
            )
        path = found
    path = Path(bpy.path.abspath(str(path)))
    if not path.exists():
        raise LibraryError(f"reaction library not found: {path}")
    library = load_library(path, cache_dir=library_cache_dir())
    # The same compiled library (its cache file is named by the content key) keeps its search index
    # and clip motions from one bake to the next, instead of building them again.
    return _OPEN_LIBRARIES.setdefault(library.cache_path or path, library)


_OPEN_LIBRARIES: dict[Path, Library] = {}


def open_classifier(model_path: str | Path | None = None) -> tuple[ReactionClassifier | None, str]:
    """The classifier and a note saying how reaction classes will be chosen.

    model_path "" or None: the shipped model if it exists, else none (the whole library is
    searched). A model path that was asked for must exist (ClassifierError names it).
    """
    if model_path:
        path = Path(bpy.path.abspath(str(model_path)))
        if not path.is_file():
            raise ClassifierError(f"classifier model not found: {path}")
    else:
        path = default_model_path()
        if not path.is_file():
            return None, f"no classifier model ({path} is missing): {WHOLE_LIBRARY}"
    return load_classifier(path), f"classifier {path.name}"


# ---------------------------------------------------------------------------------------------
# What a bake replaced, kept on the armature object


class REACTIVE_ANIM_PG_bake_state(bpy.types.PropertyGroup):
    """On the armature object: what the last bake replaced (so clear can restore it) and its summary."""

    original_action: PointerProperty(name="Original Action", type=bpy.types.Action)
    reacted_action: PointerProperty(name="Reacted Action", type=bpy.types.Action)
    original_slot: StringProperty(name="Original Slot", description="Identifier of the original action's slot")
    rotation_modes: StringProperty(name="Rotation Modes", description="JSON: bone name -> rotation mode before")
    summary: StringProperty(name="Last Bake", description="One line per impact of the last bake")


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
        raise SkeletonError(f"armature '{armature.name}' has no action to add reactions to")
    return action


# ---------------------------------------------------------------------------------------------
# Bake


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

    def impact_lines(self) -> list[str]:
        """One line per impact: frame, marker, bone, class (and how it was chosen), clip, cost, ms."""
        return [_impact_line(name, frame, r) for (name, frame), r in zip(self.markers, self.reactions, strict=True)]

    def summary(self) -> str:
        head = (
            f"'{self.armature}': {len(self.reactions)} impacts baked into '{self.reacted_action}' "
            f"(frames {self.frame_range[0]}-{self.frame_range[1]}) in {self.seconds:.2f} s; {self.classifier_note}"
        )
        return "\n".join([head, *self.impact_lines()])


def _impact_line(name: str, frame: int, r: Reaction) -> str:
    if r.impact.reaction is not None:
        chosen_by = "override"
    elif r.probabilities:
        chosen_by = f"classifier, p={r.probabilities.get(r.reaction_class, 0.0):.2f}"
    else:
        chosen_by = "whole-library search"
    over = "" if r.accepted else " (over the search threshold)"
    then = f", then {r.chained}" if r.chained else ""
    return (
        f"frame {frame} '{name}' {r.impact.bone}: {r.reaction_class} ({chosen_by}), clip {r.clip}{then}, "
        f"cost {r.cost:.1f}{over}, {r.timings.get('total', 0.0) * 1000:.0f} ms"
    )


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
    already opened (classifier, note) from open_classifier, which then replaces model_path.
    Raises a ReactiveAnimError naming the marker, clip or file at fault, leaving everything as it was.
    """
    start = time.perf_counter()
    if not isinstance(armature.data, bpy.types.Armature):
        raise SkeletonError(f"object '{armature.name}' is not an armature")
    if armature.mode == "EDIT":
        raise SkeletonError(f"armature '{armature.name}' is in Edit Mode; leave it to bake")
    # Everything that can fail on the animator's data runs before anything is created.
    source = source_action(armature)
    first, last = round(source.frame_range[0]), round(source.frame_range[1])
    markers = impacts.impact_markers(scene, armature.name)
    if not markers:
        raise ImpactError(f"armature '{armature.name}' has no impact markers to react to")
    impact_list = impacts.read_impacts(scene, armature, (first, last))
    opened = library if isinstance(library, Library) else open_library(library)
    model, note = classifier if classifier is not None else open_classifier(model_path)
    motion = action_io.read_motion(armature, source, (first, last))
    labels = [impacts.marker_label(m) for m in markers]
    for label, impact in zip(labels, impact_list, strict=True):
        if impact.bone not in motion.skeleton.names:
            raise ImpactError(f"{label} is on bone '{impact.bone}', which is not part of the animated skeleton")
    baked = _react(motion, impact_list, opened, model, settings, labels, progress)
    reacted = _write_and_assign(armature, source, baked, first)
    result = BakeResult(
        armature=armature.name,
        original_action=source.name,
        reacted_action=reacted.name,
        frame_range=(first, first + baked.motion.num_frames - 1),
        markers=[(m.name, m.frame) for m in markers],
        reactions=baked.reactions,
        classifier_note=note,
        seconds=time.perf_counter() - start,
    )
    bake_state(armature).summary = result.summary()
    return result


def _react(
    motion: Motion,
    impact_list: list[Impact],
    library: Library,
    classifier: ReactionClassifier | None,
    settings: ReactionSettings | None,
    labels: list[str],
    progress: Progress | None,
) -> Baked:
    """The core bake; an error raised while an impact is made is prefixed with its marker."""
    tracker = _MarkerProgress(labels, progress)
    try:
        return bake_reactions(motion, impact_list, library, classifier, settings, progress=tracker)
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


def _write_and_assign(
    armature: bpy.types.Object, source: bpy.types.Action, baked: Baked, first: int
) -> bpy.types.Action:
    """Write the new action and assign it; on any failure remove it and restore what was there."""
    adt = armature.animation_data
    assert adt is not None  # source_action found an action on it
    state = bake_state(armature)
    rebake = is_baked(armature)
    modes = {pb.name: pb.rotation_mode for pb in armature.pose.bones}
    saved_action, saved_slot = adt.action, _slot(adt)
    saved_state = {key: getattr(state, key) for key in _RESTORED_STATE}
    previous = state.reacted_action if rebake else None
    name = source.name + REACTED_SUFFIX
    created = None
    try:
        created = action_io.write_motion(armature, baked.motion, name, frame_start=first)
        _assign(adt, created, None)
        if not rebake:
            state.original_slot = saved_slot.identifier if saved_slot is not None else ""
            state.rotation_modes = json.dumps(modes)
        state.original_action = source
        state.reacted_action = created
    except BaseException:
        if created is not None:
            bpy.data.actions.remove(created)
        _assign(adt, saved_action, saved_slot)
        _restore_rotation_modes(armature, modes)
        for key, value in saved_state.items():
            setattr(state, key, value)
        raise
    # Past the point of failure: retire the previous bake's action and take its name.
    if previous is not None:
        bpy.data.actions.remove(previous)
        created.name = name
    source.use_fake_user = True
    return created


def _slot(adt: bpy.types.AnimData) -> Any:
    """The assigned action slot (Blender 4.4+), or None."""
    return getattr(adt, "action_slot", None)


def _assign(adt: bpy.types.AnimData, action: bpy.types.Action | None, slot: Any) -> None:
    """Play `action` through `slot` (4.4+; a slot identifier or a slot; default its first object slot)."""
    adt.action = action
    if action is None or not hasattr(adt, "action_slot"):
        return
    slots = list(cast(Any, action).slots)
    if isinstance(slot, str):
        slot = next((s for s in slots if s.identifier == slot), None)
    if slot is None:
        slot = next((s for s in slots if s.target_id_type in {"OBJECT", "UNSPECIFIED"}), None)
    if slot is not None and cast(Any, adt).action_slot != slot:
        cast(Any, adt).action_slot = slot


def _restore_rotation_modes(armature: bpy.types.Object, modes: dict[str, str]) -> None:
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
    bpy.data.actions.remove(reacted)
    if state.rotation_modes:
        _restore_rotation_modes(armature, json.loads(state.rotation_modes))
    state.original_action = None
    state.original_slot = ""
    state.rotation_modes = ""
    state.summary = ""
    return original.name


# ---------------------------------------------------------------------------------------------
# Operators


def _armature(name: str) -> bpy.types.Object:
    armature = bpy.data.objects.get(name)
    if armature is None or armature.type != "ARMATURE":
        raise SkeletonError(f"there is no armature called '{name}'" if name else "name the armature (armature_name)")
    return armature


def _has_armature(cls: type[bpy.types.Operator], context: bpy.types.Context) -> bool:
    if context.scene is None or not any(ob.type == "ARMATURE" for ob in bpy.data.objects):
        cls.poll_message_set("There is no armature in this file")
        return False
    return True


class REACTIVE_ANIM_OT_bake(bpy.types.Operator):
    """Bake the armature's impact markers into a new action with the reactions; the original is kept"""

    bl_idname = "reactive_anim.bake"
    bl_label = "Bake Reactions"
    bl_options = {"REGISTER", "UNDO"}

    armature_name: StringProperty(name="Armature", description="The armature object to bake")
    library_path: StringProperty(
        name="Library",
        description="Reaction library folder or .toml (default: the bundled sample library)",
        subtype="FILE_PATH",
    )
    model_path: StringProperty(
        name="Classifier Model", description="ONNX classifier model (default: the shipped one)", subtype="FILE_PATH"
    )

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _has_armature(cls, context)

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        wm = context.window_manager
        try:
            armature = _armature(self.armature_name)
            wm.progress_begin(0, 1)
            try:
                result = bake_armature(
                    context.scene,
                    armature,
                    self.library_path,
                    self.model_path,
                    progress=lambda k, n, _what: wm.progress_update(k / max(n, 1)),
                )
            finally:
                wm.progress_end()
        except (ReactiveAnimError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for line in result.summary().splitlines():
            self.report({"INFO"}, line)
        return {"FINISHED"}


class REACTIVE_ANIM_OT_clear_bake(bpy.types.Operator):
    """Go back to the original action and remove the baked reactions"""

    bl_idname = "reactive_anim.clear_bake"
    bl_label = "Clear Reactions"
    bl_options = {"REGISTER", "UNDO"}

    armature_name: StringProperty(name="Armature", description="The armature object whose bake is cleared")

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _has_armature(cls, context)

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        try:
            armature = _armature(self.armature_name)
            original = clear_bake(armature)
        except ReactiveAnimError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"'{armature.name}' plays '{original}' again; the reacted action is removed")
        return {"FINISHED"}
