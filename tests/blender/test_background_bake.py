"""The bake that never blocks the UI (blender/bake/worker.py, bake_ops.py): the core runs in a real
worker thread and the main thread polls it, step by step, as the modal operator's timer does;
then the operator's last step writes the result. Compared with the synchronous operator. The
modal operator's event handling (worker.ModalRun) is driven event by event with a stand-in for
the window manager's timer, since background mode has no event loop to deliver the real one."""

from __future__ import annotations

import time

import bpy
import pytest

from reactive_anim.blender.bake import bake, worker
from reactive_anim.core.model.errors import Cancelled, LibraryError, SkeletonError
from tests.support.actions import action_of, keyframes
from tests.support.bake_scene import blend_snapshot, library_without_falls, summary_without_times, walk_with_impacts
from tools.devkit.operators import addon_ops

TIMEOUT_S = 120.0


def _poll_until_done(background: worker.BackgroundBake) -> int:
    """Poll as the modal operator's timer does; the number of polls it took."""
    polls, deadline = 0, time.monotonic() + TIMEOUT_S
    while not background.poll():
        assert time.monotonic() < deadline, "the worker did not finish"
        polls += 1
        time.sleep(0.005)
    return polls


def test_the_background_bake_equals_the_synchronous_bake(empty_scene):
    rig = walk_with_impacts(empty_scene)
    assert addon_ops.bake(armature_name="walk") == {"FINISHED"}
    synchronous = keyframes(action_of(rig))
    summary = bake.bake_state(rig).summary
    addon_ops.clear_bake(armature_name="walk")

    job = bake.prepare_bake(empty_scene, rig)
    background = worker.BackgroundBake(job).start()
    assert worker.running() is background
    seen = []
    while not background.poll():
        seen.append(background.progress)
        time.sleep(0.002)
    assert worker.running() is None
    assert background.error is None and background.baked is not None
    assert {p.done for p in seen} <= {0, 1, 2, 3} and background.progress.done == 3  # reported per impact
    texts = {p.text("walk") for p in seen}
    assert "Reactions on 'walk': impact 2 of 3 (impact marker 'hit_02' at frame 131) - Esc to cancel" in texts
    result = bake.commit_bake(job, background.baked, background.seconds)

    assert action_of(rig).name == "walk.reacted"
    assert keyframes(action_of(rig)) == synchronous
    assert summary_without_times(result.summary())[1:] == summary_without_times(summary)[1:]


def test_a_cancelled_background_bake_leaves_the_file_unchanged(empty_scene):
    walk_with_impacts(empty_scene)
    before = blend_snapshot()
    job = bake.prepare_bake(empty_scene, bpy.data.objects["walk"])
    background = worker.BackgroundBake(job).start()
    deadline = time.monotonic() + TIMEOUT_S
    while background.progress.done < 1:  # Esc while the second impact is made (each takes ~50 ms)
        assert not background.poll() and time.monotonic() < deadline
        time.sleep(0.001)
    background.cancel()

    assert background.poll() and background.baked is None and isinstance(background.error, Cancelled)
    assert background.progress.done < 3, "the bake ran to the end instead of stopping"
    assert worker.running() is None
    assert blend_snapshot() == before


def test_an_error_in_the_worker_names_the_marker_and_nothing_is_written(empty_scene, tmp_path):
    walk_with_impacts(empty_scene)
    before = blend_snapshot()
    job = bake.prepare_bake(empty_scene, bpy.data.objects["walk"], library=library_without_falls(tmp_path))
    background = worker.BackgroundBake(job).start()
    _poll_until_done(background)
    assert isinstance(background.error, LibraryError)
    assert str(background.error).startswith("impact marker 'hit_02' at frame 131: the library has no clips of class")
    assert blend_snapshot() == before


def test_one_bake_at_a_time_and_the_poll_says_why(empty_scene):
    walk_with_impacts(empty_scene)
    job = bake.prepare_bake(empty_scene, bpy.data.objects["walk"])
    background = worker.BackgroundBake(job).start()
    try:
        with pytest.raises(RuntimeError, match="a bake is already running on 'walk'"):
            worker.BackgroundBake(job).start()
        with pytest.raises(RuntimeError, match=r"bake.poll\(\) Reactions are being computed for 'walk'"):
            addon_ops.bake(armature_name="walk")
        with pytest.raises(RuntimeError, match=r"preview.poll\(\) Reactions are being computed for 'walk'"):
            addon_ops.preview(armature_name="walk")
    finally:
        background.cancel()
    assert addon_ops.bake.poll()


