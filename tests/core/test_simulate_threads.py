"""Simulation state is per run (core/physics/simulate.py): a Ragdoll is never changed by a simulation, and
simulations on two threads at once give bit-identical results to the same runs one after the other
(a worker thread baking while a preview simulates). Runs on the project's own sample walk."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from reactive_anim.core.model import bvh
from reactive_anim.core.model.errors import SimulationError
from reactive_anim.core.model.impact import Impact
from reactive_anim.core.physics.ragdoll import build_ragdoll
from reactive_anim.core.physics.simulate import SimResult, simulate_impact, track
from reactive_anim.core.physics.workspace import Workspace
from tests.support.mocap import REPO

IMPACTS = (Impact(30, "chest", (1.0, 0.0, 0.0), 120.0), Impact(52, "pelvis", (0.0, 1.0, 0.2), 200.0))


@pytest.fixture(scope="module")
def walk():
    return bvh.read_bvh(REPO / "sample_clips" / "walk.bvh")


@pytest.fixture(scope="module")
def ragdoll(walk):
    return build_ragdoll(walk.skeleton)


def _react(ragdoll, walk, impact: Impact, workspace: Workspace | None = None) -> tuple[SimResult, SimResult]:
    """BC for the impact, then CD tracking the walk from C (as the pipeline chains them)."""
    bc = simulate_impact(ragdoll, walk, impact, workspace=workspace)
    cd = track(ragdoll, bc.state, walk, 0.35, target_start=int(bc.frames[-1]), workspace=workspace)
    return bc, cd


def _arrays(result: SimResult) -> list[np.ndarray]:
    m = result.motion
    return [result.qpos, result.qvel, result.com, result.com_velocity, m.root_pos, m.local_rot]


def _assert_identical(a: tuple[SimResult, ...], b: tuple[SimResult, ...]) -> None:
    for x, y in zip(a, b, strict=True):
        for u, v in zip(_arrays(x), _arrays(y), strict=True):
            assert np.array_equal(u, v)


def _work(ragdoll, walk, k: int, own: bool, barrier: threading.Barrier, out: list) -> None:
    """One thread: wait for the others, then react to impact k three times (so the runs overlap
    whatever the scheduling), with its own workspace or none."""
    workspace = Workspace(ragdoll) if own else None
    barrier.wait()
    for _ in range(3):
        out.append(_react(ragdoll, walk, IMPACTS[k], workspace))


def test_two_threads_at_once_match_one_after_the_other(ragdoll, walk):
    """Each thread with its own workspace, and each with none (a fresh one per call): both equal
    the sequential results bit for bit, the runs interleaving on a 2-core machine."""
    sequential = [_react(ragdoll, walk, impact) for impact in IMPACTS]
    for own_workspace in (True, False):
        results: dict[int, list] = {k: [] for k in range(len(IMPACTS))}
        barrier = threading.Barrier(len(IMPACTS))

        threads = [
            threading.Thread(target=_work, args=(ragdoll, walk, k, own_workspace, barrier, results[k]))
            for k in range(len(IMPACTS))
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        for k, expected in enumerate(sequential):
            assert len(results[k]) == 3
            for got in results[k]:
                _assert_identical(got, expected)


def test_a_simulation_leaves_the_ragdoll_unchanged(ragdoll, walk):
    """The model's body offsets, gains and timestep, which every run sets, stay as built."""
    model = ragdoll.model
    before = [a.copy() for a in (model.body_pos, model.actuator_gainprm, model.actuator_biasprm, model.jnt_range)]
    timestep = model.opt.timestep
    _react(ragdoll, walk, IMPACTS[0])
    after = (model.body_pos, model.actuator_gainprm, model.actuator_biasprm, model.jnt_range)
    assert all(np.array_equal(x, y) for x, y in zip(before, after, strict=True))
    assert model.opt.timestep == timestep
    with pytest.raises(ValueError):
        ragdoll.index.limit_lo[0] = 0.0  # the ragdoll's arrays are read-only


def test_a_workspace_is_not_shared_between_runs(ragdoll, walk):
    """A workspace in use refuses a second run rather than corrupting the first; one made for
    another ragdoll is refused too."""
    workspace = Workspace(ragdoll)
    with workspace, pytest.raises(SimulationError, match="in use by another run"):
        simulate_impact(ragdoll, walk, IMPACTS[0], workspace=workspace)
    other = build_ragdoll(walk.skeleton, profile="paper")
    with pytest.raises(SimulationError, match="another ragdoll"):
        simulate_impact(other, walk, IMPACTS[0], workspace=workspace)
