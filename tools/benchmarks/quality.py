"""Believability: reactions an animator would keep, each figure beside the same measure on real
capture and its goal (../shared/DESIGN.md, "Tests and benchmarks"; the measures are tools/devkit/believability.py).

Pushes: on the shared walks, runs and idles (../shared/mocap, every rig; test and benchmark data
only), on the chest and the pelvis, from behind, the front, the left and the right (horizontal,
relative to the facing at the impact), at 40, 120 and 300 N·s, each baked alone (core.react, the
sample library, the shipped classifier) at IMPACT_AT of the take. The default run takes SAMPLE (a
few takes per rig); `--full` every walk, run and idle of at least MIN_TAKE seconds. Idles: Bandai
Namco's respond_normal_001 (standing) and CMU 90_16's first two seconds (standing, before its stunt).

Per reaction, over its window (the impact B to the end of the reaction + AFTER seconds), against real
capture: the same take unpushed over the same frames (moved back to fit, or its skid scaled to the
window's length on a take shorter than the window), the real takes of the same rig (the same joints;
Bandai Namco's two datasets are one rig, CMU via iClone two) and the real CMU falls, get-ups and
stumble (../shared/mocap/cmu). All references are computed over every shared take, sample or full.

Contact sheets of the WORST reactions by each measure go to out/quality/<measure>.png (a row per
reaction: FRAMES frames from B to the window's end, each a side view, the character facing right
at B, and a front view; left limbs blue, right red, trunk black, the unpushed take light grey, joints
under the floor magenta, the push a green line at B, the frame where the measure peaks framed in
orange), each with a .txt saying which reaction is on each row.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model import bvh
from reactive_anim.core.model.classes import is_fall
from reactive_anim.core.model.errors import ReactiveAnimError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.model.skeleton import Motion, root_child
from reactive_anim.core.physics.ragdoll import Ragdoll
from reactive_anim.core.physics.workspace import Workspace
from reactive_anim.core.react import (
    Reaction,
    ReactionClassifier,
    ReactionSettings,
    character_ragdoll,
    react,
    resume_fade_frames,
)
from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.transition.casting import Casting
from reactive_anim.core.transition.ik import joint_path
from tools.devkit import believability as bl
from tools.devkit.mocap import MOCAP, REPO, mocap_files
from tools.devkit.poses import ground_axes
from tools.sample_clips.sheets import draw_line, png_bytes

from .common import report, skipped

GROUP = "quality"
OUT = REPO / "out" / "quality"
BONES = ("chest", "pelvis")
PUSH_SIDES = ("behind", "front", "left", "right")
STRENGTHS = (40.0, 120.0, 300.0)  # N·s
IMPACT_AT = (0.35, 0.65)  # of the take's frames
AFTER = 0.5  # s of the window after the reaction's end
MOMENTUM_AT = 0.5  # s after the impact
MIN_TAKE = 1.2  # s: shorter takes (Bandai's 0.7-1 s dash, run and walk takes) leave no room around the pushes
WORST = 3
FRAMES = 8
CELL = (130, 190)  # width, height of one view, pixels
SCALE = 85.0  # pixels per metre
# The default run: a few takes per rig (relative to ../shared/mocap; frames: [start, stop) used).
SAMPLE = (
    "bandai_namco/dataset-1/dataset-1_walk_normal_001.bvh",
    "bandai_namco/dataset-1/dataset-1_walk-left_normal_001.bvh",
    "bandai_namco/dataset-2/dataset-2_walk_normal_002.bvh",
    "bandai_namco/dataset-1/dataset-1_run_sad_001.bvh",
    "bandai_namco/dataset-2/dataset-2_run_exhausted_001.bvh",
    "bandai_namco/dataset-1/dataset-1_respond_normal_001.bvh",
    "cmu_iclone/002_01.bvh",
    "cmu_iclone/007_01.bvh",
    "cmu_iclone/007_12.bvh",
    "cmu_iclone/002_03.bvh",
    "cmu/90_16.bvh",
)
IDLE_FRAMES = {"cmu/90_16.bvh": (1, 241)}  # stands for 2.2 s, then leaps into its fall
GOALS = {
    "skid_median": 1.2,  # x the real takes' median
    "skid_p90": 1.5,
    "fade_slide": 0.05,  # m, any one fade, any foot
    "depth": 0.03,  # m
    "seam_share": 0.95,
    "ahead_share": 0.95,
    "still_share": 0.10,
    "over_walks_share": 0.10,
    "direction_40": 0.98,
    "direction_120": 1.0,
    "median_ms": 60.0,
    "p99_ms": 150.0,
}

FULL = False  # set by `tools/bench.py quality --full`


@dataclass
class Take:
    """A shared BVH file (or a part of one) and what it shows."""

    rel: str  # path under ../shared/mocap
    kind: str  # walk, run, idle, or other (a reference only: falls, strikes, jumps)
    frames: tuple[int, int] | None = None

    @property
    def name(self) -> str:
        return Path(self.rel).stem + ("" if self.frames is None else f"[{self.frames[0]}:{self.frames[1]}]")

    def motion(self) -> Motion:
        motion = bvh.read_bvh(MOCAP / self.rel)
        return motion if self.frames is None else motion.slice(*self.frames)


def take_kind(rel: str) -> str:
    """walk, run, idle or other, by file name (README of ../shared/mocap)."""
    stem = Path(rel).stem
    if rel in IDLE_FRAMES or "_respond_" in stem:
        return "idle"
    if rel.startswith("cmu_iclone/"):
        return {"002_01": "walk", "007_01": "walk", "007_12": "walk", "002_03": "run"}.get(stem, "other")
    if rel.startswith("bandai_namco/"):
        content = stem.split("_")[1]
        return "walk" if content.startswith("walk") else "run" if content in ("run", "dash") else "other"
    return "other"


def all_takes() -> list[Take]:
    """Every shared file as a take (CMU 90_16 twice: whole, a fall, and its standing start, an idle)."""
    takes = []
    for path in mocap_files():
        rel = path.relative_to(MOCAP).as_posix()
        if rel in IDLE_FRAMES:
            takes.append(Take(rel, "other"))
        takes.append(Take(rel, take_kind(rel), IDLE_FRAMES.get(rel)))
    return takes


def rig_of(motion: Motion, rel: str) -> str:
    """A rig: the source folder and the joint count (Bandai Namco's datasets share names; CMU via
    iClone has two layouts)."""
    return f"{rel.split('/')[0]} ({motion.skeleton.num_joints} joints)"


@dataclass
class Real:
    """One real take: its profile and what it is."""

    take: Take
    rig: str
    motion: Motion
    roles: dict[str, str]
    floor: float
    profile: bl.Profile


@dataclass
class References:
    """What real capture gives each measure (see the module docstring)."""

    takes: dict[str, Real]
    falls_accel: float  # largest body-joint acceleration in the real CMU falls, get-ups, stumble
    walks_accel: dict[str, float]  # rig -> largest in its real walks
    pelvis_p99: float  # pelvis acceleration, p99 over the real walks and runs
    largest_move: dict[tuple[str, int], float]  # (rig, fps) -> largest one-frame body-joint move
    fade_slide: dict[tuple[str, int], tuple[float, float]] = field(default_factory=dict)  # see fade_slide_reference


def references() -> References:
    """Every shared take's profile and the pooled references."""
    takes: dict[str, Real] = {}
    for take in all_takes():
        motion = take.motion()
        roles = character_ragdoll(motion).roles
        floor = bl.lowest_floor(motion, roles)
        takes[take.name] = Real(take, rig_of(motion, take.rel), motion, roles, floor, bl.profile(motion, roles, floor))
    falls = [r for r in takes.values() if r.take.rel.startswith("cmu/") and r.take.kind == "other"]
    walks: dict[str, float] = {}
    for r in takes.values():
        if r.take.kind == "walk":
            walks[r.rig] = max(walks.get(r.rig, 0.0), float(np.nanmax(r.profile.accel)))
    pelvis = np.concatenate([r.profile.pelvis_accel for r in takes.values() if r.take.kind in ("walk", "run")])
    moves: dict[tuple[str, int], float] = {}
    for r in takes.values():
        key = (r.rig, round(r.motion.fps))
        moves[key] = max(moves.get(key, 0.0), float(np.nanmax(r.profile.move)))
    return References(
        takes=takes,
        falls_accel=max(float(np.nanmax(r.profile.accel)) for r in falls),
        walks_accel=walks,
        pelvis_p99=bl.quantile(pelvis, 0.99),
        largest_move=moves,
    )


