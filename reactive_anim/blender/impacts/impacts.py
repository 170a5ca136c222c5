"""Impact markers: scene timeline markers that carry an impact.

A marker is an impact marker when its `reactive_anim` property group has a uid. The group holds what
core.impact.Impact needs (bone, world direction, strength in N·s, optional reaction class) plus the
name of the armature it hits, so one scene can hold impacts for several characters; the marker's
own frame is the impact's frame. Markers take no ID properties (`marker["x"]` raises), but a
PointerProperty registered on bpy.types.TimelineMarker is saved in the .blend.

Frames: a marker sits on the scene's timeline; the motion read from an action starts at the
action's first frame, so the core Impact's frame is `marker.frame - first`.
"""

# Blender declares properties as annotations holding calls (`bone: StringProperty(...)`), which are
# not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

import uuid
from collections.abc import Sequence
from typing import cast

import bpy
from bpy.props import EnumProperty, FloatProperty, FloatVectorProperty, PointerProperty, StringProperty

from ...core.model.classes import CLASS_SLUGS, CLASSES
from ...core.model.errors import ImpactError, SkeletonError
from ...core.model.impact import Impact

AUTO = "auto"
DEFAULT_STRENGTH = 100.0  # N·s, a strong push (core/model/impact.py gives the scale)

# Enum items carry explicit numbers: a .blend stores an enum by number, so each class's number is its
# fixed classes.ReactionClass.enum_id, whatever the table's order. 0 is "let the classifier decide".
REACTION_ITEMS = [(AUTO, "Automatic", "The classifier picks the reaction class", 0)] + [
    (c.slug, c.label, f"Force the '{c.slug}' reaction class", c.enum_id) for c in CLASSES
]
_REACTION_NUMBERS = {item[3] for item in REACTION_ITEMS}


# The Strength field's tooltip, on the impact and on Add Impact alike.
STRENGTH_DESCRIPTION = (
    "Impulse in N·s, above 0 (to push the other way, turn the direction around): 30 is a shove, "
    "100 a strong push, 300 a tackle (on the trunk: a hand or foot takes 50-190 at most)"
)


class REACTIVE_ANIM_PG_impact(bpy.types.PropertyGroup):
    """The impact a timeline marker carries (empty uid: an ordinary marker)."""

    armature: StringProperty(name="Armature", description="Name of the armature object this impact hits")
    # The object itself, so an impact follows its character through a rename (the name alone left
    # the impacts behind); the name stays for files saved before and for a character deleted since.
    character: PointerProperty(name="Character", type=bpy.types.Object, description="The armature this impact hits")
    bone: StringProperty(name="Bone", description="The bone that is hit")
    direction: FloatVectorProperty(
        name="Direction",
        description="World direction of the push (Z up); its length does not matter",
        size=3,
        subtype="XYZ",
        default=(1.0, 0.0, 0.0),
    )
    # No hard minimum: Blender would silently turn a typed -50 into the minimum. The value is kept as
    # typed and the bake refuses any strength not above 0, naming the marker and the value.
    strength: FloatProperty(
        name="Strength",
        description=STRENGTH_DESCRIPTION,
        default=DEFAULT_STRENGTH,
        soft_min=10.0,
        soft_max=400.0,
    )
    reaction: EnumProperty(
        name="Reaction", description="Force a reaction class, or let the classifier decide", items=REACTION_ITEMS
    )
    uid: StringProperty(name="UID", description="Stable identifier of this impact (markers can be renamed)")


def impact_data(marker: bpy.types.TimelineMarker) -> REACTIVE_ANIM_PG_impact:
    """The marker's impact properties (registered as `TimelineMarker.reactive_anim`)."""
    return cast(REACTIVE_ANIM_PG_impact, marker.reactive_anim)  # pyright: ignore[reportAttributeAccessIssue]


def is_impact_marker(marker: bpy.types.TimelineMarker) -> bool:
    return bool(impact_data(marker).uid)


def character_name(marker: bpy.types.TimelineMarker) -> str:
    """The name of the armature the impact hits, as it is called now."""
    props = impact_data(marker)
    return props.character.name if props.character is not None else props.armature


# ---------------------------------------------------------------------------------------------
# Add, find, read, remove


