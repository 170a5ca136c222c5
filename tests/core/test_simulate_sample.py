"""Simulation physics on the project's own clips (sample_clips/walk.bvh, idle.bvh): nothing from
../shared, so these always run.

Every test compares a pushed run with the same start unpushed (a 0 N·s impact), so gravity, the
servos' pull toward the mocap and the walker's own momentum cancel and what is left is the push.

- Momentum: an impulse J on any body changes the ragdoll's linear momentum by J, so the centre of
  mass (CoM) velocity by J / M (M = the ragdoll's total mass). Servos and joint springs are
  internal forces and cannot change it; only the floor can. The impact frame B is 0.1 frame
  before a frame, so the first sampled frame is one simulation step (1/600 s) after the impulse
  and the floor has had one step to respond: along the push measured within 0.4% of J / M for
  every bone and direction tried (walk and idle, B at 40.9 .. 160.9), across it at most 2.3% (the
  floor's response: vertical for a head push, sideways for a pelvis push). A full frame (10 steps)
  later, friction at the feet has already changed it by up to 10%, which is physics, not error,
  hence the fractional B.
- Where the CoM is at C (0.25 s later) depends on the feet, the servos and toppling, so those
  tests check direction and scale against the free-flight distance J / M * window, not a value.

Directions are the character's, computed from the motion at B: left along the hip line (left hip
minus right hip, horizontal), forward = left x up.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import ImpactError, SimulationError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion
from reactive_anim.core.physics.ragdoll import Ragdoll, build_ragdoll
from reactive_anim.core.physics.simulate import SimResult, simulate_impact, simulate_push, track
from reactive_anim.core.physics.watch import MAX_HIT_SPEED
from tests.support.mocap import REPO
from tools.devkit.poses import ground_axes

SAMPLE_CLIPS = REPO / "sample_clips"
UP = np.array([0.0, 0.0, 1.0])
IMPACT_FRAME = 60.9  # B: frame 61, the first sampled one, is one 1/600 s step after the impulse
WINDOW = 0.25  # s, B to C
PUSH = 40.0  # N·s, a firm shove (Impact: 30 is a shove, 100 a strong push)
MOMENTUM_TOLERANCE = 0.02  # along the push, fraction of J / M; measured at most 0.0035
OFF_AXIS_TOLERANCE = 0.05  # across the push, fraction of J / M; measured at most 0.023
LINEAR_TOLERANCE = 0.01  # relative, on the ratio 2 of two pushes' velocity changes; measured 0.0004
FREE_FLIGHT_RANGE = (0.25, 2.0)  # CoM displacement at C, units of J / M * WINDOW; chest measured 0.42 .. 1.28


@dataclass(frozen=True)
class Clip:
    motion: Motion
    ragdoll: Ragdoll


@pytest.fixture(scope="module")
def clips() -> dict[str, Clip]:
    """The walk and the idle, each with a ragdoll whose neutral pose is that clip's first frame."""
    out = {}
    for name in ("walk", "idle"):
        motion = bvh.read_bvh(SAMPLE_CLIPS / f"{name}.bvh")
        out[name] = Clip(motion, build_ragdoll(motion.skeleton, reference=motion))
    return out


def character_axes(clip: Clip, frame: float) -> tuple[np.ndarray, np.ndarray]:
    """(forward, left) horizontal unit vectors of the character at a frame, from its hip line."""
    return ground_axes(clip.motion, frame, clip.ragdoll.roles)


def bone(clip: Clip, role: str) -> str:
    return clip.ragdoll.roles[role]


def react(clip: Clip, role: str, direction: np.ndarray, strength: float) -> SimResult:
    """BC of a push of `strength` N·s on the role's bone at B."""
    impact = Impact(IMPACT_FRAME, bone(clip, role), tuple(direction), strength)
    return simulate_impact(clip.ragdoll, clip.motion, impact, window=WINDOW)


def push_effect(clip: Clip, role: str, direction: np.ndarray, strength: float) -> tuple[np.ndarray, np.ndarray]:
    """(dv, dx): the CoM velocity the push adds at the first sampled frame after B, and the CoM
    displacement it adds at C, both against the same start unpushed."""
    still = react(clip, role, direction, 0.0)
    pushed = react(clip, role, direction, strength)
    first = int(np.argmax(still.frames > IMPACT_FRAME))
    return pushed.com_velocity[first] - still.com_velocity[first], pushed.com[-1] - still.com[-1]


