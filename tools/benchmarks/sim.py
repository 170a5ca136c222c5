"""Simulation figures: one impact's physics as a bake runs it against bare mj_step calls for the same
steps (the overhead ratio); ragdoll build and MJCF compile time, the cost of a simulation Workspace,
us per step, wall time of a 0.25 s BC window and a 0.5 s CD transition, for the sample skeleton and
the largest shared skeleton, with the ragdoll's degrees of freedom; and how long CD tracking keeps
a walker or a standing character up, pure PD against PD with the root assist.

Runs reuse one Workspace (physics.workspace.Workspace: the run's own model copy and MjData), as a worker
thread does, so the BC and CD figures exclude making one; that cost is its own figure.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from reactive_anim.core.model import bvh
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.physics.balance import RootAssist
from reactive_anim.core.physics.mjcf import TIMESTEP
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import SimState, simulate_impact, state_from_mocap, track
from reactive_anim.core.physics.workspace import BC_GAINS, Workspace
from reactive_anim.core.react import CD_RAMP, ReactionSettings
from tools.devkit.mocap import MOCAP, REPO, mocap_files
from tools.devkit.tracking import kept_up_seconds

from .common import best_of, report, skipped

RUNS = 5
BANDAI_WALK = MOCAP / "bandai_namco" / "dataset-1" / "dataset-1_walk_normal_001.bvh"
ICLONE_WALK = MOCAP / "cmu_iclone" / "002_01.bvh"


def _largest_skeleton() -> Path | None:
    """The shared file with the most joints (iClone, ~100 joints), ties broken by name."""
    best, best_count = None, -1
    for path in mocap_files():
        with open(path, encoding="utf-8", errors="replace") as handle:
            head = handle.read(200_000)
        count = head.split("MOTION")[0].count("JOINT") + 1
        if count > best_count:
            best, best_count = path, count
    return best


def _bench_clip(label: str, path: Path, use_reference: bool) -> None:
    motion = bvh.read_bvh(path)
    reference = motion if use_reference else None
    context = {"clip": label, "joints": motion.skeleton.num_joints, "runs": RUNS}
    ragdoll = build_ragdoll(motion.skeleton, reference=reference)
    report(
        "sim",
        "model build (roles, neutral pose, 2 compiles)",
        best_of(lambda: build_ragdoll(motion.skeleton, reference=reference), RUNS) * 1e3,
        "ms",
        **context,
    )
    report(
        "sim",
        "MJCF compile",
        best_of(lambda: mujoco.MjModel.from_xml_string(ragdoll.mjcf), RUNS) * 1e3,
        "ms",
        **context,
    )
    report("sim", "Workspace (model copy, 2 MjData)", best_of(lambda: Workspace(ragdoll), RUNS) * 1e3, "ms", **context)
    workspace = Workspace(ragdoll)

    # Raw step cost: 0.25 s from the walk's state, floor at the mocap's ground, the servos holding
    # the start pose (feet on the floor, a few contacts: the typical load). A short BC run sets the
    # workspace model's body offsets and servo gains; the steps run on that model with their own
    # MjData (the Ragdoll's model is never stepped or changed).
    frame = min(40, motion.num_frames - 20)
    impact = Impact(frame, ragdoll.roles["chest"], (1.0, 0.0, 0.0), 80.0)
    simulate_impact(ragdoll, motion, impact, window=0.05, workspace=workspace)
    state = state_from_mocap(ragdoll, motion, frame, workspace=workspace)
    steps = 150
    per_step = best_of(_bare_steps(workspace, [(state, steps)]), RUNS) / steps * 1e6
    report("sim", "time per step", per_step, "us", bodies=len(ragdoll.bodies), dof=ragdoll.model.nv, **context)

    bc_time = best_of(lambda: simulate_impact(ragdoll, motion, impact, window=0.25, workspace=workspace), RUNS)
    report("sim", "BC window 0.25 s (state, impulse, steps, output Motion)", bc_time * 1e3, "ms", **context)
    bc = simulate_impact(ragdoll, motion, impact, window=0.25, workspace=workspace)
    target_start = min(int(bc.frames[-1]), motion.num_frames - 1)
    cd_time = best_of(
        lambda: track(ragdoll, bc.state, motion, 0.5, target_start=target_start, workspace=workspace), RUNS
    )
    report("sim", "CD transition 0.5 s (PD tracking, output Motion)", cd_time * 1e3, "ms", **context)
    report("sim", "BC + CD", (bc_time + cd_time) * 1e3, "ms", **context)


def _bench_tracking_hold() -> None:
    """How long CD tracking keeps a character up (tools/devkit/tracking.py), pure PD (the paper)
    against PD with the root assist (balance.py), from 12 start frames of each clip: tells how long
    the transition may run, and what the assist buys."""
    clips = [REPO / "sample_clips" / "walk.bvh", REPO / "sample_clips" / "idle.bvh"]
    clips += [p for p in (BANDAI_WALK, ICLONE_WALK) if p.is_file()]
    for path in clips:
        motion = bvh.read_bvh(path)
        ragdoll = build_ragdoll(motion.skeleton, reference=motion)
        workspace = Workspace(ragdoll)
        seconds = min(2.0, 0.6 * (motion.num_frames - 1) / motion.fps)
        starts = np.linspace(0.2 * motion.fps, motion.num_frames - 1 - seconds * motion.fps, 12).astype(int)
        for label, assist in (("pure PD", None), ("PD + root assist", RootAssist())):
            held, fraction = [], 0.0
            for start in starts:
                result = track(ragdoll, motion, motion, seconds, target_start=int(start), start_frame=float(start),
                               assist=assist, workspace=workspace)  # fmt: skip
                held.append(kept_up_seconds(result, motion, ragdoll))
                fraction = max(fraction, result.assist_fraction)
            context = {"clip": path.name, "starts": len(starts), "run_seconds": round(seconds, 2)}
            report("sim", f"CD kept up, {label}, min", float(np.min(held)), "s", **context)
            report("sim", f"CD kept up, {label}, median", float(np.median(held)), "s", **context)
            if assist is not None:
                report("sim", "largest root assist, fraction of body weight", fraction, "", **context)


def _bare_steps(workspace: Workspace, runs: list[tuple[SimState, int]]) -> Callable[[], None]:
    """mj_step alone, `steps` from each state (floor at its ground, servos holding its pose), on the
    workspace's model (its body offsets and gains set by a run before) with an MjData of its own."""
    data = mujoco.MjData(workspace.model)
    actuated = workspace.ragdoll.index.actuator_qpos

    def stepping() -> None:
        for state, steps in runs:
            data.qpos[:] = state.qpos
            data.qvel[:] = state.qvel
            data.mocap_pos[0] = (0.0, 0.0, state.floor)
            data.ctrl[:] = state.qpos[actuated]
            for _ in range(steps):
                mujoco.mj_step(workspace.model, data)

    return stepping


