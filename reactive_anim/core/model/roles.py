"""Joint roles: which joint of a skeleton plays each joint of the paper's ragdoll and pose search.

The roles come from the paper's Table 1 (ragdoll bodies and the joints that carry them: Neck,
Back, Waist, Hip, Femur, Knee, Ankle, Shoulder, Elbow, Wrist) and Table 2 (search weights for
Neck, Back, Waist, Hip, Knee, Shoulder, Elbow, Wrist, Ankle, left/right symmetric); section 2.3's
classifier also reads the head, chest and pelvis positions. Each role names the joint whose
rotation moves that body segment:

    pelvis   Table 1 "Root" body (its joint is Table 1's "Hip"): the joint legs and spine hang from
    waist    Table 1/2 "Waist", lower body: the first spine joint above the pelvis
    back     Table 1/2 "Back", upper body: the spine joint between waist and chest (rule below)
    chest    classifier "chest": the spine joint the arms hang from
    neck     Table 1/2 "Neck", head body: the first neck joint above the chest
    head     classifier "head"
    hip_l/r  Table 1 "Femur" (thigh) = Table 2 "Hip";  knee_l/r, ankle_l/r: "Knee", "Ankle"
    shoulder_l/r (upper arm, not the clavicle), elbow_l/r, wrist_l/r: "Shoulder", "Elbow", "Wrist"
    optional: toe_l/r, clavicle_l/r (not in the paper; used where a skeleton has them)

How joints are found:
- Limbs by name. A name loses its namespace (`mixamorig:`, `Armature|`) and prefix (`CC_Base_`,
  `DEF-`), is split into words (separators `_ . - space`, camelCase, digits), a word `L`/`Left`
  or `R`/`Right` gives the side, and the remaining words joined must equal one of the role's names
  (`UpLeg`, `UpperLeg`, `thigh`; `Leg`, `LowerLeg`, `shin`, `Calf`; ...). Matching the whole name
  keeps twist, share, finger, toe-digit, end and face bones out (`ForearmTwist01`,
  `ElbowShareBone`, `HandIndex1`, `PinkyToe1`, `HeadTop_End`, `upper_arm.L.001`). "Shoulder" in
  a name is the clavicle (CMU, Mixamo, Bandai `Shoulder_L`); the upper arm is `Arm`/`UpperArm`/
  `upper_arm`, or else the elbow's parent. Each limb joint must lie below the previous one of
  its chain (hip > knee > ankle > toe, shoulder > elbow > wrist); the nearest match wins.
- Torso by hierarchy. `pelvis` is the lowest common ancestor of both hips and the head, so a
  ground root (Bandai `joint_Root`, iClone `RL_BoneRoot`) and iClone's fixed `CC_Base_Pelvis`
  (not animated; only the legs hang from it) are passed over. The spine is the path from the
  pelvis to the head. Only joints that have a bone along it count (the next joint on the path is
  not at the same place), so co-located helpers such as CMU's `Spine1` (its children `Neck` and
  both shoulders have OFFSET 0) are skipped: the chest segment is the one `Spine` rotates.
  `chest` is the last such joint at or below the joint the arms hang from; `waist` the first
  above the pelvis; `neck` the first above the chest, a name starting "neck" preferred. Being
  found by hierarchy, the neck may be a "twist" bone: iClone's only neck bones are
  `CC_Base_NeckTwist01/02`, and the lower one is the neck.

The back rule: `back` is the spine joint strictly between waist and chest; with several, the
middle one (the lower of two). On a short spine with nothing between (Bandai `Hips > Spine >
Chest`, CMU `LowerBack > Spine`) `back` is the chest joint: Table 1's Back joint carries the
upper body, which there is the chest segment. It is the only role that may share a joint.

Overrides (role -> joint name) win over everything and feed the later steps (an overridden chest
moves the waist, back and neck searches with it).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass

import numpy as np

from .arrays import FloatArray
from .errors import SkeletonError
from .skeleton import Skeleton

SIDES = ("l", "r")
CENTRE_ROLES = ("pelvis", "waist", "back", "chest", "neck", "head")
LEG_ROLES = ("hip", "knee", "ankle")
ARM_ROLES = ("shoulder", "elbow", "wrist")
REQUIRED_ROLES: tuple[str, ...] = CENTRE_ROLES + tuple(
    f"{part}_{side}" for part in LEG_ROLES + ARM_ROLES for side in SIDES
)
OPTIONAL_ROLES: tuple[str, ...] = tuple(f"{part}_{side}" for part in ("toe", "clavicle") for side in SIDES)
ALL_ROLES: tuple[str, ...] = REQUIRED_ROLES + OPTIONAL_ROLES


def part_of(role: str) -> str:
    """'knee_l' -> 'knee'; centre roles are their own part."""
    return role[:-2] if side_of(role) else role


def side_of(role: str) -> str | None:
    """'knee_l' -> 'l'; a centre role has no side (None)."""
    side = role[-1]
    return side if role[-2:-1] == "_" and side in SIDES else None


# The back rule lets `back` share its joint with these roles; every other pair must differ.
BACK_MAY_SHARE = ("waist", "chest")

# Whole-name patterns per body part, matched against a joint's words without its side.
PART_NAMES = {
    "head": r"head",
    "hip": r"up(per)?leg|thigh|femur|hip|legupper",
    "knee": r"(lower|lo)?leg|shin|calf|knee|tibia|leglower",
    "ankle": r"foot|ankle",
    "toe": r"toes?|toebase|ball",
    "clavicle": r"clavicle|clav|shoulder|collar(bone)?",
    "shoulder": r"(upper|up)?arm|humerus|armupper",
    "elbow": r"(fore|lower|lo)arm|elbow|armlower",
    "wrist": r"hand|wrist",
}
# A bone shorter than this fraction of the skeleton's longest offset counts as zero length.
ZERO_BONE_FRACTION = 1e-4

_NAMESPACE = re.compile(r"^.*[:|]")
_PREFIX = re.compile(r"^(?:mixamorig\d*[_.\s-]*|(?:cc_base|def)[_.\s-]+)", re.IGNORECASE)
_WORDS = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+")
_SIDE_WORDS = {"l": "l", "left": "l", "r": "r", "right": "r"}


@dataclass(frozen=True)
class JointName:
    """A joint name read for matching: its side ("l", "r" or None) and remaining words."""

    side: str | None
    words: tuple[str, ...]

    @property
    def core(self) -> str:
        return "".join(self.words)


def read_joint_name(name: str) -> JointName:
    """Split a joint name into side and words, whatever the naming scheme's spelling."""
    bare = _PREFIX.sub("", _NAMESPACE.sub("", name))
    words = [w.lower() for w in _WORDS.findall(bare)]
    if words and words[0] not in _SIDE_WORDS:  # joined spellings such as "lefthand"
        for side_word in ("left", "right"):
            if words[0].startswith(side_word):
                words[:1] = [side_word, words[0][len(side_word) :]]
    sides = {_SIDE_WORDS[w] for w in words if w in _SIDE_WORDS}
    side = sides.pop() if len(sides) == 1 else None
    return JointName(side, tuple(w for w in words if w not in _SIDE_WORDS))


