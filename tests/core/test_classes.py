"""The reaction class table: the numbers .blend files store never change."""

from __future__ import annotations

from reactive_anim.core.model.classes import CLASS_SLUGS, CLASSES, is_fall, mirror_image, reaction_class

# The enum ids saved .blend files hold for a marker's forced reaction, as first given. A class may be
# added (with a new id) or the table reordered; a row here may never change or go.
SAVED_IDS = {
    "step_forward": 1, "steps_forward": 2, "step_back": 3, "steps_back": 4, "sway_balance": 5,
    "fall_forward_roll": 6, "fall_forward_hands": 7, "fall_backward_sit": 8, "fall_backward_hands": 9,
    "fall_side_knees": 10, "step_left": 11, "step_right": 12,
}  # fmt: skip


def test_saved_enum_ids_never_change() -> None:
    ids = {c.slug: c.enum_id for c in CLASSES}
    assert {slug: ids.get(slug) for slug in SAVED_IDS} == SAVED_IDS


def test_ids_and_slugs_are_unique_and_zero_stays_automatic() -> None:
    ids = [c.enum_id for c in CLASSES]
    assert len(set(ids)) == len(ids) and min(ids) >= 1
    assert len(set(CLASS_SLUGS)) == len(CLASS_SLUGS)


def test_the_paper_classes_come_first_in_the_papers_order() -> None:
    """The library groups its clips and the classifier reports its probabilities in this order."""
    assert CLASS_SLUGS[:10] == tuple(SAVED_IDS)[:10]


def test_families_and_ways_are_read_from_the_table() -> None:
    assert [c.slug for c in CLASSES if is_fall(c.slug)] == [s for s in CLASS_SLUGS if s.startswith("fall_")]
    assert reaction_class("sway_balance").way == "" and reaction_class("step_back").way == "backward"
    assert {c.family for c in CLASSES} == {"step", "sway", "fall"}
    assert reaction_class("fall_forward_roll").label == "Fall forward roll"


def test_a_side_steps_mirror_image_is_the_other_side_and_every_other_class_its_own() -> None:
    assert mirror_image("step_left") == "step_right" and mirror_image("step_right") == "step_left"
    assert all(mirror_image(c.slug) == c.slug for c in CLASSES if c.way not in ("left", "right"))
