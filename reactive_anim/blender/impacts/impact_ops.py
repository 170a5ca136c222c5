"""Impact operators: add one (from the viewport or typed), aim one from the view, jump to one,
remove one. Each takes its targets as properties (armature name, marker uid), so it runs the same
from a button, a script or headless; with no target given it uses the panel's character and the
impact list's active row."""

# Blender declares operator properties as annotations holding calls (`bone: StringProperty(...)`),
# which are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

from typing import TYPE_CHECKING

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, StringProperty

from ...core.model import quat
from ...core.model.errors import ImpactError, ReactiveAnimError
from ...core.model.roles import guess_roles
from ..character import action_io, role_map
from ..ui import settings
from . import impacts

if TYPE_CHECKING:
    from bpy._typing.rna_enums import OperatorReturnItems  # fake-bpy-module's name for the result set

# What one call is about (which impact, bone, frame, direction) is SKIP_SAVE, never carried over to
# the next: Blender otherwise hands an operator invoked from the UI its last call's values, so the
# second + hit the first one's bone. The strength and Flatten are carried over, as an animator's
# preference.

DIRECTION_SOURCES = (
    ("TYPED", "Typed", "The direction as typed"),
    ("VIEW", "From View", "Into the screen: the push comes from where the view looks from"),
)


def view_direction(view_rotation: tuple[float, ...], flatten: bool) -> tuple[float, float, float]:
    """The direction into the screen of a 3D view with this rotation (w, x, y, z), optionally laid flat
    on the ground (Z up). Looking straight down, flattening keeps the view's up direction instead."""
    rotation = np.asarray(view_rotation, dtype=float)
    into = quat.rotate(rotation, np.array([0.0, 0.0, -1.0]))
    if flatten:
        flat = np.array([into[0], into[1], 0.0])
        if np.linalg.norm(flat) < 1e-3:  # looking straight down or up: push the way the view's top points
            up = quat.rotate(rotation, np.array([0.0, 1.0, 0.0]))
            flat = np.array([up[0], up[1], 0.0])
        into = flat
    into = into / np.linalg.norm(into)
    return (float(into[0]), float(into[1]), float(into[2]))


def view_rotation_of(context: bpy.types.Context) -> tuple[float, ...] | None:
    """The rotation of the 3D view an operator was called from: its own region, else the view whose
    sidebar or header holds the button, else the window's first 3D view; None without any."""
    region = context.region_data
    if isinstance(region, bpy.types.RegionView3D):
        return _rotation(region)
    space = context.space_data
    if isinstance(space, bpy.types.SpaceView3D) and space.region_3d is not None:
        return _rotation(space.region_3d)
    screen = context.screen
    for area in screen.areas if screen else ():
        view = area.spaces.active
        if isinstance(view, bpy.types.SpaceView3D) and view.region_3d is not None:
            return _rotation(view.region_3d)
    return None


def _rotation(region: bpy.types.RegionView3D) -> tuple[float, ...]:
    q = region.view_rotation
    return (q.w, q.x, q.y, q.z)


def default_bone(armature: bpy.types.Object, context: bpy.types.Context) -> str:
    """The bone an impact lands on when none is named: the active pose bone of this armature, else its
    active bone, else its chest (by role), else the first bone."""
    pose_bone = context.active_pose_bone
    if pose_bone is not None and pose_bone.id_data == armature:
        return pose_bone.name
    data = armature.data
    assert isinstance(data, bpy.types.Armature)
    if data.bones.active is not None:
        return data.bones.active.name
    roles = guess_roles(action_io.armature_skeleton(armature), role_map.valid_overrides(armature))
    return roles.get("chest", data.bones[0].name if data.bones else "")


def _marker(context: bpy.types.Context, uid: str) -> bpy.types.TimelineMarker:
    """The impact marker with this uid, or the impact list's active row."""
    scene = context.scene
    if uid:
        marker = impacts.find_impact(scene, uid)
        if marker is None:
            raise ImpactError(f"scene '{scene.name}' has no impact marker with uid '{uid}'")
        return marker
    marker = settings.active_impact_marker(scene)
    if marker is not None:
        return marker
    raise ImpactError("pick an impact in the Reactions panel's list, or name it (uid)")


def has_impacts(cls: type[bpy.types.Operator], context: bpy.types.Context) -> bool:
    """Poll: the scene has impact markers, else "Add an impact first"."""
    if context.scene is None or not any(impacts.is_impact_marker(m) for m in context.scene.timeline_markers):
        cls.poll_message_set("Add an impact first")
        return False
    return True