def assert_gains_j_over_m(dv: np.ndarray, direction: np.ndarray, strength: float, clip: Clip) -> None:
    """The CoM velocity change dv is J / M along the push's unit direction and about nothing across it."""
    gain = strength / clip.ragdoll.total_mass
    along = dv @ direction
    assert abs(along / gain - 1.0) < MOMENTUM_TOLERANCE, (along, gain)
    assert np.linalg.norm(dv - along * direction) < OFF_AXIS_TOLERANCE * gain, (dv, gain)


def free_flight(strength: float, clip: Clip) -> float:
    """How far J / M would carry the CoM over the window with nothing else acting (m)."""
    return strength / clip.ragdoll.total_mass * WINDOW


def test_forward_from_the_hip_line_is_the_way_the_walk_goes(clips):
    """The push directions below rest on this: the hip-line forward at B agrees with where the
    pelvis travels over the half second around B (within 18 degrees; the hips swing ~5)."""
    walk = clips["walk"]
    forward, _ = character_axes(walk, IMPACT_FRAME)
    b, half = round(IMPACT_FRAME), int(walk.motion.fps * 0.25)
    travel = walk.motion.root_pos[b + half] - walk.motion.root_pos[b - half]
    travel[2] = 0.0
    assert forward @ travel / np.linalg.norm(travel) > 0.95


@pytest.mark.parametrize("side, sign", [("behind", 1.0), ("front", -1.0)])
def test_push_along_the_walk_changes_forward_velocity_by_j_over_m(clips, side, sign):
    """A push from behind (front) on the chest of a walker: momentum conservation makes the CoM
    forward velocity J / M faster (slower) just after it; at C the CoM is ahead of (behind) the
    unpushed one by a fair part of the free-flight distance and not beyond twice it (friction at
    the feet takes some, toppling over them adds some)."""
    walk = clips["walk"]
    forward, _ = character_axes(walk, IMPACT_FRAME)
    dv, dx = push_effect(walk, "chest", sign * forward, PUSH)
    assert_gains_j_over_m(dv, sign * forward, PUSH, walk)
    lo, hi = FREE_FLIGHT_RANGE
    assert lo < sign * (dx @ forward) / free_flight(PUSH, walk) < hi, dx


@pytest.mark.parametrize("clip_name", ["walk", "idle"])
@pytest.mark.parametrize("side", [1.0, -1.0], ids=["left", "right"])
def test_side_push_moves_the_centre_of_mass_sideways(clips, clip_name, side):
    """A push on the chest toward the character's left (right): the CoM gains J / M that way and
    next to nothing forward just after it, and at C it has moved that way far more than forward
    or back (measured at most 0.17 of the sideways distance on the walk, 0.01 standing)."""
    clip = clips[clip_name]
    forward, left = character_axes(clip, IMPACT_FRAME)
    dv, dx = push_effect(clip, "chest", side * left, PUSH)
    assert_gains_j_over_m(dv, side * left, PUSH, clip)
    sideways = side * (dx @ left)
    assert FREE_FLIGHT_RANGE[0] < sideways / free_flight(PUSH, clip) < FREE_FLIGHT_RANGE[1], dx
    assert abs(dx @ forward) < 0.4 * sideways, dx


def test_a_push_s_twin_is_the_same_run_without_the_push(clips):
    """simulate_push's twin starts where the pushed run starts and differs from it by the push
    alone: at C its centre of mass is behind the pushed one along the push. A run made without a
    twin (simulate_impact) says so when asked for one, rather than standing in for it."""
    walk = clips["walk"]
    forward, _ = character_axes(walk, IMPACT_FRAME)
    impact = Impact(IMPACT_FRAME, bone(walk, "chest"), tuple(forward), PUSH)
    pushed = simulate_push(walk.ragdoll, walk.motion, impact, window=WINDOW)
    assert np.array_equal(pushed.twin.frames, pushed.frames)
    assert np.allclose(pushed.twin.com[0], pushed.com[0], atol=0.005)  # the first sample, a step after the hit
    free_flight = PUSH / walk.ragdoll.total_mass * WINDOW
    assert (pushed.com[-1] - pushed.twin.com[-1]) @ forward > FREE_FLIGHT_RANGE[0] * free_flight
    with pytest.raises(SimulationError, match="simulate_push"):
        _ = react(walk, "chest", forward, PUSH).twin


