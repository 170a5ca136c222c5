"""The scene's reaction settings (`Scene.reactive_anim`): which character the panel works on, the
library and model the bake uses, and the impact list's active row. And how an operator that was
given no armature name finds its target, the same way from a button, a script or headless."""

# Blender declares properties as annotations holding calls (`library_path: StringProperty(...)`),
# which are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, cast

import bpy
from bpy.props import IntProperty, PointerProperty, StringProperty

from ...core.model.errors import ReactiveAnimError, SkeletonError
from ..impacts import impacts

if TYPE_CHECKING:
    from bpy._typing.rna_enums import OperatorReturnItems  # fake-bpy-module's name for the result set

GHOST_TAG = "reactive_anim_ghost"  # the ID property that marks a preview's ghost (preview.py)


def is_character(ob: bpy.types.Object) -> bool:
    """An armature an animator works on: not a preview's ghost."""
    return ob.type == "ARMATURE" and GHOST_TAG not in ob


def _is_armature(_self: bpy.types.PropertyGroup, ob: bpy.types.Object) -> bool:
    return is_character(ob)


class REACTIVE_ANIM_PG_scene(bpy.types.PropertyGroup):
    """Per scene: the character the Reactions panel shows, the library and model its bakes use."""

    character: PointerProperty(
        name="Character", description="The armature the impacts and bakes of this panel are for", type=bpy.types.Object,
        poll=_is_armature,
    )  # fmt: skip
    library_path: StringProperty(
        name="Library",
        description="Reaction library folder (with library.toml) or .toml file; empty: the bundled sample library",
        subtype="FILE_PATH",
    )
    model_path: StringProperty(
        name="Classifier",
        description="ONNX reaction classifier; empty: the shipped model",
        subtype="FILE_PATH",
    )
    active_impact: IntProperty(name="Active Impact", description="Row of the impact list (a timeline marker index)")


def scene_settings(scene: bpy.types.Scene) -> REACTIVE_ANIM_PG_scene:
    """The scene's settings (registered as `Scene.reactive_anim`)."""
    return cast(REACTIVE_ANIM_PG_scene, scene.reactive_anim)  # pyright: ignore[reportAttributeAccessIssue]


def panel_character(context: bpy.types.Context) -> bpy.types.Object | None:
    """The character the panel works on: the one picked in it, else the active armature."""
    if context.scene is not None:
        picked = scene_settings(context.scene).character
        if picked is not None and picked.name in context.scene.objects:
            return picked
    active = context.active_object
    return active if active is not None and is_character(active) else None


def target_armature(context: bpy.types.Context, name: str) -> bpy.types.Object:
    """The armature an operator acts on: the one named, else the panel's character, else the only
    armature in the file. SkeletonError says what to do when none can be told."""
    if name:
        return armature_named(name)
    found = panel_character(context)
    if found is not None:
        return found
    armatures = [ob for ob in bpy.data.objects if is_character(ob)]
    # A linked character with a library override in the file is one character, the override.
    overridden = {ob.override_library.reference for ob in armatures if ob.override_library is not None}
    armatures = [ob for ob in armatures if ob not in overridden]
    if len(armatures) == 1:
        return armatures[0]
    raise SkeletonError("pick the character in the Reactions panel, select an armature, or name it (armature_name)")


def armature_named(name: str) -> bpy.types.Object:
    """The armature object called `name`; SkeletonError names what is missing."""
    armature = bpy.data.objects.get(name) if name else None
    if armature is not None and armature.type != "ARMATURE":
        raise SkeletonError(f"object '{name}' is a {armature.type.lower()}, not an armature")
    if armature is None:
        raise SkeletonError(f"there is no armature called '{name}'" if name else "name the armature (armature_name)")
    return armature


def armatures_with_action() -> list[bpy.types.Object]:
    return [ob for ob in bpy.data.objects if is_character(ob) and ob.animation_data and ob.animation_data.action]


def nla_strips(armature: bpy.types.Object) -> list[str]:
    """The names of the armature's NLA strips."""
    adt = armature.animation_data
    return [strip.name for track in adt.nla_tracks for strip in track.strips] if adt is not None else []


def no_action_message(armature: bpy.types.Object) -> str:
    """Why the armature has nothing to bake: its motion is in NLA strips (and how to bake from
    them), or it has no animation at all."""
    strips = nla_strips(armature)
    if not strips:
        return f"armature '{armature.name}' has no action to add reactions to"
    return (
        f"armature '{armature.name}' plays its motion from NLA strips ({', '.join(strips)}), not from an action: "
        "bake them into one action (Object > Animation > Bake Action), or make a strip's action the active "
        "action (Action Editor) and mute its track, then bake reactions"
    )


def active_impact_marker(scene: bpy.types.Scene, armature_name: str | None = None) -> bpy.types.TimelineMarker | None:
    """The impact list's active row, if it is an impact marker (of `armature_name`, if given)."""
    index = scene_settings(scene).active_impact
    markers = scene.timeline_markers
    if not 0 <= index < len(markers) or not impacts.is_impact_marker(markers[index]):
        return None
    marker = markers[index]
    return marker if armature_name is None or impacts.character_name(marker) == armature_name else None


class ArmatureOperator(bpy.types.Operator):
    """An operator on one armature (named, else the panel's character): `act` does the work and
    returns what to report; a ReactiveAnimError it raises is reported instead, and nothing is done."""

    armature_name: StringProperty(
        name="Armature", description="The armature (default: the panel's)", options={"SKIP_SAVE"}
    )

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        raise NotImplementedError

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        return reported(self, lambda: self.act(context, target_armature(context, self.armature_name)))


def reported(operator: bpy.types.Operator, action: Callable[[], str]) -> set[OperatorReturnItems]:
    """Run an operator's work: FINISHED with its message reported, or CANCELLED with the
    ReactiveAnimError it raised reported as the error (it must change nothing before raising)."""
    try:
        message = action()
    except ReactiveAnimError as exc:
        operator.report({"ERROR"}, str(exc))
        return {"CANCELLED"}
    if message:
        operator.report({"INFO"}, message)
    return {"FINISHED"}
