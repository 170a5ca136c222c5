"""The believability measures (tools/devkit/believability.py) on constructed motions with known
answers: the benchmark's figures are only as good as these."""

from __future__ import annotations

import numpy as np
import pytest

from reactive_anim.core.model import quat
from reactive_anim.core.model.skeleton import Motion, Skeleton
from tools.devkit import believability as bl

FPS = 30.0
# A stick body standing on the floor: pelvis 0.9 m up, hips below it, knees, ankles 8 cm up, toes in
# front of the ankles 1 cm up with their tips on the floor, a spine to the chest and head, arms.
NAMES = [
    "pelvis", "hip_l", "knee_l", "ankle_l", "toe_l", "hip_r", "knee_r", "ankle_r", "toe_r",
    "spine", "chest", "neck", "head", "shoulder_l", "elbow_l", "wrist_l", "shoulder_r", "elbow_r", "wrist_r",
]  # fmt: skip
PARENTS = [-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 10, 13, 14, 10, 16, 17]
OFFSETS = [
    (0, 0, 0.9), (0.1, 0, -0.05), (0, 0, -0.4), (0, 0, -0.37), (0, -0.12, -0.07),
    (-0.1, 0, -0.05), (0, 0, -0.4), (0, 0, -0.37), (0, -0.12, -0.07),
    (0, 0, 0.2), (0, 0, 0.25), (0, 0, 0.1), (0, 0, 0.1),
    (0.18, 0, 0), (0, 0, -0.28), (0, 0, -0.25), (-0.18, 0, 0), (0, 0, -0.28), (0, 0, -0.25),
]  # fmt: skip
ROLES = {
    "pelvis": "pelvis", "chest": "chest", "head": "head", "neck": "neck", "waist": "spine", "back": "chest",
    **{f"{part}_{s}": f"{part}_{s}" for part in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist") for s in "lr"},
}  # fmt: skip


def skeleton() -> Skeleton:
    # End sites: the toe tips on the floor, the head's crown.
    return Skeleton(NAMES, np.asarray(PARENTS), np.asarray(OFFSETS),
                    end_sites={4: np.array([0, -0.05, -0.01]), 8: np.array([0, -0.05, -0.01]),
                               12: np.array([0, 0, 0.15])})  # fmt: skip


def standing(frames: int, sk: Skeleton | None = None) -> Motion:
    """The body standing still at the origin for `frames` frames, its rest pose."""
    sk = sk or skeleton()
    rot = np.zeros((frames, sk.num_joints, 4))
    rot[..., 0] = 1.0
    return Motion(sk, FPS, np.tile(sk.offsets[0], (frames, 1)), rot, None)


def moved_joint(motion: Motion, joint: str, offsets: np.ndarray) -> Motion:
    """The motion with one joint's translation from its parent changed by offsets (T, 3) per frame
    (what follows it moves along)."""
    j = motion.skeleton.index(joint)
    local = motion.joint_offsets().copy()
    local[:, j] += offsets
    return Motion(motion.skeleton, motion.fps, motion.root_pos, motion.local_rot, local)


def floor_of(motion: Motion) -> float:
    return bl.lowest_floor(motion, ROLES)


def test_the_standing_body_has_its_toe_tips_on_the_floor() -> None:
    motion = standing(10)
    assert floor_of(motion) == pytest.approx(0.0, abs=1e-9)
    series = bl.profile(motion, ROLES, 0.0)
    assert series.depth.max() == pytest.approx(0.0, abs=1e-9)
    assert series.skid.sum() == 0.0 and series.down.all()


def test_a_foot_sliding_10_cm_on_the_floor_skids_10_cm() -> None:
    """The left foot slid 10 cm forward over 10 frames, its toes on the floor throughout."""
    frames = 20
    slide = np.zeros((frames, 3))
    slide[5:15, 1] = np.linspace(0.0, -0.10, 10)
    slide[15:, 1] = -0.10
    motion = moved_joint(standing(frames), "ankle_l", slide)
    series = bl.profile(motion, ROLES, 0.0)
    assert series.skid[:, 0].sum() == pytest.approx(0.10, abs=1e-9)
    assert series.skid[:, 1].sum() == 0.0
    assert series.skid_in(0, frames) == pytest.approx([0.10, 0.0], abs=1e-9)
    assert series.skid_in(5, 10)[0] == pytest.approx(0.10 * 4 / 9, abs=1e-9)  # steps into 6..9


def test_a_lifted_foot_does_not_skid() -> None:
    """The same slide with the foot lifted 5 cm (over the 2 cm contact band) skids nothing; at 1.5 cm
    (within it) all of it counts."""
    frames = 20
    path = np.zeros((frames, 3))
    path[:, 1] = np.linspace(0.0, -0.10, frames)
    for lift, expected in ((0.05, 0.0), (0.015, 0.10)):
        raised = path.copy()
        raised[:, 2] = lift
        series = bl.profile(moved_joint(standing(frames), "ankle_l", raised), ROLES, 0.0)
        assert series.skid[:, 0].sum() == pytest.approx(expected, abs=1e-9)


def test_skid_follows_the_point_that_stays_down() -> None:
    """A heel-to-toe roll, the lowest point moving from one point of the foot to another 15 cm away
    with the foot itself still, is no travel."""
    points = np.zeros((4, 2, 3))
    points[:, 1, 1] = 0.15
    points[:2, 1, 2] = 0.01  # the toe lifted a centimetre, then down; the heel lifts after
    points[2:, 0, 2] = 0.01
    assert bl.skid_steps(points, 0.0).sum() == 0.0


def test_a_planted_foot_slid_in_a_fade_and_a_swinging_toe() -> None:
    """planted_slide: a foot standing at the fade's start and slid 6 cm within it gives 6 cm, until it
    lifts; a toe skimming the floor at 3 m/s (a shuffle's swing) is not planted."""
    skid = np.zeros(12)
    skid[3:7] = 0.015  # 6 cm over four steps, 0.45 m/s at 30 fps
    down = np.ones(12, dtype=bool)
    assert bl.planted_slide(skid, down, 2, 10, FPS) == pytest.approx(0.06)
    down[5] = False  # lifted at frame 5: the slide stops there
    assert bl.planted_slide(skid, down, 2, 10, FPS) == pytest.approx(0.03)
    swing = np.full(12, 0.1)  # 3 m/s
    assert bl.planted_slide(swing, np.ones(12, dtype=bool), 2, 10, FPS) == 0.0
    every = bl.planted_slides(skid, down, 8, FPS)
    assert every[2] == pytest.approx(0.03) and every[5] == 0.0
    assert every == pytest.approx([bl.planted_slide(skid, down, t, t + 8, FPS) for t in range(12)])


def test_a_joint_4_cm_under_the_floor_is_4_cm_deep() -> None:
    """The right wrist pushed down through the floor: 4 cm under it at the deepest frame."""
    frames = 6
    motion = standing(frames)
    wrist_z = motion.global_positions()[0, motion.skeleton.index("wrist_r"), 2]
    down = np.zeros((frames, 3))
    down[3, 2] = -(wrist_z + 0.04)
    series = bl.profile(moved_joint(motion, "wrist_r", down), ROLES, 0.0)
    assert series.depth[3] == pytest.approx(0.04, abs=1e-9)
    assert series.largest(series.depth, 0, frames) == pytest.approx((0.04, 3), abs=1e-9)


def test_an_end_site_under_the_floor_counts_and_a_ground_root_does_not() -> None:
    """A toe tip 2 cm through the floor is 2 cm deep; a ground root bone at the origin, 5 cm under
    the feet's floor (Bandai Namco's joint_Root), is no body part."""
    sk = skeleton()
    tips = {**sk.end_sites, 4: sk.end_sites[4] + np.array([0, 0, -0.02])}
    series = bl.profile(
        standing(3, Skeleton(NAMES, np.asarray(PARENTS), np.asarray(OFFSETS), end_sites=tips)), ROLES, 0.0
    )
    assert series.depth.max() == pytest.approx(0.02, abs=1e-9)
    # the ground bone 5 cm under the floor, the pelvis 0.95 m over it: the toe tips on the floor
    offsets = [(0, 0, -0.05), (0, 0, 0.95)] + OFFSETS[1:]
    grounded = Skeleton(["ground"] + NAMES, np.asarray([-1] + [p + 1 for p in PARENTS]), np.asarray(offsets),
                        end_sites={j + 1: off for j, off in sk.end_sites.items()})  # fmt: skip
    motion = standing(3, grounded)
    floor = floor_of(motion)
    assert floor == pytest.approx(0.0, abs=1e-9)
    assert bl.profile(motion, ROLES, floor).depth.max() == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("fps", [30.0, 60.0, 120.0])
def test_a_constant_acceleration_joint_gives_that_acceleration(fps: float) -> None:
    """x = a t^2 / 2 with a = 7 m/s^2 along a slanted axis: 7 m/s^2 wherever the stride fits, NaN at
    the ends; the stride is 1/30 s at every rate."""
    t = np.arange(40) / fps
    axis = np.array([0.6, 0.0, 0.8])
    positions = 0.5 * 7.0 * t[:, None] ** 2 * axis
    acc = bl.acceleration(positions, fps)
    s = bl.stride_frames(fps)
    assert s == round(fps / 30)
    assert np.all(np.isnan(acc[:s])) and np.all(np.isnan(acc[-s:]))
    assert acc[s:-s] == pytest.approx(np.full(40 - 2 * s, 7.0))


def test_the_body_joints_acceleration_in_a_profile() -> None:
    """The whole body accelerating at 3 m/s^2 gives 3 on every frame the stride fits; the pelvis too."""
    frames = 12
    motion = standing(frames)
    t = np.arange(frames) / FPS
    motion.root_pos = motion.root_pos + 0.5 * 3.0 * t[:, None] ** 2 * np.array([1.0, 0.0, 0.0])
    series = bl.profile(motion, ROLES, 0.0)
    assert series.accel[1:-1] == pytest.approx(np.full(frames - 2, 3.0))
    assert series.pelvis_accel[1:-1] == pytest.approx(np.full(frames - 2, 3.0))
    assert series.move[1:] == pytest.approx(3.0 * (2 * np.arange(1, frames) - 1) / (2 * FPS**2))


def test_a_calibration_first_frame_is_not_part_of_the_take() -> None:
    """A first frame 0.8 m under the floor, left at 24 m/s (over the 20 m/s rule), is no floor and no
    depth, acceleration or skid; the same frame left at 15 m/s is part of the take."""
    frames = 10
    for jump, is_calibration in ((0.8, True), (0.5, False)):
        motion = standing(frames)
        motion.root_pos = motion.root_pos.copy()
        motion.root_pos[0, 2] -= jump
        assert bl.take_start(motion.global_positions(), FPS) == int(is_calibration)
        floor = floor_of(motion)
        series = bl.profile(motion, ROLES, floor)
        if is_calibration:
            assert floor == pytest.approx(0.0, abs=1e-9)
            assert np.isnan(series.depth[0]) and np.nanmax(series.depth) == pytest.approx(0.0, abs=1e-9)
            assert np.nanmax(series.accel) == pytest.approx(0.0, abs=1e-9)
            assert np.nanmax(series.move) == pytest.approx(0.0, abs=1e-9)
        else:
            assert floor == pytest.approx(-jump)
            assert np.nanmax(series.accel) > 100.0


def test_the_hits_own_frames() -> None:
    """hit_mask: at 30 fps (a one-frame stride) a hit at B = 4 leaves out the accelerations centred
    on frames 3..6, every one whose stencil touches B's step to 5, with a frame either side."""
    assert bl.hit_mask(10, 4.0, FPS).tolist() == [False] * 3 + [True] * 4 + [False] * 3


def test_standing_still_and_ahead() -> None:
    """A pelvis walking at 1.2 m/s that stops for 0.4 s stands still 0.4 s; a point 10 cm further
    along a push's direction is 10 cm ahead, across it nothing."""
    fps = 30.0
    speed = np.concatenate([np.full(30, 1.2), np.zeros(12), np.full(30, 1.2)])
    x = np.concatenate([[0.0], np.cumsum(speed[1:]) / fps])
    pelvis = np.stack([x, np.zeros_like(x), np.full_like(x, 0.9)], axis=1)
    still = bl.longest_still(bl.horizontal_speed(pelvis, fps), fps)
    assert still == pytest.approx(11 / fps)  # 12 frames stand; the central difference sees 11 of them
    assert bl.longest_still(np.full(10, np.nan), fps) == 0.0
    assert bl.ahead(np.array([0.1, 0.3, 0.0]), np.zeros(3), np.array([1.0, 0.0, 0.5])) == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("direction", "side"), [((0, -1, 0), "behind"), ((0, 1, 0), "front"), ((1, 0, 0), "right"), ((-1, 0, 0), "left")]
)
def test_push_sides(direction: tuple[float, float, float], side: str) -> None:
    """Facing -Y (left is +X): a push along -Y comes from behind; one along +X (to its left) from its right."""
    assert bl.push_side(np.array(direction, dtype=float), np.array([0.0, -1.0, 0.0])) == side