# ---------------------------------------------------------------------------------------------
# Hierarchy helpers


def _ancestors(skeleton: Skeleton, joint: int) -> list[int]:
    """The joint itself and every ancestor up to the root, nearest first."""
    chain = [joint]
    while skeleton.parents[chain[-1]] >= 0:
        chain.append(int(skeleton.parents[chain[-1]]))
    return chain


def _is_below(skeleton: Skeleton, joint: int, ancestor: int) -> bool:
    """True when `ancestor` is a proper ancestor of `joint`."""
    return joint != ancestor and ancestor in _ancestors(skeleton, joint)


def _common_ancestor(skeleton: Skeleton, joints: list[int]) -> int:
    """The deepest joint that is an ancestor (or self) of every joint given."""
    common = set(_ancestors(skeleton, joints[0]))
    for joint in joints[1:]:
        common &= set(_ancestors(skeleton, joint))
    return max(common, key=lambda j: len(_ancestors(skeleton, j)))


def _path_down(skeleton: Skeleton, top: int, bottom: int) -> list[int] | None:
    """Joints from just below `top` down to `bottom`, or None when `bottom` is not below `top`."""
    chain = _ancestors(skeleton, bottom)
    if top not in chain or top == bottom:
        return None
    return chain[: chain.index(top)][::-1]


def _bone_lengths(skeleton: Skeleton) -> FloatArray:
    """Per joint, the length of its parent's bone toward it, with near-zero lengths set to 0
    (iClone writes co-located joints as OFFSET -0.000000 -0.000069 0.000001)."""
    lengths = np.linalg.norm(skeleton.offsets, axis=1)
    lengths[lengths <= ZERO_BONE_FRACTION * lengths.max()] = 0.0
    return lengths


# ---------------------------------------------------------------------------------------------
# Limbs, by name


