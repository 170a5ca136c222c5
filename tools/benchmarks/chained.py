"""Chained hits: a second push while the first reaction still plays (an animator's markers close
together: a combination of blows, a body hit again as it goes down or gets up).

On the quality benchmark's takes (its sample, or every walk, run and idle with --full), a first push
on the chest at the first of quality.IMPACT_AT (FIRST: two falls and a stagger), then, on the
reacted motion, a second push on the chest SECOND_AFTER seconds after the first reaction's C (SECOND:
a nudge from the front, a shove from the right, relative to the facing at the second push), baked as
bake_reactions bakes them (the second on the motion as reacted so far, the take resumed after).
Each second reaction is measured over its own window (its impact to the end of the reaction +
quality.AFTER) against the goals the single pushes have:
- depth under the floor (at most 3 cm);
- joint acceleration, the second hit's frames left out, against the real falls' largest;
- a body down at the second push (the pelvis under react.DOWN_HEIGHT leg lengths) that the
  second reaction raises over reach.HIPS_RISE more than the motion it plays would have (the first
  reaction's own get-up rising is not counted): faded into a clip's standing start, then falling again;
- pelvis acceleration within a frame of the second reaction's C and F under the real p99, or under
  what the motion it plays has there: the first reaction's fall landing on the floor at 48 m/s^2 is
  no seam of the second's (the share under the p99 alone is printed beside it).
Every second reaction's figures go to out/quality/chained.json, contact sheets of the WORST by
acceleration and by the seams' excess to out/quality/chained_<measure>.png (as the quality group's).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model.errors import ReactiveAnimError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.react import DOWN_HEIGHT, Reaction, ReactionClassifier, react
from reactive_anim.core.search.library import Library, load_library
from reactive_anim.core.search.reach import HIPS_RISE
from tools.devkit import believability as bl
from tools.devkit.mocap import REPO, mocap_files
from tools.devkit.poses import ground_axes
from tools.sample_clips.sheets import png_bytes

from . import quality
from .common import skipped

GROUP = "chained"
FIRST = (("left", 300.0), ("behind", 300.0), ("front", 120.0))  # side, N·s
SECOND = (("front", 40.0), ("right", 120.0))
SECOND_AFTER = (0.35, 0.8, 1.5, 2.5)  # s after the first reaction's C


def bench_chained() -> None:
    """The chained hits' figures (see the module docstring)."""
    if not mocap_files():
        skipped(GROUP)
        return
    start = time.perf_counter()
    refs = quality.references()
    library, classifier = load_library(REPO / "sample_clips" / "library.toml"), load_classifier()
    rows, failures = [], 0
    for real in quality.pushed_takes(refs):
        push = quality.Pushing.on(real, library, classifier)
        for first_push in FIRST:
            try:
                first = first_reaction(push, first_push)
            except ReactiveAnimError as error:
                failures += 1
                print(f"# {GROUP}: {real.take.name} {first_push}: {type(error).__name__}: {error}")
                continue
            for after in SECOND_AFTER:
                for second_push in SECOND:
                    try:
                        second = second_reaction(push, first, after, second_push)
                    except ReactiveAnimError as error:
                        failures += 1
                        print(f"# {GROUP}: {real.take.name} {first_push}, {after} s, {second_push}: "
                              f"{type(error).__name__}: {error}")  # fmt: skip
                        continue
                    if second is not None:
                        rows.append({**measure(push, first, second), "case": (first_push, after, second_push)})
    if not rows:
        print(f"# {GROUP}: no reaction measured")
        return
    quality.print_rows(figures(rows, refs, failures))
    quality.OUT.mkdir(parents=True, exist_ok=True)
    (quality.OUT / "chained.json").write_text(json.dumps(rows, indent=None, default=float))
    sheets = write_sheets(rows, refs, library, classifier)
    took = time.perf_counter() - start
    print(f"# {GROUP}: {len(rows)} second reactions in {took:.0f} s; each in {quality.OUT / 'chained.json'}, "
          f"contact sheets: {', '.join(p.name for p in sheets)}")  # fmt: skip


