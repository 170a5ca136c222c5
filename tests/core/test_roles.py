"""Joint roles (core/model/roles.py): the paper's Table 1/2 joints found on every skeleton we meet.

Real skeletons: every shared mocap file gets its dataset's exact role table, and left roles sit on
the character's left by geometry (independent of names). Synthetic skeletons (Mixamo, the common
LeftUpLeg scheme with any separator, the project's Blender-style sample, a Kinect-style one) check
the name rules; then overrides, the back rule and the errors.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from reactive_anim.core.model import bvh
from reactive_anim.core.model.errors import SkeletonError
from reactive_anim.core.model.roles import (
    ALL_ROLES,
    OPTIONAL_ROLES,
    REQUIRED_ROLES,
    apply_roles,
    assign_roles,
    part_of,
    read_joint_name,
    side_of,
)
from reactive_anim.core.model.skeleton import Skeleton
from tests.support.mocap import MOCAP, mocap_files, require_mocap

# ---------------------------------------------------------------------------------------------
# Expected tables for the shared mocap (one per dataset; both iClone layouts share one)

BANDAI = {
    "pelvis": "Hips", "waist": "Spine", "back": "Chest", "chest": "Chest", "neck": "Neck", "head": "Head",
    "hip_l": "UpperLeg_L", "hip_r": "UpperLeg_R", "knee_l": "LowerLeg_L", "knee_r": "LowerLeg_R",
    "ankle_l": "Foot_L", "ankle_r": "Foot_R",
    "shoulder_l": "UpperArm_L", "shoulder_r": "UpperArm_R", "elbow_l": "LowerArm_L", "elbow_r": "LowerArm_R",
    "wrist_l": "Hand_L", "wrist_r": "Hand_R",
    "toe_l": "Toes_L", "toe_r": "Toes_R", "clavicle_l": "Shoulder_L", "clavicle_r": "Shoulder_R",
}  # fmt: skip
CMU = {
    "pelvis": "Hips", "waist": "LowerBack", "back": "Spine", "chest": "Spine", "neck": "Neck", "head": "Head",
    "hip_l": "LeftUpLeg", "hip_r": "RightUpLeg", "knee_l": "LeftLeg", "knee_r": "RightLeg",
    "ankle_l": "LeftFoot", "ankle_r": "RightFoot",
    "shoulder_l": "LeftArm", "shoulder_r": "RightArm", "elbow_l": "LeftForeArm", "elbow_r": "RightForeArm",
    "wrist_l": "LeftHand", "wrist_r": "RightHand",
    "toe_l": "LeftToeBase", "toe_r": "RightToeBase", "clavicle_l": "LeftShoulder", "clavicle_r": "RightShoulder",
}  # fmt: skip
ICLONE = {
    "pelvis": "CC_Base_Hip", "waist": "CC_Base_Waist", "back": "CC_Base_Spine01", "chest": "CC_Base_Spine02",
    "neck": "CC_Base_NeckTwist01", "head": "CC_Base_Head",
    "hip_l": "CC_Base_L_Thigh", "hip_r": "CC_Base_R_Thigh", "knee_l": "CC_Base_L_Calf", "knee_r": "CC_Base_R_Calf",
    "ankle_l": "CC_Base_L_Foot", "ankle_r": "CC_Base_R_Foot",
    "shoulder_l": "CC_Base_L_Upperarm", "shoulder_r": "CC_Base_R_Upperarm",
    "elbow_l": "CC_Base_L_Forearm", "elbow_r": "CC_Base_R_Forearm",
    "wrist_l": "CC_Base_L_Hand", "wrist_r": "CC_Base_R_Hand",
    "toe_l": "CC_Base_L_ToeBase", "toe_r": "CC_Base_R_ToeBase",
    "clavicle_l": "CC_Base_L_Clavicle", "clavicle_r": "CC_Base_R_Clavicle",
}  # fmt: skip
DATASET_TABLES = {"bandai_namco": BANDAI, "cmu": CMU, "cmu_iclone": ICLONE}

REPRESENTATIVES = {
    "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh": BANDAI,
    "bandai_namco/dataset-2/dataset-2_walk_normal_001.bvh": BANDAI,
    "cmu/90_18.bvh": CMU,
    "cmu_iclone/002_01.bvh": ICLONE,  # RL_BoneRoot layout
    "cmu_iclone/002_04.bvh": ICLONE,  # CC_Base_Hip root layout
}


def _skeleton_of(path) -> Skeleton:
    """A real file's hierarchy in its own units and axes (roles need no conversion)."""
    data = bvh.parse_bvh(path)
    return Skeleton(data.names, np.asarray(data.parents), data.offsets)