def fade_slide_reference(refs: References, rig: str, frames: int) -> tuple[float, float]:
    """How far a foot planted at a frame slides within the next `frames` frames in the rig's real
    walks, runs and idles (believability.planted_slides over every frame and foot): p99 and largest."""
    key = (rig, frames)
    if key not in refs.fade_slide:
        slides = [
            bl.planted_slides(skid := r.profile.skid[:, k], down := r.profile.down[:, k], frames, r.profile.fps)[
                bl.planted(skid, down, r.profile.fps)
            ]
            for r in refs.takes.values() if r.rig == rig and r.take.kind != "other" for k in range(2)
        ]  # fmt: skip
        pooled = np.concatenate(slides) if slides else np.zeros(1)
        refs.fade_slide[key] = (bl.quantile(pooled, 0.99), float(pooled.max()))
    return refs.fade_slide[key]


@dataclass
class Pushing:
    """What reacting on one take needs, built once per take."""

    real: Real
    library: Library
    classifier: ReactionClassifier | None
    casting: Casting
    ragdoll: Ragdoll
    workspace: Workspace

    @classmethod
    def on(cls, real: Real, library: Library, classifier: ReactionClassifier | None) -> Pushing:
        ragdoll = character_ragdoll(real.motion)
        casting = Casting.between(real.motion, ragdoll.rig, library)
        return cls(real, library, classifier, casting, ragdoll, Workspace(ragdoll))

    def impact(self, frame: int, bone: str, side: str, strength: float) -> Impact:
        forward, left = ground_axes(self.real.motion, frame, self.real.roles)
        direction = {"behind": forward, "front": -forward, "left": -left, "right": left}[side]
        return Impact(float(frame), self.real.roles[bone], tuple(direction), strength)

    def react(self, impact: Impact) -> Reaction:
        return react(self.real.motion, impact, self.library, self.classifier, ragdoll=self.ragdoll,
                     workspace=self.workspace, casting=self.casting)  # fmt: skip

    def seams(self, reaction: Reaction) -> dict[str, int]:
        fps = self.real.motion.fps
        settings = ReactionSettings()
        window = max(2, round(self.library.window * fps / self.library.fps))
        getup, fade = None, 0
        if reaction.chained is not None:
            getup = self.casting.clip(reaction.chained, fps).num_frames
            fade = max(1, min(round(settings.chain_blend * fps), getup - 1))
        return bl.reaction_seams(reaction, resume_fade_frames(window, fps), getup, fade, window)