def first_reaction(push: quality.Pushing, first_push: tuple[str, float]) -> Reaction:
    """The first push (side, N·s) on the chest at the first of quality.IMPACT_AT."""
    first_frame = round(quality.IMPACT_AT[0] * (push.real.motion.num_frames - 1))
    return push.react(push.impact(first_frame, "chest", *first_push))


def second_reaction(
    push: quality.Pushing, first: Reaction, after: float, second_push: tuple[str, float]
) -> Reaction | None:
    """The second push (side, N·s, relative to the facing then) on the chest `after` seconds after
    the first reaction's C, on the motion as reacted (None where it would land on its last frame).
    Deterministic, so the sheets make the worst again."""
    real, played = push.real, first.motion
    assert played is not None
    frame = first.frame_c + round(after * real.motion.fps)
    if frame >= played.num_frames - 1:
        return None
    forward, left = ground_axes(played, frame, real.roles)
    way = {"front": -forward, "right": left}[second_push[0]]
    impact = Impact(float(frame), real.roles["chest"], tuple(way), second_push[1])
    return react(played, impact, push.library, push.classifier, source=real.motion, ragdoll=push.ragdoll,
                 workspace=push.workspace, casting=push.casting)  # fmt: skip


def measure(push: quality.Pushing, first: Reaction, second: Reaction) -> dict:
    """One second reaction's figures."""
    real, played, out = push.real, first.motion, second.motion
    assert played is not None
    assert out is not None
    pos, rot = out.global_transforms()
    a, b = quality.window_of(second, out.fps, out.num_frames)
    accel = bl.acceleration(pos[:, bl.body_joints(real.roles, out)], out.fps).max(axis=1)
    accel[bl.hit_mask(len(accel), second.frame_b, out.fps)] = np.nan
    points = np.concatenate([pos[:, 1:], bl.end_site_positions(out, pos, rot)], axis=1)
    pelvis = out.skeleton.index(real.roles["pelvis"])
    height = pos[:, pelvis, 2] - real.floor
    was = played.global_positions()[:, pelvis, 2] - real.floor
    f = min(second.frame_f + 2, len(was))
    low = DOWN_HEIGHT * push.ragdoll.rig.leg_length  # the core's "sits, kneels or lies"
    pelvis_accel = bl.acceleration(pos[:, pelvis], out.fps)
    played_accel = bl.acceleration(played.global_positions()[:, pelvis], out.fps)
    seams = [s for s in (second.frame_c, second.frame_f) if s + 1 < min(len(pelvis_accel), len(played_accel))]
    seams = [s for s in seams if np.isfinite(pelvis_accel[s - 1 : s + 2]).any()]  # the stride leaves the last frames
    return {
        "take": real.take.name, "first": first.reaction_class, "frame": second.frame_b, "class": second.reaction_class,
        "clip": second.clip, "c": second.frame_c, "f": second.frame_f, "window": (a, b),
        "kept": second.kept_motion, "depth": float(np.nanmax(bl.depth_under_floor(points[a:b], real.floor))),
        "accel": float(np.nanmax(accel[a:b])), "accel_at": int(a + np.nanargmax(accel[a:b])),
        "down": bool(height[a] < low),
        "raised": float(height[a:f].max() - height[a] - (was[a:f].max() - was[a])),
        "seams": [float(np.nanmax(pelvis_accel[s - 1 : s + 2])) for s in seams],
        "played_seams": [float(np.nanmax(played_accel[s - 1 : s + 2])) for s in seams],
        "seam_frames": seams,
    }  # fmt: skip


