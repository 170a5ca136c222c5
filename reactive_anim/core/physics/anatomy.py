"""Table 1 of the paper (section 2.2) and human ranges of motion: the numbers a ragdoll is built from.

Masses per body (Table 1, scaled to the character's total mass), the joint kind of each body, the two
joint profiles, capsule radii, the passive spring-damper every hinge carries, and which servo group
each joint belongs to. No engine here: the tables only.

Two joint profiles:
- "paper": Table 1 as printed: ball joints (waist, back, neck, ankle) with a swing cone and a twist
  range, hinges (femur, knee, shoulder, elbow, wrist) with a range. The printed femur range -85..0
  is read with flexion negative, i.e. our flexion 0..85 (the thigh swings forward, not back).
- "anatomical" (default): Table 1's masses and joint types with human ranges of motion (AAOS, see
  ANATOMICAL_LIMITS): knees and elbows single hinges, the ball joints three hinges each (the printed
  knee of -25..25 cannot walk).
A paper hinge follows only the flexion angle of the mocap's rotation (joints.py). Every hinge carries
a spring-damper toward the neutral pose, scaled by the mass it moves, as the paper adds at the knee.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..model.errors import SimulationError
from ..model.roles import SIDES

TABLE1_TOTAL_MASS = 97.6


# Table 1 masses per body role (kg); left and right limbs each.
TABLE1_MASSES = {
    "pelvis": 10.3, "waist": 11.4, "back": 11.7, "neck": 8.4,
    "hip": 10.2, "knee": 6.0, "ankle": 0.9, "shoulder": 8.1, "elbow": 2.1, "wrist": 0.6,
}  # fmt: skip


BODY_ROLES = ("pelvis", "waist", "back", "neck") + tuple(
    f"{part}_{side}" for side in SIDES for part in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
)


# Hinge ranges in degrees per profile and joint kind: (flexion, twist, abduction); None = no hinge.
# Positive flexion moves the segment toward FLEX_TOWARD, positive abduction away from the body's
# midline (for the spine and neck: toward the character's left).
PAPER_LIMITS = {
    "waist": ((-45, 45), (-15, 15), (-45, 45)),
    "back": ((-5, 5), (-5, 5), (-5, 5)),
    "neck": ((-30, 30), (-8, 8), (-30, 30)),
    "hip": ((0, 85), None, None),
    "knee": ((-25, 25), None, None),
    "ankle": ((-85, 85), (-10, 10), (-85, 85)),
    "shoulder": ((-80, 85), None, None),
    "elbow": ((-15, 45), None, None),
    "wrist": ((-60, 60), None, None),
}


# Normal active ranges of motion of adults, American Academy of Orthopaedic Surgeons, "Joint Motion:
# Method of Measuring and Recording" (1965), as tabulated in Norkin & White, "Measurement of Joint
# Motion" (5th ed., 2016), table of AAOS values. Rounded outward by up to 10 degrees where mocap
# routinely goes there (a run whose start pose lies beyond a limit widens that range for the run,
# workspace.set_limits). Per joint:
# - waist + back share the thoracolumbar spine (AAOS: flexion 80, extension 25, lateral bending 35,
#   rotation 45): lumbar-heavy flexion in the waist, most rotation in the back (White & Panjabi,
#   "Clinical Biomechanics of the Spine", 2nd ed. 1990: lumbar axial rotation is a few degrees).
# - neck: cervical spine flexion 45, extension 45, lateral bending 45, rotation 60 (+10, the head is
#   merged into the neck body, so its nod on the atlas is in this joint too).
# - hip: flexion 120, extension 30, abduction 45, adduction 30, internal and external rotation 45.
# - knee and elbow: single hinges, flexion 0-150 (AAOS knee 135, elbow 150; 150 for a deep squat),
#   no hyperextension (the limits are soft: a degree or two past 0 under load).
# - ankle: plantar flexion 50, inversion/eversion 35/15 about the foot's long axis (symmetric here,
#   35). Dorsiflexion (AAOS 20 from the foot square to the shin) and forefoot abduction (10) are
#   opened to 50 and 35: our zero is the standing foot, a crouch or a lunge in mocap reaches 40-50
#   there, and a start pose clamped 30 degrees short (as starts were then) put a toe 4 cm into
#   the floor and threw the body up (the demo's push from the front, during a lunge).
# - shoulder: flexion 180, extension 60, abduction 180, adduction 50 (cross-body), rotation 70/90
#   (symmetric here, 90: the twist hinge has no side-specific sign).
# - wrist: flexion 80, extension 70, radial/ulnar deviation 20/30; the forearm's pronation and
#   supination (80/80) happen here as the wrist's twist, the elbow being a single hinge.
ANATOMICAL_LIMITS = {
    "waist": ((-25, 55), (-20, 20), (-20, 20)),
    "back": ((-15, 35), (-30, 30), (-20, 20)),
    "neck": ((-50, 50), (-70, 70), (-45, 45)),
    "hip": ((-30, 120), (-45, 45), (-30, 45)),
    "knee": ((0, 150), None, None),
    "ankle": ((-55, 50), (-35, 35), (-35, 35)),
    "shoulder": ((-60, 180), (-90, 90), (-50, 180)),
    "elbow": ((0, 150), None, None),
    "wrist": ((-70, 80), (-80, 80), (-30, 30)),
}


PROFILES = {"paper": PAPER_LIMITS, "anatomical": ANATOMICAL_LIMITS}


# A profile's limits: per joint kind (Table 1 row, e.g. "knee"), the (flexion, twist, abduction)
# hinge ranges in degrees, None where the joint has no such hinge.
HingeRange = tuple[float, float] | None


JointLimits = Mapping[str, tuple[HingeRange, HingeRange, HingeRange]]


# Direction a segment moves on positive flexion, in the character's (forward, left, up) frame.
FLEX_TOWARD = {
    "waist": "forward", "back": "forward", "neck": "forward", "hip": "forward", "knee": "back",
    "ankle": "up", "shoulder": "forward", "elbow": "forward", "wrist": "forward",
}  # fmt: skip


# Capsule radius per body at 1.75 m tall (scaled with the skeleton's height).
RADII = {
    "pelvis": 0.09, "waist": 0.11, "back": 0.12, "neck": 0.085, "hip": 0.065, "knee": 0.05,
    "ankle": 0.035, "shoulder": 0.045, "elbow": 0.038, "wrist": 0.03,
}  # fmt: skip


# Passive spring-damper on every hinge (the paper adds them e.g. at the knee), per kg moved:
# damping N·m·s/rad/kg and stiffness N·m/rad/kg toward the neutral pose.
JOINT_DAMPING_PER_KG = 0.08


JOINT_STIFFNESS_PER_KG = 0.5


HINGE_NAMES = ("flex", "twist", "abd")


# Servo stiffness groups (workspace.ServoGains), by Table 1 joint kind.
JOINT_GROUPS = ("legs", "trunk", "arms", "neck")


GROUP_OF_PART = {
    "hip": "legs", "knee": "legs", "ankle": "legs", "waist": "trunk", "back": "trunk",
    "shoulder": "arms", "elbow": "arms", "wrist": "arms", "neck": "neck",
}  # fmt: skip


def resolve_profile(profile: str | JointLimits) -> tuple[str, JointLimits]:
    """(name, limits) of a profile given by name or as limits; limits must name every joint kind."""
    if isinstance(profile, str):
        if profile not in PROFILES:
            raise SimulationError(f"unknown ragdoll profile '{profile}'; profiles are: {', '.join(PROFILES)}")
        return profile, PROFILES[profile]
    missing = [part for part in TABLE1_MASSES if part != "pelvis" and part not in profile]
    if missing:
        raise SimulationError(f"the ragdoll's joint limits lack the joints: {', '.join(missing)}")
    for part, ranges in profile.items():
        if len(ranges) != 3 or any(r is not None and not r[0] <= r[1] for r in ranges):
            raise SimulationError(f"joint limits for '{part}' must be three (low, high) ranges or None, got {ranges!r}")
    return "custom", profile