def _named(skeleton: Skeleton, part: str, side: str | None) -> list[int]:
    """Joints whose name, side aside, is one of the part's names, nearest the root first."""
    pattern = re.compile(PART_NAMES[part])
    found: list[int] = []
    for j, name in enumerate(skeleton.names):
        read = read_joint_name(name)
        if read.side == side and pattern.fullmatch(read.core):
            found.append(j)
    return sorted(found, key=lambda j: (len(_ancestors(skeleton, j)), j))


def _find_chain(skeleton: Skeleton, roles: dict[str, int], parts: tuple[str, ...], side: str) -> None:
    """Fill a limb chain near to far; each joint must hang below the previous one found."""
    previous = None
    for part in parts:
        role = f"{part}_{side}"
        if role not in roles:
            used = set(roles.values())
            for j in _named(skeleton, part, side):
                if j not in used and (previous is None or _is_below(skeleton, j, previous)):
                    roles[role] = j
                    break
        previous = roles.get(role, previous)


def _upper_arm_from_elbow(skeleton: Skeleton, roles: dict[str, int], side: str) -> None:
    """Without an upper-arm name (e.g. Kinect's ShoulderLeft), take the elbow's same-side parent."""
    role, elbow = f"shoulder_{side}", roles.get(f"elbow_{side}")
    if role in roles or elbow is None:
        return
    parent = int(skeleton.parents[elbow])
    if parent >= 0 and parent not in roles.values() and read_joint_name(skeleton.names[parent]).side == side:
        roles[role] = parent


def _find_clavicle(skeleton: Skeleton, roles: dict[str, int], side: str) -> None:
    """The clavicle is the nearest clavicle-named joint above the upper arm."""
    role, upper_arm = f"clavicle_{side}", roles.get(f"shoulder_{side}")
    if role in roles or upper_arm is None:
        return
    named = set(_named(skeleton, "clavicle", side)) - set(roles.values())
    above = [j for j in _ancestors(skeleton, upper_arm)[1:] if j in named]
    if above:
        roles[role] = above[0]


def _find_limbs(skeleton: Skeleton, roles: dict[str, int]) -> None:
    for side in SIDES:
        _find_chain(skeleton, roles, LEG_ROLES + ("toe",), side)
        _find_chain(skeleton, roles, ARM_ROLES, side)
        _upper_arm_from_elbow(skeleton, roles, side)
        _find_clavicle(skeleton, roles, side)


# ---------------------------------------------------------------------------------------------
# Torso, by hierarchy


def _find_head(skeleton: Skeleton, roles: dict[str, int]) -> None:
    if "head" not in roles:
        heads = [j for j in _named(skeleton, "head", None) if j not in roles.values()]
        if heads:
            roles["head"] = heads[0]


def _find_pelvis(skeleton: Skeleton, roles: dict[str, int]) -> None:
    """The pelvis is the joint both legs and the spine hang from (their common ancestor)."""
    anchors = [roles[r] for r in ("hip_l", "hip_r", "head") if r in roles]
    if "pelvis" not in roles and len(anchors) >= 2:
        roles["pelvis"] = _common_ancestor(skeleton, anchors)


def _spine_with_bones(skeleton: Skeleton, roles: dict[str, int]) -> list[int]:
    """Joints on the path pelvis -> head (head excluded) whose bone along that path has length."""
    if "pelvis" not in roles or "head" not in roles:
        return []
    path = _path_down(skeleton, roles["pelvis"], roles["head"]) or []
    lengths = _bone_lengths(skeleton)
    return [j for j, above in itertools.pairwise(path) if lengths[above] > 0]


def _find_chest(skeleton: Skeleton, roles: dict[str, int], spine: list[int]) -> None:
    """The chest is the last spine joint with a bone at or below where the arms hang from."""
    arms = [roles[r] for r in ("shoulder_l", "shoulder_r") if r in roles]
    if "chest" in roles or not arms or not spine:
        return
    arms_base = _common_ancestor(skeleton, arms + [roles["head"]])
    below_arms = [j for j in spine if j == arms_base or _is_below(skeleton, arms_base, j)]
    if below_arms:
        roles["chest"] = below_arms[-1]