def window_of(reaction: Reaction, fps: float, frames: int) -> tuple[int, int]:
    """The reaction's window [a, b): the impact to the end of the reaction + AFTER (within the output)."""
    a = int(np.ceil(reaction.frame_b))
    return a, min(reaction.end_frame + round(AFTER * fps) + 1, frames)


def real_window(real: bl.Profile, a: int, b: int) -> tuple[int, int, float]:
    """The unpushed take's frames for a window [a, b) and the factor its skid is scaled by: the same
    frames, moved back to fit the take, or the whole take scaled to the window's length."""
    n, length = real.num_frames, b - a
    if b <= n:
        return a, b, 1.0
    if length <= n - real.start:
        return n - length, n, 1.0
    return real.start, n, (length - 1) / max(n - real.start - 1, 1)


def measure(
    push: Pushing, refs: References, impact: Impact, side: str, bone: str, reaction: Reaction, warm: bool
) -> dict:
    """One reaction's figures (see the module docstring) and the frames where each peaks; warm: its
    clips were cast onto the rig by an earlier reaction (a first use retargets them)."""
    real, out = push.real, reaction.motion
    assert out is not None
    fps, n_out = out.fps, out.num_frames
    a, b = window_of(reaction, fps, n_out)
    s = bl.stride_frames(fps)
    lo, hi = max(a - s - 2, 0), min(b + s + 2, n_out)
    prof = bl.profile(out.slice(lo, hi), real.roles, real.floor, start=0)
    hit = bl.hit_mask(prof.num_frames, reaction.frame_b - lo, fps)
    ra, rb, scale = real_window(real.profile, a, b)
    seams = push.seams(reaction)
    fades = [(reaction.frame_c, reaction.frame_f + 1)]
    if "get-up end" in seams:
        fades.append((seams["get-up start"], seams["get-up end"]))
    if "resume start" in seams:
        fades.append((seams["resume start"], seams["resume end"]))
    phases = skid_phases(prof, a, b, lo, reaction, seams)
    steps = prof.skid[a - lo + 1 : b - lo].sum(axis=1)
    skid_at = a + 1 + int(np.argmax(steps)) if len(steps) else a
    fade_slides = [
        max(bl.planted_slide(prof.skid[:, k], prof.down[:, k], fa - lo, fb - lo, fps) for k in range(2))
        for fa, fb in fades
    ]
    accel, accel_at = prof.largest(prof.accel, a - lo, b - lo, hit)
    depth, depth_at = prof.largest(prof.depth, a - lo, b - lo)
    seam_rows = {}
    for name, f in seams.items():
        pel, pel_at = prof.largest(prof.pelvis_accel, f - 1 - lo, f + 2 - lo)
        move, move_at = prof.largest(prof.move, f - 1 - lo, f + 3 - lo)
        seam_rows[name] = {"pelvis_accel": pel, "at": pel_at + lo, "move": move, "move_at": move_at + lo}
    move_any, move_any_at = prof.largest(prof.move, a - lo, b - lo, hit)
    k = round(reaction.frame_b + MOMENTUM_AT * fps)
    ahead = float("nan")
    if k < real.profile.num_frames and k < hi:
        ahead = bl.ahead(prof.pelvis[k - lo], real.profile.pelvis[k], np.asarray(impact.direction))
    speed = prof.speed[a - lo : b - lo]
    still = bl.longest_still(speed, fps)
    still_at = a + int(np.nanargmin(np.where(np.isnan(speed), np.inf, speed))) if len(speed) else a
    return {
        "take": real.take.name, "kind": real.take.kind,
        "rig": real.rig, "fps": round(fps), "frame": int(impact.frame), "bone": bone, "side": side,
        "strength": impact.strength, "class": reaction.reaction_class, "clip": reaction.clip,
        "window": (a, b), "skid": float(prof.skid_in(a - lo, b - lo).sum()), "skid_at": skid_at,
        "skid_phases": phases, "real_skid": float(real.profile.skid_in(ra, rb).sum() * scale),
        "fade_slide": max(fade_slides), "fade_slides": fade_slides, "fade_at": fades[int(np.argmax(fade_slides))][0],
        "depth": depth, "depth_at": depth_at + lo,
        "real_depth": real.profile.largest(real.profile.depth, ra, rb)[0],
        "real_accel": real.profile.largest(real.profile.accel, ra, rb)[0],
        "accel": accel, "accel_at": accel_at + lo, "seams": seam_rows,
        "move_any": move_any, "move_any_at": move_any_at + lo,
        "ahead": ahead, "ahead_at": k, "still": still, "still_at": still_at,
        "real_still": bl.longest_still(real.profile.speed[ra:rb], fps),
        "right_direction": bl.right_direction(side, reaction.reaction_class),
        "predicted_right": reaction.predicted is None or bl.right_direction(side, reaction.predicted),
        "ms": reaction.timings.get("total", float("nan")) * 1e3, "warm": warm,
    }  # fmt: skip


