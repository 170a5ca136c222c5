"""A rig: a skeleton and which of its joints plays each role, with what every stage reads of the pair.

The stages used to receive the skeleton and its role map as two loose parts, each looking joints up
by name again and falling back on its own to `skeleton.roles` or to finding the roles by name
(roles.py). A Rig is that pair made once: the roles as given (or the skeleton's own, or found by
name), each role's joint index, and the leg length balance, steps and feet are scaled by.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .errors import SkeletonError
from .roles import SIDES, assign_roles
from .skeleton import Skeleton

MIN_LEG_LENGTH = 0.05  # m, hip to ankle: shorter legs cannot stand, and would divide by next to nothing


@dataclass(frozen=True)
class Rig:
    """skeleton; roles: role -> joint name; joints: role -> joint index (the same roles)."""

    skeleton: Skeleton
    roles: dict[str, str]
    joints: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints", {role: self.skeleton.index(name) for role, name in self.roles.items()})

    @classmethod
    def of(cls, skeleton: Skeleton, roles: Mapping[str, str] | None = None) -> Rig:
        """The rig of a skeleton: `roles` as given, else the skeleton's own, else found by name
        (assign_roles, which raises SkeletonError naming what it cannot find)."""
        chosen = roles or skeleton.roles or assign_roles(skeleton)
        return cls(skeleton, dict(chosen))

    def joint(self, role: str) -> int:
        """The joint index of a role (KeyError for a role the rig does not have)."""
        return self.joints[role]

    @cached_property
    def leg_length(self) -> float:
        """Mean of the two legs' thigh + shin rest lengths, metres: the one length everything about
        balance, steps and feet is scaled by. SkeletonError when shorter than MIN_LEG_LENGTH."""
        pos = self.skeleton.rest_positions()
        lengths: list[np.float64] = []
        for s in SIDES:
            hip, knee, ankle = (pos[self.joints[f"{p}_{s}"]] for p in ("hip", "knee", "ankle"))
            lengths.append(np.linalg.norm(knee - hip) + np.linalg.norm(ankle - knee))
        length = float(np.mean(lengths))
        if not length > MIN_LEG_LENGTH:
            raise SkeletonError(f"the legs are {length:.3f} m long (hip to ankle); the skeleton cannot stand")
        return length
