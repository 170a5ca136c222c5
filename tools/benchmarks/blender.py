"""Blender: import + read_motion of the largest shared file, write_motion of 3,000 frames x 22
bones (the sample walk repeated), and the bake operator's work on that 3,000-frame action with 20
impact markers (read, pipeline with the shipped classifier, keyframe write), in the bpy module of
the running Python."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from tests.support.mocap import MOCAP, REPO

from .common import best_of, largest_mocap, report, skipped

WRITE_FRAMES = 3000


def bench_blender() -> None:
    """Blender import + read_motion of the largest shared file; write_motion of 3,000 x 22 bones."""
    # Before bpy loads: keep Blender's user configuration out of the user's home.
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="reactive_anim_bench_"))
    import bpy

    import reactive_anim
    from reactive_anim.blender import action_io, bvh_import

    reactive_anim.register()
    try:
        path = largest_mocap()
        if path is None:
            skipped("blender import")
        else:
            _bench_import_read(bpy, bvh_import, action_io, path)
        _bench_write(bpy, bvh_import, action_io)
        _bench_bake(bpy, bvh_import, action_io)
    finally:
        reactive_anim.unregister()  # the bpy module misbehaves at exit with classes still registered


def _bench_import_read(bpy, bvh_import, action_io, path: Path) -> None:
    runs = 3
    import_times, read_times = [], []
    for _ in range(runs):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        start = time.perf_counter()
        rig = bvh_import.import_bvh(bpy.context, path)
        middle = time.perf_counter()
        motion = action_io.read_motion(rig)
        import_times.append(middle - start)
        read_times.append(time.perf_counter() - middle)
    context = {
        "file": str(path.relative_to(MOCAP)),
        "frames": motion.num_frames,
        "bones": motion.skeleton.num_joints,
        "runs": runs,
        "blender": bpy.app.version_string,
    }
    report("blender", "import (Blender's importer after our check)", min(import_times), "s", **context)
    report("blender", "read_motion", min(read_times), "s", **context)
    report("blender", "read_motion frames/s", motion.num_frames / min(read_times), "frames/s", **context)


def _bench_write(bpy, bvh_import, action_io) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    rig = bvh_import.import_bvh(bpy.context, REPO / "sample_clips" / "walk.bvh")
    walk = action_io.read_motion(rig)
    repeats = -(-WRITE_FRAMES // walk.num_frames)
    motion = walk
    for _ in range(repeats - 1):
        motion = motion.concat(walk)
    motion = motion.slice(0, WRITE_FRAMES)
    runs = 5
    seconds = best_of(lambda: action_io.write_motion(rig, motion, "bench"), runs)
    report(
        "blender",
        "write_motion 3000 frames x 22 bones",
        seconds,
        "s",
        bones=motion.skeleton.num_joints,
        frames=motion.num_frames,
        keys=motion.num_frames * (22 * 4 + 3),
        runs=runs,
        blender=bpy.app.version_string,
    )


def _bench_bake(bpy, bvh_import, action_io) -> None:
    """A bake of 20 impacts (chest and pelvis, from around the character, 40-250 N·s) on the sample
    walk repeated to 3,000 frames, as the bake operator does it (bake.bake_armature)."""
    from reactive_anim.blender import bake, impacts, resources

    from .react import push_impacts, repeated_walk

    bpy.ops.wm.read_factory_settings(use_empty=True)
    rig = bvh_import.import_bvh(bpy.context, REPO / "sample_clips" / "walk.bvh")
    long = repeated_walk(action_io.read_motion(rig), WRITE_FRAMES)
    rig.animation_data.action = action_io.write_motion(rig, long, "long walk")
    scene = bpy.context.scene
    first = int(rig.animation_data.action.frame_range[0])
    for impact in push_impacts(long, [int(f) for f in range(60, 2900, 142)][:20]):
        impacts.add_impact(scene, rig, impact.bone, first + int(impact.frame), impact.direction, impact.strength)
    library = resources.open_library()
    library.search_index()  # built once per library; a bake after the first reuses it
    start = time.perf_counter()
    result = bake.bake_armature(scene, rig, library=library)
    report("blender", "bake of 20 impacts on 3,000 frames (read, react, write)", time.perf_counter() - start, "s",
           frames=WRITE_FRAMES, impacts=len(result.reactions), blender=bpy.app.version_string)  # fmt: skip