def test_the_result_is_refused_if_the_character_changed_its_action_meanwhile(empty_scene):
    rig = walk_with_impacts(empty_scene)
    job = bake.prepare_bake(empty_scene, rig)
    baked = job.run()
    rig.animation_data.action = bpy.data.actions.new("other")
    before = blend_snapshot()
    with pytest.raises(SkeletonError, match="now plays 'other', not 'walk' as when the bake began"):
        bake.commit_bake(job, baked, 0.0)
    assert blend_snapshot() == before


class WindowManagerStandIn:
    """Records what ModalRun asks of the window manager (background mode has no event loop, so the
    real timer would never fire); the events are then delivered by the test, as Blender would."""

    def __init__(self) -> None:
        self.added: list[tuple[float, object]] = []
        self.removed: list[object] = []

    def event_timer_add(self, seconds: float, window: object = None) -> object:
        timer = object()
        self.added.append((seconds, timer))
        return timer

    def event_timer_remove(self, timer: object) -> None:
        self.removed.append(timer)


def _modal_run(job: bake.BakeJob, write=bake.commit_bake) -> tuple[worker.ModalRun, WindowManagerStandIn, list]:
    wm, statuses = WindowManagerStandIn(), []
    run = worker.ModalRun(worker.BackgroundBake(job), write, wm, bpy.context.window, statuses.append, lambda: None)
    return run, wm, statuses


def _until_done(run: worker.ModalRun) -> worker.Outcome:
    """Deliver timer events (and a mouse move between them) until the operator ends."""
    deadline = time.monotonic() + TIMEOUT_S
    while True:
        assert run.handle("MOUSEMOVE", "NOTHING").result == "PASS_THROUGH"  # the UI stays live
        outcome = run.handle("TIMER", "NOTHING")
        if outcome.result != "PASS_THROUGH":
            return outcome
        assert time.monotonic() < deadline, "the modal run did not finish"
        time.sleep(0.005)


def test_the_modal_run_driven_by_timer_events_equals_the_synchronous_bake(empty_scene):
    rig = walk_with_impacts(empty_scene)
    addon_ops.bake(armature_name="walk")
    synchronous = keyframes(action_of(rig))
    addon_ops.clear_bake(armature_name="walk")

    run, wm, statuses = _modal_run(bake.prepare_bake(empty_scene, rig))
    run.start()
    assert action_of(rig).name == "walk"  # nothing is written while it runs
    outcome = _until_done(run)

    assert outcome.result == "FINISHED"
    assert outcome.reports[0][1].startswith("'walk': 3 impacts baked into 'walk.reacted'")
    assert keyframes(action_of(rig)) == synchronous
    assert len(wm.added) == 1 and wm.removed == [wm.added[0][1]]  # one timer, removed once
    assert statuses[0].startswith("Reactions on 'walk': impact 1 of 3") and statuses[-1] is None
    assert worker.running() is None


def test_esc_in_the_modal_run_stops_it_and_changes_nothing(empty_scene):
    rig = walk_with_impacts(empty_scene)
    before = blend_snapshot()
    run, wm, statuses = _modal_run(bake.prepare_bake(empty_scene, rig))
    run.start()
    while run.background.progress.done < 1:
        assert run.handle("TIMER", "NOTHING").result == "PASS_THROUGH"
        time.sleep(0.001)

    outcome = run.handle("ESC", "PRESS")

    assert outcome.result == "CANCELLED" and outcome.reports == [("WARNING", worker.CANCELLED_TEXT)]
    assert wm.removed == [wm.added[0][1]] and statuses[-1] is None
    assert blend_snapshot() == before
    deadline = time.monotonic() + TIMEOUT_S
    while worker.running() is not None:  # the thread ends after the impact it was making
        assert time.monotonic() < deadline
        time.sleep(0.01)


def test_the_modal_run_reports_errors_by_marker_and_bugs_without_a_traceback(empty_scene, tmp_path):
    rig = walk_with_impacts(empty_scene)
    before = blend_snapshot()
    run, _wm, statuses = _modal_run(bake.prepare_bake(empty_scene, rig, library=library_without_falls(tmp_path)))
    run.start()
    outcome = _until_done(run)
    assert outcome.result == "CANCELLED" and outcome.reports[0][0] == "ERROR"
    assert outcome.reports[0][1].startswith("impact marker 'hit_02' at frame 131: the library has no clips of class")
    assert blend_snapshot() == before and statuses[-1] is None

    def broken_write(job, baked, seconds):
        raise ZeroDivisionError("a bug")

    run, _wm, _statuses = _modal_run(bake.prepare_bake(empty_scene, rig), write=broken_write)
    run.start()
    outcome = _until_done(run)
    assert outcome.result == "CANCELLED"
    assert outcome.reports == [("ERROR", "reactions failed unexpectedly: ZeroDivisionError('a bug')")]
