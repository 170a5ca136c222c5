"""The demo's scene: the sample walk on an armature, a mannequin that renders, a floor, a camera, a sun.

Built in a fresh, empty Blender (factory settings), so the demo depends on nobody's startup file.
The character comes in through the project's own importer (blender/character/bvh_import.py), as an animator's
mocap would. The mannequin is one mesh of capsules, one per link of the skeleton, deformed by an
Armature modifier through vertex groups (each capsule wholly on the bone that rotates it), so it
follows whatever action the armature plays, the reacted one included. Its proportions come from
the skeleton's joint roles (core/model/roles.py), not from bone names, and its left limbs are tinted
slightly blue, its right ones slightly warm, so the pose reads at a glance. The floor is a 1 m
checker, so a sliding foot shows against it. The camera rides on an empty that follows the root
bone over the ground, three-quarter side-on to the direction of the walk; the sun is there for
Eevee and Cycles (the filmstrip's Workbench uses its own studio light).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix, Vector

from reactive_anim.blender.character import action_io, bvh_import
from reactive_anim.core.model.roles import assign_roles, read_joint_name
from tools.devkit.blender_types import as_buffer

CHARACTER_NAME = "Walker"
MANNEQUIN_NAME = "Mannequin"
CAMERA_NAME = "Camera"
CAMERA_TARGET_NAME = "Camera target"

# Colours (linear RGB): a neutral grey body, the left side a little blue, the right a little warm.
BODY_COLOUR = (0.50, 0.50, 0.48)
LEFT_COLOUR = (0.36, 0.44, 0.62)
RIGHT_COLOUR = (0.64, 0.42, 0.34)
FLOOR_COLOURS = ((0.80, 0.80, 0.78), (0.60, 0.60, 0.60))
SKY_COLOUR = (0.62, 0.66, 0.72)

FLOOR_SIZE = 60  # metres, square, in 1 m checker tiles
CAMERA_DISTANCE = 4.2  # metres from the followed point, over the ground
CAMERA_HEIGHT = 1.25  # metres
CAMERA_AIM_HEIGHT = 0.7  # metres: the camera looks at this height above the followed point
CAMERA_QUARTER = math.radians(35)  # from side-on toward the character's front
CAMERA_LENS = 35  # mm (36 mm sensor)
SUN_DIRECTION = (-0.35, 0.45, -0.82)  # the sun shines along this (world axes; high in the sky)


@dataclass(frozen=True)
class Part:
    """One capsule of the mannequin, for a link from a joint to a child joint (metres).

    width: semi-axis across the body (along the hip line, where the link allows it); depth: the
    other semi-axis; cap: how far the rounded ends reach past the link's ends; start, stop: the
    part of the link the capsule's core covers, as fractions of its length.
    """

    width: float
    depth: float
    cap: float
    start: float = 0.0
    stop: float = 1.0


# A part per joint role (core/model/roles.py); links from the trunk to a limb get their own parts.
PARTS = {
    "pelvis": Part(0.15, 0.11, 0.08, 0.0, 1.0),
    "waist": Part(0.13, 0.095, 0.06),
    "back": Part(0.14, 0.10, 0.06),
    "chest": Part(0.16, 0.105, 0.07, 0.0, 0.55),
    "neck": Part(0.045, 0.045, 0.03),
    "head": Part(0.08, 0.095, 0.085, 0.35, 0.45),
    "clavicle": Part(0.05, 0.05, 0.05),
    "shoulder": Part(0.05, 0.05, 0.045),
    "elbow": Part(0.042, 0.042, 0.04),
    "wrist": Part(0.02, 0.042, 0.03, 0.0, 0.75),
    "hip": Part(0.075, 0.075, 0.065),
    "knee": Part(0.055, 0.055, 0.05),
    "ankle": Part(0.045, 0.03, 0.03),
    "toe": Part(0.04, 0.018, 0.015),
    "hip_link": Part(0.085, 0.085, 0.085),
    "shoulder_link": Part(0.055, 0.055, 0.05),
    "other": Part(0.03, 0.03, 0.03),
}
TRUNK_ROLES = ("pelvis", "waist", "back", "chest", "neck", "head")
CAPSULE_SEGMENTS = 16  # around the capsule
CAP_RINGS = 4  # rings per rounded end, pole excluded


# ---------------------------------------------------------------------------------------------
# The scene


def build_scene(bvh_path: str | Path) -> bpy.types.Object:
    """A fresh Blender with the sample character, mannequin, floor, camera and sun; returns the armature.

    The scene takes the action's frame rate (the importer sets it) and frame range.
    """
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    armature = bvh_import.import_bvh(bpy.context, bvh_path, name=CHARACTER_NAME)
    action = armature.animation_data.action
    assert action is not None
    fit_frame_range(scene, action.frame_range[:])
    add_mannequin(armature)
    first, last = (round(f) for f in action.frame_range)
    start, end = ground_point(armature, first), ground_point(armature, last)
    travel = end - start
    add_floor(scene, (start + end) / 2)
    add_camera(scene, armature, travel)
    add_sun(scene)
    add_world(scene)
    scene.frame_set(first)
    return armature


def fit_frame_range(scene: bpy.types.Scene, frame_range: Iterable[float]) -> None:
    """The scene's range becomes the (inclusive) frame range given, e.g. an action's."""
    first, last = (round(f) for f in frame_range)
    scene.frame_start, scene.frame_end = first, last


def character_roles(armature: bpy.types.Object) -> dict[str, str]:
    """Joint role -> bone name for the armature (core/model/roles.py)."""
    return assign_roles(action_io.armature_skeleton(armature))


def world_heads(armature: bpy.types.Object, frame: int, bones: Iterable[str]) -> dict[str, np.ndarray]:
    """World positions of the bones' heads in the evaluated pose at `frame` (the scene moves there)."""
    bpy.context.scene.frame_set(frame)
    world = armature.matrix_world
    return {name: np.array(world @ armature.pose.bones[name].head) for name in bones}


