#!/usr/bin/env python3
"""Benchmarks: figures to read, never assertions. Prints a table and one JSON line per figure.

    .venv/bpy-5.0/bin/python tools/bench.py            # everything
    .venv/bpy-5.0/bin/python tools/bench.py bvh        # some groups only

Real mocap comes from ../shared/mocap (test and benchmark data only); a group that needs it is
skipped with a note where it is absent. Each timing is the best of several runs (the least disturbed
by other work on the machine), with the run count printed beside it.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

from bench_common import MOCAP, REPO, best_of, print_table, report

from reactive_anim.core import bvh


def largest_mocap() -> Path | None:
    files = sorted(MOCAP.glob("**/*.bvh"), key=lambda p: p.stat().st_size) if MOCAP.is_dir() else []
    return files[-1] if files else None


def bench_bvh() -> None:
    """BVH parse throughput on the largest shared file (parse + conversion to metres, Z up)."""
    path = largest_mocap()
    if path is None:
        print(f"# bvh: skipped, no mocap at {MOCAP}")
        return
    data = bvh.parse_bvh(path)
    runs = 5
    parse = best_of(lambda: bvh.parse_bvh(path), runs)
    full = best_of(lambda: bvh.read_bvh(path), runs)
    size = {"file": str(path.relative_to(MOCAP)), "frames": data.num_frames, "channels": data.values.shape[1], "runs": runs}
    report("bvh", "parse frames/s", data.num_frames / parse, "frames/s", **size)
    report("bvh", "parse values/s", data.values.size / parse, "values/s", **size)
    report("bvh", "parse + convert frames/s", data.num_frames / full, "frames/s", **size)


def bench_blender() -> None:
    """Blender import + read_motion of the largest shared file; write_motion of 3,000 x 22 bones."""
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="reactive_anim_bench_"))
    import bpy

    import reactive_anim
    from reactive_anim.blender import action_io, bvh_import

    reactive_anim.register()
    try:
        path = largest_mocap()
        if path is None:
            print(f"# blender import: skipped, no mocap at {MOCAP}")
        else:
            _bench_import_read(bpy, bvh_import, action_io, path)
        _bench_write(bpy, bvh_import, action_io)
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
    context = {"file": str(path.relative_to(MOCAP)), "frames": motion.num_frames, "bones": motion.skeleton.num_joints,
               "runs": runs, "blender": bpy.app.version_string}
    report("blender", "import (Blender's importer after our check)", min(import_times), "s", **context)
    report("blender", "read_motion", min(read_times), "s", **context)
    report("blender", "read_motion frames/s", motion.num_frames / min(read_times), "frames/s", **context)


def _bench_write(bpy, bvh_import, action_io) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    rig = bvh_import.import_bvh(bpy.context, REPO / "sample_clips" / "walk.bvh")
    walk = action_io.read_motion(rig)
    repeats = -(-3000 // walk.num_frames)
    motion = walk
    for _ in range(repeats - 1):
        motion = motion.concat(walk)
    motion = motion.slice(0, 3000)
    runs = 5
    seconds = best_of(lambda: action_io.write_motion(rig, motion, "bench"), runs)
    report("blender", "write_motion 3000 frames x 22 bones", seconds, "s", bones=motion.skeleton.num_joints,
           frames=motion.num_frames, keys=motion.num_frames * (22 * 4 + 3), runs=runs, blender=bpy.app.version_string)


def bench_simulation() -> None:
    """Ragdoll build, step cost, BC and CD windows (figures defined in tools/bench_sim.py)."""
    from bench_sim import bench_sim

    bench_sim(report)


def bench_jump_search() -> None:
    """Reference vs full vs class-narrowed jump search (figures defined in tools/bench_search.py)."""
    from bench_search import bench_search

    bench_search(report)


GROUPS = {"bvh": bench_bvh, "blender": bench_blender, "sim": bench_simulation, "search": bench_jump_search}


def main(argv: list[str]) -> int:
    chosen = argv or list(GROUPS)
    unknown = [g for g in chosen if g not in GROUPS]
    if unknown:
        print(f"unknown group(s) {unknown}; choose from {list(GROUPS)}", file=sys.stderr)
        return 2
    for group in chosen:
        GROUPS[group]()
    print_table()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
