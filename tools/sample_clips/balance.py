"""Balance: one linear inverted pendulum with a capture-point controller decides how a pushed body
recovers, for both the stepping reactions (it steps) and the sways (feet planted).

The centre of mass u (along the push) moves as u'' = w^2 (u - p), w = sqrt(g / z0). The centre
of pressure p stays within the feet on the floor (their soles' extent along the push); there
it follows a capture-point controller p = xi + k (xi - target), xi = u + u'/w, k = 1.5, which
brings the body to rest over the middle of its feet (the ankle strategy).

Stepping: when xi is outside the feet (the push is too strong to ride out on the ankles), a foot
lifts, and it lands where xi will be when it lands (the capture point, predicted with p held at
the stance foot's edge), or as far as `max_step` allows; when that falls short, the other foot
steps next. Across the push the pendulum is planar; a landing foot keeps at least 14 cm sideways
from the other, so the feet never cross.

Planted (the sways): the feet never move; the push must be small enough that the capture point
never leaves the soles (the plan raises if it would: that push needs a step).

Besides the path, the model keeps an alarm (the centre of mass's speed over 0.8 m/s, at most 1,
followed by a critically damped filter): how far the trunk bends and the arms rise (the hip
strategy) in the clips made from a plan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .curves import lift_bump, minimum_jerk
from .poses import STAND_WIDTH
from .skeleton import ANKLE_HEIGHT, FPS, SIDES, X_AXIS, heading

GRAVITY = 9.81
COM_HEIGHT = 0.95  # the pendulum's height: the centre of mass of a 1.75 m adult standing, m
OMEGA = float(np.sqrt(GRAVITY / COM_HEIGHT))
SIM_STEPS = 10  # pendulum steps per frame (dt = 1/600 s)
CAPTURE_GAIN = 1.5  # k in p = xi + k (xi - target)
# The sole as a rectangle around the ankle (x to the left, y along world Y: the toes are at -Y).
SOLE = np.array([[-0.045, -0.19], [0.045, -0.19], [0.045, 0.05], [-0.045, 0.05]])
FOOT_CENTRE = np.array([0.0, -0.07])  # the sole's middle, ankle-relative: where a step aims
STEP_MARGIN = 0.01  # a foot lifts once the capture point is this far outside the soles, m
MIN_STEP_WIDTH = 0.14  # a landing ankle keeps this far sideways from the other, m
SETTLED_HOLD = 0.6  # seconds a plan runs on after the body has come to rest
MAX_SECONDS = 6.0  # a plan not at rest by then does not recover (raises)
MAX_STEPS = 4


@dataclass(frozen=True)
class Push:
    """One pushed body: the push and how the character may step to catch itself."""

    direction: float  # degrees from the facing direction, positive to the character's left
    speed: float  # centre-of-mass speed the push leaves, m/s
    max_step: float  # longest step, ankle to ankle over the ground, m
    first: str  # the foot that steps first, "L" or "R"
    react: float = 0.15  # time before the first foot lifts, s
    swing: float = 0.30  # time a foot is in the air, s
    pause: float = 0.06  # double support between steps, s


@dataclass
class StepPlan:
    """What the balance model decided, per frame: CoM over the ground (T, 2), each ankle (T, 3)
    and foot pitch (T,), how alarmed the body is (T,, 0..1), and the touch-down frames."""

    com: np.ndarray
    ankles: dict[str, np.ndarray]
    pitch: dict[str, np.ndarray]
    alarm: np.ndarray
    touchdowns: list[tuple[str, int]]


def _interval(points: np.ndarray, axis: np.ndarray) -> tuple[float, float]:
    """The extent of 2D points along a unit axis."""
    along = points @ axis
    return float(along.min()), float(along.max())


def balance_plan(push: Push, *, planted: bool = False) -> StepPlan:
    """Simulate the pushed body as a linear inverted pendulum along the push (see the module
    docstring), stepping to its capture point, or with `planted` feet riding it out on the ankles.

    The centre of mass starts over the ankles' line when stepping (the stepping clips were tuned
    so) and over the middle of the feet when planted; `com` is reported from where it starts.
    Ends SETTLED_HOLD seconds after the body has come to rest over the middle of its feet: speed and
    capture point within 3 mm/s and 3 mm of it after a step, 2 mm/s and 2 mm planted.
    """
    dt = 1.0 / (FPS * SIM_STEPS)
    axis = heading(push.direction)[:2]
    base = {side: np.array([s * STAND_WIDTH / 2, 0.0]) for side, s in SIDES.items()}
    along = dict.fromkeys(SIDES, 0.0)  # each foot's travel along the push
    shift = dict.fromkeys(SIDES, 0.0)  # sideways correction that keeps the feet uncrossed

    def foot(side: str) -> np.ndarray:
        return base[side] + along[side] * axis + shift[side] * X_AXIS[:2]

    def sole(side: str) -> tuple[float, float]:
        return _interval(foot(side) + SOLE, axis)

    def middle(support: list[str]) -> float:
        """Where the controller brings the centre of mass: the middle of the feet on the floor."""
        return float(np.mean([(foot(side) + FOOT_CENTRE) @ axis for side in support]))

    start = middle(list(SIDES)) if planted else 0.0
    tolerance = 0.002 if planted else 0.003
    u, v = start, push.speed
    planted_feet = {"L": True, "R": True}
    swing: tuple[str, np.ndarray, np.ndarray, float] | None = None  # side, from, to, lift time
    next_lift, mover, touchdowns = push.react, push.first, []
    alarm_state = np.zeros(2)  # a critically damped follower of the alarm signal, and its rate
    com, ankles, pitch, alarm = [], {s: [] for s in SIDES}, {s: [] for s in SIDES}, []
    settled_at, t, frame = None, 0.0, 0
    while settled_at is None or frame < settled_at + int(SETTLED_HOLD * FPS):
        if frame > MAX_SECONDS * FPS or len(touchdowns) > MAX_STEPS:
            raise RuntimeError(f"the balance model does not recover from {push}")
        com.append((u - start) * axis)
        alarm.append(alarm_state[0])
        for side in SIDES:
            if swing is not None and swing[0] == side:
                w = (t - swing[3]) / push.swing
                bump = lift_bump(w)
                xy = swing[1] + (swing[2] - swing[1]) * minimum_jerk(np.array(w))
                clearance = 0.05 + 0.1 * float(np.linalg.norm(swing[2] - swing[1]))  # long steps lift higher
                ankles[side].append([xy[0], xy[1], ANKLE_HEIGHT + clearance * bump])
                pitch[side].append(-np.radians(10.0) * bump)
            else:
                ankles[side].append([*foot(side), ANKLE_HEIGHT])
                pitch[side].append(0.0)
        xi = target = 0.0  # both set by the first of the SIM_STEPS steps
        for _ in range(SIM_STEPS):
            xi = u + v / OMEGA
            support = [side for side in SIDES if planted_feet[side]]
            lo = min(sole(side)[0] for side in support)
            hi = max(sole(side)[1] for side in support)
            target = middle(support)
            if planted:
                if not lo <= xi <= hi:
                    raise RuntimeError(f"{push}: the capture point leaves the feet; that push needs a step")
            elif swing is None and t >= next_lift and (xi < lo - STEP_MARGIN or xi > hi + STEP_MARGIN):
                # Step: the free foot flies to where the capture point will be when it lands.
                stance = "R" if mover == "L" else "L"
                edge = float(np.clip(xi, *sole(stance)))
                capture = edge + (xi - edge) * np.exp(OMEGA * push.swing)
                reach = capture - (base[mover] + FOOT_CENTRE) @ axis - along[stance]
                reach = float(np.clip(reach, -push.max_step, push.max_step))
                lifted_from = foot(mover)
                along[mover] = along[stance] + reach
                s = SIDES[mover]
                shift[mover] += s * max(0.0, MIN_STEP_WIDTH - s * (foot(mover)[0] - foot(stance)[0]))
                swing = (mover, lifted_from, foot(mover), t)
                planted_feet[mover] = False
            if swing is not None and t >= swing[3] + push.swing - 1e-9:
                planted_feet[swing[0]] = True
                touchdowns.append((swing[0], frame + 1))
                mover = "R" if swing[0] == "L" else "L"
                next_lift = t + push.pause
                swing = None
            # The pendulum: the centre of pressure by the capture-point controller, within the soles.
            p = float(np.clip(xi + CAPTURE_GAIN * (xi - target), lo, hi))
            v += OMEGA * OMEGA * (u - p) * dt
            u += v * dt
            raw = min(abs(v) / 0.8, 1.0)
            alarm_state += dt * np.array([alarm_state[1], 144.0 * (raw - alarm_state[0]) - 24.0 * alarm_state[1]])
            t += dt
        frame += 1
        # At rest over the middle of the feet, after its steps (if it may step) have landed.
        can_settle = (planted or bool(touchdowns)) and swing is None
        if settled_at is None and can_settle and abs(v) < tolerance and abs(xi - target) < tolerance:
            settled_at = frame
    return StepPlan(
        com=np.array(com),
        ankles={s: np.array(a) for s, a in ankles.items()},
        pitch={s: np.array(a) for s, a in pitch.items()},
        alarm=np.array(alarm),
        touchdowns=touchdowns,
    )
