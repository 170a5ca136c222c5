"""Blender: BVH import + read_motion, ours against Blender's importer in the same run, on the
largest shared file and on a 10,000-frame file (a shared walk repeated, written to a temporary
folder); write_motion of 3,000 frames x 22 bones (the sample walk repeated); and the bake
operator's work on that 3,000-frame action with 20 impact markers (read, pipeline with the shipped
classifier, keyframe write), in the bpy module of the running Python."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from tools.devkit.mocap import MOCAP, REPO

from .common import best_of, largest_mocap, report, skipped

WRITE_FRAMES = 3000
LONG_FRAMES = 10_000
LONG_WALK = MOCAP / "bandai_namco" / "dataset-1" / "dataset-1_walk_normal_001.bvh"  # 22 joints, 195 frames


def bench_blender() -> None:
    """BVH import + read_motion (ours and Blender's importer); write_motion; a 20-impact bake."""
    # Before bpy loads: keep Blender's user configuration out of the user's home.
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="reactive_anim_bench_"))
    import bpy

    import reactive_anim
    from reactive_anim.blender.character import action_io, bvh_import

    reactive_anim.register()
    try:
        path = largest_mocap()
        if path is None:
            skipped("blender import")
        else:
            _bench_import_read(bpy, path, str(path.relative_to(MOCAP)), runs=5, blender_runs=3)
        if not LONG_WALK.is_file():
            skipped("blender import", f"{LONG_FRAMES} frames")
        else:
            with tempfile.TemporaryDirectory(prefix="reactive_anim_bench_") as folder:
                long = _repeated_bvh(LONG_WALK, Path(folder) / "long_walk.bvh", LONG_FRAMES)
                label = f"{LONG_WALK.relative_to(MOCAP)} repeated to {LONG_FRAMES} frames"
                _bench_import_read(bpy, long, label, runs=5, blender_runs=1)
        _bench_write(bpy, bvh_import, action_io)
        _bench_bake(bpy, bvh_import, action_io)
    finally:
        reactive_anim.unregister()  # the bpy module misbehaves at exit with classes still registered


def _bench_import_read(bpy, path: Path, label: str, *, runs: int, blender_runs: int) -> None:
    """Import + read_motion of one file: ours (our reader, armature builder, bulk keys; the
    F-curves read in numpy) and as before (our reader's check, Blender's importer; every frame
    evaluated), each the best of its runs from a fresh empty scene (the first imports in a process
    are up to 40% slower while memory is first allocated, so ours, cheap, gets more runs)."""
    from reactive_anim.blender.character import action_io, bvh_import
    from reactive_anim.core.model import bvh
    from tools.devkit.blender_bvh import import_with_blender

    def import_and_read(importer, evaluate: bool) -> tuple[float, float, int, int]:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        start = time.perf_counter()
        rig = importer(bpy.context, path)
        middle = time.perf_counter()
        motion = action_io.read_motion(rig, evaluate=evaluate)
        return middle - start, time.perf_counter() - middle, motion.num_frames, motion.skeleton.num_joints

    ours = [import_and_read(bvh_import.import_bvh, evaluate=False) for _ in range(runs)]
    before = [import_and_read(import_with_blender, evaluate=True) for _ in range(blender_runs)]
    reader = best_of(lambda: bvh.read_bvh(path), runs)
    frames, joints = ours[0][2], ours[0][3]
    context = {"file": label, "frames": frames, "bones": joints, "blender": bpy.app.version_string}
    ours_import, ours_read = min(r[0] for r in ours), min(r[1] for r in ours)
    before_import, before_read = min(r[0] for r in before), min(r[1] for r in before)
    report("blender", "import, ours", ours_import, "s", runs=runs, **context)
    report("blender", "  of which our reader (parse + convert)", reader, "s", runs=runs, **context)
    report("blender", "read_motion, ours (F-curves in numpy)", ours_read, "s", runs=runs, **context)
    report("blender", "import + read_motion, ours", ours_import + ours_read, "s", runs=runs, **context)
    report("blender", "import, Blender's importer (after our check)", before_import, "s", runs=len(before), **context)
    report("blender", "read_motion, every frame evaluated", before_read, "s", runs=len(before), **context)
    report("blender", "import + read_motion, Blender's importer", before_import + before_read, "s",
           runs=len(before), **context)  # fmt: skip
    report("blender", "speed-up of import + read_motion", (before_import + before_read) / (ours_import + ours_read),
           "x", **context)  # fmt: skip


def _repeated_bvh(source: Path, target: Path, frames: int) -> Path:
    """`source`'s motion lines repeated to `frames` frames, written to `target` (a long file to time;
    the root jumps back where the walk restarts, which no importer minds)."""
    hierarchy, motion = source.read_text().split("MOTION", 1)
    lines = [line for line in motion.splitlines() if line.strip()]
    frame_time, rows = lines[1], lines[2:]  # after "Frames: n" and "Frame Time: t"
    body = "\n".join(rows[i % len(rows)] for i in range(frames))
    target.write_text(f"{hierarchy}MOTION\nFrames: {frames}\n{frame_time}\n{body}\n")
    return target


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
    from reactive_anim.blender.bake import bake, resources
    from reactive_anim.blender.impacts import impacts

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
