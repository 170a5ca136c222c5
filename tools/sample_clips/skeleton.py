"""The sample skeleton (a 22-joint, 1.75 m adult) and the world its clips live in.

World: metres, Z up; the character faces -Y (Blender's convention: the front view looks along +Y
at the character's face), so its left (.L) is +X. In the written BVH (Y up) it faces +Z. Clips run
at FPS frames a second.

Also here: the rotations about the world axes every clip is built from, the direction of a push
or a step given as an angle from the facing, and the few lines that turn per-frame arrays into a
clip.
"""

from __future__ import annotations

import numpy as np

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Motion, Skeleton

HEIGHT = 1.75
FPS = 60
FORWARD = np.array([0.0, -1.0, 0.0])  # the direction the character faces and walks
UP = np.array([0.0, 0.0, 1.0])
X_AXIS = np.array([1.0, 0.0, 0.0])
Y_AXIS = np.array([0.0, 1.0, 0.0])
SIDES = {"L": 1.0, "R": -1.0}  # sign of the character's side along +X

# Proportions as fractions of body height H, from the Drillis & Contini (1966) segment-length
# table reproduced in D. A. Winter, "Biomechanics and Motor Control of Human Movement" (4th ed.,
# 2009), Fig. 4.1: shoulder 0.818H, hip 0.530H, knee 0.285H, ankle 0.039H; upper arm 0.186H,
# forearm 0.146H, hand 0.108H, thigh 0.245H, shank 0.246H, foot length 0.152H; crown at 1.0H.
# The spine's subdivision, joint-centre widths and the split of the foot into heel / ball / toe
# are this project's estimates from typical adult anatomy.
SHOULDER_Z = 0.818
HIP_Z = 0.530
UPPER_ARM = 0.186
FOREARM = 0.146
HAND = 0.108
THIGH = 0.245
SHANK = 0.246
ANKLE_Z = HIP_Z - THIGH - SHANK  # 0.039, as in the table
PELVIS_Z = 0.555  # root: mid-pelvis, above the hip joint centres
SPINE_Z = 0.620  # lumbar
SPINE1_Z = 0.690  # lower thoracic
CHEST_Z = 0.760  # upper thoracic
CLAVICLE_Z = 0.805  # sternoclavicular joint, just below the shoulder line
NECK_Z = 0.835  # C7, base of the neck
HEAD_Z = 0.910  # skull base; the crown (End Site) is at 1.0H
HIP_HALF_WIDTH = 0.050  # hip joint centres 0.10H apart
SHOULDER_HALF_WIDTH = 0.100  # shoulder joint centres 0.20H apart (bideltoid width is 0.259H)
CLAVICLE_HALF_WIDTH = 0.012
BALL_FORWARD = 0.080  # ankle to ball of the foot (the toe joint)
BALL_Z = 0.014  # the toe joint's height above the floor
TOE_LENGTH = 0.040  # ball to toe tip; with the heel, foot length is 0.032 + 0.080 + 0.040 = 0.152H
TOE_TIP_Z = 0.006
HEEL_BACK = 0.032  # heel behind the ankle (not a joint: used to roll the foot over the heel)
ANKLE_HEIGHT = ANKLE_Z * HEIGHT  # the ankle joint's height above the floor when the foot is flat, m