def _dataset(path) -> str:
    return path.relative_to(MOCAP).parts[0]


# ---------------------------------------------------------------------------------------------
# Role lists


def test_role_lists_cover_the_paper_joints_once():
    assert len(REQUIRED_ROLES) == 18 and len(set(REQUIRED_ROLES)) == 18
    assert set(OPTIONAL_ROLES) == {"toe_l", "toe_r", "clavicle_l", "clavicle_r"}
    assert not set(REQUIRED_ROLES) & set(OPTIONAL_ROLES)
    assert ALL_ROLES == REQUIRED_ROLES + OPTIONAL_ROLES
    for paper_joint in ("pelvis", "waist", "back", "chest", "neck", "head"):
        assert paper_joint in REQUIRED_ROLES
    for limb in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist"):
        assert f"{limb}_l" in REQUIRED_ROLES and f"{limb}_r" in REQUIRED_ROLES


# ---------------------------------------------------------------------------------------------
# Real mocap


@pytest.mark.mocap
@pytest.mark.parametrize("relative", sorted(REPRESENTATIVES))
def test_representative_file_gets_exact_roles(relative):
    skeleton = _skeleton_of(require_mocap(relative))
    assert assign_roles(skeleton) == REPRESENTATIVES[relative]


@pytest.mark.mocap
@pytest.mark.parametrize("path", mocap_files(), ids=lambda p: str(p.relative_to(MOCAP)))
def test_every_shared_file_gets_its_dataset_table(path):
    roles = assign_roles(_skeleton_of(path))
    assert set(REQUIRED_ROLES) <= set(roles)
    assert roles == DATASET_TABLES[_dataset(path)]
    assert _sides_agree(roles)


def test_every_shared_dataset_is_covered():
    """The table test above must not silently skip a dataset folder it has no table for."""
    folders = {_dataset(p) for p in mocap_files()}
    if not folders:
        pytest.skip(f"real mocap not available: {MOCAP} is absent (../shared/mocap is test-only data)")
    assert folders == set(DATASET_TABLES)


@pytest.mark.mocap
@pytest.mark.parametrize(
    "relative, frame",
    [
        ("bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh", 100),
        ("bandai_namco/dataset-2/dataset-2_run_normal_001.bvh", 30),
        ("cmu/90_18.bvh", 30),  # standing, before the fall
        ("cmu/91_59.bvh", 20),
        ("cmu_iclone/002_01.bvh", 80),
        ("cmu_iclone/002_04.bvh", 60),
    ],
)
def test_left_roles_are_on_the_characters_left(relative, frame):
    """Geometry, not names: in the body's own frame (up = pelvis to head, forward = along the
    feet) the left hip and upper arm lie left of their right twins. (Knees, elbows and wrists
    may cross in a stride; hips and shoulders hang from the rigid pelvis and chest.)"""
    motion = bvh.read_bvh(require_mocap(relative))
    roles = apply_roles(motion.skeleton)
    pos = motion.global_positions()[frame]

    def at(role: str) -> np.ndarray:
        return pos[motion.skeleton.index(roles[role])]

    up = at("head") - at("pelvis")
    up /= np.linalg.norm(up)
    forward = (at("toe_l") - at("ankle_l")) + (at("toe_r") - at("ankle_r"))
    forward -= up * np.dot(forward, up)
    left = np.cross(up, forward / np.linalg.norm(forward))
    for limb in ("hip", "shoulder"):
        separation = np.dot(at(f"{limb}_l") - at(f"{limb}_r"), left)
        assert separation > 0.05, f"{limb}: left joint is {separation:.3f} m left of the right one"