def add_impact(
    scene: bpy.types.Scene,
    armature: bpy.types.Object,
    bone: str,
    frame: int,
    direction: Sequence[float],
    strength: float = DEFAULT_STRENGTH,
    reaction: str | None = None,
    name: str = "",
) -> bpy.types.TimelineMarker:
    """A new impact marker on `scene`'s timeline; errors name the bone or value at fault.

    reaction: a class slug from CLASS_SLUGS, or None / "auto" to let the classifier decide.
    name: the marker's name (default `hit_01`, `hit_02`, ... the first free one).
    """
    data = armature.data
    if not isinstance(data, bpy.types.Armature):
        raise SkeletonError(f"object '{armature.name}' is not an armature")
    if bone not in data.bones:
        raise ImpactError(f"armature '{armature.name}' has no bone '{bone}'")
    reaction = None if reaction in (None, "", AUTO) else reaction
    if reaction is not None and reaction not in CLASS_SLUGS:
        raise ImpactError(f"unknown reaction '{reaction}'; classes are: {AUTO}, {', '.join(CLASS_SLUGS)}")
    Impact(0.0, bone, cast(tuple[float, float, float], tuple(direction)), strength, reaction)  # checks the values
    marker = scene.timeline_markers.new(name or _free_name(scene), frame=int(frame))
    props = impact_data(marker)
    props.armature, props.character = armature.name, armature
    props.bone = bone
    props.direction = tuple(float(v) for v in direction)
    props.strength = float(strength)
    props.reaction = reaction or AUTO
    props.uid = uuid.uuid4().hex
    return marker


def _free_name(scene: bpy.types.Scene) -> str:
    taken = {m.name for m in scene.timeline_markers}
    return next(f"hit_{k:02d}" for k in range(1, len(taken) + 2) if f"hit_{k:02d}" not in taken)


def impact_markers(scene: bpy.types.Scene, armature_name: str) -> list[bpy.types.TimelineMarker]:
    """The scene's impact markers on one armature, in frame order (then name, then uid)."""
    found = [m for m in scene.timeline_markers if is_impact_marker(m) and character_name(m) == armature_name]
    return sorted(found, key=lambda m: (m.frame, m.name, impact_data(m).uid))


def find_impact(scene: bpy.types.Scene, uid: str) -> bpy.types.TimelineMarker | None:
    return next((m for m in scene.timeline_markers if uid and impact_data(m).uid == uid), None)


def remove_impact(scene: bpy.types.Scene, marker: bpy.types.TimelineMarker | str) -> None:
    """Remove an impact marker, given as the marker or its uid."""
    if isinstance(marker, str):
        found = find_impact(scene, marker)
        if found is None:
            raise ImpactError(f"scene '{scene.name}' has no impact marker with uid '{marker}'")
        marker = found
    # TimelineMarkers.remove frees the marker but not its properties (Blender 4.2-5.0): unset ours
    # first, which leaves only the empty property container (a few hundred bytes) unfreed.
    marker.property_unset("reactive_anim")
    scene.timeline_markers.remove(marker)


def read_impacts(
    scene: bpy.types.Scene, armature: bpy.types.Object, frame_range: tuple[int, int] | None = None
) -> list[Impact]:
    """The armature's impact markers as core Impacts, in frame order (the order of impact_markers).

    frame_range: inclusive (first, last) timeline frames of the motion the impacts land on; default
    the frame range of the armature's action. An Impact's frame is `marker.frame - first`. A marker
    outside the range, on a bone the armature lacks, with a strength not above 0, a reaction this
    version does not know or another bad value raises ImpactError naming it.
    """
    if frame_range is None:
        action = armature.animation_data.action if armature.animation_data else None
        if action is None:
            raise SkeletonError(f"armature '{armature.name}' has no action for its impacts to land on")
        frame_range = (round(action.frame_range[0]), round(action.frame_range[1]))
    first, last = frame_range
    bones = armature.data.bones if isinstance(armature.data, bpy.types.Armature) else ()
    impacts = []
    for marker in impact_markers(scene, armature.name):
        props = impact_data(marker)
        where = marker_label(marker)
        if not first <= marker.frame <= last:
            raise ImpactError(f"{where} is outside the animation's frames {first}-{last}")
        if props.bone not in bones:
            raise ImpactError(f"{where} is on bone '{props.bone}', which armature '{armature.name}' does not have")
        if not props.strength > 0:
            turn = " (to push the other way, turn its direction around)" if props.strength < 0 else ""
            raise ImpactError(f"{where} has strength {props.strength:g} N·s: give it a strength above 0{turn}")
        stored = props.get("reaction")  # the enum's stored number (None: never set, the default)
        if stored is not None and stored not in _REACTION_NUMBERS:
            raise ImpactError(
                f"{where} has reaction number {stored}, which this version of the add-on does not know "
                "(saved by a newer version?): pick its reaction again"
            )
        reaction = None if props.reaction == AUTO else props.reaction
        try:
            impacts.append(Impact(marker.frame - first, props.bone, tuple(props.direction), props.strength, reaction))
        except ImpactError as exc:
            raise ImpactError(f"{where}: {exc}") from None
    return impacts


def marker_label(marker: bpy.types.TimelineMarker) -> str:
    """How errors and reports name a marker: `impact marker 'hit_02' at frame 130`."""
    return f"impact marker '{marker.name}' at frame {marker.frame}"
