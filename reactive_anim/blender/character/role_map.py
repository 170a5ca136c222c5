"""The character's role map: which bone plays which joint role (roles.py), for rigs whose bone names
are not recognised. Saved with the armature data (`Armature.reactive_anim_roles`, one entry per
role; an empty bone lets roles.py find it by name), read by the bake (bake.prepare_bake), edited in
the Reactions panel (Character Roles) with Detect, a preset for a common rig, or by hand."""

# Blender declares properties as annotations holding calls (`bone: StringProperty(...)`), which are
# not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import bpy
import numpy as np
from bpy.props import EnumProperty, StringProperty

from ...core.model.errors import ReactiveAnimError, SkeletonError
from ...core.model.roles import (
    ALL_ROLES,
    REQUIRED_ROLES,
    RIG_PRESETS,
    apply_roles,
    assign_roles,
    guess_roles,
    preset_roles,
)
from ...core.model.skeleton import Skeleton
from ..ui import settings
from . import action_io

if TYPE_CHECKING:
    pass  # fake-bpy-module's name for the result set

PRESET_ITEMS = [(name, name.replace("_", " ").title(), f"Bone names as {name} writes them") for name in RIG_PRESETS]


class REACTIVE_ANIM_PG_role(bpy.types.PropertyGroup):
    """One role and the bone that plays it ("": found by name)."""

    role: StringProperty(name="Role", description="A joint role of the ragdoll and the search")
    bone: StringProperty(name="Bone", description="The bone that plays this role (empty: found by its name)")


def role_entries(armature: bpy.types.Object) -> Any:
    """The armature's role map entries (a CollectionProperty of REACTIVE_ANIM_PG_role)."""
    return cast(Any, armature.data).reactive_anim_roles  # registered on bpy.types.Armature


def role_overrides(armature: bpy.types.Object) -> dict[str, str]:
    """The roles the animator mapped (role -> bone name)."""
    return {e.role: e.bone for e in role_entries(armature) if e.bone}


def set_roles(armature: bpy.types.Object, roles: dict[str, str]) -> None:
    """One entry per role, in the roles' order, bones from `roles` (others left empty)."""
    entries = role_entries(armature)
    entries.clear()
    for role in ALL_ROLES:
        entry = entries.add()
        entry.role = role
        entry.bone = roles.get(role, "")


def apply_character_roles(armature: bpy.types.Object, skeleton: Skeleton) -> dict[str, str]:
    """Give the bake's skeleton the armature's roles (its map, the rest by name); SkeletonError
    names the roles that are missing, the bones there are, and where to map them."""
    try:
        return apply_roles(skeleton, valid_overrides(armature) or None)  # as the panel: stale bones found by name
    except SkeletonError as exc:
        raise SkeletonError(
            f"armature '{armature.name}': {exc}. Map them in the Reactions panel, Character Roles"
        ) from None


def missing_roles(armature: bpy.types.Object) -> list[str]:
    """The required roles nothing plays (neither mapped nor found by name)."""
    found = guess_roles(action_io.armature_skeleton(armature), valid_overrides(armature))
    return [role for role in REQUIRED_ROLES if role not in found]


def valid_overrides(armature: bpy.types.Object) -> dict[str, str]:
    """The mapped roles whose bone exists (a renamed bone must not stop the editor)."""
    bones = cast(bpy.types.Armature, armature.data).bones
    return {role: bone for role, bone in role_overrides(armature).items() if bone in bones}


def _has_armature(cls: type[bpy.types.Operator], context: bpy.types.Context) -> bool:
    if not any(settings.is_character(ob) for ob in bpy.data.objects):
        cls.poll_message_set("There is no armature in this file: import a BVH first")
        return False
    return True


class _OnCharacter(settings.ArmatureOperator):
    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _has_armature(cls, context)


class REACTIVE_ANIM_OT_detect_roles(_OnCharacter):
    """Find each joint role's bone by the bones' names and hierarchy; roles already mapped are kept"""

    bl_idname = "reactive_anim.detect_roles"
    bl_label = "Detect Roles"
    bl_options = {"REGISTER", "UNDO"}

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        found = guess_roles(action_io.armature_skeleton(armature), valid_overrides(armature))
        set_roles(armature, found)
        missing = [r for r in REQUIRED_ROLES if r not in found]
        if missing:
            self.report({"WARNING"}, f"'{armature.name}': no bone found for {', '.join(missing)}; map them by hand")
            return ""
        return f"'{armature.name}': every role has its bone"


class REACTIVE_ANIM_OT_role_preset(_OnCharacter):
    """Map the joint roles from a common rig's bone names (Mixamo, Rigify, CMU, Bandai Namco, the sample)"""

    bl_idname = "reactive_anim.role_preset"
    bl_label = "Role Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Rig", items=PRESET_ITEMS)

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        found = preset_roles(self.preset, list(cast(bpy.types.Armature, armature.data).bones.keys()))
        if not found:
            raise SkeletonError(f"'{armature.name}' has none of the {self.preset} rig's bone names")
        set_roles(armature, found)
        return f"'{armature.name}': {len(found)} roles mapped from the {self.preset} preset"


class REACTIVE_ANIM_OT_clear_roles(_OnCharacter):
    """Forget the role map: every role is found by the bones' names again"""

    bl_idname = "reactive_anim.clear_roles"
    bl_label = "Clear Roles"
    bl_options = {"REGISTER", "UNDO"}

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        role_entries(armature).clear()
        return f"'{armature.name}': every role is found by name again"


def check_roles(armature: bpy.types.Object) -> str:
    """One line for the panel: every role found, or which are missing. Kept per rig (bone names,
    parents, rest heads and the role map): the panel draws on every mouse move over it, and finding
    the roles of a large rig costs far more than reading the rig for the key."""
    key = _rig_key(armature)
    status = _CHECKED.get(key)
    if status is None:
        status = _check(armature)
        if len(_CHECKED) >= CHECKED_KEPT:
            _CHECKED.pop(next(iter(_CHECKED)))
        _CHECKED[key] = status
    return status


CHECKED_KEPT = 16  # rigs whose role check is kept
_CHECKED: dict[tuple, str] = {}


def _rig_key(armature: bpy.types.Object) -> tuple:
    """What the roles are found from: bone names, parents and rest heads, and the role map."""
    bones = cast(bpy.types.Armature, armature.data).bones
    heads = np.empty(3 * len(bones), dtype=np.float32)
    bones.foreach_get("head_local", heads)  # pyright: ignore[reportArgumentType]
    names = tuple(b.name for b in bones)
    parents = tuple(b.parent.name if b.parent else "" for b in bones)
    return names, parents, heads.tobytes(), tuple(sorted(valid_overrides(armature).items()))


def _check(armature: bpy.types.Object) -> str:
    try:
        assign_roles(action_io.armature_skeleton(armature), valid_overrides(armature) or None)
    except ReactiveAnimError as exc:
        missing = missing_roles(armature)
        return f"Missing: {', '.join(missing)}" if missing else str(exc)
    return "Every role has its bone"