def skid_phases(prof: bl.Profile, a: int, b: int, lo: int, reaction: Reaction, seams: dict[str, int]) -> dict:
    """The window's foot skid split where its sources meet: the hit to C (BC), C to F (the
    transition), F to the resume's fade or the reaction's end (the clip, a chained get-up in it), the
    resume's fade, and what follows (the take resumed, or the held last frame)."""
    cuts = [("BC", a), ("C-F", reaction.frame_c), ("clip", reaction.frame_f)]
    if "resume start" in seams:
        cuts += [("resume", seams["resume start"]), ("after", seams["resume end"])]
    else:
        cuts.append(("after", reaction.end_frame + 1))
    bounds = [min(max(f, a), b - 1) for _, f in cuts] + [b - 1]
    steps = prof.skid.sum(axis=1)  # steps[i]: the travel into frame i; a phase [x, y) takes those into x + 1 .. y
    return {
        name: float(steps[x + 1 - lo : y + 1 - lo].sum())
        for (name, _), x, y in zip(cuts, bounds, bounds[1:], strict=False)
    }


def push_grid(real: Real) -> list[tuple[int, str, str, float]]:
    """(frame, bone, side, strength) of every push on a take."""
    n = real.motion.num_frames
    frames = sorted({round(f * (n - 1)) for f in IMPACT_AT})
    return [(f, bone, side, s) for f in frames for bone in BONES for side in PUSH_SIDES for s in STRENGTHS]


def pushed_takes(refs: References) -> list[Real]:
    """The takes pushed: SAMPLE, or with FULL every walk, run and idle of at least MIN_TAKE seconds."""
    chosen = []
    for key, real in refs.takes.items():
        if real.take.kind not in ("walk", "run", "idle") or real.motion.num_frames / real.motion.fps < MIN_TAKE:
            continue
        if FULL or real.take.rel in SAMPLE:
            chosen.append(refs.takes[key])
    return chosen


# ---------------------------------------------------------------------------------------------
# Figures


@dataclass
class Row:
    measure: str
    figure: str
    value: str
    real: str
    goal: str
    met: bool | None


def table_adder(out: list[Row], group: str) -> Callable[..., None]:
    """add(measure, figure, value, unit, real, goal, met, **context): a row of `out` for the table,
    also reported as the group's JSON line."""

    def add(
        measure: str, figure: str, value: float | np.floating, unit: str, real: str, goal: str,
        met: bool | np.bool_ | None, **ctx,
    ):  # fmt: skip
        shown = f"{value:.1f} %" if unit == "%" else f"{value:.3g} {unit}"
        if float(value).is_integer():
            shown = f"{int(value)} {unit}"
        met = None if met is None else bool(met)
        out.append(Row(measure, figure, shown, real, goal, met))
        report(group, f"{measure}: {figure}", float(value), unit, real=real, goal=goal, met=met, **ctx)

    return add


