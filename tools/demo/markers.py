"""The demo's impacts: four hits on the sample walk, each aimed from where the character faces then.

A push "from behind" means along the character's forward at that frame, not along a world axis:
the forward is measured from the evaluated pose, perpendicular to the hip line (the left hip's
head minus the right one's, crossed with up), so the same hits work on a walk in any direction.
Impacts are added in time order and the earlier ones are baked before the next is aimed (the
`bake` callback), so a hit that lands after an earlier reaction is aimed from the reacted pose,
the one it really hits.

The hits (frames on the timeline, from the action's first frame at the sample's 60 fps):
  push_from_behind  a firm push on the chest from behind: a few steps forward;
  push_from_front   a second later, a push on the chest from the front: a step back;
  push_during_step  a push from behind while the step back still plays (it lands during an earlier
                    reaction, paper Fig. 4): a step forward;
  side_hit          a hard hit on the hips from the character's right: it falls sideways onto the
                    knees, gets up (the library chains a get-up) and walks on.
Each names the class the demo expects. While no classifier model ships, the whole-library search
alone picks by pose, not by push (../shared/DESIGN.md, "Library and classifier"), so the demo then forces
the expected classes through the markers' reaction override and says so.

Each impact also gets an arrow (an object, shown from shortly before the hit until the end of the
reaction window) pointing along the push into the hit bone, so a viewer sees where the push came from.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import bmesh
import bpy
import numpy as np
from mathutils import Matrix, Vector

from reactive_anim.blender.impacts import impacts

from . import scene as demo_scene

ARROW_COLOUR = (0.9, 0.12, 0.02)
ARROW_LENGTH = 0.55  # metres, tail to tip
ARROW_GAP = 0.16  # metres between the tip and the hit bone's middle (about the trunk's half depth)
ARROW_LEAD = 10  # frames the arrow shows before the hit
ARROW_LAG = 15  # frames it stays after the hit (the reaction window at 60 fps)
VIEW_QUARTER = math.radians(30)  # the filmstrip's view of a push: this far from square to it, toward the front


@dataclass(frozen=True)
class DemoImpact:
    """One hit of the demo, in the character's own terms.

    seconds: when, after the action's first frame. role: the joint role hit (core/model/roles.py), so the
    bone is this armature's. push: "from_behind", "from_front", "from_right" or "from_left".
    strength: N·s. expected: the reaction class the demo expects (forced while no model ships).
    """

    name: str
    seconds: float
    role: str
    push: str
    strength: float
    expected: str


DEMO_IMPACTS = (
    DemoImpact("push_from_behind", 40 / 60, "chest", "from_behind", 150.0, "steps_forward"),
    DemoImpact("push_from_front", 100 / 60, "chest", "from_front", 150.0, "step_back"),
    DemoImpact("push_during_step", 145 / 60, "chest", "from_behind", 100.0, "step_forward"),
    DemoImpact("side_hit", 205 / 60, "pelvis", "from_right", 350.0, "fall_side_knees"),
)


def facing(armature: bpy.types.Object, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """(forward, left) over the ground at `frame`, unit (3,) vectors, from the evaluated hip line."""
    roles = demo_scene.character_roles(armature)
    hips = demo_scene.world_heads(armature, frame, [roles["hip_l"], roles["hip_r"]])
    left = hips[roles["hip_l"]] - hips[roles["hip_r"]]
    left[2] = 0.0
    left /= np.linalg.norm(left)
    forward = np.cross(left, [0.0, 0.0, 1.0])
    return forward, left


def push_direction(push: str, forward: np.ndarray, left: np.ndarray) -> np.ndarray:
    """The world direction the push moves the body: from behind = forward, from the right = left."""
    directions = {"from_behind": forward, "from_front": -forward, "from_right": left, "from_left": -left}
    if push not in directions:
        raise ValueError(f"push '{push}' is not one of {', '.join(directions)}")
    return directions[push]


def impact_frame(armature: bpy.types.Object, hit: DemoImpact) -> int:
    """The hit's timeline frame: the action's first frame plus its time at the scene's rate."""
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    source = armature.animation_data.action
    assert source is not None
    first = round(source.frame_range[0])
    return first + round(hit.seconds * fps)


