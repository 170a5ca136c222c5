"""One exception family for the whole add-on.

Every error names what is at fault (file and line, bone, clip, value) so the Blender layer and the
CLI can show it to the animator as is. They are raised where the problem is known and caught once,
at the edge (operator or command line).
"""

from __future__ import annotations

from pathlib import Path


class ReactiveAnimError(Exception):
    """Base of every error the add-on raises on purpose."""


class BVHError(ReactiveAnimError):
    """A BVH file that cannot be read; carries the file and the 1-based line at fault."""

    def __init__(self, message: str, path: str | Path | None = None, line: int | None = None) -> None:
        self.reason = message
        self.path = str(path) if path is not None else None
        self.line = line
        where = self.path or "<bvh>"
        if line is not None:
            where += f", line {line}"
        super().__init__(f"{where}: {message}")


class SkeletonError(ReactiveAnimError):
    """A skeleton that lacks joints or roles the method needs, or is otherwise unusable."""


class SimulationError(ReactiveAnimError):
    """A physics simulation that became unstable or was given unusable input."""


class ImpactError(ReactiveAnimError):
    """An impact that cannot be applied: outside the motion, on a bone the skeleton lacks, without
    a direction or with a bad strength; the message names the impact. `impact`: the Impact refused,
    where the raiser has it (too strong for its bone), for a caller that retries it weaker."""

    def __init__(self, message: str, impact: object | None = None) -> None:
        self.impact = impact
        super().__init__(message)


class Cancelled(ReactiveAnimError):  # noqa: N818  (a stop the caller asked for, not a failure)
    """A bake stopped because the caller asked it to (no result is returned)."""


class LibraryError(ReactiveAnimError):
    """A reaction-clip library that cannot be built or searched."""


class ClassifierError(ReactiveAnimError):
    """A reaction classifier model that is missing or malformed."""