def ground_point(armature: bpy.types.Object, frame: int) -> np.ndarray:
    """Where the root bone is over the ground at `frame`, (x, y)."""
    root = action_io.armature_skeleton(armature).names[0]
    return world_heads(armature, frame, [root])[root][:2]


# ---------------------------------------------------------------------------------------------
# The mannequin


def add_mannequin(armature: bpy.types.Object) -> bpy.types.Object:
    """A capsule mesh skinned to the armature's rest pose, one vertex group per bone."""
    data = armature.data
    assert isinstance(data, bpy.types.Armature)
    role_of = {bone: role for role, bone in character_roles(armature).items()}
    # The body's axes at rest, in armature space: across (right to left) along the hip line.
    lateral = (
        data.bones[role_of_bone(role_of, "hip_l")].head_local - data.bones[role_of_bone(role_of, "hip_r")].head_local
    )
    lateral = np.array(lateral.normalized())
    vertices: list[np.ndarray] = []
    faces: list[list[int]] = []
    groups: dict[str, list[int]] = {}
    sides: list[int] = []  # per face: 0 body, 1 left, 2 right
    for bone in data.bones:
        head = np.array(bone.head_local)
        ends = [np.array(child.head_local) for child in bone.children] or [np.array(bone.tail_local)]
        for child, end in zip(bone.children or [None], ends, strict=True):
            part = _part(role_of, bone.name, None if child is None else child.name)
            if np.linalg.norm(end - head) < 1e-3:
                continue
            verts, capsule_faces = capsule(head, end, part, lateral)
            first = sum(len(v) for v in vertices)
            groups.setdefault(bone.name, []).extend(range(first, first + len(verts)))
            vertices.append(verts)
            faces += [[first + v for v in face] for face in capsule_faces]
            sides.extend([_side_index(role_of.get(bone.name), bone.name)] * len(capsule_faces))
    mesh = bpy.data.meshes.new(MANNEQUIN_NAME)
    mesh.from_pydata(np.concatenate(vertices).tolist(), [], faces)
    for colour, name in ((BODY_COLOUR, "body"), (LEFT_COLOUR, "left"), (RIGHT_COLOUR, "right")):
        mesh.materials.append(material(f"{MANNEQUIN_NAME} {name}", colour))
    mesh.polygons.foreach_set("material_index", as_buffer(np.array(sides, dtype=np.int32)))
    mesh.polygons.foreach_set("use_smooth", as_buffer(np.ones(len(sides), dtype=bool)))
    mesh.update()
    body = bpy.data.objects.new(MANNEQUIN_NAME, mesh)
    bpy.context.scene.collection.objects.link(body)
    body.parent = armature  # identity: the mesh's space is the armature's
    for bone_name, indices in groups.items():
        body.vertex_groups.new(name=bone_name).add(indices, 1.0, "REPLACE")
    modifier = body.modifiers.new("Armature", "ARMATURE")
    assert isinstance(modifier, bpy.types.ArmatureModifier)
    modifier.object = armature
    return body