def figures(rows: list[dict], refs: References, failures: int) -> list[Row]:
    """The table's rows (each also reported as a JSON line)."""
    out: list[Row] = []
    add = table_adder(out, GROUP)

    n = len(rows)
    add("reactions", "reactions measured", n, "reactions", "-", "-", None, failed=failures,
        takes=len({r["take"] for r in rows}), full=FULL)  # fmt: skip
    skid, real_skid = [r["skid"] for r in rows], [r["real_skid"] for r in rows]
    for q, goal in ((0.5, GOALS["skid_median"]), (0.9, GOALS["skid_p90"])):
        v, rv = bl.quantile(skid, q) * 100, bl.quantile(real_skid, q) * 100
        add("foot skid", f"p{round(q * 100)} per reaction (both feet)", v, "cm", f"{rv:.3g} cm",
            f"<= {goal}x real", v <= goal * rv, ratio=round(v / rv, 2) if rv else None)  # fmt: skip
    for rig in sorted({r["rig"] for r in rows}):
        sub = [r for r in rows if r["rig"] == rig]
        v, rv = bl.quantile([r["skid"] for r in sub], 0.5) * 100, bl.quantile([r["real_skid"] for r in sub], 0.5) * 100
        add("foot skid", f"median, {rig}", v, "cm", f"{rv:.3g} cm", f"<= {GOALS['skid_median']}x real",
            v <= GOALS["skid_median"] * rv, reactions=len(sub))  # fmt: skip
    for phase in ("BC", "C-F", "clip", "resume", "after"):
        part = [r["skid_phases"][phase] for r in rows if phase in r["skid_phases"]]
        add("foot skid", f"median in the phase {phase} (of reactions that have it)", bl.quantile(part, 0.5) * 100,
            "cm", "-", "-", None, reactions=len(part), total_m=round(float(np.sum(part)), 1))  # fmt: skip
    slides = [s for r in rows for s in r["fade_slides"]]
    over = sum(s > GOALS["fade_slide"] for s in slides)
    real_slide = [fade_slide_reference(refs, rig, round(ReactionSettings().transition * fps) + 1)
                  for rig, fps in sorted({(r["rig"], r["fps"]) for r in rows})]  # fmt: skip
    add("foot skid", "largest slide of a planted foot in one fade", max(slides) * 100, "cm",
        "p99 " + "/".join(f"{p * 100:.2g}" for p, _ in real_slide) + " cm by rig", "<= 5 cm",
        max(slides) <= GOALS["fade_slide"],
        fades=len(slides), fades_over_5cm=over, real_largest_cm=[round(m * 100, 1) for _, m in real_slide],
        rigs=sorted({(r["rig"], r["fps"]) for r in rows}),
        p90_cm=round(bl.quantile(slides, 0.9) * 100, 1))  # fmt: skip
    add("foot skid", "fades sliding a planted foot over 5 cm", 100 * over / len(slides), "%", "-", "0 %", over == 0,
        fades=len(slides))  # fmt: skip
    depth = [r["depth"] for r in rows]
    add("depth", "deepest joint or end site under the floor", max(depth) * 100, "cm",
        f"{np.nanmax([r['real_depth'] for r in rows]) * 100:.3g} cm", "<= 3 cm", max(depth) <= GOALS["depth"],
        over_3cm=sum(d > GOALS["depth"] for d in depth), p99_cm=round(bl.quantile(depth, 0.99) * 100, 2))  # fmt: skip
    accel = [r["accel"] for r in rows]
    add("acceleration", "largest body joint, hit left out", float(np.nanmax(accel)), "m/s^2",
        f"{refs.falls_accel:.4g} (CMU falls)", "<= real falls", float(np.nanmax(accel)) <= refs.falls_accel,
        over=sum(a > refs.falls_accel for a in accel), p99=round(bl.quantile(accel, 0.99), 1))  # fmt: skip
    all_walks = max(refs.walks_accel.values())
    light = [r for r in rows if r["strength"] == STRENGTHS[0]]
    above = [r["accel"] > refs.walks_accel.get(r["rig"], all_walks) for r in light]
    walks_text = ", ".join(f"{v:.0f}" for v in sorted(refs.walks_accel.values()))
    add("acceleration", "40 N·s reactions above the rig's real walks' largest", 100 * np.mean(above), "%",
        f"walks' largest {walks_text} m/s^2", "<= 10 %", np.mean(above) <= GOALS["over_walks_share"],
        reactions=len(light))  # fmt: skip
    for kind in sorted({r["kind"] for r in light}):
        of_kind = [r for r in light if r["kind"] == kind]
        limit = [refs.walks_accel.get(r["rig"], all_walks) for r in of_kind]
        share = np.mean([r["accel"] > w for r, w in zip(of_kind, limit, strict=True)])
        real_share = np.mean([r["real_accel"] > w for r, w in zip(of_kind, limit, strict=True)])
        add("acceleration", f"  on {kind}s", 100 * share, "%", f"{100 * real_share:.1f} % (same windows unpushed)",
            "(context)", None, reactions=len(of_kind))  # fmt: skip
    seam_values = [(name, s) for r in rows for name, s in r["seams"].items()]
    within = [s["pelvis_accel"] <= refs.pelvis_p99 for _, s in seam_values if np.isfinite(s["pelvis_accel"])]
    kinds = {}
    for name, s in seam_values:
        if np.isfinite(s["pelvis_accel"]):
            kinds.setdefault(name, []).append(s["pelvis_accel"] <= refs.pelvis_p99)
    add("seams", "pelvis acceleration within a frame of a seam under real p99", 100 * np.mean(within), "%",
        f"p99 {refs.pelvis_p99:.3g} m/s^2 (walks, runs)", ">= 95 %", np.mean(within) >= GOALS["seam_share"],
        seams=len(within), by_seam={k: f"{100 * np.mean(v):.0f}% of {len(v)}" for k, v in kinds.items()})  # fmt: skip
    for name in kinds:
        add("seams", f"  at {name}", 100 * np.mean(kinds[name]), "%", f"p99 {refs.pelvis_p99:.3g} m/s^2",
            ">= 95 %", np.mean(kinds[name]) >= GOALS["seam_share"], seams=len(kinds[name]))  # fmt: skip
    over_move = [
        (s["move"], refs.largest_move[(r["rig"], r["fps"])]) for r in rows for s in r["seams"].values()
        if np.isfinite(s["move"])
    ]  # fmt: skip
    worst = max(over_move, key=lambda m: m[0] / m[1])
    moves_text = ", ".join(f"{v * 100:.3g}" for v in sorted(set(refs.largest_move.values())))
    add("seams", "seams with a one-frame joint move over the rig's real largest", sum(m > rm for m, rm in over_move),
        "seams", f"largest {moves_text} cm (per rig, fps)", "0", all(m <= rm for m, rm in over_move),
        of=len(over_move), worst_cm=round(worst[0] * 100, 1), worst_real_cm=round(worst[1] * 100, 1))  # fmt: skip
    any_move = [(r["move_any"], refs.largest_move[(r["rig"], r["fps"])]) for r in rows]
    add("seams", "reactions with any such move (hit left out)", sum(m > rm for m, rm in any_move), "reactions",
        "-", "(context)", None, of=len(any_move))  # fmt: skip
    behind = [r for r in rows if r["kind"] == "walk" and r["side"] == "behind" and np.isfinite(r["ahead"])]
    if behind:
        share = np.mean([r["ahead"] > 0 for r in behind])
        add("momentum", "walkers pushed from behind ahead of unpushed at B + 0.5 s", 100 * share, "%",
            "0 cm (itself)", ">= 95 %", share >= GOALS["ahead_share"], reactions=len(behind),
            median_cm=round(bl.quantile([r["ahead"] for r in behind], 0.5) * 100, 1))  # fmt: skip
    steps = [r for r in rows if r["kind"] == "walk" and not is_fall(r["class"])]
    if steps:
        share = np.mean([r["still"] >= bl.STILL_TIME for r in steps])
        real_share = np.mean([r["real_still"] >= bl.STILL_TIME for r in steps])
        add("momentum", "non-fall walker reactions standing still >= 0.2 s", 100 * share, "%",
            f"{100 * real_share:.1f} % (same windows unpushed)", "<= 10 %", share <= GOALS["still_share"],
            reactions=len(steps), median_still_s=round(bl.quantile([r["still"] for r in steps], 0.5), 2))  # fmt: skip
    for strengths, goal, label in (
        ((40.0,), GOALS["direction_40"], "40"),
        ((120.0, 300.0), GOALS["direction_120"], "120+"),
    ):
        sub = [r for r in rows if r["strength"] in strengths and r["side"] in ("behind", "front")]
        share = np.mean([r["right_direction"] for r in sub])
        add("class sense", f"front/back pushes the right way, {label} N·s", 100 * share, "%", "-",
            f">= {goal * 100:.0f} %", share >= goal, reactions=len(sub))  # fmt: skip
    off = [r for r in rows if not r["predicted_right"]]
    add("class sense", "the classifier's first class off the push (left out, the animator told)",
        100 * len(off) / len(rows), "%", "-", "(context)", None, reactions=len(off), of=len(rows))  # fmt: skip
    side = [r for r in rows if r["side"] in ("left", "right")]
    share = np.mean([r["right_direction"] for r in side])
    classes = {}
    for r in side:
        classes[r["class"]] = classes.get(r["class"], 0) + 1
    add("class sense", "side pushes given a side reaction (or a sway)", 100 * share, "%", "-", "100 %",
        share >= 1.0, reactions=len(side), classes=classes)  # fmt: skip
    ms, warm = [r["ms"] for r in rows], [r["ms"] for r in rows if r["warm"]]
    add("time", "per impact, median", bl.quantile(ms, 0.5), "ms", "-", "<= 60 ms",
        bl.quantile(ms, 0.5) <= GOALS["median_ms"], warm_median=round(bl.quantile(warm, 0.5), 1))  # fmt: skip
    add("time", "per impact, p99", bl.quantile(ms, 0.99), "ms", "-", "<= 150 ms",
        bl.quantile(ms, 0.99) <= GOALS["p99_ms"])  # fmt: skip
    add("time", "per impact, p99, clips already cast onto the rig", bl.quantile(warm, 0.99), "ms", "-", "(context)",
        None, reactions=len(warm))  # fmt: skip
    return out


