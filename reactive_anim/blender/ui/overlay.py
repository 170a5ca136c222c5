"""Viewport overlay: each impact marker drawn as an arrow at the bone it hits, on and around its frame.

The arrow's tip sits at the hit bone's middle (the average of the pose bone's head and tail, in world
space, at the pose the armature shows now); its shaft points along the push, so it comes from where
the push comes from: `tail = tip - unit(direction) * length`, the length growing with the strength.
The head is a cone of UNIFORM_COLOR triangles around the shaft at the tip.

An arrow shows from IMPACT_FRAMES_BEFORE frames before its marker to IMPACT_FRAMES_AFTER after,
fully opaque on the marker's frame and fading linearly with the distance in frames, so that while
scrubbing the animator sees a hit coming and, for longer, what caused the reaction that follows.

Geometry (`impact_arrows`) is kept apart from drawing (`draw_impact_arrows`) so tests can check it in
background mode, where gpu drawing is unavailable. A draw handler runs on every redraw: it reads the
scene as it is (no frame_set), skips markers whose armature or bone is gone, and the installed
callback swallows any exception after printing one warning, so a bad marker can neither crash nor
spam the viewport.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import bpy
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from ..impacts.impacts import AUTO, character_name, impact_data, is_impact_marker
from . import settings

Vec3 = tuple[float, float, float]
RGBA = tuple[float, float, float, float]

# An arrow shows on frames [impact - BEFORE, impact + AFTER]: half a second at 24 fps of lead-in to
# see the hit coming, and a second after it, about as long as the reaction it causes takes to play.
IMPACT_FRAMES_BEFORE = 12
IMPACT_FRAMES_AFTER = 24

# Shaft length in metres: ARROW_BASE_LENGTH for a feather touch, plus ARROW_STRENGTH_LENGTH at
# STRENGTH_FOR_FULL_LENGTH N·s and beyond (the strength slider's soft maximum; 300 N·s is a tackle).
ARROW_BASE_LENGTH = 0.25
ARROW_STRENGTH_LENGTH = 0.35
STRENGTH_FOR_FULL_LENGTH = 400.0

# The head: a cone HEAD_LENGTH_FRACTION of the arrow long, its radius a fraction of its own length.
HEAD_LENGTH_FRACTION = 0.22
HEAD_RADIUS_FRACTION = 0.35
HEAD_SEGMENTS = 8

# Warm orange when the classifier picks the reaction, sky blue when the animator forced one; the
# active impact is mixed halfway to white and drawn with a thicker shaft.
AUTO_COLOR = (1.0, 0.55, 0.1)
OVERRIDDEN_COLOR = (0.3, 0.7, 1.0)
ACTIVE_WHITEN = 0.5
LINE_WIDTH = 3.0
ACTIVE_LINE_WIDTH = 5.0


@dataclass(frozen=True)
class Arrow:
    """One impact marker's arrow, in world space (metres).

    head: the cone's triangles as a flat vertex list, three vertices per triangle.
    neck: where the shaft meets the head (the shaft is drawn tail -> neck, so it does not poke
    through the cone's point).
    """

    uid: str
    tip: Vec3
    tail: Vec3
    neck: Vec3
    head: tuple[Vec3, ...]
    color: RGBA
    active: bool


# ---------------------------------------------------------------------------------------------
# Geometry (no gpu)


def arrow_length(strength: float) -> float:
    """Shaft length in metres for a push of `strength` N·s: longer for a stronger push, bounded."""
    share = strength / STRENGTH_FOR_FULL_LENGTH if math.isfinite(strength) else 0.0
    return ARROW_BASE_LENGTH + ARROW_STRENGTH_LENGTH * min(max(share, 0.0), 1.0)


def fade_alpha(frame_offset: float) -> float | None:
    """Opacity of an arrow `frame_offset` frames after its impact (negative: before); None outside
    the window. 1 on the impact's frame, falling linearly to reach 0 one frame past the window."""
    side = IMPACT_FRAMES_AFTER if frame_offset >= 0 else IMPACT_FRAMES_BEFORE
    distance = abs(frame_offset)
    if distance > side:
        return None
    return 1.0 - distance / (side + 1)


def cone_triangles(tip: np.ndarray, axis: np.ndarray, length: float, radius: float, segments: int) -> np.ndarray:
    """A closed cone pointing along unit `axis` with its point at `tip`: (segments * 2 * 3, 3) vertices.

    Each segment gives a side triangle (point, ring, next ring) and a base triangle closing the cone.
    """
    # Two unit vectors across the axis: cross it with whichever world axis is least parallel to it.
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    across = np.cross(axis, helper)
    across /= np.linalg.norm(across)
    across2 = np.cross(axis, across)
    base = tip - axis * length
    angles = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    ring = base + radius * (np.cos(angles)[:, None] * across + np.sin(angles)[:, None] * across2)
    triangles = []
    for k in range(segments):
        triangles += [tip, ring[k], ring[k + 1], base, ring[k + 1], ring[k]]
    return np.array(triangles)


def arrow_color(reaction: str, alpha: float, active: bool) -> RGBA:
    """The arrow's colour: orange for an automatic reaction, blue for a forced one, whiter if active."""
    rgb = np.array(AUTO_COLOR if reaction == AUTO else OVERRIDDEN_COLOR)
    if active:
        rgb = rgb + (1.0 - rgb) * ACTIVE_WHITEN
    red, green, blue = (float(c) for c in rgb)
    return (red, green, blue, float(alpha))


def bone_middle(armature: bpy.types.Object, bone: str) -> Vec3 | None:
    """World-space middle of the pose bone at the pose the armature shows now; None if it has no such bone."""
    if armature.type != "ARMATURE" or armature.pose is None:
        return None
    pose_bone = armature.pose.bones.get(bone)
    if pose_bone is None:
        return None
    middle = armature.matrix_world @ ((pose_bone.head + pose_bone.tail) / 2.0)
    return (float(middle.x), float(middle.y), float(middle.z))


def impact_arrows(scene: bpy.types.Scene, frame: float, active_uid: str | None = None) -> list[Arrow]:
    """The arrows to draw at `frame`: one per impact marker within its window, in frame order.

    Markers whose armature is not in the scene, whose bone the armature lacks, or whose direction
    is zero are skipped (a draw callback must not raise). A hidden armature still gets its arrows:
    animators often hide the rig and watch the mesh.
    """
    arrows = []
    markers = sorted((m for m in scene.timeline_markers if is_impact_marker(m)), key=lambda m: (m.frame, m.name))
    for marker in markers:
        alpha = fade_alpha(frame - marker.frame)
        if alpha is None:
            continue
        props = impact_data(marker)
        armature = scene.objects.get(character_name(marker))
        tip = bone_middle(armature, props.bone) if armature is not None else None
        direction = np.array(props.direction, dtype=float)
        norm = float(np.linalg.norm(direction))
        if tip is None or not (math.isfinite(norm) and norm > 1e-9):
            continue

        # Shaft upstream of the bone along -direction; the head's cone ends at the tip.
        axis = direction / norm
        length = arrow_length(props.strength)
        head_length = HEAD_LENGTH_FRACTION * length
        tip_at = np.array(tip)
        head = cone_triangles(tip_at, axis, head_length, HEAD_RADIUS_FRACTION * head_length, HEAD_SEGMENTS)
        active = bool(active_uid) and props.uid == active_uid
        arrows.append(
            Arrow(
                uid=props.uid,
                tip=tip,
                tail=_vec3(tip_at - axis * length),
                neck=_vec3(tip_at - axis * head_length),
                head=tuple(_vec3(v) for v in head),
                color=arrow_color(props.reaction, alpha, active),
                active=active,
            )
        )
    return arrows


def _vec3(v: np.ndarray) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


# ---------------------------------------------------------------------------------------------
# Drawing


def draw_impact_arrows(arrows: list[Arrow]) -> None:
    """Draw arrows in the current 3D viewport (a POST_VIEW handler's context); raises in background mode.

    No depth test (the gpu default in a handler): the tip sits inside the body and must show through.
    """
    if not arrows:
        return
    line_shader = gpu.shader.from_builtin("POLYLINE_UNIFORM_COLOR")
    fill_shader = gpu.shader.from_builtin("UNIFORM_COLOR")
    viewport_size = tuple(float(v) for v in gpu.state.viewport_get()[2:])
    gpu.state.blend_set("ALPHA")
    gpu.state.depth_test_set("NONE")
    try:
        # The active arrow last, on top of the others.
        for arrow in sorted(arrows, key=lambda a: a.active):
            shaft = batch_for_shader(line_shader, "LINES", {"pos": [arrow.tail, arrow.neck]})
            line_shader.bind()
            line_shader.uniform_float("viewportSize", viewport_size)
            line_shader.uniform_float("lineWidth", ACTIVE_LINE_WIDTH if arrow.active else LINE_WIDTH)
            line_shader.uniform_float("color", arrow.color)
            shaft.draw(line_shader)

            head = batch_for_shader(fill_shader, "TRIS", {"pos": list(arrow.head)})
            fill_shader.bind()
            fill_shader.uniform_float("color", arrow.color)
            head.draw(fill_shader)
    finally:
        gpu.state.blend_set("NONE")


_handle: Any = None  # the SpaceView3D draw handler while registered (never in background mode)
_warned = False


def active_impact_uid(scene: bpy.types.Scene) -> str | None:
    """The uid of the impact selected in the Reactions panel's list (a timeline marker index), if any."""
    marker = settings.active_impact_marker(scene)
    return impact_data(marker).uid if marker is not None else None


def draw_callback() -> None:
    """The draw handler: the current scene's arrows at its current frame; never raises.

    The first failure prints one warning; later ones are silent (a handler runs on every redraw).
    """
    global _warned
    try:
        scene = bpy.context.scene
        if scene is not None:
            draw_impact_arrows(impact_arrows(scene, scene.frame_current, active_impact_uid(scene)))
    except Exception as exc:
        if not _warned:
            _warned = True
            print(f"reactive_anim: the impact overlay could not draw and stays quiet from now on: {exc!r}")


def tag_redraw() -> None:
    """Ask every 3D viewport of every window to redraw (after markers change); no windows, no-op."""
    for window_manager in bpy.data.window_managers:
        for window in window_manager.windows:
            if window.screen is None:
                continue
            for area in window.screen.areas:
                if area.type == "VIEW_3D":
                    area.tag_redraw()


def register() -> None:
    """Install the draw handler where there are windows to draw in.

    Blender runs register() inside RestrictBlend, where bpy.data has no window managers: the first
    redraw is asked for from a timer, which runs once the add-on is enabled. Not in background
    mode: a draw handler still installed when a background Blender 4.2 exits crashes it, and there
    is nothing to draw on there.
    """
    global _handle
    if _handle is not None or not has_windows():
        return
    _handle = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), "WINDOW", "POST_VIEW")
    bpy.app.timers.register(_first_redraw, first_interval=0.0)


def has_windows() -> bool:
    """Whether this Blender draws (the one place the overlay asks; tests stand in a window here)."""
    return not bpy.app.background


def _first_redraw() -> None:
    """Timer callback: show the arrows of a file loaded before the add-on was enabled; runs once."""
    tag_redraw()


def unregister() -> None:
    """Remove the draw handler if it is installed."""
    global _handle
    if bpy.app.timers.is_registered(_first_redraw):
        bpy.app.timers.unregister(_first_redraw)
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        _handle = None
        tag_redraw()