def role_of_bone(role_of: dict[str, str], role: str) -> str:
    """The bone that plays `role` (role_of maps bone -> role)."""
    return next(bone for bone, r in role_of.items() if r == role)


def _part(role_of: dict[str, str], bone: str, child: str | None) -> Part:
    """The capsule for the link bone -> child (child None: the bone's own tail)."""
    role = _role_kind(role_of.get(bone))
    child_role = _role_kind(role_of.get(child)) if child else None
    if role in TRUNK_ROLES and child_role is not None and child_role not in TRUNK_ROLES:
        return PARTS["hip_link" if child_role == "hip" else "shoulder_link"]
    return PARTS.get(role or "other", PARTS["other"])


def _role_kind(role: str | None) -> str | None:
    """The role without its side ("hip_l" -> "hip"); trunk roles stay as they are."""
    return None if role is None else role.removesuffix("_l").removesuffix("_r")


def _side_index(role: str | None, bone: str) -> int:
    """0 for the middle of the body, 1 for the left side, 2 for the right (by role, else by name)."""
    side = role[-1] if role is not None and role.endswith(("_l", "_r")) else read_joint_name(bone).side
    return {"l": 1, "r": 2}.get(side or "", 0)


def capsule(p0: np.ndarray, p1: np.ndarray, part: Part, lateral: np.ndarray) -> tuple[np.ndarray, list[list[int]]]:
    """Vertices (V, 3) and faces (quads around, triangles at the two poles), indices from 0.

    The core runs from p0 + start * (p1 - p0) to p0 + stop * (p1 - p0); its cross-section is an
    ellipse with semi-axes width (along `lateral` made perpendicular to the link) and depth; the
    ends are half-ellipsoids reaching `cap` past the core.
    """
    link = p1 - p0
    axis = link / np.linalg.norm(link)
    across = lateral - axis * float(lateral @ axis)
    if np.linalg.norm(across) < 0.3:  # a link along the hip line: measure width along the up axis
        up = np.array([0.0, 0.0, 1.0])
        across = up - axis * float(up @ axis)
    across /= np.linalg.norm(across)
    other = np.cross(axis, across)
    a, b = p0 + part.start * link, p0 + part.stop * link
    # Rings from the pole at a, over the core, to the pole at b: (height along axis, radius scale).
    angles = np.linspace(-math.pi / 2, 0.0, CAP_RINGS + 1)[1:]
    rings = [(float(part.cap * math.sin(t)), float(math.cos(t)), a) for t in angles]
    rings += [(float(part.cap * math.sin(-t)), float(math.cos(t)), b) for t in angles[::-1]]
    around = np.linspace(0.0, 2 * math.pi, CAPSULE_SEGMENTS, endpoint=False)
    circle = np.outer(np.cos(around), across * part.width) + np.outer(np.sin(around), other * part.depth)
    vertices = [a - axis * part.cap]
    for height, scale, centre in rings:
        vertices.extend(centre + axis * height + scale * circle)
    vertices.append(b + axis * part.cap)
    n, count = CAPSULE_SEGMENTS, len(rings)
    k = np.arange(n)
    faces: list[list[int]] = [[0, 1 + (i + 1) % n, 1 + i] for i in range(n)]
    for r in range(count - 1):
        lo, hi = 1 + r * n, 1 + (r + 1) * n
        faces += np.column_stack([lo + k, lo + (k + 1) % n, hi + (k + 1) % n, hi + k]).tolist()
    top, last = 1 + count * n, 1 + (count - 1) * n
    faces += [[last + i, last + (i + 1) % n, top] for i in range(n)]
    return np.array(vertices), faces


def material(name: str, colour: tuple[float, float, float]) -> bpy.types.Material:
    """A plain diffuse material: the colour for Workbench (diffuse_color) and for Eevee/Cycles."""
    mat = bpy.data.materials.new(name)
    mat.diffuse_color = (*colour, 1.0)
    mat.roughness = 0.7
    if mat.node_tree is None and hasattr(mat, "use_nodes"):
        mat.use_nodes = True
    shader = mat.node_tree.nodes.get("Principled BSDF") if mat.node_tree else None
    if shader is not None:
        shader.inputs["Base Color"].default_value = (*colour, 1.0)  # pyright: ignore[reportAttributeAccessIssue]
        shader.inputs["Roughness"].default_value = 0.7  # pyright: ignore[reportAttributeAccessIssue]
    return mat


