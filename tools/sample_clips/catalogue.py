"""The catalogue: every clip the tool makes (CLIPS, in the order they are written), which are
reactions and of what class, the reaction library's library.toml text, and writing it all out.

To add a clip: write a function returning a Motion on `sample_skeleton()` and list it in CLIPS.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from reactive_anim.core.model import bvh
from reactive_anim.core.model.skeleton import Motion

from .falls import FALLS, NEXT, fall_clip
from .gaits import run_clip, walk_clip
from .getups import GETUPS, keyed_clip
from .idle import idle_clip
from .steps import STEPS, SWAYS, step_clip, sway_clip

P = TypeVar("P")  # a clip function's parameters

LOCOMOTION = ("walk", "run", "idle")  # not reactions: kept out of the library


def clip_maker(build: Callable[[P], Motion], params: P, what: str) -> Callable[[], Motion]:
    """A CLIPS entry (a clip function without arguments) for one row of a parameter table."""

    def make() -> Motion:
        return build(params)

    make.__doc__ = what
    return make


CLIPS: dict[str, Callable[[], Motion]] = {
    "walk": walk_clip,
    "run": run_clip,
    "idle": idle_clip,
    **{name: clip_maker(step_clip, push, f"The stepping reaction {name}: {push}") for name, push in STEPS.items()},
    **{name: clip_maker(sway_clip, sway, f"The pendulum sway {name}: {sway}") for name, sway in SWAYS.items()},
    **{name: clip_maker(fall_clip, fall, f"The physics fall {name}: {fall}") for name, fall in FALLS.items()},
    **{name: clip_maker(keyed_clip, keys, f"The keyframed get-up {name}.") for name, keys in GETUPS.items()},
}
REACTIONS = [name for name in CLIPS if name not in LOCOMOTION and name not in GETUPS]
PHYSICS = list(FALLS)  # made by the ragdoll: the same bits on one machine, not on every CPU


def reaction_class(name: str) -> str:
    """The class slug of a reaction clip: its name without the variant number."""
    return name.rsplit("_", 1)[0]


def library_toml() -> str:
    """The reaction library's clip list (read by reactive_anim's library module)."""
    lines = [
        # The header of the committed sample_clips/library.toml, old tool path and all: change the
        # two together (the test wants this file byte for byte).
        "# The reaction library over the clips in this folder, written by python -m tools.sample_clips.",
        "# One [[clip]] per reaction clip: file, class (a slug of reactive_anim/core/model/classes.py), optional",
        "# frames = [start, end] and optional next = the clip that follows it (a get-up after a fall).",
        "# [[chain]] tables list clips reached only through `next` (the get-ups); they are no class.",
        "",
    ]
    for name in REACTIONS:
        lines += ["[[clip]]", f'file = "{name}.bvh"', f'class = "{reaction_class(name)}"']
        if name in NEXT:
            lines.append(f'next = "{NEXT[name]}"')
        lines.append("")
    for name in GETUPS:
        lines += ["[[chain]]", f'file = "{name}.bvh"', ""]
    return "\n".join(lines)


def write_clip(path: Path, motion: Motion) -> None:
    """One clip as BVH: centimetres to 4 decimals (1 um), Y up, ZXY, the common dialect; 4 rather
    than 6 decimals keep the folder a fifth smaller."""
    bvh.write_bvh(path, motion, rotation_order="ZXY", unit="cm", up="Y", decimals=4)


def write_clips(out_dir: Path) -> list[Path]:
    """Write every clip in CLIPS as <name>.bvh and the reaction library's library.toml."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, make in CLIPS.items():
        path = out_dir / f"{name}.bvh"
        write_clip(path, make())
        written.append(path)
    library = out_dir / "library.toml"
    library.write_text(library_toml(), encoding="utf-8", newline="\n")
    written.append(library)
    return written