def figures(rows: list[dict], refs: quality.References, failures: int) -> list[quality.Row]:
    """The table's rows (each also reported as a JSON line)."""
    out: list[quality.Row] = []
    add = quality.table_adder(out, GROUP)
    add("reactions", "second reactions measured", len(rows), "reactions", "-", "-", None, failed=failures,
        takes=len({r["take"] for r in rows}), kept_motion=sum(r["kept"] for r in rows), full=quality.FULL)  # fmt: skip
    add("bakes", "second pushes that failed", failures, "pushes", "-", "0", failures == 0)
    depth = max(r["depth"] for r in rows)
    add("depth", "deepest joint or end site under the floor", depth * 100, "cm", "0 cm", "<= 3 cm",
        depth <= quality.GOALS["depth"])  # fmt: skip
    over = [r for r in rows if r["accel"] > refs.falls_accel]
    largest = round(max(r["accel"] for r in rows), 1)
    add("acceleration", "second reactions over the real falls' largest", len(over), "reactions",
        f"{refs.falls_accel:.4g} m/s^2 (CMU falls)", "0", not over, largest=largest)  # fmt: skip
    down = [r for r in rows if r["down"]]
    raised = [r for r in down if r["raised"] > HIPS_RISE]
    most = round(max([r["raised"] for r in down] or [0.0]), 2)
    add("stood up", f"bodies down raised {HIPS_RISE:g} m+ beyond the motion they play", len(raised), "reactions",
        "-", "0", not raised, down=len(down), largest_m=most)  # fmt: skip
    seams = [(s, p) for r in rows for s, p in zip(r["seams"], r["played_seams"], strict=True)]
    share = float(np.mean([s <= max(refs.pelvis_p99, p) for s, p in seams]))
    goal = quality.GOALS["seam_share"]
    add("seams", "pelvis acceleration at C and F under real p99 or the played motion's", 100 * share, "%",
        f"p99 {refs.pelvis_p99:.3g} m/s^2", ">= 95 %", share >= goal, seams=len(seams),
        under_p99=round(100 * float(np.mean([s <= refs.pelvis_p99 for s, _ in seams])), 1))  # fmt: skip
    return out


def write_sheets(
    rows: list[dict], refs: quality.References, library: Library, classifier: ReactionClassifier | None
) -> list[Path]:
    """The WORST second reactions by acceleration and by their seams' excess over the real p99 or the
    played motion's, made again and drawn as the quality group's sheets (quality.contact_sheet: the
    grey figure is the take unpushed) in out/quality/chained_<measure>.png, with a .txt per sheet."""
    for row in rows:
        excess = [s - max(refs.pelvis_p99, p) for s, p in zip(row["seams"], row["played_seams"], strict=True)]
        worst = int(np.argmax(excess)) if excess else -1
        row["seam_excess"] = excess[worst] if excess else -np.inf
        row["seam_at"] = row["seam_frames"][worst] if excess else row["frame"]
    pushes: dict[str, quality.Pushing] = {}
    written = []
    for name, key, peak in (("acceleration", "accel", "accel_at"), ("seams", "seam_excess", "seam_at")):
        cases, lines = [], [f"chained_{name}: worst {quality.WORST} by {key}; columns: frames from the second "
                            "push to the window's end, side view | front view each"]  # fmt: skip
        for rec in sorted(rows, key=lambda r: r[key], reverse=True)[: quality.WORST]:
            real = refs.takes[rec["take"]]
            push = pushes.setdefault(rec["take"], quality.Pushing.on(real, library, classifier))
            first_push, after, second_push = rec["case"]
            second = second_reaction(push, first_reaction(push, first_push), after, second_push)
            assert second is not None
            cases.append((rec, push, second, second.impact))
            lines.append(json.dumps({k: rec[k] for k in ("take", "case", "first", "class", "clip", key, peak)},
                                    ensure_ascii=False, default=float))  # fmt: skip
        path = quality.OUT / f"chained_{name}.png"
        path.write_bytes(png_bytes(quality.contact_sheet(cases, peak)))
        path.with_suffix(".txt").write_text("\n".join(lines) + "\n")
        written.append(path)
    return written