def add_demo_impacts(
    scene: bpy.types.Scene,
    armature: bpy.types.Object,
    bake: Callable[[], object],
    force_classes: bool,
    hits: tuple[DemoImpact, ...] = DEMO_IMPACTS,
) -> list[bpy.types.TimelineMarker]:
    """Add each hit as an impact marker (and an arrow), in time order; `bake` runs before each hit
    after the first, so the armature plays the earlier hits' reactions when the next one is aimed.

    force_classes: put each hit's expected class in its marker's reaction override.
    """
    frames = {hit.name: impact_frame(armature, hit) for hit in hits}
    roles = demo_scene.character_roles(armature)
    markers = []
    for hit in sorted(hits, key=lambda h: frames[h.name]):
        if markers:
            bake()  # the earlier hits, so this one is aimed from the pose it lands on
        frame = frames[hit.name]
        forward, left = facing(armature, frame)
        direction = push_direction(hit.push, forward, left)
        bone = roles[hit.role]
        marker = impacts.add_impact(
            scene,
            armature,
            bone,
            frame,
            tuple(direction),
            hit.strength,
            reaction=hit.expected if force_classes else None,
            name=hit.name,
        )
        markers.append(marker)
        add_arrow(scene, armature, bone, frame, direction, hit.name)
    return markers


def view_across(push: np.ndarray, forward: np.ndarray, left: np.ndarray) -> np.ndarray:
    """Where a camera should stand (a ground direction from the character) to see `push` go across
    the picture: square to the push, on the character's front-left side, turned VIEW_QUARTER toward
    the front-left diagonal (from behind/front pushes: the left side, quartering to the front; side
    pushes: the front, quartering to the left)."""
    ground = np.array([push[0], push[1]]) / np.hypot(push[0], push[1])
    square = np.array([-ground[1], ground[0]])
    diagonal = (forward[:2] + left[:2]) / np.linalg.norm(forward[:2] + left[:2])
    if square @ diagonal < 0:
        square = -square
    # Turn toward the diagonal by VIEW_QUARTER, or all the way if it is nearer than that.
    angle = min(VIEW_QUARTER, math.acos(float(np.clip(square @ diagonal, -1.0, 1.0))))
    turn = 1.0 if square[0] * diagonal[1] - square[1] * diagonal[0] > 0 else -1.0
    c, s = math.cos(turn * angle), math.sin(turn * angle)
    return np.array([c * square[0] - s * square[1], s * square[0] + c * square[1]])


# ---------------------------------------------------------------------------------------------
# Arrows


def add_arrow(
    scene: bpy.types.Scene, armature: bpy.types.Object, bone: str, frame: int, direction: np.ndarray, name: str
) -> bpy.types.Object:
    """An arrow along `direction` whose tip stops ARROW_GAP short of the bone's middle at `frame`,
    shown (viewport and render) from ARROW_LEAD frames before the hit to ARROW_LAG after."""
    scene.frame_set(frame)
    pose_bone = armature.pose.bones[bone]
    middle = armature.matrix_world @ ((pose_bone.head + pose_bone.tail) / 2)
    tip = middle - Vector(direction.tolist()) * ARROW_GAP
    arrow = bpy.data.objects.new(f"{name} arrow", arrow_mesh(f"{name} arrow"))
    arrow.matrix_world = (
        Matrix.Translation(tip) @ Vector(direction.tolist()).to_track_quat("Z", "Y").to_matrix().to_4x4()
    )
    scene.collection.objects.link(arrow)
    for key_frame, hidden in (
        (frame - ARROW_LEAD - 1, True),
        (frame - ARROW_LEAD, False),
        (frame + ARROW_LAG + 1, True),
    ):
        arrow.hide_render = arrow.hide_viewport = hidden
        arrow.keyframe_insert("hide_render", frame=key_frame)
        arrow.keyframe_insert("hide_viewport", frame=key_frame)
    return arrow


def arrow_mesh(name: str) -> bpy.types.Mesh:
    """A shaft and a cone head along +Z, the tip at the origin, ARROW_LENGTH long."""
    head_length, shaft_radius, head_radius = 0.16, 0.022, 0.06
    mesh = bpy.data.meshes.new(name)
    shape = bmesh.new()
    shaft_length = ARROW_LENGTH - head_length
    bmesh.ops.create_cone(
        shape, cap_ends=True, segments=16, radius1=shaft_radius, radius2=shaft_radius, depth=shaft_length,
        matrix=Matrix.Translation((0.0, 0.0, -head_length - shaft_length / 2)),
    )  # fmt: skip
    bmesh.ops.create_cone(
        shape, cap_ends=True, segments=16, radius1=head_radius, radius2=0.0, depth=head_length,
        matrix=Matrix.Translation((0.0, 0.0, -head_length / 2)),
    )  # fmt: skip
    shape.to_mesh(mesh)
    shape.free()
    mesh.materials.append(demo_scene.material("Impact arrow", ARROW_COLOUR))
    return mesh