def print_rows(rows: list[Row]) -> None:
    print()
    print(f"{'measure':13s} {'figure':62s} {'value':>12s}  {'real capture':34s} {'goal':16s} met")
    for r in rows:
        met = "-" if r.met is None else ("yes" if r.met else "NO")
        print(f"{r.measure:13s} {r.figure:62s} {r.value:>12s}  {r.real:34s} {r.goal:16s} {met}")
    print()


# ---------------------------------------------------------------------------------------------
# Contact sheets

SHEETS = {  # measure: (key in a row, larger is worse, frame key, only rows for which it applies)
    "foot_skid": ("skid", True, "skid_at", None),
    "fade_slide": ("fade_slide", True, "fade_at", None),
    "depth": ("depth", True, "depth_at", None),
    "acceleration": ("accel", True, "accel_at", None),
    "seam_pelvis": ("seam_pelvis", True, "seam_at", None),
    "seam_move": ("seam_move", True, "seam_move_at", None),
    "momentum": ("ahead", False, "ahead_at", lambda r: r["kind"] == "walk" and r["side"] == "behind"),
    "standing_still": ("still", True, "still_at", lambda r: r["kind"] == "walk" and not is_fall(r["class"])),
    "class_sense": ("wrong", True, "frame", None),
}


def _sheet_keys(row: dict) -> None:
    """Per-row values the sheets rank by: the worst seam, a wrong direction."""
    seam = max(row["seams"].values(), key=lambda s: -np.inf if np.isnan(s["pelvis_accel"]) else s["pelvis_accel"])
    row["seam_pelvis"], row["seam_at"] = seam["pelvis_accel"], seam["at"]
    mv = max(row["seams"].values(), key=lambda s: -np.inf if np.isnan(s["move"]) else s["move"])
    row["seam_move"], row["seam_move_at"] = mv["move"], mv["move_at"]
    row["wrong"] = 0.0 if row["right_direction"] else row["strength"]


