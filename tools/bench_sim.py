#!/usr/bin/env python3
"""Simulation benchmark figures (issue 4): model compile time, µs per step, wall time of a 0.25 s
BC window and a 0.5 s CD transition, for the sample skeleton and the largest shared skeleton, and
how long pure PD tracking (CD) of a real walk stays within bounds.

`bench_sim(report)` is wired into tools/bench.py; standalone:

    .venv/bpy-5.0/bin/python tools/bench_sim.py
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from bench_common import MOCAP, REPO, best_of, print_table, report

import mujoco  # noqa: E402
import numpy as np  # noqa: E402  (after bench_common limits BLAS to one core)

from reactive_anim.core import bvh  # noqa: E402
from reactive_anim.core.impact import Impact  # noqa: E402
from reactive_anim.core.ragdoll import build_ragdoll  # noqa: E402
from reactive_anim.core.simulate import simulate_impact, state_from_mocap, track  # noqa: E402

RUNS = 5
BANDAI_WALK = MOCAP / "bandai_namco" / "dataset-1" / "dataset-1_walk_normal_001.bvh"


def _largest_skeleton() -> Path | None:
    """The shared file with the most joints (iClone, ~100 joints), ties broken by name."""
    best, best_count = None, -1
    for path in sorted(MOCAP.glob("**/*.bvh")) if MOCAP.is_dir() else []:
        with open(path, encoding="utf-8", errors="replace") as handle:
            head = handle.read(200_000)
        count = head.split("MOTION")[0].count("JOINT") + 1
        if count > best_count:
            best, best_count = path, count
    return best


def _bench_clip(report, label: str, path: Path, use_reference: bool) -> None:
    motion = bvh.read_bvh(path)
    reference = motion if use_reference else None
    context = {"clip": label, "joints": motion.skeleton.num_joints, "runs": RUNS}
    ragdoll = build_ragdoll(motion.skeleton, reference=reference)
    report("sim", "model build (roles, neutral pose, 2 compiles)",
           best_of(lambda: build_ragdoll(motion.skeleton, reference=reference), RUNS) * 1e3, "ms", **context)
    report("sim", "MJCF compile", best_of(lambda: mujoco.MjModel.from_xml_string(ragdoll.mjcf), RUNS) * 1e3, "ms", **context)

    # Raw step cost: 0.25 s from the walk's state, floor at the mocap's ground, CD servos holding
    # the start pose (feet on the floor, a few contacts: the typical load).
    frame = min(40, motion.num_frames - 20)
    impact = Impact(frame, ragdoll.roles["chest"], (1.0, 0.0, 0.0), 80.0)
    simulate_impact(ragdoll, motion, impact, window=0.05)  # leaves the model's servos and body offsets set
    state = state_from_mocap(ragdoll, motion, frame)
    data = mujoco.MjData(ragdoll.model)
    steps = 150

    def stepping() -> None:
        data.qpos[:] = state.qpos
        data.qvel[:] = state.qvel
        data.mocap_pos[0] = (0.0, 0.0, state.floor)
        data.ctrl[:] = state.qpos[ragdoll.model.jnt_qposadr[ragdoll.model.actuator_trnid[:, 0]]]
        for _ in range(steps):
            mujoco.mj_step(ragdoll.model, data)

    report("sim", "time per step", best_of(stepping, RUNS) / steps * 1e6, "us", bodies=len(ragdoll.bodies), **context)

    bc_time = best_of(lambda: simulate_impact(ragdoll, motion, impact, window=0.25), RUNS)
    report("sim", "BC window 0.25 s (state, impulse, steps, output Motion)", bc_time * 1e3, "ms", **context)
    bc = simulate_impact(ragdoll, motion, impact, window=0.25)
    target_start = min(int(bc.frames[-1]), motion.num_frames - 1)
    cd_time = best_of(lambda: track(ragdoll, bc.state, motion, 0.5, target_start=target_start), RUNS)
    report("sim", "CD transition 0.5 s (PD tracking, output Motion)", cd_time * 1e3, "ms", **context)
    report("sim", "BC + CD", (bc_time + cd_time) * 1e3, "ms", **context)


def _bench_tracking_hold(report) -> None:
    """How long pure PD tracking of a real walk stays within 5 cm mean joint error and 10 cm pelvis
    height (no balance feedback, so it drifts): tells the pipeline how long CD may run."""
    motion = bvh.read_bvh(BANDAI_WALK)
    ragdoll = build_ragdoll(motion.skeleton, reference=motion)
    joints = [motion.skeleton.index(n) for n in ragdoll.roles.values()]
    pelvis = motion.skeleton.index(ragdoll.roles["pelvis"])
    truth = motion.global_positions()
    holds = []
    for start in range(10, motion.num_frames - 70, 10):
        result = track(ragdoll, motion, motion, 2.0, target_start=start, start_frame=start)
        frames = result.frames.astype(int)
        inside = frames < motion.num_frames
        sim = result.motion.global_positions()[inside]
        ref = truth[frames[inside]]
        error = np.linalg.norm(sim[:, joints] - ref[:, joints], axis=-1).mean(axis=1)
        height = np.abs(sim[:, pelvis, 2] - ref[:, pelvis, 2])
        outside = (error > 0.05) | (height > 0.10)
        holds.append((np.argmax(outside) if outside.any() else len(error)) / motion.fps)
    context = {"clip": BANDAI_WALK.name, "starts": len(holds)}
    report("sim", "CD tracking within bounds, median", float(np.median(holds)), "s", **context)
    report("sim", "CD tracking within bounds, min", float(np.min(holds)), "s", **context)
    report("sim", "CD tracking within bounds, max", float(np.max(holds)), "s", **context)


def bench_sim(report: Callable[..., None]) -> None:
    """Print the simulation figures through `report(group, name, value, unit, **context)`."""
    _bench_clip(report, "sample walk (22 joints)", REPO / "sample_clips" / "walk.bvh", use_reference=False)
    largest = _largest_skeleton()
    if largest is None:
        print(f"# sim: largest shared skeleton skipped, no mocap at {MOCAP}")
    else:
        _bench_clip(report, largest.name, largest, use_reference=True)
    if BANDAI_WALK.is_file():
        _bench_tracking_hold(report)
    else:
        print(f"# sim: tracking figure skipped, {BANDAI_WALK} is absent")


if __name__ == "__main__":
    bench_sim(report)
    print_table()