def sample_skeleton() -> Skeleton:
    """The project's 22-joint, 1.75 m adult, standing with arms hanging, facing -Y (see README).

    Joints are ordered depth-first, the order a BVH file lists them, so reading a written file back
    gives the same indices.
    """
    h = HEIGHT
    names: list[str] = []
    parents: list[int] = []
    rest_h: list[tuple[float, float, float]] = []  # rest positions in units of H
    end_sites: dict[int, np.ndarray] = {}

    def add(name: str, parent: str | None, x: float, y: float, z: float) -> None:
        names.append(name)
        parents.append(-1 if parent is None else names.index(parent))
        rest_h.append((x, y, z))

    add("pelvis", None, 0.0, 0.0, PELVIS_Z)
    add("spine", "pelvis", 0.0, 0.0, SPINE_Z)
    add("spine.001", "spine", 0.0, 0.0, SPINE1_Z)
    add("chest", "spine.001", 0.0, 0.0, CHEST_Z)
    add("neck", "chest", 0.0, 0.0, NECK_Z)
    add("head", "neck", 0.0, 0.0, HEAD_Z)
    end_sites[names.index("head")] = np.array([0.0, 0.0, (1.0 - HEAD_Z) * h])
    for side, s in SIDES.items():
        add(f"shoulder.{side}", "chest", s * CLAVICLE_HALF_WIDTH, 0.0, CLAVICLE_Z)
        add(f"upper_arm.{side}", f"shoulder.{side}", s * SHOULDER_HALF_WIDTH, 0.0, SHOULDER_Z)
        add(f"forearm.{side}", f"upper_arm.{side}", s * SHOULDER_HALF_WIDTH, 0.0, SHOULDER_Z - UPPER_ARM)
        add(f"hand.{side}", f"forearm.{side}", s * SHOULDER_HALF_WIDTH, 0.0, SHOULDER_Z - UPPER_ARM - FOREARM)
        end_sites[names.index(f"hand.{side}")] = np.array([0.0, 0.0, -HAND * h])
    for side, s in SIDES.items():
        add(f"thigh.{side}", "pelvis", s * HIP_HALF_WIDTH, 0.0, HIP_Z)
        add(f"shin.{side}", f"thigh.{side}", s * HIP_HALF_WIDTH, 0.0, HIP_Z - THIGH)
        add(f"foot.{side}", f"shin.{side}", s * HIP_HALF_WIDTH, 0.0, ANKLE_Z)
        add(f"toe.{side}", f"foot.{side}", s * HIP_HALF_WIDTH, -BALL_FORWARD, BALL_Z)
        end_sites[names.index(f"toe.{side}")] = np.array([0.0, -TOE_LENGTH * h, (TOE_TIP_Z - BALL_Z) * h])
    rest = np.array(rest_h) * h
    offsets = rest.copy()
    offsets[1:] -= rest[parents[1:]]
    return Skeleton(names, np.array(parents), offsets, end_sites)


def end_site_position(skeleton: Skeleton, pos: np.ndarray, rot: np.ndarray, joint: int) -> np.ndarray:
    """World position (T, 3) of a joint's End Site (fingertips, toe tip, crown), from the global
    positions (T, J, 3) and rotations (T, J, 4) of forward kinematics."""
    return pos[:, joint] + quat.rotate(rot[:, joint], skeleton.end_sites[joint])


def clip_motion(skeleton: Skeleton, root: np.ndarray, local: np.ndarray) -> Motion:
    """A clip at FPS from root positions (T, 3) and local rotations (T, J, 4), made unit length."""
    return Motion(skeleton=skeleton, fps=float(FPS), root_pos=root, local_rot=quat.normalize(local))


# ---------------------------------------------------------------------------------------------
# Rotations about the world axes, and directions given as angles from the facing


def about(axis: np.ndarray, angle: float | np.ndarray) -> np.ndarray:
    """Quaternions for rotations by `angle` (radians, any shape) about a fixed world axis."""
    return quat.from_axis_angle(axis, np.asarray(angle, dtype=float))


def about_x(angle: float | np.ndarray) -> np.ndarray:
    """Pitch: about +X, the character's left; positive bends forward (the front, -Y, goes down)."""
    return about(X_AXIS, angle)


def about_y(angle: np.ndarray) -> np.ndarray:
    """Roll: about +Y, the character's back; positive leans to the character's left."""
    return about(Y_AXIS, angle)


def about_z(angle: np.ndarray) -> np.ndarray:
    """Yaw: about +Z (up); positive turns the facing to the character's left."""
    return about(UP, angle)


def heading(degrees: float) -> np.ndarray:
    """The unit ground direction (3,) at `degrees` from the facing, positive to the character's
    left: 0 is FORWARD, 90 the left (+X), 180 backwards."""
    angle = np.radians(degrees)
    return np.cos(angle) * FORWARD + np.sin(angle) * X_AXIS