@dataclass
class Posed:
    """What a stick figure is drawn from: joint positions (T, J, 3), end sites (T, E, 3) and the
    joint each hangs from, the skeleton's parents."""

    pos: np.ndarray
    tips: np.ndarray
    tip_joints: np.ndarray
    parents: np.ndarray
    ground_root: bool

    @classmethod
    def of(cls, motion: Motion) -> Posed:
        pos, rot = motion.global_transforms()
        joints = np.array(list(motion.skeleton.end_sites), dtype=int)
        ground = root_child(motion.skeleton) is not None
        return cls(pos, bl.end_site_positions(motion, pos, rot), joints, motion.skeleton.parents, ground)


class View:
    """One cell of a sheet: a view of the image array, a horizontal axis across it (the facing at B
    for the side view, the character's left for the front view), the pelvis in the middle, the floor
    14 pixels above the bottom."""

    def __init__(self, cell: np.ndarray, across: np.ndarray, centre: np.ndarray, floor: float):
        self.cell, self.across, self.centre, self.floor = cell, across, centre, floor

    def px(self, p: np.ndarray) -> np.ndarray:
        h, w = self.cell.shape[:2]
        across, up = float((p - self.centre) @ self.across), float(p[2] - self.floor)
        return np.array([w / 2 + SCALE * across, h - 14 - SCALE * up])

    def line(self, p: np.ndarray, q: np.ndarray, colour: tuple[int, int, int]) -> None:
        draw_line(self.cell, self.px(p), self.px(q), colour)

    def figure(self, posed: Posed, frame: int, colours: list[tuple[int, int, int]] | None) -> None:
        """The pose at `frame`; colours None: a light grey ghost; joints under the floor marked."""
        grey = (205, 205, 205)
        for j in range(1 + posed.ground_root, len(posed.parents)):  # a ground root bone is not drawn
            self.line(posed.pos[frame, posed.parents[j]], posed.pos[frame, j], colours[j] if colours else grey)
        for k, j in enumerate(posed.tip_joints):
            self.line(posed.pos[frame, j], posed.tips[frame, k], colours[j] if colours else grey)
        if colours:
            points = np.concatenate([posed.pos[frame, int(posed.ground_root) :], posed.tips[frame]])
            for p in points[points[:, 2] < self.floor - 0.01]:
                x, y = np.round(self.px(p)).astype(int)
                self.cell[max(y - 2, 0) : max(y + 3, 0), max(x - 2, 0) : max(x + 3, 0)] = (230, 0, 200)

    def frame(self, colour: tuple[int, int, int]) -> None:
        for edge in (self.cell[:3], self.cell[-3:], self.cell[:, :3], self.cell[:, -3:]):
            edge[...] = colour


def _colours(motion: Motion, roles: dict[str, str]) -> list[tuple[int, int, int]]:
    """Per joint: left limbs blue, right red, the rest black."""
    sk = motion.skeleton
    out = [(0, 0, 0)] * sk.num_joints
    for side, colour in (("l", (40, 90, 220)), ("r", (220, 50, 40))):
        tops = {sk.index(roles[f"hip_{side}"]), sk.index(roles[f"shoulder_{side}"])}
        for j in range(sk.num_joints):
            if tops & set(joint_path(sk, 0, j)):
                out[j] = colour
    return out


def sheet_frames(a: int, b: int, peak: int) -> np.ndarray:
    """FRAMES frames evenly over [a, b), the first B's, the peak in place of the nearest other."""
    frames = np.linspace(a, b - 1, FRAMES).round().astype(int)
    if a < peak < b and peak not in frames:
        k = 1 + int(np.argmin(np.abs(frames[1:] - peak)))
        frames[k] = peak
        frames.sort()
    return frames


