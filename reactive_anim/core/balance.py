"""Balance during the transition (CD): a capped root assist that keeps a tracked character up.

The paper's CD is pure PD tracking (Eq. 2). Joint servos alone have no balance feedback: tracking
a real walk, the ragdoll stays within bounds for about half a second before it drifts and falls
(measured on the sample walk: median 0.55 s over 12 starts). Two remedies were open: balance
feedback through the ankles and hips from the capture point, or an assist at the root. We use the
root assist, because it is the one that keeps the joint servos' meaning (they still track the
mocap, Eq. 2 unchanged) and whose strength can be stated and capped:
- An upward force on the pelvis toward the target's pelvis height, a spring-damper at
  `frequency` Hz (critically damped), never pulling down and never above `max_fraction` of the
  body's weight.
- A torque on the pelvis toward the target pelvis' tilt (pitch and roll; heading is left free),
  stiffness twice the toppling stiffness m g h of the body about its feet, never above
  `max_fraction` of m g h. Below about 8 degrees of tilt it holds the body fully; past
  asin(max_fraction) (17.5 degrees at 0.3) gravity's toppling torque exceeds the cap.
- The assist fades out between `fade_start` and `fade_end` of tilt error, so a push that has
  knocked the body over lets it fall: a hand that catches only what is still standing (as
  PuppetMaster's pin weight lets go of a character that has lost its balance).
- Nothing acts horizontally: where the body goes is physics, the push's momentum is kept.
The assist is computed every ASSIST_STEPS steps (1/150 s) and held in between: cheaper than every
step, and at kd * dt / m = 0.2 the held damping is stable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from . import quat

GRAVITY = 9.81
ASSIST_STEPS = 4


@dataclass(frozen=True)
class RootAssist:
    """Settings of the root assist (see the module docstring). Angles in radians."""

    max_fraction: float = 0.3
    frequency: float = 1.5
    fade_start: float = math.radians(20.0)
    fade_end: float = math.radians(40.0)


class AssistController:
    """Applies the assist to one run's MjData; remembers the largest fraction of body weight used."""

    def __init__(self, assist: RootAssist, model: mujoco.MjModel, pelvis_body: int, targets: np.ndarray) -> None:
        """targets: (K, 7) the target's pelvis position and orientation (free-joint qpos) per frame."""
        self.assist = assist
        self.body = pelvis_body
        self.targets = targets
        self.mass = float(np.sum(model.body_mass))
        self.weight = self.mass * GRAVITY
        omega = 2.0 * math.pi * assist.frequency
        self.kz, self.cz = self.mass * omega**2, 2.0 * self.mass * omega
        self.largest_fraction = 0.0

    def apply(self, data: mujoco.MjData, frame: float, fps: float, floor: float) -> None:
        """Set the pelvis' applied force and torque for the target at `frame` (fractional)."""
        target, velocity = self._target(frame, fps)
        pos, q = data.qpos[0:3], data.qpos[3:7]
        height = max(float(target[2]) - floor, 0.1)
        lever = self.weight * height  # toppling stiffness m g h, N·m/rad
        error = quat.mul(target[3:7], quat.conj(q))
        error = error if error[0] >= 0 else -error
        rotvec = (
            2.0 * error[1:] * (math.atan2(np.linalg.norm(error[1:]), error[0]) / max(np.linalg.norm(error[1:]), 1e-12))
        )
        tilt = math.hypot(rotvec[0], rotvec[1])
        fade = float(np.clip((self.assist.fade_end - tilt) / (self.assist.fade_end - self.assist.fade_start), 0.0, 1.0))
        spin = quat.rotate(q, data.qvel[3:6])  # free-joint angular velocity is in the body frame
        inertia = self.mass * height * height
        kr = 2.0 * lever
        torque = kr * rotvec - 2.0 * math.sqrt(kr * inertia) * spin
        torque[2] = 0.0
        torque *= min(1.0, self.assist.max_fraction * lever / max(float(np.linalg.norm(torque)), 1e-12)) * fade
        lift = self.kz * (target[2] - pos[2]) + self.cz * (velocity - data.qvel[2])
        lift = float(np.clip(lift, 0.0, self.assist.max_fraction * self.weight)) * fade
        data.xfrc_applied[self.body] = (0.0, 0.0, lift, *torque)
        used = max(lift / self.weight, float(np.linalg.norm(torque)) / lever)
        self.largest_fraction = max(self.largest_fraction, used)

    def _target(self, frame: float, fps: float) -> tuple[np.ndarray, float]:
        """The target pelvis (7,) at a fractional frame, and its vertical speed."""
        last = len(self.targets) - 1
        i = int(np.clip(np.floor(frame), 0, max(last - 1, 0)))
        j = min(i + 1, last)
        s = float(np.clip(frame - i, 0.0, 1.0))
        row = self.targets[i] + (self.targets[j] - self.targets[i]) * s
        row[3:7] = quat.slerp(self.targets[i, 3:7], self.targets[j, 3:7], s)
        return row, float(self.targets[j, 2] - self.targets[i, 2]) * fps