@pytest.mark.mocap
@pytest.mark.parametrize("relative", ["cmu_iclone/002_01.bvh", "cmu_iclone/002_04.bvh"])
def test_iclone_twist_share_finger_and_face_bones_are_never_chosen(relative):
    skeleton = _skeleton_of(require_mocap(relative))
    helper = re.compile(r"Twist|Share|Toe\d|Thumb|Index|Mid\d|Ring|Pinky|Facial|Jaw|Eye|Teeth|Tongue|Breast|Ribs")
    roles = assign_roles(skeleton)
    chosen = {role: joint for role, joint in roles.items() if role != "neck"}
    assert not [j for j in chosen.values() if helper.search(j)]
    # The documented exception: the rig's only neck bones are NeckTwist01/02; the lower is the neck.
    assert roles["neck"] == "CC_Base_NeckTwist01"
    # Twist bones share their limb joint's position; the limb joint is the one with the bone.
    assert skeleton.names.index("CC_Base_L_UpperarmTwist01") > skeleton.names.index(roles["shoulder_l"])


@pytest.mark.mocap
def test_cmu_zero_offset_helpers_are_passed_over():
    """Spine1's children (Neck, both shoulders) sit on it: its bone has no length, so the chest
    segment is Spine's; Neck (whose bone reaches Neck1) is the neck; Head is the head."""
    skeleton = _skeleton_of(require_mocap("cmu/90_18.bvh"))
    roles = assign_roles(skeleton)
    assert np.allclose(skeleton.offsets[skeleton.index("Neck")], 0.0)
    assert "Spine1" not in roles.values() and "Neck1" not in roles.values()
    assert "LHipJoint" not in roles.values() and "RHipJoint" not in roles.values()
    assert (roles["chest"], roles["neck"], roles["head"]) == ("Spine", "Neck", "Head")


@pytest.mark.mocap
def test_roles_survive_reading_to_metres_z_up():
    """read_bvh rotates and scales offsets; the roles depend on neither."""
    path = require_mocap("bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh")
    assert assign_roles(bvh.read_bvh(path).skeleton) == BANDAI


# ---------------------------------------------------------------------------------------------
# Synthetic skeletons


Row = tuple[str, str | None, tuple[float, float, float]]  # a joint: name, parent's name, offset


def _build(joints: list[Row]) -> Skeleton:
    """Skeleton from (name, parent name, offset in metres, Z up, +Y forward, +X left) rows."""
    names = [name for name, _, _ in joints]
    parents = [-1 if parent is None else names.index(parent) for _, parent, _ in joints]
    return Skeleton(names, np.asarray(parents), np.asarray([offset for _, _, offset in joints]))


def _rows(skeleton: Skeleton) -> list[Row]:
    """The (name, parent name, offset) rows of a skeleton, to edit and rebuild."""
    parents = [None if p < 0 else skeleton.names[p] for p in skeleton.parents]
    return list(zip(skeleton.names, parents, map(tuple, skeleton.offsets), strict=True))


def _mirror(rows: list[Row], left: str, right: str) -> list[Row]:
    """The right-hand rows of a left limb: names with `left` swapped for `right`, x negated."""

    def swap(name: str) -> str:
        return name.replace(left, right)

    return [(swap(n), None if p is None else swap(p), (-o[0], o[1], o[2])) for n, p, o in rows]


# Offsets below the hip joint: knee and ankle straight down, then the toe and a toe tip forward.
LEG_OFFSETS = [(0.0, 0.0, -0.42), (0.0, 0.0, -0.42), (0.0, 0.12, -0.06), (0.0, 0.05, 0.0)]