def _find_waist_and_back(skeleton: Skeleton, roles: dict[str, int], spine: list[int]) -> None:
    """Waist: first spine joint; back: the middle one strictly between waist and chest, else chest."""
    chest = roles.get("chest")
    if chest not in spine:
        return
    lower = spine[: spine.index(chest)]
    if "waist" not in roles and lower:
        roles["waist"] = lower[0]
    if "back" not in roles and roles.get("waist") in lower:
        between = lower[lower.index(roles["waist"]) + 1 :]
        roles["back"] = between[(len(between) - 1) // 2] if between else chest


def _find_neck(skeleton: Skeleton, roles: dict[str, int], spine: list[int]) -> None:
    """Neck: the first joint with a bone above the chest, a name starting "neck" preferred."""
    chest = roles.get("chest")
    if "neck" in roles or chest not in spine:
        return
    above = [j for j in spine[spine.index(chest) + 1 :] if j not in roles.values()]
    named = [j for j in above if read_joint_name(skeleton.names[j]).core.startswith("neck")]
    if named or above:
        roles["neck"] = (named or above)[0]


def _find_torso(skeleton: Skeleton, roles: dict[str, int]) -> None:
    _find_head(skeleton, roles)
    _find_pelvis(skeleton, roles)
    spine = _spine_with_bones(skeleton, roles)
    _find_chest(skeleton, roles, spine)
    _find_waist_and_back(skeleton, roles, spine)
    _find_neck(skeleton, roles, spine)


# ---------------------------------------------------------------------------------------------
# Checks and public API


def _checked_overrides(skeleton: Skeleton, overrides: dict[str, str] | None) -> dict[str, int]:
    """Overrides as role -> joint index; unknown roles and joints are errors naming them."""
    fixed: dict[str, int] = {}
    for role, joint in (overrides or {}).items():
        if role not in ALL_ROLES:
            raise SkeletonError(f"unknown joint role '{role}' in the overrides; roles are: {', '.join(ALL_ROLES)}")
        if joint not in skeleton.names:
            raise SkeletonError(
                f"the override for role '{role}' names joint '{joint}', which the skeleton does not have; "
                f"its joints are: {', '.join(skeleton.names)}"
            )
        fixed[role] = skeleton.names.index(joint)
    return fixed


def _check_complete(skeleton: Skeleton, roles: dict[str, int]) -> None:
    """Every required role found, so the animator learns at once which overrides to write."""
    missing = [r for r in REQUIRED_ROLES if r not in roles]
    if missing:
        raise SkeletonError(
            f"no joint found for the roles: {', '.join(missing)}. Give them as overrides "
            f"(role -> joint name); the skeleton's joints are: {', '.join(skeleton.names)}"
        )


def _check_distinct(skeleton: Skeleton, roles: dict[str, int]) -> None:
    """Two roles on one joint would merge two ragdoll bodies; only the back rule allows it."""
    owner: dict[int, str] = {}
    for role in (r for r in ALL_ROLES if r in roles and r != "back"):
        joint = roles[role]
        if joint in owner:
            raise SkeletonError(
                f"roles '{owner[joint]}' and '{role}' both map to joint '{skeleton.names[joint]}'; "
                "each role needs its own joint (only 'back' may share the waist's or chest's)"
            )
        owner[joint] = role
    back = roles.get("back")
    if back is not None and back in owner and owner[back] not in BACK_MAY_SHARE:
        raise SkeletonError(
            f"role 'back' maps to joint '{skeleton.names[back]}', which is already '{owner[back]}'; "
            "'back' may share only the waist's or the chest's joint"
        )


def assign_roles(skeleton: Skeleton, overrides: dict[str, str] | None = None) -> dict[str, str]:
    """Map the paper's joint roles to this skeleton's joint names (role -> joint name).

    Overrides (role -> joint name) win. Raises SkeletonError when a required role has no joint
    (the message lists the missing roles and every joint, for writing an override), when an
    override names an unknown role or joint, or when two roles land on one joint.
    """
    roles = _checked_overrides(skeleton, overrides)
    _find_limbs(skeleton, roles)
    _find_torso(skeleton, roles)
    _check_complete(skeleton, roles)
    _check_distinct(skeleton, roles)
    return {role: skeleton.names[roles[role]] for role in ALL_ROLES if role in roles}


def apply_roles(skeleton: Skeleton, overrides: dict[str, str] | None = None) -> dict[str, str]:
    """Assign roles and store them in `skeleton.roles`, where the ragdoll and search read them."""
    skeleton.roles = assign_roles(skeleton, overrides)
    return skeleton.roles


def guess_roles(skeleton: Skeleton, overrides: dict[str, str] | None = None) -> dict[str, str]:
    """What assign_roles finds, without requiring every role or checking them: where a role editor
    starts from on a rig whose names are only partly recognised. Overrides win, as there."""
    roles = _checked_overrides(skeleton, overrides)
    try:
        _find_limbs(skeleton, roles)
        _find_torso(skeleton, roles)
    except SkeletonError:
        pass  # keep what was found before the part that could not be read
    return {role: skeleton.names[roles[role]] for role in ALL_ROLES if role in roles}


def _rig(centre: tuple[str, ...], limbs: dict[str, str], sides: tuple[str, str]) -> dict[str, str]:
    """A rig's role table: the centre joints in CENTRE_ROLES order, limb names with '{}' for the side."""
    table: dict[str, str] = dict(zip(CENTRE_ROLES, centre, strict=True))
    for side, word in zip(SIDES, sides, strict=True):
        table |= {f"{part}_{side}": name.format(word) for part, name in limbs.items()}
    return table


# Role tables of common rigs (bone names as each tool writes them): a preset for the role editor
# when the names are there but the hierarchy confuses the search (extra helper bones, a split spine).
RIG_PRESETS: dict[str, dict[str, str]] = {
    "mixamo": _rig(
        (
            "mixamorig:Hips",
            "mixamorig:Spine",
            "mixamorig:Spine1",
            "mixamorig:Spine2",
            "mixamorig:Neck",
            "mixamorig:Head",
        ),
        {
            "hip": "mixamorig:{}UpLeg",
            "knee": "mixamorig:{}Leg",
            "ankle": "mixamorig:{}Foot",
            "toe": "mixamorig:{}ToeBase",
            "clavicle": "mixamorig:{}Shoulder",
            "shoulder": "mixamorig:{}Arm",
            "elbow": "mixamorig:{}ForeArm",
            "wrist": "mixamorig:{}Hand",
        },
        ("Left", "Right"),
    ),
    "rigify": _rig(
        ("DEF-spine", "DEF-spine.001", "DEF-spine.002", "DEF-spine.003", "DEF-spine.004", "DEF-spine.006"),
        {
            "hip": "DEF-thigh.{}",
            "knee": "DEF-shin.{}",
            "ankle": "DEF-foot.{}",
            "toe": "DEF-toe.{}",
            "clavicle": "DEF-shoulder.{}",
            "shoulder": "DEF-upper_arm.{}",
            "elbow": "DEF-forearm.{}",
            "wrist": "DEF-hand.{}",
        },
        ("L", "R"),
    ),
    "cmu": _rig(
        ("Hips", "LowerBack", "Spine", "Spine", "Neck", "Head"),  # Spine1 sits at the neck: the chest is Spine
        {
            "hip": "{}UpLeg",
            "knee": "{}Leg",
            "ankle": "{}Foot",
            "toe": "{}ToeBase",
            "clavicle": "{}Shoulder",
            "shoulder": "{}Arm",
            "elbow": "{}ForeArm",
            "wrist": "{}Hand",
        },
        ("Left", "Right"),
    ),
    "bandai_namco": _rig(
        ("Hips", "Spine", "Chest", "Chest", "Neck", "Head"),
        {
            "hip": "UpperLeg_{}",
            "knee": "LowerLeg_{}",
            "ankle": "Foot_{}",
            "toe": "Toes_{}",
            "clavicle": "Shoulder_{}",
            "shoulder": "UpperArm_{}",
            "elbow": "LowerArm_{}",
            "wrist": "Hand_{}",
        },
        ("L", "R"),
    ),
    "sample": _rig(
        ("pelvis", "spine", "spine.001", "chest", "neck", "head"),
        {
            "hip": "thigh.{}",
            "knee": "shin.{}",
            "ankle": "foot.{}",
            "toe": "toe.{}",
            "clavicle": "shoulder.{}",
            "shoulder": "upper_arm.{}",
            "elbow": "forearm.{}",
            "wrist": "hand.{}",
        },
        ("L", "R"),
    ),
}


def preset_roles(preset: str, names: list[str]) -> dict[str, str]:
    """The preset's roles whose bone the rig has (a namespace prefix such as 'mixamorig1:' ignored)."""
    if preset not in RIG_PRESETS:
        raise SkeletonError(f"unknown rig preset '{preset}'; presets are: {', '.join(RIG_PRESETS)}")
    bare = {_NAMESPACE.sub("", name): name for name in names}
    found: dict[str, str] = {}
    for role, bone in RIG_PRESETS[preset].items():
        name = bone if bone in names else bare.get(_NAMESPACE.sub("", bone))
        if name is not None:
            found[role] = name
    return found