class REACTIVE_ANIM_OT_add_impact(bpy.types.Operator):
    """Add an impact on the timeline: at the current frame, on the active bone, pushed into the screen"""

    bl_idname = "reactive_anim.add_impact"
    bl_label = "Add Impact"
    bl_options = {"REGISTER", "UNDO"}

    armature_name: StringProperty(
        name="Armature", description="The armature the impact hits (default: the panel's)", options={"SKIP_SAVE"}
    )
    bone: StringProperty(
        name="Bone", description="The bone that is hit (default: the active bone)", options={"SKIP_SAVE"}
    )
    frame: IntProperty(
        name="Frame", description="Timeline frame of the impact (default: the current frame)", options={"SKIP_SAVE"}
    )
    direction_source: EnumProperty(name="Direction", items=DIRECTION_SOURCES, default="TYPED", options={"SKIP_SAVE"})
    direction: FloatVectorProperty(
        name="Push Direction", description="World direction of the push", size=3, subtype="XYZ",
        default=(1.0, 0.0, 0.0), options={"SKIP_SAVE"},
    )  # fmt: skip
    flatten: BoolProperty(
        name="Flatten", description="Lay a direction from the view flat on the ground (no up or down)", default=True
    )
    view_rotation: FloatVectorProperty(
        name="View Rotation", description="The 3D view's rotation the direction is taken from", size=4,
        default=(1.0, 0.0, 0.0, 0.0), options={"HIDDEN", "SKIP_SAVE"},
    )  # fmt: skip
    strength: FloatProperty(
        name="Strength",
        description=impacts.STRENGTH_DESCRIPTION,
        default=impacts.DEFAULT_STRENGTH,
        soft_min=10.0,
        soft_max=400.0,
    )
    reaction: EnumProperty(name="Reaction", items=impacts.REACTION_ITEMS, options={"SKIP_SAVE"})
    marker_name: StringProperty(name="Marker Name", description="Default: hit_01, hit_02, ...", options={"SKIP_SAVE"})

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        if context.scene is None or not any(ob.type == "ARMATURE" for ob in bpy.data.objects):
            cls.poll_message_set("There is no armature to hit: import a BVH first")
            return False
        return True

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[OperatorReturnItems]:
        """From the viewport: the push goes into the screen, unless a direction was given."""
        rotation = view_rotation_of(context)
        if rotation is not None and not self.properties.is_property_set("direction"):
            self.view_rotation = rotation
            self.direction_source = "VIEW"
        return self.execute(context)

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        armature = bpy.data.objects.get(self.armature_name)
        if armature is not None and isinstance(armature.data, bpy.types.Armature):
            layout.prop_search(self, "bone", armature.data, "bones")
        else:
            layout.prop(self, "bone")
        layout.prop(self, "frame")
        layout.prop(self, "direction_source", expand=True)
        if self.direction_source == "VIEW":
            layout.prop(self, "flatten")
        else:
            layout.prop(self, "direction")
        layout.prop(self, "strength")
        layout.prop(self, "reaction")
        layout.prop(self, "marker_name")

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        try:
            armature = settings.target_armature(context, self.armature_name)
            self.armature_name = armature.name
            self.bone = self.bone or default_bone(armature, context)
            if not self.properties.is_property_set("frame"):
                self.frame = context.scene.frame_current
            if self.direction_source == "VIEW":
                self.direction = view_direction(tuple(self.view_rotation), self.flatten)
            marker = impacts.add_impact(
                context.scene, armature, self.bone, self.frame, tuple(self.direction), self.strength, self.reaction,
                self.marker_name,
            )  # fmt: skip
        except ReactiveAnimError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _make_active(context.scene, marker)
        self.report({"INFO"}, f"Added {impacts.marker_label(marker)} on '{armature.name}' bone '{self.bone}'")
        return {"FINISHED"}


def _make_active(scene: bpy.types.Scene, marker: bpy.types.TimelineMarker) -> None:
    """The marker becomes the impact list's active row and the timeline's only selected marker."""
    for k, other in enumerate(scene.timeline_markers):
        other.select = other == marker
        if other == marker:
            settings.scene_settings(scene).active_impact = k


class _OnImpact(bpy.types.Operator):
    """An operator on one impact (its uid, else the impact list's active row): `act` does the work
    and returns what to report; a ReactiveAnimError it raises is reported instead."""

    uid: StringProperty(
        name="Impact", description="The impact marker's uid (default: the list's active row)", options={"SKIP_SAVE"}
    )

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return has_impacts(cls, context)

    def act(self, context: bpy.types.Context, marker: bpy.types.TimelineMarker) -> str:
        raise NotImplementedError

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        return settings.reported(self, lambda: self.act(context, _marker(context, self.uid)))


class REACTIVE_ANIM_OT_aim_impact(_OnImpact):
    """Aim an impact into the screen: its push comes from where the 3D view looks from"""

    bl_idname = "reactive_anim.aim_impact"
    bl_label = "Aim Impact from View"
    bl_options = {"REGISTER", "UNDO"}

    flatten: BoolProperty(name="Flatten", description="Lay the direction flat on the ground", default=True)
    view_rotation: FloatVectorProperty(
        name="View Rotation", size=4, default=(1.0, 0.0, 0.0, 0.0), options={"HIDDEN", "SKIP_SAVE"}
    )

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[OperatorReturnItems]:
        rotation = view_rotation_of(context)
        if rotation is None:
            self.report({"ERROR"}, "there is no 3D view to aim from")
            return {"CANCELLED"}
        self.view_rotation = rotation
        return self.execute(context)

    def act(self, context: bpy.types.Context, marker: bpy.types.TimelineMarker) -> str:
        impacts.impact_data(marker).direction = view_direction(tuple(self.view_rotation), self.flatten)
        return ""


class REACTIVE_ANIM_OT_jump_to_impact(_OnImpact):
    """Go to an impact's frame and make it the active one"""

    bl_idname = "reactive_anim.jump_to_impact"
    bl_label = "Jump to Impact"
    bl_options = {"REGISTER"}

    def act(self, context: bpy.types.Context, marker: bpy.types.TimelineMarker) -> str:
        context.scene.frame_set(marker.frame)
        _make_active(context.scene, marker)
        return ""


class REACTIVE_ANIM_OT_remove_impact(_OnImpact):
    """Remove an impact and its timeline marker"""

    bl_idname = "reactive_anim.remove_impact"
    bl_label = "Remove Impact"
    bl_options = {"REGISTER", "UNDO"}

    def act(self, context: bpy.types.Context, marker: bpy.types.TimelineMarker) -> str:
        label = impacts.marker_label(marker)
        impacts.remove_impact(context.scene, marker)
        active = settings.scene_settings(context.scene)
        active.active_impact = min(active.active_impact, len(context.scene.timeline_markers) - 1)
        return f"Removed {label}"