def contact_sheet(cases: list[tuple[dict, Pushing, Reaction, Impact]], peak_key: str) -> np.ndarray:
    """Rows of reactions, FRAMES frames each from B to the window's end (see the module docstring)."""
    cw, ch = CELL
    image = np.full((ch * len(cases), 2 * cw * FRAMES, 3), 255, dtype=np.uint8)
    for row, (rec, push, reaction, impact) in enumerate(cases):
        out, source, roles = reaction.motion, push.real.motion, push.real.roles
        assert out is not None
        posed, ghost = Posed.of(out), Posed.of(source)
        a, b = rec["window"]
        frames = sheet_frames(a, b, int(rec[peak_key]))
        peak = int(rec[peak_key])
        forward, left = ground_axes(out, a, roles)  # at B the output is the motion pushed, as it was
        pelvis, hit = out.skeleton.index(roles["pelvis"]), out.skeleton.index(impact.bone)
        colours = _colours(out, roles)
        for col, frame in enumerate(frames):
            for side, across in enumerate((forward, left)):
                ox, oy = (2 * col + side) * cw, row * ch
                view = View(image[oy : oy + ch, ox : ox + cw], across, posed.pos[frame, pelvis], push.real.floor)
                view.cell[ch - 14, 4 : cw - 4] = (170, 170, 170)
                view.cell[:, cw - 1] = (225, 225, 225) if side == 0 else (120, 120, 120)
                view.cell[ch - 1, :] = (120, 120, 120)
                if frame < source.num_frames:
                    view.figure(ghost, frame, None)
                view.figure(posed, frame, colours)
                if frame == a:  # the push: 0.4 m of green line into the hit bone, along its direction
                    at = posed.pos[frame, hit]
                    view.line(at - 0.4 * np.asarray(impact.direction), at, (0, 170, 0))
                if frame == peak:
                    view.frame((255, 140, 0))
    return image


def write_sheets(
    rows: list[dict], library: Library, classifier: ReactionClassifier | None, refs: References
) -> list[Path]:
    """The worst WORST reactions by each measure, re-made (the pipeline is deterministic) and drawn."""
    OUT.mkdir(parents=True, exist_ok=True)
    for row in rows:
        _sheet_keys(row)
    pushes: dict[str, Pushing] = {}
    written = []
    for name, (key, larger, peak_key, applies) in SHEETS.items():
        pool = [r for r in rows if (applies is None or applies(r)) and np.isfinite(r[key])]
        if name == "class_sense":
            pool = [r for r in pool if r["wrong"] > 0]
        if not pool:
            continue
        pool.sort(key=lambda r: r[key], reverse=larger)
        cases = []
        for rec in pool[:WORST]:
            real = refs.takes[rec["take"]]
            push = pushes.setdefault(rec["take"], Pushing.on(real, library, classifier))
            impact = push.impact(rec["frame"], rec["bone"], rec["side"], rec["strength"])
            cases.append((rec, push, push.react(impact), impact))
        path = OUT / f"{name}.png"
        path.write_bytes(png_bytes(contact_sheet(cases, peak_key)))
        lines = [f"{name}: worst {len(cases)} by {key} ({'largest' if larger else 'smallest'} first); "
                 "columns: frames from B to the window's end, side view | front view each"]  # fmt: skip
        for k, (rec, *_rest) in enumerate(cases):
            a, b = rec["window"]
            frames = sheet_frames(a, b, int(rec[peak_key])).tolist()
            lines.append(json.dumps({
                "row": k + 1, "take": rec["take"], "rig": rec["rig"], "frame": rec["frame"], "bone": rec["bone"],
                "from": rec["side"], "N·s": rec["strength"], "class": rec["class"], "clip": rec["clip"],
                key: round(float(rec[key]), 4), "peak_frame": int(rec[peak_key]), "columns": frames,
            }, ensure_ascii=False))  # fmt: skip
        (OUT / f"{name}.txt").write_text("\n".join(lines) + "\n")
        written.append(path)
    return written


# ---------------------------------------------------------------------------------------------


def bench_quality() -> None:
    """The believability figures (see the module docstring)."""
    if not mocap_files():
        skipped(GROUP)
        return
    start = time.perf_counter()
    refs = references()
    print(f"# quality: references from {len(refs.takes)} real takes in {time.perf_counter() - start:.1f} s", flush=True)
    library, classifier = load_library(REPO / "sample_clips" / "library.toml"), load_classifier()
    rows, failures = [], 0
    for real in pushed_takes(refs):
        took = time.perf_counter()
        push = Pushing.on(real, library, classifier)
        cast: set[str] = set()
        for frame, bone, side, strength in push_grid(real):
            impact = push.impact(frame, bone, side, strength)
            try:
                reaction = push.react(impact)
            except ReactiveAnimError as error:
                failures += 1
                print(f"# quality: {real.take.name} frame {frame} {bone} from {side} {strength:g} N·s: "
                      f"{type(error).__name__}: {error}")  # fmt: skip
                continue
            used = {reaction.clip, reaction.chained} - {None}
            rows.append(measure(push, refs, impact, side, bone, reaction, warm=used <= cast))
            cast |= used
        print(f"# quality: {real.take.name} ({real.rig}): {time.perf_counter() - took:.1f} s", flush=True)
    if not rows:
        print("# quality: no reaction measured")
        return
    table = figures(rows, refs, failures)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "reactions.json").write_text(json.dumps(rows, indent=None, default=float))
    sheets = write_sheets(rows, library, classifier, refs)
    print_rows(table)
    takes = len({r["take"] for r in rows})
    print(f"# quality: {len(rows)} reactions on {takes} takes in {time.perf_counter() - start:.0f} s; "
          f"contact sheets: {', '.join(p.name for p in sheets)} in {OUT}")  # fmt: skip
