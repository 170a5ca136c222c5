"""Benchmarks: figures to read, never assertions. Prints one JSON line per figure and a table.

    .venv/bpy-5.0/bin/python tools/bench.py                 # everything
    .venv/bpy-5.0/bin/python tools/bench.py bvh sim         # some groups only
    .venv/bpy-5.0/bin/python -m tools.benchmarks search     # the same, as a module
    .venv/core/bin/python tools/bench.py quality --full     # believability on every shared take

Groups: bvh (parse throughput), blender (import, read_motion, write_motion in bpy), sim (ragdoll
build, step, BC and CD windows), search (the jump search against the reference), react (the reaction
pipeline per impact and a 20-impact bake), cast (search costs on other skeletons, retarget time),
sweep (random pushes baked on every shared file: failures, pops, time), quality (believability:
pushes on the shared walks, runs and idles measured against real capture; a sample of takes, every
one with --full; contact sheets of the worst in out/quality), chained (a second push while the first
reaction plays, on the same takes: depth, pops, bodies stood up, seams), farm (batch bakes per minute in one
process and on a local Dask cluster of 1 and 2 workers, the cluster's cost per task; the farm
environment). Real mocap comes from
../shared/mocap (test and benchmark data only); a group that needs it is skipped with a note where
it is absent. Each timing is the best of several runs (the least disturbed by other work on the
machine), with the run count printed beside it."""

from __future__ import annotations

import sys
from collections.abc import Callable

from . import quality
from .blender import bench_blender
from .bvh import bench_bvh
from .casting import bench_casting
from .chained import bench_chained
from .common import print_table
from .farm import bench_farm
from .react import bench_react
from .search import bench_search
from .sim import bench_sim
from .sweep import bench_sweep

GROUPS: dict[str, Callable[[], None]] = {
    "bvh": bench_bvh,
    "blender": bench_blender,
    "sim": bench_sim,
    "search": bench_search,
    "react": bench_react,
    "cast": bench_casting,
    "sweep": bench_sweep,
    "quality": quality.bench_quality,
    "chained": bench_chained,
    "farm": bench_farm,
}
FLAGS = {"--full": "quality, chained: push every shared walk, run and idle, not the sample"}


def main(argv: list[str]) -> int:
    """Run the named groups (all by default) and print the table; 2 for an unknown group or flag."""
    flags = [a for a in argv if a.startswith("--")]
    chosen = [a for a in argv if not a.startswith("--")] or list(GROUPS)
    unknown = [g for g in chosen if g not in GROUPS] + [f for f in flags if f not in FLAGS]
    if unknown:
        print(f"unknown group(s) or flag(s) {unknown}; choose from {list(GROUPS)} and {FLAGS}", file=sys.stderr)
        return 2
    quality.FULL = "--full" in flags
    for group in chosen:
        GROUPS[group]()
    print_table()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