def test_small_pushes_are_linear_in_the_impulse(clips):
    """Twice the impulse, twice the CoM velocity change (the impulse enters the dynamics linearly
    and one step of floor contact barely differs: measured ratio 1.9996); at C the stronger push
    has gone further (1.6 .. 2.0 times as far depending on B: the feet make it only roughly linear)."""
    walk = clips["walk"]
    forward, _ = character_axes(walk, IMPACT_FRAME)
    dv20, dx20 = push_effect(walk, "chest", forward, 20.0)
    dv40, dx40 = push_effect(walk, "chest", forward, 40.0)
    assert abs((dv40 @ forward) / (dv20 @ forward) / 2.0 - 1.0) < LINEAR_TOLERANCE
    assert dx40 @ forward > dx20 @ forward > 0


@pytest.mark.parametrize("clip_name", ["walk", "idle"])
@pytest.mark.parametrize("role", ["chest", "pelvis", "head"])
def test_every_hit_body_passes_the_whole_impulse_to_the_centre_of_mass(clips, clip_name, role):
    """Momentum conservation: wherever the push lands (the 10.3 kg pelvis body, the chest's body,
    the 8.4 kg head on its neck joints) the whole ragdoll's CoM gains J / M; the joints pass it on, none is lost."""
    clip = clips[clip_name]
    forward, _ = character_axes(clip, IMPACT_FRAME)
    dv, _ = push_effect(clip, role, forward, PUSH)
    assert_gains_j_over_m(dv, forward, PUSH, clip)


def trunk_direction(result: SimResult, clip: Clip) -> np.ndarray:
    """Unit vector pelvis -> head joint at C."""
    positions = result.motion.global_positions()[-1]
    index = clip.motion.skeleton.index
    trunk = positions[index(bone(clip, "head"))] - positions[index(bone(clip, "pelvis"))]
    return trunk / np.linalg.norm(trunk)


@pytest.mark.parametrize("clip_name", ["walk", "idle"])
def test_head_push_tilts_the_trunk_more_than_a_pelvis_push(clips, clip_name):
    """Same impulse, same CoM velocity change, but a push at the head body acts 0.63 m above the
    CoM (standing) and so also gives the body angular momentum J x 0.63 m; a push at the pelvis
    body acts 5 cm from the CoM and mostly translates it. At C the trunk (pelvis -> head joint) has
    tilted forward, the way it was pushed, more than 1.5 times as far as after the pelvis push
    (measured 1.9 .. 2.5 times; 10 .. 11 degrees against 4 .. 6)."""
    clip = clips[clip_name]
    forward, _ = character_axes(clip, IMPACT_FRAME)
    still = trunk_direction(react(clip, "head", forward, 0.0), clip)
    head = trunk_direction(react(clip, "head", forward, PUSH), clip)
    pelvis = trunk_direction(react(clip, "pelvis", forward, PUSH), clip)
    head_tilt = np.degrees(np.arccos(np.clip(head @ still, -1.0, 1.0)))
    pelvis_tilt = np.degrees(np.arccos(np.clip(pelvis @ still, -1.0, 1.0)))
    assert head_tilt > 1.5 * pelvis_tilt, (head_tilt, pelvis_tilt)
    assert (head - still) @ forward > 0  # the trunk leans the way it was pushed


