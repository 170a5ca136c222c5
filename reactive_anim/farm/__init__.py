"""Batch bakes at farm scale: `python -m reactive_anim bake FILES --scheduler tcp://HOST:PORT` or
`--workers N` (docs/command-line.md).

Modules: outputs (an output written whole and resumable: the atomic save, the hash of its inputs
recorded inside it), report (one file's outcome, the summary row and the JSON line), task (one
file's bake in a Blender process of its own, as a Dask worker runs it), cluster (the Dask client:
one task per file, progress, lost workers). Only cluster imports Dask, and only when a farm run
asks for it: the plain command and the extension never need it.
"""
