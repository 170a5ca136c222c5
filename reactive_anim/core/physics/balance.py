"""Balance during the transition (CD): a capped root assist that keeps a tracked character up.

The paper's CD is pure PD tracking (Eq. 2). Joint servos alone have no balance feedback: tracking
a real walk, the ragdoll stays within bounds for well under a second before it drifts and falls
(docs/measurements.md, "Balance during CD"). Two remedies were open: balance
feedback through the ankles and hips from the capture point, or an assist at the root. We use the
root assist, because it is the one that keeps the joint servos' meaning (they still track the
mocap, Eq. 2 unchanged) and whose strength can be stated and capped:
- An upward force on the pelvis toward the target's pelvis height, a spring-damper at
  `lift_frequency` Hz (critically damped), never pulling down and never above `lift_fraction` of
  the body's weight.
- A torque on the pelvis toward the target pelvis' tilt (pitch and roll), stiffness
  `tilt_stiffness` times the toppling stiffness m g h of the body about its feet, never above
  `max_fraction` of m g h: past asin(max_fraction) (24 degrees at 0.4) gravity's toppling torque
  exceeds the cap. A mocap pose is balanced for the captured body, not always for the ragdoll's
  capsules; the stiffness keeps the lean that difference causes to about 3 degrees.
- A torque about the vertical toward the target's heading, a spring-damper at `heading_frequency`
  Hz on the body's spin inertia (m (0.14 h)^2, about 1.2 kg m^2 for a 70 kg adult), same cap.
  Without it a tracked walker turned far off its heading within seconds: the swing leg's and the arms'
  reaction torques turn the body about its stance foot, which a person resists with the foot's
  free moment and by steering the next step, neither of which PD tracking does.
- The assist fades out between `fade_start` and `fade_end` of tilt error, so a push that has
  knocked the body over lets it fall: a hand that catches only what is still standing (as
  PuppetMaster's pin weight lets go of a character that has lost its balance).
- Nothing acts horizontally: where the body goes is physics, the push's momentum is kept.
The assist is computed every ASSIST_STEPS steps (1/150 s) and held in between: cheaper than every
step, and at kd * dt / m = 0.2 the held damping is stable.

The settings below were chosen with `tools/bench.py sim` (how long tracked walks and a standing
idle stay up, how far a planted foot slides); the figures, and the stronger tilt cap that was
tried, are in docs/measurements.md and docs/decisions.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..model.arrays import FloatArray

GRAVITY = 9.81
ASSIST_STEPS = 4
YAW_RADIUS = 0.14  # spin radius of gyration per metre of pelvis height


@dataclass(frozen=True)
class RootAssist:
    """Settings of the root assist (see the module docstring). Angles in radians."""

    max_fraction: float = 0.4
    tilt_stiffness: float = 4.0
    heading_frequency: float = 2.0
    lift_fraction: float = 0.3
    lift_frequency: float = 3.0
    fade_start: float = math.radians(20.0)
    fade_end: float = math.radians(40.0)


# The assist for a walk kept through a push (react: a sway or a single step on a walker): the push
# did not upset the walk, so CD is held up while it fades back into it: the lift may bear up to 0.8
# of the weight, the torques 0.8 m g h, and it lets go only past 60-90 degrees of tilt. With
# RootAssist's own settings the tracked body sank 20 cm or more below the walk by F in 458 of 1128
# kept walks and 271 of 486 kept runs on the shared mocap (a walker dipping, or diving face first,
# and pulled back up by the fade); with these, 75 and 65 (docs/measurements.md).
KEPT_WALK = RootAssist(max_fraction=0.8, lift_fraction=0.8, fade_start=math.radians(60.0), fade_end=math.radians(90.0))


class AssistController:
    """Applies the assist to one run's MjData; remembers the largest fraction of body weight used."""

    def __init__(self, assist: RootAssist, model: mujoco.MjModel, pelvis_body: int, targets: FloatArray) -> None:
        """targets: (K, 7) the target's pelvis position and orientation (free-joint qpos) per frame."""
        self.assist = assist
        self.body = pelvis_body
        self.targets = targets
        self.mass = float(np.sum(model.body_mass))
        self.weight = self.mass * GRAVITY
        omega = 2.0 * math.pi * assist.lift_frequency
        self.kz, self.cz = self.mass * omega**2, 2.0 * self.mass * omega
        self.largest_fraction = 0.0

    def apply(self, data: mujoco.MjData, frame: float, fps: float, floor: float) -> None:
        """Set the pelvis' applied force and torque for the target at `frame` (fractional).

        Plain float arithmetic on 3- and 4-vectors: numpy's per-call overhead would cost more than
        the simulation steps it runs between."""
        target, rising = self._target(frame, fps)
        qw, qx, qy, qz = (float(v) for v in data.qpos[3:7])
        tw, tx, ty, tz = target[3:7]
        # Rotation from the pelvis' orientation to the target's: t * conj(q), as a rotation vector.
        ew = tw * qw + tx * qx + ty * qy + tz * qz
        ex = -tw * qx + tx * qw - ty * qz + tz * qy
        ey = -tw * qy + tx * qz + ty * qw - tz * qx
        ez = -tw * qz - tx * qy + ty * qx + tz * qw
        if ew < 0.0:
            ew, ex, ey, ez = -ew, -ex, -ey, -ez
        sine = math.sqrt(ex * ex + ey * ey + ez * ez)
        scale = 2.0 * math.atan2(sine, ew) / sine if sine > 1e-12 else 2.0
        rx, ry, rz = ex * scale, ey * scale, ez * scale
        tilt = math.hypot(rx, ry)
        fade = min(1.0, max(0.0, (self.assist.fade_end - tilt) / (self.assist.fade_end - self.assist.fade_start)))
        # World angular velocity: the free joint's is in the body frame, rotate it by q.
        wx, wy, wz = (float(v) for v in data.qvel[3:6])
        spin_x, spin_y, spin_z = _rotate((qw, qx, qy, qz), (wx, wy, wz))
        height = max(target[2] - floor, 0.1)
        lever = self.weight * height  # toppling stiffness m g h, N·m/rad
        kr = self.assist.tilt_stiffness * lever
        damping = 2.0 * math.sqrt(kr * self.mass * height * height)
        torque_x, torque_y = kr * rx - damping * spin_x, kr * ry - damping * spin_y
        size = math.hypot(torque_x, torque_y)
        cap = self.assist.max_fraction * lever
        factor = fade * (min(1.0, cap / size) if size > 0.0 else 0.0)
        torque_x, torque_y = torque_x * factor, torque_y * factor
        spin_inertia = self.mass * (YAW_RADIUS * height) ** 2
        wyaw = 2.0 * math.pi * self.assist.heading_frequency
        torque_z = spin_inertia * (wyaw * wyaw * rz - 2.0 * wyaw * spin_z)
        torque_z = max(-cap, min(cap, torque_z)) * fade
        lift = self.kz * (target[2] - float(data.qpos[2])) + self.cz * (rising - float(data.qvel[2]))
        lift = min(max(lift, 0.0), self.assist.lift_fraction * self.weight) * fade
        data.xfrc_applied[self.body] = (0.0, 0.0, lift, torque_x, torque_y, torque_z)
        used = max(lift / self.weight, size * factor / lever, abs(torque_z) / lever)
        self.largest_fraction = max(self.largest_fraction, used)

    def _target(self, frame: float, fps: float) -> tuple[list[float], float]:
        """The target pelvis (x, y, z, qw, qx, qy, qz) at a fractional frame (orientation of the
        nearer frame: they are a frame apart), and its vertical speed."""
        last = len(self.targets) - 1
        i = min(max(math.floor(frame), 0), max(last - 1, 0))
        j = min(i + 1, last)
        s = min(max(frame - i, 0.0), 1.0)
        a, b = self.targets[i], self.targets[j]
        z = float(a[2] + (b[2] - a[2]) * s)
        q = b if s >= 0.5 else a
        return [float(a[0]), float(a[1]), z, *(float(v) for v in q[3:7])], float(b[2] - a[2]) * fps


def _rotate(q: tuple[float, float, float, float], v: tuple[float, float, float]) -> tuple[float, float, float]:
    """The vector v rotated by the unit quaternion q (w, x, y, z)."""
    qw, qx, qy, qz = q
    vx, vy, vz = v
    # v' = v + 2 w (u x v) + 2 u x (u x v), u = (qx, qy, qz)
    cx, cy, cz = qy * vz - qz * vy, qz * vx - qx * vz, qx * vy - qy * vx
    return (
        vx + 2.0 * (qw * cx + qy * cz - qz * cy),
        vy + 2.0 * (qw * cy + qz * cx - qx * cz),
        vz + 2.0 * (qw * cz + qx * cy - qy * cx),
    )
