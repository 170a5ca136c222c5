#!/usr/bin/env python3
"""Benchmarks: figures to read, never assertions. Prints a table and one JSON line per figure.

    .venv/bpy-5.0/bin/python tools/bench.py            # everything
    .venv/bpy-5.0/bin/python tools/bench.py bvh        # some groups: bvh, blender, sim, search
    .venv/core/bin/python tools/bench.py quality --full    # believability, every shared take

The benchmarks are the package tools/benchmarks (this script runs its main; `python -m
tools.benchmarks` from the repository root does the same). Real mocap comes from ../shared/mocap
(test and benchmark data only); a group that needs it is skipped with a note where it is absent.
"""

import sys
from pathlib import Path

# Run as a script, Python puts tools/ on sys.path, not the repository root: add the root, the one
# path fix the tools make, so that tools.benchmarks, tools.devkit and reactive_anim import as
# packages. (Nothing else here: the package limits BLAS threads before numpy loads.)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tools.benchmarks.__main__ import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
