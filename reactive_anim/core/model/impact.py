"""The impact: what hits the character, where, when and how hard (paper section 2, step 2, point B).

The paper applies "a force" at a key press; we describe it as an impulse (N·s) so the result does
not depend on the simulation timestep: simulate.py spreads it over one step as force = J / dt, and
the character's centre of mass gains exactly J / M.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .arrays import FloatArray
from .errors import ImpactError


@dataclass(frozen=True)
class Impact:
    """One hit on the character.

    frame: when it lands, in the motion's frames (may be fractional).
    bone: name of the skeleton joint whose body is hit (a merged bone hits the body it belongs to).
    direction: world direction of the push (Z up); normalised here, so any non-zero length is fine.
    strength: the impulse in N·s (>= 0). For scale: 30 is a shove, 100 a strong push, 300 a tackle
      (on the trunk; physics.watch.MAX_HIT_SPEED refuses what would start the hit body part faster than
      50 m/s: a hand or a foot takes 50-190 N·s).
    reaction: optional reaction-class slug that overrides the classifier (None: let it decide).
    """

    frame: float
    bone: str
    direction: tuple[float, float, float]
    strength: float
    reaction: str | None = None

    def __post_init__(self) -> None:
        frame = float(self.frame)
        if not math.isfinite(frame) or frame < 0:
            raise ImpactError(f"impact on '{self.bone}': frame must be a finite number >= 0, got {self.frame!r}")
        if not _is_name(self.bone):
            raise ImpactError(f"impact at frame {frame:g}: bone must be a joint name, got {self.bone!r}")
        direction = np.asarray(self.direction, dtype=np.float64).reshape(-1)
        if direction.shape != (3,) or not np.all(np.isfinite(direction)):
            raise ImpactError(
                f"impact on '{self.bone}': direction must be three finite numbers, got {self.direction!r}"
            )
        length = float(np.linalg.norm(direction))
        if length < 1e-9:
            raise ImpactError(f"impact on '{self.bone}': direction {self.direction!r} has no length")
        strength = float(self.strength)
        if not math.isfinite(strength) or strength < 0:
            raise ImpactError(
                f"impact on '{self.bone}': strength must be a finite impulse >= 0 N·s, got {self.strength!r}"
            )
        if self.reaction is not None and not _is_name(self.reaction):
            raise ImpactError(f"impact on '{self.bone}': reaction must be a class slug or None, got {self.reaction!r}")
        object.__setattr__(self, "frame", frame)
        object.__setattr__(self, "direction", tuple(float(v) for v in direction / length))
        object.__setattr__(self, "strength", strength)

    @property
    def impulse(self) -> FloatArray:
        """The impulse vector, N·s, (3,)."""
        return np.asarray(self.direction) * self.strength


def _is_name(value: object) -> bool:
    """A non-empty string: the annotations say str, but a caller (a script, a .blend) may pass anything."""
    return isinstance(value, str) and bool(value)