# ---------------------------------------------------------------------------------------------
# Floor, camera, light


def add_floor(scene: bpy.types.Scene, centre: np.ndarray) -> bpy.types.Object:
    """A FLOOR_SIZE m square at z = 0 around `centre`, in 1 m checker tiles (two materials)."""
    n = FLOOR_SIZE
    grid = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij"), axis=-1).reshape(-1, 2)
    vertices = np.column_stack([grid - n / 2, np.zeros(len(grid))])
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    corner = i * (n + 1) + j
    faces = np.column_stack([corner, corner + n + 1, corner + n + 2, corner + 1])
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata(vertices.tolist(), [], faces.tolist())
    for k, colour in enumerate(FLOOR_COLOURS):
        mesh.materials.append(material(f"Floor {k + 1}", colour))
    mesh.polygons.foreach_set("material_index", as_buffer(((i + j) % 2).astype(np.int32)))
    mesh.update()
    floor = bpy.data.objects.new("Floor", mesh)
    floor.location = (round(float(centre[0])), round(float(centre[1])), 0.0)
    scene.collection.objects.link(floor)
    return floor


def add_camera(scene: bpy.types.Scene, armature: bpy.types.Object, travel: np.ndarray) -> bpy.types.Object:
    """A camera on an empty that follows the root bone over the ground (Copy Location, x and y).

    It looks from the character's left, CAMERA_QUARTER from side-on toward where the walk goes.
    """
    root = action_io.armature_skeleton(armature).names[0]
    target = bpy.data.objects.new(CAMERA_TARGET_NAME, None)
    scene.collection.objects.link(target)
    follow = target.constraints.new("COPY_LOCATION")
    assert isinstance(follow, bpy.types.CopyLocationConstraint)
    follow.target, follow.subtarget, follow.use_z = armature, root, False
    heading = travel / np.linalg.norm(travel) if np.linalg.norm(travel) > 1e-6 else np.array([0.0, -1.0])
    left = np.array([-heading[1], heading[0]])  # the walker's left, looking along the heading
    data = bpy.data.cameras.new(CAMERA_NAME)
    data.lens = CAMERA_LENS
    camera = bpy.data.objects.new(CAMERA_NAME, data)
    scene.collection.objects.link(camera)
    camera.parent = target
    camera.matrix_parent_inverse = Matrix.Identity(4)
    place_camera(camera, math.cos(CAMERA_QUARTER) * left + math.sin(CAMERA_QUARTER) * heading)
    scene.camera = camera
    return camera


def place_camera(camera: bpy.types.Object, view: Iterable[float]) -> None:
    """Put the camera CAMERA_DISTANCE from the followed point along `view` (over the ground, (x, y))
    at CAMERA_HEIGHT, looking at CAMERA_AIM_HEIGHT above the followed point."""
    x, y = view
    length = math.hypot(x, y)
    offset = Vector((CAMERA_DISTANCE * x / length, CAMERA_DISTANCE * y / length, CAMERA_HEIGHT))
    camera.location = offset
    camera.rotation_euler = (Vector((0.0, 0.0, CAMERA_AIM_HEIGHT)) - offset).to_track_quat("-Z", "Y").to_euler()


def add_sun(scene: bpy.types.Scene) -> bpy.types.Object:
    """A sun shining along SUN_DIRECTION."""
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    assert isinstance(sun.data, bpy.types.SunLight)
    sun.data.energy = 3.0
    sun.data.angle = math.radians(3)
    sun.location = (0.0, 0.0, 6.0)
    sun.rotation_euler = Vector(SUN_DIRECTION).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(sun)
    return sun


def add_world(scene: bpy.types.Scene) -> bpy.types.World:
    """A plain sky colour behind everything (Workbench reads world.color; Cycles its Background node)."""
    world = bpy.data.worlds.new("Sky")
    world.color = SKY_COLOUR
    if world.node_tree is None and hasattr(world, "use_nodes"):
        world.use_nodes = True
    background = world.node_tree.nodes.get("Background") if world.node_tree else None
    if background is not None:
        background.inputs["Color"].default_value = (*SKY_COLOUR, 1.0)  # pyright: ignore[reportAttributeAccessIssue]
    scene.world = world
    return world
