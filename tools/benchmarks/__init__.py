"""Benchmarks: figures to read, never assertions (`tools/bench.py`, or `python -m tools.benchmarks`).

Modules: common (the figure report, timing, shared paths), bvh (BVH parsing), blender (import and
action I/O in Blender), sim (ragdoll simulation), search (the jump search), __main__ (the groups and
the command line).

Figures are for one core: importing this package limits the BLAS thread pools before any of its
modules loads numpy (set the variables yourself to measure otherwise).
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
