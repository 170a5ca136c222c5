"""The reaction class a push leads to, from the simulated state at C: the classifier's training labels.

The paper takes its labels "from the simulation outcome" (section 2.3) without saying how; this is
our rule, grounded in balance mechanics. It never looks at the reaction library, so one model
serves any library (labels from the search's choice were measured wrong most of the time).

The rule reads a features.ReactionState (the same numbers the classifier's inputs come from):
the simulated body at B and C, the motion at C, the base of support at C (capture.py).

THE MODEL. The body is a linear inverted pendulum of height z0 (the centre of mass above the floor)
with eigenfrequency w0 = sqrt(g / z0). Its extrapolated centre of mass (XCoM; Hof, Gazendam and
Sinke 2005, Hof 2008), xi = x + v / w0 over the floor, is where the centre of pressure (CoP) must be
for the body to come to rest over it; in capture-point terms (Pratt et al. 2006, Koolen et al. 2012) it
is the instantaneous capture point. With the CoP held at p, xi runs away from p as e^(w0 t).

THE PUSH'S DEMAND. A walker's XCoM is ahead of its stance foot most of the time (Hof 2008), and its
own next step captures it: that is walking, not a reaction. So the rule measures how far the push
took the body from the motion it was playing:
    d_xi = xi(simulated, C) - xi(motion, C),
the motion's own XCoM being that of the same BC run without the push (physics.simulate_push).
The mocap pose at C through the ragdoll's masses was the reference until 2026-11-28, but BC's weak
servos do not follow the mocap: the unpushed body departs from it by a median 10 cm (p90 15 cm)
at C, as far as a 40 N·s push moves it, and 17% of front and back pushes at 40 N·s got a side or
the opposite direction's class. Against the twin the departure falls in the push's sector far more
often (docs/measurements.md). Its cost: a second BC run per impact. (An unpushed reference had been
tried before and dropped: the sample walker's contacts make its response to a 10 N·s push
non-monotonic, a forward push moving its XCoM back by up to 9 cm, so labels near zero push flip
with the gait phase. They still do; at 40 N·s and up the twin is the better reference.)
The motion's CoP is taken as the point of the base of support nearest to its XCoM (the XCoM
itself when it is inside, as in quiet standing; the front of the foot for a walker). From there the
CoP can still move to the edge of the base of support along d_xi (the ankle strategy: Hof,
Vermerris and Gjaltema 2010 measured it as the fastest response); what is left over is the excess
    e = |d_xi| - margin(d_xi).
A small excess needs no visible step: a walker's next step absorbs it within the normal variation
of foot placement, a standing body with the hip strategy (Horak and Nashner 1986). Up to
SWAY_TOLERANCE the push is a sway.

STEPS (N-step capturability, Koolen et al. 2012, Part 1, for the point-foot LIPM): with the CoP at
the support's edge the excess grows as e e^(w0 t). The first step lands FIRST_STEP_DELAY after the
push (Hof et al. 2010: foot placement needs at least 0.3 s), i.e. 0.3 s - (C - B) after C; each step
moves the CoP at most MAX_STEP_LENGTH; each further step takes STEP_TIME. So
    e_1 = e e^(w0 t_1) - l_max,  e_(n+1) = e_n e^(w0 dt_s) - l_max,
and the push is captured in the first n steps with e_n <= 0. If the excess
grows anyway (e_n beyond l_max / (e^(w0 dt_s) - 1), Koolen's infinite-step capture region), a
body other than a foot already touches the floor at C, or the centre of mass is already low and
sinking at C (the pendulum's constant height no longer holds: COLLAPSE_HEIGHT), the character falls.

CONSTANTS, with their reasons:
- SWAY_TOLERANCE 0.08 leg lengths: two standard deviations of step-to-step foot placement in
  normal walking (step length and step width each vary by about 4 % of leg length in healthy
  adults: J NeuroEng Rehabil 9:69, 2012, Table 1).
- FIRST_STEP_DELAY 0.3 s: Hof, Vermerris and Gjaltema 2010 (J Exp Biol 213:2655): the stepping
  strategy needs at least 300 ms from the perturbation to foot placement.
- STEP_TIME 0.3 s: the same 300 ms for each further corrective step (sense, plan, place).
- MAX_STEP_LENGTH 1.0 leg length (hip to ankle): a step that long opens the legs to about 60 deg,
  the widest stance from which the trailing leg can still be brought through. Hsiao-Wecksler and
  Robinovitch 2007 (Clin Biomech 22:574) found young women recover with single steps up to the
  35 % of body height they tested (about 0.65 leg length), longer steps still helping.
- Fall subtype by speed: FALL_FROUDE 1.0. An inverted pendulum of length L pivoting over its
  support at speed v needs a centripetal acceleration v^2 / L, which gravity supplies only while
  v^2 / (g L) < 1: the upper limit of walking (Alexander 1989). The speed is the CoM's horizontal
  velocity along the fall (along d_xi) at C, L the leg length. Slower, the body still pivots down
  over its support: falling forward it catches itself on its hands, falling backward it squats and
  sits down (the squat protective response, Robinovitch et al. 2004). Faster, it is thrown past
  its support: forward it tucks and rolls over, backward it lands on its hands behind it. (The
  sample library's falls were made the same way round: a light push from the front sits down, a
  harder one lands on the hands; a hard shove from behind rolls.)

DIRECTION, relative to the facing at B (the spine frame of features.py, in which the classifier
sees the push; a hard off-centre push can spin the ragdoll half a turn by C, and a label in that
frame would flip with it): d_xi within 45 deg
of forward -> forward classes, of backward -> backward classes, otherwise to the left or right. The
paper has no side-step class; we add one per side (classes.py): a sideways push that steps can
capture steps to that side, a standing character with a side step, a walker with its next steps
placed out to that side (Hof 2008). It used to get the step class of the way the motion travels
(a walker) or a sway (a stander), which an animator reads as the wrong way. A sideways fall is
`fall_side_knees`, the paper's only one, either side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.arrays import FloatArray
from ..model.impact import Impact
from ..model.rig import Rig
from ..model.skeleton import Motion
from ..physics.simulate import REACTION_WINDOW, SimResult, simulate_push
from ..physics.workspace import Workspace
from .capture import GRAVITY
from .features import FeatureReader, ReactionState

SWAY_TOLERANCE = 0.08  # leg lengths: 2 SD of normal foot placement (J NeuroEng Rehabil 9:69)
FIRST_STEP_DELAY = 0.3  # s from the push to the first foot placement (Hof, Vermerris, Gjaltema 2010)
STEP_TIME = 0.3  # s per further step (same source)
MAX_STEP_LENGTH = 1.0  # leg lengths (see the module docstring)
FALL_FROUDE = 1.0  # v^2 / (g L) at the upper limit of walking (Alexander 1989)
SIDE_ANGLE = 45.0  # degrees off the facing axis beyond which a push counts as sideways
MAX_STEPS = 8  # corrective steps counted before a push counts as not capturable (the series has converged)
# A body whose centre of mass is already this low at C (leg lengths above the floor; standing is
# about 1.1) and sinking this fast (m/s) is falling whatever its XCoM says: the pendulum model holds
# the height constant. Chosen so that no label changes on pushes from the sample clips (the few that
# cross both are already falls by the XCoM; docs/measurements.md, "Limits and rules"); a push during
# an earlier reaction's deep crouch sank far lower and faster and was judged a step.
COLLAPSE_HEIGHT = 0.75
COLLAPSE_SPEED = 0.8


@dataclass(frozen=True)
class Outcome:
    """The rule's verdict and the numbers behind it.

    reaction: a CLASS_SLUGS entry. steps: corrective steps (0 = sway), None for a fall.
    direction: "forward", "backward", "left" or "right". xcom_shift: d_xi in the facing frame (forward,
    left), m. excess: e, m (negative: inside the support's reach). speed: the centre of mass's
    horizontal velocity along d_xi, m/s. down: a body other than the feet is on the floor at C.
    collapsing: the centre of mass is low and sinking at C (collapsing()).
    """

    reaction: str
    steps: int | None
    direction: str
    xcom_shift: FloatArray
    excess: float
    speed: float
    down: bool
    collapsing: bool = False


def collapsing(rig: Rig, com: FloatArray, com_velocity: FloatArray, floor: float) -> bool:
    """Whether the body is already going down at C: its centre of mass below COLLAPSE_HEIGHT leg
    lengths and sinking faster than COLLAPSE_SPEED (see the constants)."""
    return bool(com[2] - floor < COLLAPSE_HEIGHT * rig.leg_length and com_velocity[2] < -COLLAPSE_SPEED)


def judge(rig: Rig, state: ReactionState, window: float = REACTION_WINDOW, *, going_down: bool = False) -> Outcome:
    """The reaction class of a reaction state (see the module docstring); window: C - B in seconds.
    going_down: the caller knows the body is on its way to the floor whatever the state at C says
    (react._played_down: an earlier fall still playing), so the verdict is a fall."""
    shift = state.xcom_departure()
    norm = float(np.linalg.norm(shift))
    excess = norm - state.reach()
    omega = state.omega()
    sinking = collapsing(rig, state.com_c, state.com_velocity, state.floor)
    falls = going_down or state.support.down or sinking
    steps = None if falls else _steps_to_capture(excess, omega, rig.leg_length, window)
    frame = state.facing(rig)[:2, :2]
    local = frame @ shift
    direction = way(local)
    speed = float(state.com_velocity[:2] @ shift / norm) if norm > 0.0 else 0.0
    reaction = _reaction(steps, direction, speed, rig.leg_length)
    return Outcome(reaction, steps, direction, local, excess, speed, state.support.down, sinking)


def way(local: FloatArray) -> str:
    """Where a horizontal vector in the facing frame (forward, left) points: "forward" or "backward"
    within SIDE_ANGLE of the facing axis, else "left" or "right" (a class's way: model/classes.py)."""
    angle = math.degrees(math.atan2(abs(local[1]), local[0]))  # 0 ahead .. 180 behind
    if angle <= SIDE_ANGLE:
        return "forward"
    if angle >= 180.0 - SIDE_ANGLE:
        return "backward"
    return "left" if local[1] > 0.0 else "right"


def _steps_to_capture(excess: float, omega: float, leg: float, window: float) -> int | None:
    """Koolen's N-step capturability of an XCoM `excess` beyond the support (None: not capturable)."""
    if excess <= SWAY_TOLERANCE * leg:
        return 0
    reach = MAX_STEP_LENGTH * leg
    left = excess * math.exp(omega * max(FIRST_STEP_DELAY - window, 0.0)) - reach
    for steps in range(1, MAX_STEPS + 1):
        if left <= 0.0:
            return steps
        left = left * math.exp(omega * STEP_TIME) - reach
    return None


# The step classes by direction: one step, several (a side step class counts any number).
STEP_CLASSES = {
    "forward": ("step_forward", "steps_forward"),
    "backward": ("step_back", "steps_back"),
    "left": ("step_left", "step_left"),
    "right": ("step_right", "step_right"),
}


def _reaction(steps: int | None, direction: str, speed: float, leg: float) -> str:
    """The class from the steps, the direction and the speed along the departure."""
    if steps == 0:
        return "sway_balance"
    if steps is None:
        fast = speed > 0.0 and speed**2 >= FALL_FROUDE * GRAVITY * leg
        if direction == "forward":
            return "fall_forward_roll" if fast else "fall_forward_hands"
        if direction == "backward":
            return "fall_backward_hands" if fast else "fall_backward_sit"
        return "fall_side_knees"
    return STEP_CLASSES[direction][0 if steps == 1 else 1]


def simulate_outcome(
    reader: FeatureReader,
    motion: Motion,
    impact: Impact,
    window: float = REACTION_WINDOW,
    workspace: Workspace | None = None,
) -> tuple[SimResult, ReactionState, Outcome]:
    """Simulate an impact's BC on the reader's ragdoll and judge the state at C."""
    bc = simulate_push(reader.ragdoll, motion, impact, window=window, workspace=workspace)
    state = reader.simulated(motion, bc)
    return bc, state, judge(reader.rig, state, (bc.frames[-1] - impact.frame) / motion.fps)
