"""The reaction classes: the paper's 10 (section 2.3) and our side steps, one table, one row each.

The table's order is the paper's (one step forward ... fall sideways to the knees), then ours; the
library groups its clips in this order and the classifier's probabilities follow it. The paper has
no side step: a walker or a stander pushed sideways hard enough to step got a forward or backward
step or a sway (45% of side pushes in tools/bench.py quality were given a side reaction). Everything else a
caller needs about a class (is it a fall, which way does the body go) is read from its row, not
from the slug's spelling.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ReactionClass:
    """One reaction class.

    slug: its name in library manifests, ONNX models, .blend files and messages.
    family: "step" (one or more corrective steps), "sway" (balance kept on planted feet) or "fall".
    way: where the body goes, relative to its facing at the push: "forward", "backward", "left",
      "right", "side" (either side: the paper's side fall), or "" for a sway, which keeps its place.
    enum_id: the number a .blend stores for a marker's forced reaction (blender/impacts/impacts.py): fixed
      once given, never reused or renumbered, new classes take the next free number; 0 is
      "automatic". Position in the table is not the id, so the table may be reordered.
    """

    slug: str
    family: str
    way: str
    enum_id: int

    @property
    def is_fall(self) -> bool:
        return self.family == "fall"

    @property
    def label(self) -> str:
        """The name a UI shows: "Fall forward roll"."""
        return self.slug.replace("_", " ").capitalize()


CLASSES: tuple[ReactionClass, ...] = (
    ReactionClass("step_forward", "step", "forward", 1),
    ReactionClass("steps_forward", "step", "forward", 2),
    ReactionClass("step_back", "step", "backward", 3),
    ReactionClass("steps_back", "step", "backward", 4),
    ReactionClass("sway_balance", "sway", "", 5),
    ReactionClass("fall_forward_roll", "fall", "forward", 6),
    ReactionClass("fall_forward_hands", "fall", "forward", 7),
    ReactionClass("fall_backward_sit", "fall", "backward", 8),
    ReactionClass("fall_backward_hands", "fall", "backward", 9),
    ReactionClass("fall_side_knees", "fall", "side", 10),
    ReactionClass("step_left", "step", "left", 11),
    ReactionClass("step_right", "step", "right", 12),
)
CLASS_SLUGS: tuple[str, ...] = tuple(c.slug for c in CLASSES)
_BY_SLUG = {c.slug: c for c in CLASSES}


def reaction_class(slug: str) -> ReactionClass:
    """The row of `slug` (KeyError for a slug that is no class: callers check CLASS_SLUGS first
    where the slug comes from a user)."""
    return _BY_SLUG[slug]


def is_fall(slug: str) -> bool:
    return _BY_SLUG[slug].is_fall


def mirror_image(slug: str) -> str:
    """The class of the same reaction with left and right swapped (a side step's other side; any
    other class is its own mirror image)."""
    way = _BY_SLUG[slug].way
    if way not in ("left", "right"):
        return slug
    other = "right" if way == "left" else "left"
    return next(c.slug for c in CLASSES if c.family == _BY_SLUG[slug].family and c.way == other)
