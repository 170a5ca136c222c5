"""BVH parse throughput on the largest shared file (parse alone, and parse + conversion to metres,
Z up)."""

from __future__ import annotations

from reactive_anim.core.model import bvh
from tools.devkit.mocap import MOCAP

from .common import best_of, largest_mocap, report, skipped

RUNS = 5


def bench_bvh() -> None:
    """BVH parse throughput on the largest shared file (parse + conversion to metres, Z up)."""
    path = largest_mocap()
    if path is None:
        skipped("bvh")
        return
    data = bvh.parse_bvh(path)
    parse = best_of(lambda: bvh.parse_bvh(path), RUNS)
    full = best_of(lambda: bvh.read_bvh(path), RUNS)
    size = {
        "file": str(path.relative_to(MOCAP)),
        "frames": data.num_frames,
        "channels": data.values.shape[1],
        "runs": RUNS,
    }
    report("bvh", "parse frames/s", data.num_frames / parse, "frames/s", **size)
    report("bvh", "parse values/s", data.values.size / parse, "values/s", **size)
    report("bvh", "parse + convert frames/s", data.num_frames / full, "frames/s", **size)
