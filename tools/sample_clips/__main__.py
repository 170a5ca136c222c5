"""Generate the project's own sample skeleton and clips into sample_clips/.

    python -m tools.sample_clips                  # rewrites sample_clips/*.bvh and library.toml
    python -m tools.sample_clips --out DIR        # writes elsewhere
    python -m tools.sample_clips --sheets out/contact_sheets   # also draws contact sheet PNGs

Run from the repository root (with the project's Python, e.g. .venv/bpy-5.0/bin/python).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from reactive_anim.core.model import bvh

from .catalogue import write_clips
from .sheets import write_contact_sheets

REPO = Path(__file__).resolve().parents[2]


def main(argv: list[str] | None = None) -> int:
    """Write the clips and say what was written, read back through the BVH reader as a check."""
    assert __doc__ is not None
    parser = argparse.ArgumentParser(prog="python -m tools.sample_clips", description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, default=REPO / "sample_clips", help="output folder (default: sample_clips/)"
    )
    parser.add_argument("--sheets", type=Path, help="also draw contact sheet PNGs into this folder (e.g. out/)")
    args = parser.parse_args(argv)
    if args.sheets:
        for path in write_contact_sheets(args.sheets):
            print(f"drew {path}")
    for path in write_clips(args.out):
        if path.suffix != ".bvh":
            print(f"wrote {path}")
            continue
        motion = bvh.read_bvh(path)
        seconds = motion.num_frames / motion.fps
        distance = np.linalg.norm(motion.root_pos[-1, :2] - motion.root_pos[0, :2])
        print(
            f"wrote {path}: {motion.skeleton.num_joints} joints, {motion.num_frames} frames at "
            f"{motion.fps:g} fps ({seconds:.2f} s), root travels {distance:.2f} m"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
