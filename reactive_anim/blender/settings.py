"""The scene's reaction settings (`Scene.reactive_anim`): which character the panel works on, the
library and model the bake uses, and the impact list's active row. And how an operator that was
given no armature name finds its target, the same way from a button, a script or headless."""

# Blender declares properties as annotations holding calls (`library_path: StringProperty(...)`),
# which are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

from typing import cast

import bpy
from bpy.props import IntProperty, PointerProperty, StringProperty

from ..core.errors import SkeletonError


def _is_armature(_self: bpy.types.PropertyGroup, ob: bpy.types.Object) -> bool:
    return ob.type == "ARMATURE"


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
    return active if active is not None and active.type == "ARMATURE" else None


def target_armature(context: bpy.types.Context, name: str) -> bpy.types.Object:
    """The armature an operator acts on: the one named, else the panel's character, else the only
    armature in the file. SkeletonError says what to do when none can be told."""
    if name:
        armature = bpy.data.objects.get(name)
        if armature is None or armature.type != "ARMATURE":
            raise SkeletonError(f"there is no armature called '{name}'")
        return armature
    found = panel_character(context)
    if found is not None:
        return found
    armatures = [ob for ob in bpy.data.objects if ob.type == "ARMATURE"]
    if len(armatures) == 1:
        return armatures[0]
    raise SkeletonError("pick the character in the Reactions panel, select an armature, or name it (armature_name)")


def armatures_with_action() -> list[bpy.types.Object]:
    return [ob for ob in bpy.data.objects if ob.type == "ARMATURE" and ob.animation_data and ob.animation_data.action]
