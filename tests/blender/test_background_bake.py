"""The bake that never blocks the UI (blender/worker.py, bake_ops.py): the core runs in a real
worker thread and the main thread polls it, step by step, as the modal operator's timer does;
then the operator's last step writes the result. Compared with the synchronous operator."""

from __future__ import annotations

import time

import bpy
import pytest

from reactive_anim.blender import bake, worker
from reactive_anim.core.errors import Cancelled, LibraryError, SkeletonError
from tests.support.actions import keyframes
from tests.support.bake_scene import blend_snapshot, library_without_falls, walk_with_impacts

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
    assert bpy.ops.reactive_anim.bake(armature_name="walk") == {"FINISHED"}
    synchronous = keyframes(rig.animation_data.action)
    summary = bake.bake_state(rig).summary
    bpy.ops.reactive_anim.clear_bake(armature_name="walk")

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

    assert rig.animation_data.action.name == "walk.reacted"
    assert keyframes(rig.animation_data.action) == synchronous
    strip_time = [line.rsplit(",", 1)[0] for line in summary.splitlines()[1:]]
    assert [line.rsplit(",", 1)[0] for line in result.summary().splitlines()[1:]] == strip_time


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
            bpy.ops.reactive_anim.bake(armature_name="walk")
        with pytest.raises(RuntimeError, match=r"preview.poll\(\) Reactions are being computed for 'walk'"):
            bpy.ops.reactive_anim.preview(armature_name="walk")
    finally:
        background.cancel()
    assert bpy.ops.reactive_anim.bake.poll()


def test_the_result_is_refused_if_the_character_changed_its_action_meanwhile(empty_scene):
    rig = walk_with_impacts(empty_scene)
    job = bake.prepare_bake(empty_scene, rig)
    baked = job.run()
    rig.animation_data.action = bpy.data.actions.new("other")
    before = blend_snapshot()
    with pytest.raises(SkeletonError, match="now plays 'other', not 'walk' as when the bake began"):
        bake.commit_bake(job, baked, 0.0)
    assert blend_snapshot() == before