def _bench_impact_physics() -> None:
    """One impact's physics as a bake runs it (BC 0.25 s, then CD over the transition with the root
    assist, reusing a Workspace) against bare mj_step calls for the same number of steps from the
    same states: the ratio is what the Python around the steps costs (the goal: at most 1.3)."""
    motion = bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")
    ragdoll = build_ragdoll(motion.skeleton)
    workspace = Workspace(ragdoll)
    settings = ReactionSettings()
    impact = Impact(40, ragdoll.roles["chest"], (1.0, 0.0, 0.0), 80.0)
    bc = simulate_impact(ragdoll, motion, impact, window=settings.reaction_window, workspace=workspace)
    target_start = int(bc.frames[-1])
    duration = round(settings.transition * motion.fps) / motion.fps

    def physics() -> None:
        first = simulate_impact(ragdoll, motion, impact, window=settings.reaction_window, workspace=workspace)
        track(ragdoll, first.state, motion, duration, target_start=target_start, assist=settings.assist,
              ramp=(BC_GAINS, CD_RAMP), workspace=workspace)  # fmt: skip

    start = state_from_mocap(ragdoll, motion, impact.frame, workspace=workspace)
    runs = [(start, round(settings.reaction_window / TIMESTEP)), (bc.state, round(duration / TIMESTEP))]
    total, stepping = best_of(physics, RUNS), best_of(_bare_steps(workspace, runs), RUNS)
    context = {"clip": "sample walk", "steps": sum(n for _, n in runs), "timestep": round(TIMESTEP, 6)}
    label = f"one impact's physics (BC {settings.reaction_window:g} s + CD {settings.transition:g} s, assist)"
    report("sim", label, total * 1e3, "ms", **context)
    report("sim", "  bare mj_step, same steps", stepping * 1e3, "ms", **context)
    report("sim", "  ratio total / bare steps", total / stepping, "x", **context)


def bench_sim() -> None:
    """The simulation figures (see the module docstring)."""
    _bench_impact_physics()
    _bench_clip("sample walk (22 joints)", REPO / "sample_clips" / "walk.bvh", use_reference=False)
    largest = _largest_skeleton()
    if largest is None:
        skipped("sim", "largest shared skeleton")
    else:
        _bench_clip(largest.name, largest, use_reference=True)
    _bench_tracking_hold()