def _humanoid(
    spine: list[str], neck: list[str], head_parts: list[str], arm: list[str], leg: list[str],
    left: str, right: str, root: str,
) -> Skeleton:  # fmt: skip
    """A standing humanoid facing +Y: a spine up Z, arms out along +X (left) and -X, legs down."""
    chain = [root] + spine + neck + head_parts
    rows: list[Row] = [(root, None, (0.0, 0.0, 1.0))]
    rows += [(name, chain[i], (0.0, 0.0, 0.12)) for i, name in enumerate(chain[1:])]
    arm_rows: list[Row] = [(arm[0], spine[-1], (0.04, 0.0, 0.1))]
    arm_rows += [(name, arm[i], (0.15 + 0.1 * i, 0.0, 0.0)) for i, name in enumerate(arm[1:])]
    leg_rows: list[Row] = [(leg[0], root, (0.1, 0.0, -0.05))]
    leg_rows += [(name, leg[i], LEG_OFFSETS[i]) for i, name in enumerate(leg[1:])]
    return _build(rows + arm_rows + _mirror(arm_rows, left, right) + leg_rows + _mirror(leg_rows, left, right))


def _mixamo(prefix: str = "mixamorig:") -> Skeleton:
    fingers = ["LeftHandThumb1", "LeftHandIndex1", "LeftHandMiddle1"]
    skeleton = _humanoid(
        spine=["Spine", "Spine1", "Spine2"], neck=["Neck"], head_parts=["Head", "HeadTop_End"],
        arm=["LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand"],
        leg=["LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "LeftToe_End"],
        left="Left", right="Right", root="Hips",
    )  # fmt: skip
    names = skeleton.names + fingers
    parents = list(skeleton.parents) + [names.index("LeftHand")] * len(fingers)
    offsets = np.vstack([skeleton.offsets, np.full((len(fingers), 3), 0.03)])
    return Skeleton([prefix + n for n in names], np.asarray(parents), offsets)


COMMON = {
    "pelvis": "Hips", "waist": "Spine", "back": "Spine1", "chest": "Spine2", "neck": "Neck", "head": "Head",
    "hip_l": "LeftUpLeg", "hip_r": "RightUpLeg", "knee_l": "LeftLeg", "knee_r": "RightLeg",
    "ankle_l": "LeftFoot", "ankle_r": "RightFoot",
    "shoulder_l": "LeftArm", "shoulder_r": "RightArm", "elbow_l": "LeftForeArm", "elbow_r": "RightForeArm",
    "wrist_l": "LeftHand", "wrist_r": "RightHand",
    "toe_l": "LeftToeBase", "toe_r": "RightToeBase", "clavicle_l": "LeftShoulder", "clavicle_r": "RightShoulder",
}  # fmt: skip


@pytest.mark.parametrize("prefix", ["mixamorig:", "mixamorig1:", "Armature|mixamorig:", "Character1|Armature|"])
def test_mixamo_names_with_prefixes_and_namespaces(prefix):
    roles = assign_roles(_mixamo(prefix))
    assert roles == {role: prefix + joint for role, joint in COMMON.items()}


def test_mixamo_finger_and_end_bones_are_never_chosen():
    roles = assign_roles(_mixamo())
    assert not [j for j in roles.values() if re.search(r"Thumb|Index|Middle|_End", j)]


def _respelled(name: str, separator: str) -> str:
    """LeftUpLeg -> left<sep>up<sep>leg: the same joint in another naming habit."""
    return separator.join(w.lower() for w in re.findall(r"[A-Z][a-z]*|\d+", name))


def _common(separator: str | None = None) -> Skeleton:
    skeleton = _mixamo(prefix="")
    keep = [i for i, n in enumerate(skeleton.names) if not re.search(r"Thumb|Index|Middle", n)]
    names = [skeleton.names[i] for i in keep]
    if separator is not None:
        names = [_respelled(n, separator) for n in names]
    return Skeleton(names, skeleton.parents[keep], skeleton.offsets[keep])


def test_common_scheme():
    assert assign_roles(_common()) == COMMON


@pytest.mark.parametrize("separator", ["_", ".", " ", "-", ""])
def test_common_scheme_with_any_separator_and_case(separator):
    roles = assign_roles(_common(separator))
    assert roles == {role: _respelled(joint, separator) for role, joint in COMMON.items()}


def _sample() -> Skeleton:
    """The project's own sample skeleton: Blender-style names, .L/.R suffixes, 22 joints."""
    return _humanoid(
        spine=["spine", "spine.001", "chest"], neck=["neck"], head_parts=["head"],
        arm=["shoulder.L", "upper_arm.L", "forearm.L", "hand.L"],
        leg=["thigh.L", "shin.L", "foot.L", "toe.L"],
        left=".L", right=".R", root="pelvis",
    )  # fmt: skip


SAMPLE = {
    "pelvis": "pelvis", "waist": "spine", "back": "spine.001", "chest": "chest", "neck": "neck", "head": "head",
    "hip_l": "thigh.L", "hip_r": "thigh.R", "knee_l": "shin.L", "knee_r": "shin.R",
    "ankle_l": "foot.L", "ankle_r": "foot.R",
    "shoulder_l": "upper_arm.L", "shoulder_r": "upper_arm.R", "elbow_l": "forearm.L", "elbow_r": "forearm.R",
    "wrist_l": "hand.L", "wrist_r": "hand.R",
    "toe_l": "toe.L", "toe_r": "toe.R", "clavicle_l": "shoulder.L", "clavicle_r": "shoulder.R",
}  # fmt: skip


def test_sample_skeleton():
    skeleton = _sample()
    assert skeleton.num_joints == 22
    assert assign_roles(skeleton) == SAMPLE


def test_apply_roles_stores_the_map_on_the_skeleton():
    skeleton = _sample()
    assert skeleton.roles == {}
    returned = apply_roles(skeleton)
    assert skeleton.roles == SAMPLE and returned == SAMPLE


def test_rigify_deform_bones_and_their_segments():
    """DEF- prefixes are read through; the .001 segments (twist parts) are not limb joints."""
    rows = [
        ("root", None, (0, 0, 0)), ("DEF-pelvis", "root", (0, 0, 1.0)),
        ("DEF-spine", "DEF-pelvis", (0, 0, 0.1)), ("DEF-spine.001", "DEF-spine", (0, 0, 0.12)),
        ("DEF-spine.002", "DEF-spine.001", (0, 0, 0.12)), ("DEF-spine.003", "DEF-spine.002", (0, 0, 0.12)),
        ("DEF-spine.004", "DEF-spine.003", (0, 0, 0.15)), ("DEF-spine.005", "DEF-spine.004", (0, 0, 0.05)),
        ("DEF-spine.006", "DEF-spine.005", (0, 0, 0.05)),
    ]  # fmt: skip
    arm = [
        ("DEF-shoulder.L", "DEF-spine.003", (0.03, 0, 0.1)), ("DEF-upper_arm.L", "DEF-shoulder.L", (0.15, 0, 0)),
        ("DEF-upper_arm.L.001", "DEF-upper_arm.L", (0.14, 0, 0)),
        ("DEF-forearm.L", "DEF-upper_arm.L.001", (0.14, 0, 0)),
        ("DEF-forearm.L.001", "DEF-forearm.L", (0.12, 0, 0)), ("DEF-hand.L", "DEF-forearm.L.001", (0.12, 0, 0)),
    ]  # fmt: skip
    leg = [
        ("DEF-thigh.L", "DEF-pelvis", (0.1, 0, -0.05)), ("DEF-thigh.L.001", "DEF-thigh.L", (0, 0, -0.2)),
        ("DEF-shin.L", "DEF-thigh.L.001", (0, 0, -0.2)), ("DEF-shin.L.001", "DEF-shin.L", (0, 0, -0.2)),
        ("DEF-foot.L", "DEF-shin.L.001", (0, 0, -0.2)), ("DEF-toe.L", "DEF-foot.L", (0, 0.1, -0.05)),
    ]  # fmt: skip
    skeleton = _build(rows + arm + _mirror(arm, ".L", ".R") + leg + _mirror(leg, ".L", ".R"))
    # Rigify names its neck and head spine.004-.006: nothing says "head", so the animator says it.
    with pytest.raises(SkeletonError, match="head"):
        assign_roles(skeleton)
    roles = assign_roles(skeleton, overrides={"head": "DEF-spine.006"})
    assert [roles[r] for r in ("pelvis", "waist", "back", "chest", "neck")] == [
        "DEF-pelvis", "DEF-spine", "DEF-spine.001", "DEF-spine.003", "DEF-spine.004",
    ]  # fmt: skip
    assert roles["hip_l"] == "DEF-thigh.L" and roles["knee_l"] == "DEF-shin.L" and roles["ankle_l"] == "DEF-foot.L"
    assert roles["shoulder_r"] == "DEF-upper_arm.R" and roles["elbow_r"] == "DEF-forearm.R"
    assert roles["wrist_r"] == "DEF-hand.R" and roles["clavicle_r"] == "DEF-shoulder.R"
    assert not [j for r, j in roles.items() if r.endswith(("_l", "_r")) and j.endswith(".001")]


def test_kinect_style_upper_arm_is_the_elbows_parent():
    """ShoulderLeft is the upper arm there (no Arm/UpperArm name): taken as the elbow's parent.
    AnkleLeft and WristLeft win over FootLeft and HandLeft because they are nearer the body."""
    skeleton = _humanoid(
        spine=["SpineMid", "SpineShoulder"], neck=["Neck"], head_parts=["Head"],
        arm=["ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft"],
        leg=["HipLeft", "KneeLeft", "AnkleLeft", "FootLeft"],
        left="Left", right="Right", root="SpineBase",
    )  # fmt: skip
    roles = assign_roles(skeleton)
    assert roles["shoulder_l"] == "ShoulderLeft" and roles["shoulder_r"] == "ShoulderRight"
    assert roles["elbow_l"] == "ElbowLeft" and roles["wrist_l"] == "WristLeft"
    assert roles["hip_r"] == "HipRight" and roles["ankle_r"] == "AnkleRight"
    assert "clavicle_l" not in roles and "toe_l" not in roles
    assert (roles["pelvis"], roles["waist"], roles["back"], roles["chest"]) == (
        "SpineBase",
        "SpineMid",
        "SpineShoulder",
        "SpineShoulder",
    )


def test_pelvis_is_where_legs_and_spine_meet_not_the_ground_root():
    """Bandai-like: a ground root above the hips; iClone-like: a fixed Pelvis the legs hang from."""
    legs = [
        ("L_Thigh", "Pelvis", (0.1, 0, -0.05)), ("L_Calf", "L_Thigh", (0, 0, -0.45)),
        ("L_Foot", "L_Calf", (0, 0, -0.45)),
    ]  # fmt: skip
    arms = [
        ("L_Upperarm", "Spine02", (0.18, 0, 0.2)), ("L_Forearm", "L_Upperarm", (0.28, 0, 0)),
        ("L_Hand", "L_Forearm", (0.25, 0, 0)),
    ]  # fmt: skip
    torso = [
        ("RootNode", None, (0, 0, 0)), ("Hip", "RootNode", (0, 0, 1.0)), ("Pelvis", "Hip", (0, 0, 0)),
        ("Waist", "Hip", (0, 0, 0.1)), ("Spine01", "Waist", (0, 0, 0.1)), ("Spine02", "Spine01", (0, 0, 0.15)),
        ("Neck", "Spine02", (0, 0, 0.25)), ("Head", "Neck", (0, 0, 0.1)),
    ]  # fmt: skip
    skeleton = _build(torso + legs + _mirror(legs, "L_", "R_") + arms + _mirror(arms, "L_", "R_"))
    roles = assign_roles(skeleton)
    assert roles["pelvis"] == "Hip"
    assert (roles["waist"], roles["back"], roles["chest"]) == ("Waist", "Spine01", "Spine02")


# ---------------------------------------------------------------------------------------------
# The back rule


def _spine_of(count: int) -> Skeleton:
    spine = [f"Spine{i}" for i in range(1, count + 1)]
    return _humanoid(
        spine=spine,
        neck=["Neck"],
        head_parts=["Head"],
        arm=["LeftArm", "LeftForeArm", "LeftHand"],
        leg=["LeftUpLeg", "LeftLeg", "LeftFoot"],
        left="Left",
        right="Right",
        root="Hips",
    )


@pytest.mark.parametrize(
    "count, waist, back, chest",
    [
        (2, "Spine1", "Spine2", "Spine2"),  # short spine: back is the chest joint
        (3, "Spine1", "Spine2", "Spine3"),
        (4, "Spine1", "Spine2", "Spine4"),  # two between: the lower
        (5, "Spine1", "Spine3", "Spine5"),  # three between: the middle
    ],
)
def test_back_rule(count, waist, back, chest):
    roles = assign_roles(_spine_of(count))
    assert (roles["waist"], roles["back"], roles["chest"]) == (waist, back, chest)
    assert roles["neck"] == "Neck"


def test_a_single_spine_joint_cannot_be_both_waist_and_chest():
    with pytest.raises(SkeletonError) as caught:
        assign_roles(_spine_of(1))
    message = str(caught.value)
    assert "waist" in message and "back" in message
    assert "Spine1" in message and "LeftUpLeg" in message


# ---------------------------------------------------------------------------------------------
# Overrides and errors


def test_override_wins_and_moves_the_dependent_spine_roles():
    roles = assign_roles(_sample(), overrides={"chest": "spine.001"})
    assert roles["chest"] == "spine.001"
    assert roles["waist"] == "spine" and roles["back"] == "spine.001"  # nothing between: back = chest
    assert roles["neck"] == "neck"  # the first neck-named joint above the new chest


def test_override_of_a_limb_joint():
    skeleton = _sample()
    overrides = {"wrist_l": "forearm.L", "elbow_l": "upper_arm.L", "shoulder_l": "shoulder.L"}
    roles = assign_roles(skeleton, overrides=overrides)
    assert (roles["shoulder_l"], roles["elbow_l"], roles["wrist_l"]) == ("shoulder.L", "upper_arm.L", "forearm.L")
    assert "clavicle_l" not in roles  # shoulder.L is taken; nothing clavicle-like above it
    assert roles["wrist_r"] == "hand.R"


def test_override_supplies_a_role_the_names_cannot():
    skeleton = _sample()
    skeleton.names[skeleton.index("hand.L")] = "paw.L"
    with pytest.raises(SkeletonError, match="wrist_l"):
        assign_roles(skeleton)
    assert assign_roles(skeleton, overrides={"wrist_l": "paw.L"})["wrist_l"] == "paw.L"


def test_override_naming_a_missing_joint_raises_naming_it():
    with pytest.raises(SkeletonError, match=r"'hip_l'.*'LeftThigh'"):
        assign_roles(_sample(), overrides={"hip_l": "LeftThigh"})


def test_override_naming_an_unknown_role_raises():
    with pytest.raises(SkeletonError, match=r"unknown joint role 'hand_l'.*wrist_l"):
        assign_roles(_sample(), overrides={"hand_l": "hand.L"})


def test_overrides_that_put_two_roles_on_one_joint_raise():
    with pytest.raises(SkeletonError, match=r"'hip_l' and 'knee_l' both map to joint 'thigh.L'"):
        assign_roles(_sample(), overrides={"knee_l": "thigh.L", "hip_l": "thigh.L"})
    with pytest.raises(SkeletonError, match=r"'back' may share only"):
        assign_roles(_sample(), overrides={"back": "thigh.L", "hip_l": "thigh.L"})


def test_back_may_be_overridden_onto_the_waist():
    assert assign_roles(_sample(), overrides={"back": "spine"})["back"] == "spine"


def test_missing_roles_error_lists_the_roles_and_every_bone():
    # The sample without its left arm (the left leg stays).
    rows = [r for r in _rows(_sample()) if not r[0].endswith(".L") or r[0].startswith(("thigh", "shin", "foot", "toe"))]
    skeleton = _build(rows)
    with pytest.raises(SkeletonError) as caught:
        assign_roles(skeleton)
    message = str(caught.value)
    assert "shoulder_l, elbow_l, wrist_l" in message
    assert "hip_l" not in message and "shoulder_r" not in message
    for bone in skeleton.names:
        assert bone in message
    assert "override" in message


def test_nothing_human_lists_every_required_role():
    skeleton = Skeleton(["Root", "Boom", "Hook"], np.asarray([-1, 0, 1]), np.eye(3))
    with pytest.raises(SkeletonError) as caught:
        assign_roles(skeleton)
    message = str(caught.value)
    for role in REQUIRED_ROLES:
        assert role in message
    assert "Root, Boom, Hook" in message


# ---------------------------------------------------------------------------------------------
# Name reading


@pytest.mark.parametrize(
    "name, side, core",
    [
        ("LeftUpLeg", "l", "upleg"),
        ("mixamorig:RightForeArm", "r", "forearm"),
        ("mixamorig1:LeftHand", "l", "hand"),
        ("Armature|Spine1", None, "spine1"),
        ("UpperArm_L", "l", "upperarm"),
        ("hand.R", "r", "hand"),
        ("upper_arm.L", "l", "upperarm"),
        ("CC_Base_L_Thigh", "l", "thigh"),
        ("CC_Base_R_UpperarmTwist01", "r", "upperarmtwist01"),
        ("LHipJoint", "l", "hipjoint"),
        ("RThumb", "r", "thumb"),
        ("RL_BoneRoot", None, "rlboneroot"),
        ("DEF-thigh.L.001", "l", "thigh001"),
        ("lefthand", "l", "hand"),
        ("HandLeft", "l", "hand"),
        ("left-fore arm", "l", "forearm"),
    ],
)
def test_read_joint_name(name, side, core):
    read = read_joint_name(name)
    assert (read.side, read.core) == (side, core)


def _sides_agree(roles: dict[str, str]) -> bool:
    """Every left role on a joint whose name says left, every right role on a right one."""
    return all(read_joint_name(j).side == r[-1] for r, j in roles.items() if r.endswith(("_l", "_r")))


@pytest.mark.parametrize("build", [_common, _mixamo, _sample, lambda: _common("."), lambda: _spine_of(4)])
def test_left_right_never_swapped_by_name(build):
    roles = assign_roles(build())
    assert _sides_agree(roles) and roles["hip_l"] != roles["hip_r"]


def test_right_side_listed_first_in_the_hierarchy_changes_nothing():
    """Joint order must not matter: the same sample with every .R joint before its .L twin."""
    rows = _rows(_sample())
    centre = [r for r in rows if not r[0].endswith((".L", ".R"))]
    right = [r for r in rows if r[0].endswith(".R")]
    left = [r for r in rows if r[0].endswith(".L")]
    assert assign_roles(_build(centre + right + left)) == SAMPLE


def test_a_role_names_its_part_and_side_once() -> None:
    assert [(part_of(r), side_of(r)) for r in ("knee_l", "wrist_r", "pelvis", "neck")] == [
        ("knee", "l"), ("wrist", "r"), ("pelvis", None), ("neck", None)]  # fmt: skip
    sided = {part_of(r) for r in ALL_ROLES if side_of(r)}
    assert sided == {"hip", "knee", "ankle", "toe", "shoulder", "elbow", "wrist", "clavicle"}
