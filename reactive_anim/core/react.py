"""One impact end to end, and a timeline of impacts (paper section 2, steps 2-6, Fig. 1, Fig. 4).

For an impact at B on a playing motion:
  BC  the ragdoll takes the impulse and runs forward dynamics for a reaction time (simulate.py);
  C   the classifier names the likely reaction classes from the state at C (features.py);
      the jump search (search.py) finds, within the most probable class the library has, the clip
      window closest to the simulated window ending at C; its last frame is the clip's E, matched to
      C, and the clip is placed so that E's pelvis stands where the simulated pelvis is at C (the
      search aligns the windows' first frames; by C the push has carried the body further);
  CD  PD servos track theta_blend from C: the motion the character was playing, faded into the clip
      from E (blend.py), so the body moves toward the clip while physics keeps the hit's momentum;
      the servos stiffen from BC's gains to CD's over CD_RAMP rather than at once;
  CF  the simulated CD is faded into the clip's E..F (root lerp, joint slerp); at F the pose is the
      clip's (exactly, but for legs that hold a planted foot: see Feet below), and the clip plays on
      from there, placed where the character is. F is C + `transition`; for a fall (or a body down
      keeping the fall it plays) it may come up to `fall_transition` later, where the clip's pelvis
      moves most steadily (_calm_end).
What we add beyond the paper, and why:
- A clip whose library entry names a `next` clip (a get-up after a fall, paper Fig. 3) is followed
  by it, placed where the fall ends and faded in over `chain_blend`.
- Resume: when the reaction ends standing, the original motion resumes. Its best re-entry window
  (Eq. 1, after B) is aligned with a window of the reaction's frames and faded in over
  RESUME_FADE, the pelvis' travel faded by velocity over the window (blend.blend_travel), so a
  walker who stumbles walks on. (Over the 0.27 s window alone, a side step's wide stance handed
  back to the walk raised the pelvis 21 cm with 20 m/s² at both ends: docs/measurements.md.) The
  fade may start from F on (after a get-up, at its end), where Eq. 1 plus a cost per second of
  waiting (RESUME_WAIT) is least: a walker walks on once the stumble's step has landed instead of
  standing through the clip's recovery, and a stand resumes where the clip has come to rest. A
  reaction that ends lying down holds its last pose.
- Several impacts: each starts from the motion as already reacted at its frame (Fig. 4), so a hit
  that lands during an earlier reaction reacts from that reaction.
- A class the library lacks (a library of real falls and get-ups has no steps): the push is judged
  by the outcome rule (outcome.py, the classifier's own labels). A push that keeps its feet never
  gets a fall: it plays the nearest class the library has that keeps them (NEAR: the same way, more
  or fewer steps, a sway), and with none of those it keeps the motion it was playing: BC's hit,
  then CD tracks back to that motion and fades into it by F, from where it plays on unchanged
  (Reaction.kept_motion; its timing stays the animator's, later markers land where they were put;
  a walk is moved over the floor by the push's gain at C, _gain, a stand stays where it was). A
  push the rule says falls searches the probable classes the library has, as before. Either way
  Reaction.note says what the library lacked and what was done.
- A push the classifier calls a sway or a single step (any way), on a character walking (faster
  than WALKING_SPEED) that the push has not stopped, keeps the walk as a missing class does
  (above): the sway and step clips start and end standing, so a nudged walker stopped and fell
  behind where it would have been. A single step is measured against the unpushed twin: for a
  walker it is its next step landing shorter, longer or wider, not a step from a stand (_walking;
  override the class on the marker to play a clip anyway).
- Feet: where the sources cross-fade (C..F, a get-up fading in, the resume), a planted foot keeps
  its footprint instead of sliding from one source's to the other's, and feet and hands that a
  fade or a cast clip puts through the floor are lifted onto it (footing.py).
- Impact frames are on the output's clock (the baked action's timeline); the output keeps the
  original's frames before the first impact bit for bit.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from .classify.capture import foot_bodies
from .classify.features import FeatureReader, feature_rig
from .classify.outcome import COLLAPSE_HEIGHT, STEP_CLASSES, Outcome, collapsing, judge, way
from .model.acceleration import accelerations, stride_frames
from .model.arrays import BoolArray, FloatArray
from .model.classes import CLASS_SLUGS, CLASSES, is_fall, reaction_class
from .model.errors import Cancelled, ImpactError, LibraryError, SkeletonError
from .model.impact import Impact
from .model.rig import Rig
from .model.skeleton import Motion, hold_root, static_root
from .physics.balance import KEPT_WALK, RootAssist
from .physics.ragdoll import Ragdoll, build_ragdoll
from .physics.simulate import SimResult, simulate_push, track
from .physics.workspace import BC_GAINS, Workspace
from .search.library import Library
from .search.reach import reachable_windows
from .search.search import Match, search, search_with_fallback, with_allowed
from .search.window import (
    TABLE2_POSITION_WEIGHTS,
    TABLE2_ROTATION_WEIGHTS,
    Query,
    Windows,
    frame_features,
    joint_weights,
    yaw_rotate,
)
from .transition.blend import blend, blend_travel, carry, fade_weights, place
from .transition.casting import Casting
from .transition.fade_shape import calmest_fade, fade_context
from .transition.footing import hold_feet, lift_onto_floor
from .transition.soften import OUTDONE, OUTDONE_PASSES, context_frames, soften

RESUME_WAIT = 60.0  # Eq. 1 cost per second a reaction goes on before the motion resumes (_resume)
RESUME_RATE = 30.0  # fade starts and re-entries tried per second (_resume)
RESUME_SEARCH = 1.0  # s after the earliest fade start within which the fade may start (_resume)
# s the resume fades the pose over; the pelvis' travel fades over the re-entry's Eq. 1 window (_resume)
RESUME_FADE = 0.4
# fades' worth of the source a re-entry leaves to play (_resume_or_hold, _resume): one nearer its end
# faded into its last pose, repeated, and a runner froze mid-stride as the fade ended (a toe stopped
# dead at 216 m/s^2); a fade into a run that stops as it ends is no better than the clip's stand
RESUME_LEFT = 2
DOWN_AHEAD = 0.5  # s after C within which the motion being played reaching the floor counts (_going_down)
DOWN_HEIGHT = 0.5  # leg lengths: a pelvis this low over the floor sits, kneels or lies (_going_down)
STILL_KEPT = 0.5  # s of a clip's still tail played before the motion resumes or a get-up begins
CARRY_TIME = 0.15  # s over which theta_blend lets go of the body's departure at C (blend.carry; measured 0.15-0.25)
# s over which CD's servos stiffen from BC's gains (simulate.track's ramp): switched on at once they
# caught a body landing on a foot at C within a frame (docs/measurements.md; measured 0.1-0.25)
CD_RAMP = 0.15
# The classes that keep the feet nearest each, nearest first, for a push that keeps its feet whose
# class the library lacks: the same way with more or fewer steps, then a sway. Not a step the other
# way (a push from behind does not step back), nor a step for a sway (more than the push called for):
# with none of them in the library the motion is kept, the hit simulated (Reaction.kept_motion).
NEAR: dict[str, tuple[str, ...]] = {
    "step_forward": ("steps_forward", "sway_balance"),
    "steps_forward": ("step_forward", "sway_balance"),
    "step_back": ("steps_back", "sway_balance"),
    "steps_back": ("step_back", "sway_balance"),
    "step_left": ("sway_balance",),
    "step_right": ("sway_balance",),
    "sway_balance": (),
}
KEPT_CLIP = "(the original motion)"  # Reaction.clip when the motion was kept
SWAY = "sway_balance"
# m/s: the centre of mass's mean pace over the floor from B to C (unpushed) above which a push the
# classifier calls a sway or a single step keeps the walk (_search, _walking), if the push's J / M
# leaves it going that way at this pace too; the shared walks go at 0.3-1.6 m/s (the Bandai sad,
# elderly and not-confident walks at 0.3-0.6), a standing body shifting its weight under 0.2
WALKING_SPEED = 0.3
OFF_PUSH = "does not go the way of the push"  # the note when the first choice is left out (_off_push)
# The single steps, one per way (outcome.STEP_CLASSES): on a walker, its next step adjusted (_walking)
SINGLE_STEPS = frozenset(steps[0] for steps in STEP_CLASSES.values())


@dataclass(frozen=True)
class ReactionSettings:
    """How a reaction is made; defaults in brackets.

    reaction_window: BC, seconds of free physics after the hit [0.25, a human reaction time].
    transition: C to F, seconds of PD tracking faded into the clip [0.5: against a third of a second,
      the fade's pops and a walker's stops are fewer (tools/bench.py quality), its feet skid more].
    fall_transition: for a fall (or a body down keeping the fall it plays), the longest the
      transition may run: F is put where the clip's pelvis moves most steadily, from `transition`
      to this (_calm_end) [0.95: a fade ending as the
      body lands hands the seam the landing's jolt; at F the pelvis of 58 of 528 reactions, nearly
      all falls, accelerated more than real walks do 1% of the time: docs/measurements.md].
    profile: the ragdoll's joint profile, "anatomical" or "paper" (physics/anatomy.py) ["anatomical"].
    search_threshold: Eq. 1 cost above which a class's best window passes the search on to the
      next probable class; when none is within it, the most probable class's best window is used
      anyway, marked not accepted (search_with_fallback) [40.0: the sample library's matches of
      pushed walks cost 10-40].
    min_probability: classes less probable than this are not searched, unless none that likely is
      in the library (then its most probable class; but a push that keeps its feet gets no fall
      when the library lacks its class: NEAR) or the body is going down (the falls) [0.1].
    resume: after a reaction that ends standing, resume the original motion [True].
    chain_blend: seconds over which a chained get-up fades in where the fall ends [0.2].
    assist: the root assist that keeps the body up during CD (balance.py), None for the paper's
      pure PD tracking [RootAssist(): lift at most 0.3 of body weight, torques at most 0.4 m g h, let go
      past 20-40 degrees of tilt].
    kept_assist: the assist in place of `assist` when the motion is kept through the push (a sway
      or a single step on a walker, or a push whose class the library lacks), None for pure PD
      there [balance.KEPT_WALK: lift up to 0.8 of the weight, torques at most 0.8 m g h, let go
      past 60-90 degrees: CD held up while it fades back into the motion].
    hold_feet: planted feet keep their footprints where the sources cross-fade, and the body stays
      out of the floor (footing.py) [True; False leaves the feet where the fades put them, sliding].
    soften: the simulated stretch (BC, CD) averaged over time where a joint's acceleration spikes,
      and the whole reaction where a joint outdoes real falls (soften.py) [True; False plays it as
      sampled: a struck foot stops between two frames].
    calm_fade: a fall's C..F faded along whichever of a few fade shapes accelerates the body least,
      where the plain one makes it accelerate faster than the simulation and the clip do alone, and
      jolts the pelvis at F no harder than real motion mostly does (fade_shape.py) [True; False:
      the plain smootherstep, as theta_blend's and every other reaction's].
    """

    reaction_window: float = 0.25
    transition: float = 0.5
    profile: str = "anatomical"
    search_threshold: float = 40.0
    min_probability: float = 0.1
    resume: bool = True
    chain_blend: float = 0.2
    fall_transition: float = 0.95
    assist: RootAssist | None = field(default_factory=RootAssist)
    kept_assist: RootAssist | None = KEPT_WALK
    hold_feet: bool = True
    soften: bool = True
    calm_fade: bool = True


class ReactionClassifier(Protocol):
    """What the pipeline needs of a classifier (classifier.py): class probabilities of a simulated
    impact, in CLASS_SLUGS order."""

    def classify(self, before: Motion, bc: SimResult, ragdoll: Ragdoll) -> FloatArray: ...


@dataclass(frozen=True)
class Reaction:
    """The result for one impact. Frames are on the output's clock.

    frame_b, frame_c, frame_f: the impact, the end of BC (classify and search), the end of the
      transition (pose = the clip's; past the output's end where a kept motion ends mid-fade);
      end_frame: the last frame of the reaction (clip, get-up).
    probabilities: class slug -> probability (empty without a classifier); predicted: the most
      probable class, or the override. scope: what the search covered ("all", a class, ...).
    match: the search's best window (search.Match), None when the motion was kept; reaction_class,
      clip, jump_frame, cost, accepted and scope read it (jump_frame: the window's first frame in
      the clip, library rate). placement: (yaw, (x, y)) that put the clip on the character: its
      frame E (the window's last, matched to C) where the simulated body is at C.
    chained: the get-up clip that followed, if any; resumed_at: the original motion's frame at
      which it resumed (None: held the last pose, or resume off).
    going_down: the body was already down or going down at C, so the search looked among the falls,
      the outcome rule's first (_going_down), rather than at the classifier's choice.
    note: for the animator, why the reaction is not what the push called for (the library lacks
      its class: what it played instead, or that it kept the motion); empty when it is.
    kept_motion (match None): no clip was played: the push keeps its feet and the library has no
      class that does (NEAR), or it is a sway or a single step on a walk (_walking), so CD tracked
      back to the motion, which plays on from F (clip KEPT_CLIP, cost 0; placement: a walk moved by
      the push's gain, _gain, else none); kept_class: the class it stands for then.
    timings: seconds per step (bc, classify, search, cd, blend, splice, total).
    """

    impact: Impact
    frame_b: float
    frame_c: int
    frame_f: int
    end_frame: int
    probabilities: dict[str, float]
    predicted: str | None
    match: Match | None
    placement: tuple[float, tuple[float, float]]
    chained: str | None
    resumed_at: int | None
    going_down: bool = False
    note: str = ""
    kept_class: str = ""
    timings: dict[str, float] = field(default_factory=dict[str, float])
    motion: Motion | None = field(default=None, repr=False)

    @property
    def kept_motion(self) -> bool:
        return self.match is None

    @property
    def reaction_class(self) -> str:
        return self.kept_class if self.match is None else self.match.reaction_class

    @property
    def clip(self) -> str:
        return KEPT_CLIP if self.match is None else self.match.clip

    @property
    def jump_frame(self) -> int:
        return 0 if self.match is None else self.match.jump_frame

    @property
    def cost(self) -> float:
        return 0.0 if self.match is None else self.match.cost

    @property
    def accepted(self) -> bool:
        return True if self.match is None else self.match.accepted

    @property
    def scope(self) -> str:
        return "none" if self.match is None else self.match.scope


@dataclass(frozen=True)
class Baked:
    """The whole reacted motion and one Reaction per impact, in time order."""

    motion: Motion
    reactions: list[Reaction]


class _Clock:
    """Seconds per named step."""

    def __init__(self) -> None:
        self.times: dict[str, float] = {}
        self._start = self._last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.times[name] = self.times.get(name, 0.0) + now - self._last
        self._last = now

    def total(self) -> dict[str, float]:
        return {**self.times, "total": time.perf_counter() - self._start}


# ---------------------------------------------------------------------------------------------
# Public API


def react(
    motion: Motion,
    impact: Impact,
    library: Library,
    classifier: ReactionClassifier | None = None,
    settings: ReactionSettings | None = None,
    *,
    source: Motion | None = None,
    ragdoll: Ragdoll | None = None,
    workspace: Workspace | None = None,
    casting: Casting | None = None,
) -> Reaction:
    """Steps 2-6 for one impact on `motion`; Reaction.motion is the whole motion with the reaction.

    source: the motion to resume after the reaction (default `motion`; a bake passes the original).
    ragdoll, workspace, casting: reuse across impacts (default: built for the motion's skeleton;
    casting.py when the library's clips are on another skeleton).
    """
    settings = settings or ReactionSettings()
    clock = _Clock()
    _check_impact(motion, impact)
    ragdoll = ragdoll or character_ragdoll(motion, settings.profile)
    workspace = workspace or Workspace(ragdoll)
    casting = casting or Casting.between(source or motion, ragdoll.rig, library)
    bc, before = _bc(motion, impact, ragdoll, settings, workspace)
    frame_c = int(bc.frames[-1])
    clock.lap("bc")
    probabilities = _probabilities(classifier, motion, bc, ragdoll)
    falling, lying = (None, False) if impact.reaction is not None else _going_down(motion, bc, ragdoll, impact, library)
    clock.lap("classify")
    query = _query_ending_at(before, frame_c, casting, impact)
    walking = _walking(bc, impact, ragdoll.total_mass)
    choice = _search(library, query, impact, probabilities, settings, falling,
                     lambda: _judge(motion, bc, ragdoll, impact), walking,
                     _off_push(motion, impact, ragdoll.rig), lying)  # fmt: skip
    match = choice.match
    clock.lap("search")
    if match is None:  # the motion kept: the "clip" is the motion, jumped into at C; a walk moved by the push
        placement = (0.0, _gain(bc) if walking else (0.0, 0.0))
        clip, frame_e = place(motion, *placement), frame_c
    else:
        clip_raw = casting.clip(match.clip, motion.fps)
        # E: the window's last frame on the character's clock (a clip resampled to a frame rate such
        # as 59.9988 may end a frame short of the rounded time)
        frame_e = min(
            round((match.jump_frame + library.window - 1) / library.fps * motion.fps), clip_raw.num_frames - 1
        )
        at_c = before.slice(frame_c, frame_c + 1)
        placement = _alignment(at_c, clip_raw.slice(frame_e, frame_e + 1), ragdoll.rig)
        clip = place(clip_raw, *placement)
    steps = max(1, round(settings.transition * motion.fps))
    # a fall, or a body down keeping the fall it plays: F where that lands calmly
    fall_like = is_fall(match.reaction_class) if match is not None else falling is not None
    if fall_like and settings.fall_transition > settings.transition:
        steps = _calm_end(clip, frame_e, steps, round(settings.fall_transition * motion.fps), ragdoll.rig)
    clip_ef = clip.frames(frame_e, steps + 1)  # E..F; a clip that ends sooner holds its last pose
    # theta_blend: what the character was playing (an earlier reaction, if one plays; a kept walk where
    # the push moved it), starting from the simulated pose at C (blend.carry), faded into the clip.
    playing = motion if match is not None else clip
    played = carry(playing.frames(frame_c, steps + 1), before.slice(frame_c, frame_c + 1),
                   round(CARRY_TIME * motion.fps))  # fmt: skip
    target = blend(played, clip_ef, fade_weights(steps + 1))
    assist = settings.assist if match is not None else settings.kept_assist
    cd = track(ragdoll, bc.state, target, steps / motion.fps, assist=assist, ramp=(BC_GAINS, CD_RAMP),
               workspace=workspace)  # fmt: skip
    # the simulated stretch: BC from the frames soften reads before the one after the hit, then CD
    hit = int(np.ceil(impact.frame)) + 1
    lead = max(hit - context_frames(motion.fps), 0)
    sim = _join(before.slice(lead, frame_c), cd.motion)
    if settings.soften:
        sim = soften(sim, hit - lead)
    clock.lap("cd")
    # a fall's only: on steps and kept walks a shape chosen on the blend alone did worse once the
    # feet were held (a kept walk's toe 95 -> 182 m/s^2), and there the body is not thrown
    fade = fade_weights(steps + 1)
    before_c, after_f = fade_context(motion.fps)  # the frames the shapes are judged on must exist
    thrown = settings.calm_fade and match is not None and is_fall(match.reaction_class)
    if thrown and min(frame_c - lead, frame_e) >= before_c:
        sim_cf = sim.slice(frame_c - lead - before_c, sim.num_frames)
        clip_cf = clip.frames(frame_e - before_c, before_c + steps + 1 + after_f)
        fade = calmest_fade(sim_cf, clip_cf, ragdoll.rig)
    transition = blend(sim.slice(frame_c - lead, sim.num_frames), clip_ef, fade)
    to_c = (before.slice(0, lead), sim.slice(0, frame_c - lead))
    if match is None:  # the motion plays on from F; the reaction ends there
        out = _join(*to_c, transition, clip.slice(frame_e + steps + 1, clip.num_frames))
        # where the fade runs past the motion's end, it faded into the motion's last pose held and a
        # runner stopped dead: the motion ends where it ends, mid-fade
        out = out.slice(0, max(min(out.num_frames, motion.num_frames), frame_c + 1))
        clock.lap("blend")
        chained, chain_fade, end_frame = None, [], min(frame_c + steps, out.num_frames - 1)
        out, resumed_at, resume_fade = _resume_or_hold(out, source or motion, 0, 0, ragdoll.rig)
    else:
        stop = max(frame_e + steps + 1, _still_from(library, match.clip_index, motion.fps))
        out = _join(*to_c, transition, clip.slice(frame_e + steps + 1, min(stop, clip.num_frames)))
        clock.lap("blend")
        out, chained, chain_fade = _chain(out, casting, match, ragdoll.rig, settings)
        standing = chained is not None or not is_fall(match.reaction_class)
        window = max(2, round(library.window * motion.fps / library.fps)) if settings.resume and standing else 0
        # a stumble may hand back to the motion from F on; a get-up plays to its end first
        earliest = frame_c + steps if chained is None else out.num_frames - window
        out, resumed_at, resume_fade = _resume_or_hold(out, source or motion, int(np.ceil(impact.frame)), window,
                                                       ragdoll.rig, earliest)  # fmt: skip
        end_frame = resume_fade[0][1] - 1 if resume_fade else out.num_frames - 1
    # B's own pose stays; a held last pose (a fall with nothing chained) is held lifted as it ends
    reacting = (
        int(np.ceil(impact.frame)) + 1,
        end_frame + 1 if resumed_at is not None or match is None else out.num_frames,
    )
    if settings.hold_feet:
        # from B, not C: the ragdoll's soles creep under a push (a standing foot 5 cm under a side
        # push at 40 N·s), and a standing foot is held in BC as where the sources cross-fade
        fades = [(int(np.ceil(impact.frame)), frame_c + steps + 1), *chain_fade, *resume_fade]
        out = lift_onto_floor(hold_feet(out, ragdoll.rig, reacting, fades, casting.sole), reacting, casting.sole)
    ground_root = static_root(source or motion)
    if ground_root is not None:
        out = hold_root(out, *ground_root)
    if settings.soften:
        # what the stitching still throws near or past the real falls' largest (after the root is
        # held: a ground root's sources put it anywhere, and averaged so it dragged the hips metres)
        calmed = soften(out, reacting[0], OUTDONE, passes=OUTDONE_PASSES, last=reacting[1])
        if calmed is not out:
            out = lift_onto_floor(calmed, reacting, casting.sole) if settings.hold_feet else calmed
            if ground_root is not None:  # the lift raised the ground root with the body
                out = hold_root(out, *ground_root)
    clock.lap("splice")
    return Reaction(
        impact=impact,
        frame_b=impact.frame,
        frame_c=frame_c,
        frame_f=frame_c + steps,
        end_frame=end_frame,
        probabilities=dict(zip(CLASS_SLUGS, map(float, probabilities), strict=True))
        if probabilities is not None
        else {},
        predicted=impact.reaction or (None if probabilities is None else CLASS_SLUGS[int(np.argmax(probabilities))]),
        match=match,
        placement=placement,
        chained=chained,
        resumed_at=resumed_at,
        going_down=falling is not None,
        note=choice.note,
        kept_class=choice.kept_class,
        timings=clock.total(),
        motion=out,
    )


def bake_reactions(
    motion: Motion,
    impacts: list[Impact],
    library: Library,
    classifier: ReactionClassifier | None = None,
    settings: ReactionSettings | None = None,
    *,
    progress: Callable[[int, int, str], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Baked:
    """Every impact in time order, each on the motion as reacted so far (paper Fig. 4).

    progress(i, n, step) is called before each impact (step "react") and at the end ("done");
    cancel() returning True stops the bake with Cancelled, returning nothing half-made.
    """
    settings = settings or ReactionSettings()
    if not impacts:
        return Baked(motion, [])
    ordered = sorted(impacts, key=lambda i: i.frame)
    for impact in ordered:
        _check_impact(motion, impact)
    ragdoll = character_ragdoll(motion, settings.profile)
    workspace = Workspace(ragdoll)
    casting = Casting.between(motion, ragdoll.rig, library)
    current = motion
    reactions: list[Reaction] = []
    for k, impact in enumerate(ordered):
        if cancel is not None and cancel():
            raise Cancelled(f"bake cancelled before impact {k + 1} of {len(ordered)}")
        if progress is not None:
            progress(k, len(ordered), "react")
        reaction = react(current, impact, library, classifier, settings, source=motion, ragdoll=ragdoll,
                         workspace=workspace, casting=casting)  # fmt: skip
        current = reaction.motion if reaction.motion is not None else current
        reactions.append(replace(reaction, motion=None))
    if progress is not None:
        progress(len(ordered), len(ordered), "done")
    return Baked(current, reactions)


def impact_query(
    motion: Motion,
    impact: Impact,
    library: Library,
    ragdoll: Ragdoll,
    *,
    settings: ReactionSettings | None = None,
    workspace: Workspace | None = None,
    casting: Casting | None = None,
) -> tuple[Query, SimResult]:
    """The search's query for an impact as `react` makes it (BC simulated, the library-rate window
    ending at C, on the library's skeleton), and the BC result (for the classifier): the pipeline's
    real queries, for benchmarks and tools that study the search."""
    settings = settings or ReactionSettings()
    _check_impact(motion, impact)
    casting = casting or Casting.between(motion, ragdoll.rig, library)
    bc, before = _bc(motion, impact, ragdoll, settings, workspace)
    return _query_ending_at(before, int(bc.frames[-1]), casting, impact), bc


def _bc(
    motion: Motion, impact: Impact, ragdoll: Ragdoll, settings: ReactionSettings, workspace: Workspace | None
) -> tuple[SimResult, Motion]:
    """BC simulated (with its unpushed twin, the classifier's reference), and the motion up to C with
    it (the mocap before B, the simulation from B)."""
    bc = simulate_push(ragdoll, motion, impact, window=settings.reaction_window, workspace=workspace)
    return bc, _join(motion.slice(0, int(bc.frames[0])), bc.motion)


def character_ragdoll(motion: Motion, profile: str = "anatomical") -> Ragdoll:
    """The ragdoll of the motion's skeleton: neutral pose from the rest pose when it stands, else
    from the motion's first frame."""
    try:
        return build_ragdoll(motion.skeleton, profile=profile)
    except SkeletonError:
        return build_ragdoll(motion.skeleton, profile=profile, reference=motion)


# ---------------------------------------------------------------------------------------------
# Steps


def _check_impact(motion: Motion, impact: Impact) -> None:
    where = f"impact at frame {impact.frame:g} on '{impact.bone}'"
    if not 0 <= impact.frame <= motion.num_frames - 1:
        raise ImpactError(f"{where} is outside the motion's frames 0..{motion.num_frames - 1}")
    if impact.bone not in motion.skeleton.names:
        raise ImpactError(f"{where}: the skeleton has no bone '{impact.bone}'")
    if impact.reaction is not None and impact.reaction not in CLASS_SLUGS:
        raise ImpactError(f"{where}: unknown reaction '{impact.reaction}'; classes are: {', '.join(CLASS_SLUGS)}")


def _probabilities(
    classifier: ReactionClassifier | None, before: Motion, bc: SimResult, ragdoll: Ragdoll
) -> FloatArray | None:
    return None if classifier is None else np.asarray(classifier.classify(before, bc, ragdoll), dtype=np.float64)


def _query_ending_at(before: Motion, frame_c: int, casting: Casting, impact: Impact) -> Query:
    """The library-rate window whose last frame is C, from the motion with BC in it."""
    library = casting.library
    start = frame_c - (library.window - 1) * before.fps / library.fps
    if start < 0:
        raise ImpactError(
            f"impact at frame {impact.frame:g} on '{impact.bone}' is too early: the search needs "
            f"{(library.window - 1) / library.fps:.2f} s of motion before the end of the reaction window"
        )
    return casting.query(before, start)


@dataclass(frozen=True)
class _Choice:
    """What the search chose: a match, or None to keep the motion (then kept_class is the class the
    push calls for); note: for the animator, what the library lacked and what was done instead."""

    match: Match | None
    note: str = ""
    kept_class: str = ""


def _search(
    library: Library,
    query: Query,
    impact: Impact,
    probabilities: FloatArray | None,
    settings: ReactionSettings,
    falling: str | None = None,
    rule: Callable[[], Outcome] | None = None,
    walking: bool = False,
    off: frozenset[str] = frozenset(),
    lying: bool = False,
) -> _Choice:
    """The override's class alone; a body going down, the rule's fall and then the other falls; else
    the classifier's classes (without one, the whole library); either way those `off` the push's way
    (_off_push) left out while any other is left, the animator told when the first choice was, in
    order: a sway or a single step while `walking` (_walking), the walk kept; else the probable
    classes (search_with_fallback). When the library lacks the predicted class (or, with no
    classifier, has only falls), `rule` (the outcome rule's verdict, asked only then) decides: see
    _missing_class. A body down or going down is faded only into fall windows it can reach over the
    fade (reach.reachable_windows); when none of the push's way is, one whose motion goes to the floor
    within DOWN_AHEAD (`lying`: an earlier fall still playing, _going_down) keeps that motion, and
    one going down for the first time takes the nearest fall."""
    if impact.reaction is not None:
        return _Choice(search(library, query, [impact.reaction], settings.search_threshold))
    ranked = range(len(CLASS_SLUGS)) if probabilities is None else np.argsort(-probabilities, kind="stable")
    order = [CLASS_SLUGS[k] for k in ranked]
    if falling is not None:
        falls = _with_push([falling] + [slug for slug in order if is_fall(slug) and slug != falling], off)
        # the shortest fade's frames: over a fall's longest, a kneeling clip's own fall onto its face
        # ruled its windows out against a body still kneeling, and rougher ones were taken
        fade = round(settings.transition * library.fps)
        allowed: BoolArray | None = reachable_windows(library, query, falls, fade)
        reachable = with_allowed(library, falls, allowed)
        if not reachable and lying:
            return _Choice(None, "no fall clip of the push's way lies as the body does (each would stand it up or "
                                 "turn it over): kept the motion it plays, the hit simulated", falling)  # fmt: skip
        if not reachable:  # a body going down for the first time falls anyway: the nearest fall
            allowed, reachable = None, falls
        match = search_with_fallback(library, query, reachable, settings.search_threshold, allowed=allowed)
        notes = [f"the outcome rule's {falling} {OFF_PUSH}"] if falls[0] != falling else []
        if reachable[0] != falls[0]:
            notes.append(f"no {falls[0]} clip lies as the body does")
        return _Choice(match, "; ".join(notes) + f"; played {match.reaction_class}" if notes else "")
    chance = {} if probabilities is None else dict(zip(CLASS_SLUGS, map(float, probabilities), strict=True))
    turned = f"the classifier's {order[0]} {OFF_PUSH}; " if probabilities is not None and order[0] in off else ""
    ranked_all, order = order, _with_push(order, off)
    predicted = None if probabilities is None else order[0]
    if walking and (predicted == SWAY or predicted in SINGLE_STEPS):  # the clips stand: the walk is kept
        spoken = reaction_class(predicted).label.lower()
        return _Choice(None, turned + f"a {spoken} on a walk: kept the walk, the hit simulated", predicted)
    have = library.class_ranges
    missing = predicted not in have if predicted is not None else not any(not is_fall(s) for s in have)
    if missing and rule is not None:
        choice = _missing_class(library, query, predicted, rule(), settings, off)
        if choice is not None:
            return choice
    if probabilities is None:  # the whole library, but for the classes off the push's way
        return _Choice(search(library, query, _with_push(list(have), off) if off else None, settings.search_threshold))
    likely = [slug for slug in order if chance[slug] >= settings.min_probability]
    if not any(slug in library.class_ranges for slug in likely):  # else the likeliest it has, the push's way first
        likely = [slug for slug in order + ranked_all if slug in library.class_ranges][:1]
    if not likely:
        raise LibraryError("the library has no usable class for this reaction")
    match = search_with_fallback(library, query, likely, settings.search_threshold)
    note = f"the library has no {predicted} clips: played {match.reaction_class} instead" if missing else ""
    if turned:
        note = turned + (note or f"played {match.reaction_class}")
    return _Choice(match, note)


def _with_push(classes: list[str], off: frozenset[str]) -> list[str]:
    """The classes, in order, without those off the push's way, unless that would leave none (a
    library of nothing else plays what it has)."""
    return [slug for slug in classes if slug not in off] or classes


def _off_push(motion: Motion, impact: Impact, rig: Rig) -> frozenset[str]:
    """The classes whose body does not go the push's way (forward, backward, left or right over the
    floor, in the facing at the impact: outcome.way). A sway goes no way, and the side fall either
    side, so neither is off a push to the side; a push from the front or behind sends the body
    along it, not sideways. The classifier learnt its labels from BC against its unpushed twin,
    which mixes the walker's own gait into the answer: a walker hit from the front at 40 N·s was
    given a step forward with certainty, and on the shared walks and runs 62 of 3264 pushes were
    given a class across or against them, most of them a side step for a push from the front
    (docs/measurements.md)."""
    frame = min(round(impact.frame), motion.num_frames - 1)
    heading = float(frame_features(motion.slice(frame, frame + 1), rig).heading[0])
    push = yaw_rotate(-heading, np.array([impact.direction[0], impact.direction[1], 0.0]))[:2]
    if not push.any():  # straight down: no way over the floor
        return frozenset()
    pushed = way(push)
    kept = ("", pushed, "side") if pushed in ("left", "right") else ("", pushed)
    return frozenset(c.slug for c in CLASSES if c.way not in kept)


def _walking(bc: SimResult, impact: Impact, mass: float) -> bool:
    """Whether the character was walking (or running) when hit and the push leaves it walking: its
    centre of mass, unpushed, going faster than WALKING_SPEED over the floor from B to C on the
    mean (a slow walk's pace swings with its steps), and still going that way that fast with the
    push's J / M added. A push the classifier calls a sway or a
    single step then keeps the walk, the hit simulated, rather than playing a clip that starts and
    ends standing. The classes are measured against the unpushed twin, so a walker's single step
    is its next step landing shorter, longer or wider, and it walks on: with the clips, walkers
    nudged from behind stood still and fell up to 29 cm behind their unpushed selves within half a
    second, and 15.8% of non-fall walker reactions on every shared walk stood still for 0.2 s or
    more; with the pace at the hit over 0.6 m/s, the slow walks still played clips and stood, 11.2%
    (docs/measurements.md). A push that stops the walker (120 N·s from the front) plays its
    clip."""
    travel = bc.twin.com_velocity[:, :2].mean(axis=0)
    pace = float(np.linalg.norm(travel))
    if pace <= WALKING_SPEED:
        return False
    return pace + float(impact.impulse[:2] @ travel) / (pace * mass) > WALKING_SPEED


def _gain(bc: SimResult) -> tuple[float, float]:
    """How far the push has moved the body over the floor by C: the pushed centre of mass less its
    unpushed twin's. A kept walk is moved by it, so the walker goes on from where the push put it
    (a walker pushed from behind stays ahead of its unpushed self) instead of being pulled back."""
    gain = bc.com[-1, :2] - bc.twin.com[-1, :2]
    return float(gain[0]), float(gain[1])


def _missing_class(
    library: Library,
    query: Query,
    predicted: str | None,
    verdict: Outcome,
    settings: ReactionSettings,
    off: frozenset[str],
) -> _Choice | None:
    """A push whose class the library lacks: when the outcome rule says it keeps its feet, the
    nearest class the library has that keeps them (NEAR, from the class the push calls for: the
    classifier's, or the rule's when the classifier says fall), else the motion kept. None when the
    rule says it falls (the probable classes the library has are searched, as before). Classes `off`
    the push's way (_off_push) are never among the nearest: the rule reads the walker's own gait
    into its verdict as the classifier does, and a step across a push from behind is no nearer
    than keeping the walk (a sway is never off the push, so one is always left to name)."""
    if verdict.steps is None:  # the rule says it falls: any fall the library has will do
        return None
    wanted = predicted if predicted is not None and not is_fall(predicted) else verdict.reaction
    near = [slug for slug in dict.fromkeys([wanted, *NEAR[wanted], verdict.reaction, *NEAR[verdict.reaction]])
            if slug not in off] or [SWAY]  # fmt: skip
    usable = [slug for slug in near if slug in library.class_ranges]
    why = "the push does not fell the character"
    if usable:
        match = search_with_fallback(library, query, usable, settings.search_threshold)
        lacks = predicted or "step or sway"
        return _Choice(match, f"the library has no {lacks} clips: played {match.reaction_class}, the nearest it "
                              f"has that keeps the feet ({why})")  # fmt: skip
    standing = [slug for slug in library.class_ranges if not is_fall(slug)]
    lacks = (", ".join(near[:-1]) + " or " if len(near) > 1 else "") + near[-1] if standing else "step or sway"
    return _Choice(None, f"the library has no {lacks} clips: kept the original motion, the hit simulated "
                         f"({why})", near[0])  # fmt: skip


def _going_down(
    motion: Motion, bc: SimResult, ragdoll: Ragdoll, impact: Impact, library: Library
) -> tuple[str | None, bool]:
    """The outcome rule's fall when the body is already down at C (a body other than the feet on the
    floor) or going down (low and sinking, outcome.collapsing; or low while the motion it plays goes
    to the floor, _played_down), else None (also when the library has no falls); and whether the
    motion it plays goes to the floor so (an earlier fall still playing). The classifier learnt
    from pushes on walks, runs and stands and has not seen such states: a push during an earlier
    reaction's deep crouch, the hips low and sinking fast, came out a sway with certainty and the
    character stood up out of the collapse (how often: docs/measurements.md, "Limits and rules"); a
    body lying on the floor was given a sway and stood up."""
    if not any(is_fall(slug) for slug in library.class_ranges):
        return None, False
    rig = feature_rig(ragdoll.rig)
    on_floor = np.delete(bc.contacts[-1], foot_bodies(ragdoll)).any()
    low = bc.com[-1][2] - bc.floor < COLLAPSE_HEIGHT * rig.leg_length
    played_down = low and _played_down(motion, int(bc.frames[-1]), rig, bc.floor)
    if not (on_floor or played_down or collapsing(rig, bc.com[-1], bc.com_velocity[-1], bc.floor)):
        return None, False
    return _judge(motion, bc, ragdoll, impact, going_down=played_down).reaction, played_down


def _played_down(motion: Motion, frame_c: int, rig: Rig, floor: float) -> bool:
    """Whether the motion being played sits, kneels or lies within DOWN_AHEAD of C: an earlier
    fall still playing. A push during it lands on a body already low; the ragdoll bouncing off the
    floor in BC can be rising at C (a walk pushed into a backward sit, pushed again as it went
    down: 0.49 m at +0.7 m/s) and was judged a step that stood the falling body up."""
    first = min(frame_c, motion.num_frames - 1)  # C past the motion's end: its last pose holds
    ahead = motion.slice(first, min(first + round(DOWN_AHEAD * motion.fps) + 1, motion.num_frames))
    pelvis = ahead.global_positions()[:, rig.joints["pelvis"], 2]
    return bool(pelvis.min() - floor < DOWN_HEIGHT * rig.leg_length)


def _judge(motion: Motion, bc: SimResult, ragdoll: Ragdoll, impact: Impact, *, going_down: bool = False) -> Outcome:
    """The outcome rule's verdict on the simulated state at C (outcome.judge)."""
    reader = FeatureReader(ragdoll)
    window = (bc.frames[-1] - impact.frame) / motion.fps
    return judge(reader.rig, reader.simulated(motion, bc), window, going_down=going_down)


def _chain(
    out: Motion, casting: Casting, match: Match, rig: Rig, settings: ReactionSettings
) -> tuple[Motion, str | None, list[tuple[int, int]]]:
    """The clip's `next` (a get-up) placed where the reaction ends and faded in; its name and the
    fade's frames [a, b) (none without a get-up)."""
    name = casting.library.clips[match.clip_index].next
    if name is None:
        return out, None, []
    fps = out.fps
    follow = casting.clip(name, fps)
    yaw, offset = _alignment(out.slice(out.num_frames - 1, out.num_frames), follow.slice(0, 1), rig)
    follow = place(follow, yaw, offset)
    overlap = max(1, min(round(settings.chain_blend * fps), follow.num_frames - 1, out.num_frames - 1))
    tail = out.slice(out.num_frames - 1, out.num_frames)
    held = _join(*([tail] * overlap))
    faded = blend(held, follow.slice(0, overlap), fade_weights(overlap))
    start = out.num_frames - 1
    return _join(out.slice(0, start), faded, follow.slice(overlap, follow.num_frames)), name, [(start, start + overlap)]


def _still_from(library: Library, clip_index: int, fps: float) -> int:
    """The frame (at `fps`) where the reaction ends: the clip's still tail (search_index.window_limits)
    kept for STILL_KEPT, then the motion resumes or the get-up begins (the sample step clips stand
    still for 2 s after recovering: a walker stood as long before walking on)."""
    still = int(library.search_index().limits[clip_index])
    return round(still / library.fps * fps) + round(STILL_KEPT * fps)


def _resume_or_hold(
    out: Motion, source: Motion, first: int, window: int, rig: Rig, earliest: int | None = None
) -> tuple[Motion, int | None, list[tuple[int, int]]]:
    """Resume the source over a fade of resume_fade_frames (`window` frames or more, computed here and
    passed to _resume; `window` 0: do not resume, as after a fall with nothing chained) that starts
    at a frame from `earliest` on (default: the last `window` frames of `out`; see _resume),
    re-entering at a source frame from `first` to the fade's start (the resumed motion stays near
    the timeline's own time: a walk repeats within a second, and later markers still land where the
    animator put them) and leaving the source two fades' frames to play; else hold the last pose.
    Either way the result runs at least to the source's end. Also returns the source's frame it
    re-entered at (None: held) and the fade's frames [a, b) (none when held)."""
    earliest = out.num_frames - window if earliest is None else max(0, min(earliest, out.num_frames - window))
    resumed_at, fades = None, []
    fade = resume_fade_frames(window, out.fps)
    latest_entry = min(source.num_frames - RESUME_LEFT * fade, out.num_frames - window)
    if window and latest_entry > first:
        out, resumed_at, faded = _resume(out, source, first, window, fade, rig, earliest)
        fades = [faded]
    missing = source.num_frames - out.num_frames  # a bake never shortens the action
    if missing > 0:
        hold = out.slice(out.num_frames - 1, out.num_frames)
        out = _join(out, *([hold] * missing))
    return out, resumed_at, fades


def _resume(
    out: Motion, source: Motion, first: int, window: int, fade: int, rig: Rig, earliest: int
) -> tuple[Motion, int, tuple[int, int]]:
    """The source's best re-entry window (Eq. 1, at source frames from `first` to the fade's start)
    aligned with `out`'s `window` frames from the best fade start (from `earliest` to the last
    `window` frames), faded in from there over `fade` frames (resume_fade_frames; the pelvis'
    travel over `window` frames: blend_travel) and played on. The fade
    start weighs in: each second the reaction goes on past `earliest` costs RESUME_WAIT (a pushed
    walker whose step has landed walks on rather than standing through the clip's recovery, while
    a stand resumes where the clip has come to rest, which matches it far better). Starts and
    entries are tried every `stride` frames (about RESUME_RATE a second: a 120 fps take would
    otherwise try 16 times as many pairs), starts only within RESUME_SEARCH of `earliest` (waiting
    longer costs more than the re-entries' Eq. 1 costs differ). No re-entry is later than the
    fade's start: the result is the output up to the start and the source from the entry on, so a
    re-entry ahead runs the source out that much before the action ends, and its last pose was held
    there (a runner froze mid-stride, a toe stopped dead at 257 m/s^2). Returns the motion, the
    source frame re-entered at and the fade's frames [start, end)."""
    stride = max(1, round(out.fps / RESUME_RATE))
    span = max(2, round(window / stride))
    latest = min(out.num_frames - window, earliest + round(RESUME_SEARCH * out.fps))
    stop = min(source.num_frames, latest + (span + 1) * stride)  # a window from the latest re-entry
    tails = frame_features(out.slice(earliest, latest + window), rig).rows(slice(None, None, stride))
    candidates = frame_features(source.slice(first, stop), rig).rows(slice(None, None, stride))
    wp, wq = joint_weights(TABLE2_POSITION_WEIGHTS), joint_weights(TABLE2_ROTATION_WEIGHTS)
    windows = Windows.of(candidates, np.arange(max(0, candidates.num_frames - span + 1)), span)
    tried: list[tuple[float, int, int]] = [(np.inf, out.num_frames - window, first)]
    for k in range((latest - earliest) // stride + 1):
        start = earliest + k * stride
        wait = RESUME_WAIT * (start - earliest) / out.fps
        if wait >= min(tried)[0]:
            break  # Eq. 1 costs are never negative: no later start can win
        query = Query(tails.rows(slice(k, k + span)))
        last = min(source.num_frames - RESUME_LEFT * fade, start)  # leaving the source RESUME_LEFT fades
        entries = min((last - first) // stride + 1, candidates.num_frames - span + 1)
        if entries <= 0 or query.window < span:
            continue
        costs = windows.costs(query, wp, wq, entries)
        j = int(np.argmin(costs))
        tried.append((float(costs[j]) + wait, start, first + j * stride))
    _, begin, entry = min(tried)  # on an exact tie, the earliest start and re-entry
    tail = out.frames(begin, fade)
    yaw, offset = _alignment(tail.slice(0, 1), source.slice(entry, entry + 1), rig)
    resumed = place(source.slice(entry, source.num_frames), yaw, offset)
    pelvis = rig.joint("pelvis")
    pace = np.concatenate([fade_weights(window), np.ones(fade - window)])
    faded, carried = blend_travel(tail, resumed.frames(0, fade), fade_weights(fade), pelvis, pace)
    rest = place(resumed.slice(min(fade, resumed.num_frames), resumed.num_frames), 0.0, carried)
    return _join(out.slice(0, begin), faded, rest), entry, (begin, begin + fade)


# ---------------------------------------------------------------------------------------------
# Helpers


def _calm_end(clip: Motion, frame_e: int, shortest: int, longest: int, rig: Rig) -> int:
    """The transition's length in frames, from `shortest` to `longest`, that ends it (F) where the
    clip's pelvis accelerates least over F and the frames either side of it (on a tie, the
    shortest): a fade into a fall that ends as the body lands on the floor hands the seam the
    landing's jolt (ReactionSettings.fall_transition). Frames past the clip's end are not tried.
    Measured over a 1/30 s stride (model/acceleration.py), as the seams are judged, at any rate."""
    stride = stride_frames(clip.fps)
    longest = min(longest, clip.num_frames - 2 - stride - frame_e)
    first = frame_e + shortest - 1 - stride  # a stride before F - 1 at the shortest
    if longest <= shortest or first < 0:
        return shortest
    pelvis = clip.slice(first, frame_e + longest + 2 + stride).global_positions()[:, [rig.joint("pelvis")]]
    jolt = accelerations(pelvis, clip.fps)[stride:-stride, 0]  # F - 1 (shortest) .. F + 1 (longest)
    around = np.lib.stride_tricks.sliding_window_view(jolt, 3).max(axis=1)  # per F, shortest .. longest
    return shortest + int(np.argmin(around))


def resume_fade_frames(window: int, fps: float) -> int:
    """The resume's fade in frames: RESUME_FADE, or the re-entry's Eq. 1 window (`window` frames)
    if that is longer."""
    return max(window, round(RESUME_FADE * fps))


def _alignment(anchor: Motion, moving: Motion, rig: Rig) -> tuple[float, tuple[float, float]]:
    """(yaw, offset) that put the first frame of `moving` on the first frame of `anchor`: same
    pelvis ground point and heading (window.py's heading frame)."""
    a, m = frame_features(anchor.slice(0, 1), rig), frame_features(moving.slice(0, 1), rig)
    yaw = float(a.heading[0] - m.heading[0])
    offset = a.ground[0] - yaw_rotate(yaw, np.append(m.ground[0], 0.0))[:2]
    return yaw, (float(offset[0]), float(offset[1]))


def _join(*parts: Motion) -> Motion:
    out = parts[0]
    for part in parts[1:]:
        if part.num_frames:
            out = out.concat(part)
    return out