def test_same_push_twice_gives_bit_identical_results(clips):
    """Fixed timestep and step counts: the same hard push twice, with another run in between (which
    must leave nothing behind in the ragdoll), gives the same arrays bit for bit."""
    walk = clips["walk"]
    forward, left = character_axes(walk, IMPACT_FRAME)
    direction = 0.6 * forward + 0.8 * left
    first = react(walk, "head", direction, 120.0)
    react(walk, "pelvis", -left, 200.0)
    second = react(walk, "head", direction, 120.0)

    def arrays(r: SimResult) -> list[np.ndarray | None]:
        m = r.motion
        return [r.frames, r.qpos, r.qvel, r.com, r.com_velocity, m.root_pos, m.local_rot, m.local_pos,
                r.state.qpos, r.state.qvel]  # fmt: skip

    for a, b in zip(arrays(first), arrays(second), strict=True):
        assert (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
    assert first.state.floor == second.state.floor
    assert np.all(np.isfinite(first.qpos))


def test_contacts_report_the_feet_then_the_body_that_lands(clips):
    """Walking, a foot touches the floor during BC; after a tackle-strength push the
    character lands, and the first contact of each body is reported once, in time order with its
    samples. The centre of mass height is measured from the run's own floor."""
    walk, ragdoll = clips["walk"].motion, clips["walk"].ragdoll
    forward, _ = character_axes(clips["walk"], 40)
    bc = simulate_impact(ragdoll, walk, Impact(40, bone(clips["walk"], "chest"), tuple(forward), 300.0))
    assert bc.contacts.shape == (len(bc.frames), len(ragdoll.bodies))
    feet = [k for k, b in enumerate(ragdoll.bodies) if b.name.startswith("ankle")]
    assert bc.contacts[:, feet].any()
    cd = track(ragdoll, bc.state, walk, 1.5, target_start=int(bc.frames[-1]))
    landed = {name for name in cd.first_contact if not name.startswith("ankle")}
    assert landed, "a 300 N·s push should put something other than the feet on the floor"
    for name, t in cd.first_contact.items():
        k = [b.name for b in ragdoll.bodies].index(name)
        first = int(np.argmax(cd.contacts[:, k]))
        assert t == pytest.approx((cd.frames[first] - cd.frames[0]) / walk.fps)
    assert 0.8 < bc.com_height[0] < 1.2  # a standing adult's centre of mass, about 55% of height
    assert cd.com_height[-1] < 0.5  # lying down


def test_the_trunk_bend_is_shared_and_the_toes_follow_the_mocap(clips):
    """A hard chest push bends the trunk: every spine joint the back body spans (spine.001, chest)
    and both neck and head turn away from the start pose, not one of them alone; the toes, which
    the ragdoll does not have, keep the walk's animation frame by frame."""
    clip = clips["walk"]
    walk, ragdoll = clip.motion, clip.ragdoll
    forward, _ = character_axes(clip, 40)
    bc = simulate_impact(ragdoll, walk, Impact(40, bone(clip, "chest"), tuple(forward), 200.0))
    names = walk.skeleton.names
    start = bc.motion.local_rot[0]
    for segment in (("spine.001", "chest"), ("neck", "head")):
        turned = [np.degrees(quat.angle_between(bc.motion.local_rot[-1, names.index(j)], start[names.index(j)]))
                  for j in segment]  # fmt: skip
        assert min(turned) > 0.25 * max(turned) > 0.1, (segment, turned)
    frames = bc.frames.astype(int)
    for toe in ("toe.L", "toe.R"):
        k = names.index(toe)
        assert np.allclose(np.abs(np.sum(bc.motion.local_rot[:, k] * walk.local_rot[frames, k], axis=-1)), 1.0)


def test_a_push_no_hit_could_give_is_refused_naming_the_most_the_bone_takes(clips):
    """278 N·s on a hand (a 0.6 kg body) would start it at about 200 m/s and spin the wrist past
    the explosion check; it is refused before simulating, with the most this bone takes here, and
    that much is simulated. The trunk takes the same push."""
    clip = clips["walk"]
    forward, _ = character_axes(clip, IMPACT_FRAME)
    with pytest.raises(ImpactError) as refused:
        react(clip, "wrist_l", forward, 278.0)
    message = str(refused.value)
    assert bone(clip, "wrist_l") in message and "278 N·s" in message
    found = re.search(r"at ([\d.]+) m/s; this bone takes at most (\d+) N·s", message)
    assert found is not None, message
    speed, most = (float(x) for x in found.groups())
    assert speed > 3 * MAX_HIT_SPEED and 20.0 < most <= 278.0 * MAX_HIT_SPEED / speed
    react(clip, "wrist_l", forward, most)  # the figure named passes (it was rounded to nearest: 77.85 refused, "78")
    with pytest.raises(ImpactError):
        react(clip, "wrist_l", forward, most + 1.0)
    react(clip, "chest", forward, 278.0)