def test_class_sense() -> None:
    assert bl.right_direction("behind", "steps_forward") and bl.right_direction("front", "fall_backward_sit")
    assert not bl.right_direction("behind", "step_back") and not bl.right_direction("front", "fall_forward_roll")
    assert bl.right_direction("left", "fall_side_knees") and bl.right_direction("right", "sway_balance")
    assert not bl.right_direction("left", "step_forward")
    assert bl.right_direction("left", "step_right") and not bl.right_direction("left", "step_left")


def test_reaction_seams() -> None:
    """Seams from a Reaction's frames as react.py builds them: a fall with a get-up chained, and a
    step that resumes."""

    class Fake:
        def __init__(self, chained: str | None, resumed_at: int | None) -> None:
            self.frame_c, self.frame_f, self.end_frame = 40, 50, 200
            self.chained, self.resumed_at = chained, resumed_at

    fall = {"C": 40, "F": 50, "get-up start": 111, "get-up end": 117}  # the get-up's 90 frames end at 200
    assert bl.reaction_seams(Fake("getup", None), 4, 90, 6) == fall
    assert bl.reaction_seams(Fake(None, 70), 4) == {"C": 40, "F": 50, "resume start": 197, "resume end": 201}
    # a get-up the walk resumes after: the 12-frame fade starts the 4-frame window before the
    # get-up's end (193) and holds its last pose for the other 8
    both = {"C": 40, "F": 50, "get-up start": 103, "get-up end": 109, "resume start": 189, "resume end": 201}
    assert bl.reaction_seams(Fake("getup", 70), 12, 90, 6, 4) == both


def test_end_sites_follow_their_joint() -> None:
    """An end site turned with its joint: the head's crown 15 cm along the head's turned axis."""
    motion = standing(2)
    motion.local_rot = motion.local_rot.copy()
    motion.local_rot[:, motion.skeleton.index("head")] = quat.from_axis_angle(np.array([1.0, 0, 0]), np.pi / 2)
    pos, rot = motion.global_transforms()
    tips = bl.end_site_positions(motion, pos, rot)
    head = motion.skeleton.index("head")
    crown = tips[:, list(motion.skeleton.end_sites).index(head)]
    assert np.linalg.norm(crown - pos[:, head], axis=-1) == pytest.approx([0.15, 0.15])
    assert crown[0, 2] == pytest.approx(pos[0, head, 2], abs=1e-9)
