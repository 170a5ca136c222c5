"""The reaction library: BVH clips by reaction class, compiled once into search features (paper 2.4).

The paper searches a library of reaction clips, narrowed to the class the network predicts (section
2.3's 10 strategies). Here a library is a folder of BVH clips described by `library.toml`:

    # library.toml: one [[clip]] table per clip
    [[clip]]
    file = "falls/fall_back_01.bvh"   # relative to this file's folder, or absolute
    class = "fall_backward_sit"       # one of CLASS_SLUGS
    frames = [12, 240]                # optional: the BVH frames to use, start inclusive, end exclusive
    next = "getup/getup_01.bvh"       # optional: the `file` of the clip to chain after this one
    roles = { neck = "Neck1" }        # optional: joint-role overrides (roles.py) for this skeleton

    [[chain]]                         # a clip reached only through `next` (a get-up): no class,
    file = "getup/getup_01.bvh"       # not searched; the bake plays it after the clip that names it
    frames = [180, 560]               # optional, as for a clip: where the get-up starts and ends

Without a library.toml, sub-folders named by class slug are read instead (`step_back/*.bvh`, ...).
`load_library` also accepts the path of a .toml file anywhere (its `file` entries may be absolute),
so a library can be described without writing into the folder that holds the clips.

Compilation: each clip is read (bvh.py), given its joint roles (roles.py), resampled to the
library's rate and turned into Eq. 1's per-frame features (window.frame_features). A first frame
that the take leaves faster than CALIBRATION_JUMP (a calibration or converter T-pose, as every CMU
file opens with) is left out of every clip and chain, so it is never searched or played; each
chained clip is read once to find the frames it plays, kept with the cache. The arrays are
contiguous float32, grouped by class in CLASS_SLUGS order, then by clip in manifest order, with
per-frame clip and frame indices; that order is the search's tie-break. The result is cached as an
.npz named by a SHA-256 of the feature version, the settings, the manifest and every clip file's
bytes, so an edited clip (or manifest, or setting) compiles afresh. The clips' hashes are
remembered by size and modification time, so a second load of an unchanged library reads only the
manifest, the file status of each clip and the cache.

What we do differently from the paper, and why:
- Mixed frame rates: every clip is resampled on compile to the library's rate (`fps`, default 30),
  and queries are resampled to it too (window.query_from_motion). Eq. 1 sums per frame, so without
  this a 120 fps clip's window would cover a quarter of the time of a 30 fps one.
- The window length is a library setting (`window`, default 8 frames = 0.27 s at 30 fps, a typical
  transition), because a clip shorter than the window cannot be searched and is reported on compile.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
import numpy.typing as npt

from ..model import bvh
from ..model.arrays import FloatArray, IndexArray
from ..model.classes import CLASS_SLUGS
from ..model.errors import BVHError, LibraryError, SkeletonError
from ..model.rig import Rig
from ..model.roles import assign_roles
from ..model.skeleton import Motion, frame_times, resample
from .manifest import ChainEntry, ClipEntry, entry_error, read_chain_entries, read_manifest
from .search_index import SearchIndex, build_index
from .window import FrameFeatures, frame_features

# Bump when the features or the cache layout change, so old caches are never read.
# 2: each clip keeps its roles (a character on another skeleton needs them); 3: a calibration first
# frame is left out of clips and chains, and the chains' frames are kept
FEATURE_VERSION = 3
# m/s: faster than a body's joints move in a take (the shared takes peak at 13); the shared files that
# open on a calibration pose leave it at 77-172
CALIBRATION_JUMP = 20.0
DEFAULT_FPS = 30.0
DEFAULT_WINDOW = 8
# file-hashes.json: clip path -> [size, mtime_ns, SHA-256 hex digest], as _file_digest stores them.
FileMemo = dict[str, list[int | str]]


@dataclass(frozen=True)
class LibrarySettings:
    """Compile settings; all of them are part of the cache key.

    fps: the library's frame rate (every clip is resampled to it).
    window: search window in frames at `fps` (Eq. 1's ws); clips shorter than it are errors.
    unit, up: how to read the BVH files (bvh.read_bvh).
    """

    fps: float = DEFAULT_FPS
    window: int = DEFAULT_WINDOW
    unit: str = "auto"
    up: str = "Y"


@dataclass
class ClipInfo:
    """A compiled clip: where its frames sit in the library arrays and how they map to the file."""

    name: str
    path: str
    reaction_class: str
    source_fps: float
    source_start: int  # first BVH frame used
    num_frames: int  # frames at the library's rate
    next: str | None = None
    library_fps: float = DEFAULT_FPS
    roles: dict[str, str] = field(default_factory=dict[str, str])  # the roles its features were computed with

    def source_frame(self, frame: int) -> float:
        """The BVH frame (fractional when resampled) of a library frame of this clip."""
        fps = self.library_fps
        if np.isclose(self.source_fps, fps):
            return float(self.source_start + frame)  # not resampled: frames correspond one to one
        return self.source_start + frame * self.source_fps / fps


class Library:
    """Compiled reaction library: Eq. 1 features of every frame, grouped by class.

    Arrays (N frames in all): pos_local (N, 15, 3), heading (N,), ground (N, 2), rot (N, 15, 4),
    float32; clip_index, frame_index (N,) int32. `class_ranges[slug]` = (start, stop) frame range.
    `clip_frames[c]` = frames of clip c. See window.FrameFeatures for the meaning of each array.
    """

    def __init__(
        self,
        clips: list[ClipInfo],
        settings: LibrarySettings,
        frames: FrameFeatures,
        clip_index: IndexArray,
        frame_index: IndexArray,
    ) -> None:
        self.clips = clips
        self.settings = settings
        self.pos_local = np.ascontiguousarray(frames.pos_local, dtype=np.float32)
        self.heading = np.ascontiguousarray(frames.heading, dtype=np.float32)
        self.ground = np.ascontiguousarray(frames.ground, dtype=np.float32)
        self.rot = np.ascontiguousarray(frames.rot, dtype=np.float32)
        self.clip_index = np.ascontiguousarray(clip_index, dtype=np.int32)
        self.frame_index = np.ascontiguousarray(frame_index, dtype=np.int32)
        self.clip_frames = np.array([c.num_frames for c in clips], dtype=np.int64)
        for clip in clips:
            clip.library_fps = settings.fps
        self.class_ranges: dict[str, tuple[int, int]] = {}
        classes: IndexArray | list[int] = (
            np.array([CLASS_SLUGS.index(c.reaction_class) for c in clips])[self.clip_index] if clips else []
        )
        for k, slug in enumerate(CLASS_SLUGS):
            where = np.flatnonzero(np.asarray(classes) == k)
            if len(where):
                if where[-1] - where[0] + 1 != len(where):
                    raise LibraryError("library arrays are not grouped by class")
                self.class_ranges[slug] = (int(where[0]), int(where[-1]) + 1)
        self._index: SearchIndex | None = None
        self.cache_path: Path | None = None
        self.loaded_from_cache = False
        self.chains: dict[str, Path] = {}  # clips played only after another ([[chain]]): name -> file
        # the BVH frames [start, stop) each chain plays (its `frames`, a calibration first frame left out)
        self.chain_frames: dict[str, tuple[int, int]] = {}
        self._motions: dict[tuple[str, float], Motion] = {}

    @property
    def fps(self) -> float:
        return self.settings.fps

    @property
    def window(self) -> int:
        return self.settings.window

    @property
    def num_frames(self) -> int:
        return int(self.heading.shape[0])

    @property
    def nbytes(self) -> int:
        arrays = (self.pos_local, self.heading, self.ground, self.rot, self.clip_index, self.frame_index)
        return sum(a.nbytes for a in arrays)

    def require_class(self, slug: str) -> tuple[int, int]:
        """The frame range of a class; an error naming the class and what the library has."""
        if slug not in CLASS_SLUGS:
            raise LibraryError(f"unknown reaction class '{slug}'; classes are: {', '.join(CLASS_SLUGS)}")
        if slug not in self.class_ranges:
            have = ", ".join(f"{s} ({sum(c.reaction_class == s for c in self.clips)} clips)" for s in self.class_ranges)
            raise LibraryError(f"the library has no clips of class '{slug}'; it has: {have or 'nothing'}")
        return self.class_ranges[slug]

    def clip(self, name: str) -> ClipInfo:
        for clip in self.clips:
            if clip.name == name:
                return clip
        raise LibraryError(f"the library has no clip '{name}'")

    def search_index(self) -> SearchIndex:
        """The search's index (window summaries, the tree, the strategy per scope), built on first
        use and kept: a second and later search of this library reuses it."""
        if self._index is None:
            self._index = build_index(self)
        return self._index

    @property
    def frames(self) -> FrameFeatures:
        """Every frame's features (float32 views of the library's arrays)."""
        return FrameFeatures(self.pos_local, self.heading, self.ground, self.rot)

    def features(self, start: int, stop: int) -> FrameFeatures:
        """Flat frames [start, stop) as FrameFeatures (float64 copies)."""
        sl = slice(start, stop)
        return FrameFeatures(
            self.pos_local[sl].astype(np.float64), self.heading[sl].astype(np.float64),
            self.ground[sl].astype(np.float64), self.rot[sl].astype(np.float64),
        )  # fmt: skip

    def clip_motion(self, name: str, fps: float) -> Motion:
        """A clip's (or a chained clip's) motion at `fps`, over the frames the library uses, from
        its BVH file; kept, so a bake reads each clip once. Errors name the clip."""
        key = (name, float(fps))
        if key not in self._motions:
            self._motions[key] = self._read_motion(name, fps)
        return self._motions[key]

    def _read_motion(self, name: str, fps: float) -> Motion:
        settings = self.settings
        info = next((c for c in self.clips if c.name == name), None)
        path = Path(info.path) if info is not None else self.chains.get(name)
        if path is None:
            raise LibraryError(f"the library has no clip '{name}' (neither a [[clip]] nor a [[chain]])")
        try:
            motion = bvh.read_bvh(path, unit=settings.unit, up=settings.up)
        except (BVHError, OSError) as exc:
            raise entry_error(name, f"cannot be read again for the bake: {exc}") from None
        if info is not None:
            duration = (info.num_frames - 1) / info.library_fps
            stop = min(motion.num_frames, info.source_start + int(np.floor(duration * motion.fps + 1e-6)) + 1)
            motion = motion.slice(info.source_start, stop)
            motion.skeleton.roles = dict(info.roles)  # as its features were computed (manifest overrides)
        else:  # a chain: the frames found when the library was compiled (a library assembled by hand: found now)
            frames = self.chain_frames.get(name) or used_frames(name, motion, None)
            if frames[1] > motion.num_frames:
                raise entry_error(name, f"has {motion.num_frames} frames now, fewer than the library's {frames}")
            motion = motion.slice(*frames)
        return motion if np.isclose(motion.fps, fps) else resample(motion, frame_times(motion, fps))

    def clip_start(self, clip_index: int) -> int:
        """Flat index of the clip's first frame."""
        return int(np.searchsorted(self.clip_index, clip_index))

    @classmethod
    def concatenate(cls, parts: list[tuple[ClipInfo, FrameFeatures]], settings: LibrarySettings) -> Library:
        """A library from compiled clips; they are put in (class, given order) order."""
        order = sorted(range(len(parts)), key=lambda k: (CLASS_SLUGS.index(parts[k][0].reaction_class), k))
        parts = [parts[k] for k in order]
        if not parts:
            raise LibraryError("the library has no clips")
        feats = [f for _, f in parts]
        frames = FrameFeatures(
            np.concatenate([f.pos_local for f in feats]),
            np.concatenate([f.heading for f in feats]),
            np.concatenate([f.ground for f in feats]),
            np.concatenate([f.rot for f in feats]),
        )
        return cls(
            [c for c, _ in parts],
            settings,
            frames,
            np.concatenate([np.full(f.num_frames, k) for k, f in enumerate(feats)]),
            np.concatenate([np.arange(f.num_frames) for f in feats]),
        )


# ---------------------------------------------------------------------------------------------
# Compile and cache


def _read_bytes(name: str, path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise entry_error(name, f"file not found: {path}") from None
    except OSError as exc:
        raise entry_error(name, f"cannot read {path}: {exc}") from None


def _file_digest(name: str, path: Path, memo: FileMemo) -> str:
    """SHA-256 of a clip file's bytes; reused from `memo` while its size and mtime are unchanged,
    so checking an unchanged library touches no clip's bytes (only its file status)."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise entry_error(name, f"file not found: {path}") from None
    except OSError as exc:
        raise entry_error(name, f"cannot read {path}: {exc}") from None
    key = str(path.resolve())
    known = memo.get(key)
    if known is not None and known[0] == st.st_size and known[1] == st.st_mtime_ns:
        return cast(str, known[2])  # the digest stored with that size and mtime
    digest = hashlib.sha256(_read_bytes(name, path)).hexdigest()
    memo[key] = [st.st_size, st.st_mtime_ns, digest]
    return digest


def cache_key(
    entries: list[ClipEntry],
    settings: LibrarySettings,
    memo: FileMemo | None = None,
    chains: list[ChainEntry] | dict[str, Path] | None = None,
) -> str:
    """SHA-256 of the feature version, settings, manifest and every clip file's bytes, the chained
    clips' (get-ups) included with their frames: a bake reads them too (their hashes memoised by
    size and mtime in `memo`, which this updates)."""
    memo = {} if memo is None else memo
    h = hashlib.sha256()
    h.update(json.dumps({"version": FEATURE_VERSION, "settings": asdict(settings)}, sort_keys=True).encode())
    for e in entries:
        meta = {"name": e.name, "class": e.reaction_class, "frames": e.frames, "next": e.next, "roles": e.roles}
        h.update(json.dumps(meta, sort_keys=True).encode())
        h.update(_file_digest(e.name, e.path, memo).encode())
    if isinstance(chains, dict):
        chains = [ChainEntry(name, path) for name, path in chains.items()]
    for chain in sorted(chains or [], key=lambda c: c.name):
        h.update(json.dumps({"chain": chain.name, "frames": chain.frames}).encode())
        h.update(_file_digest(chain.name, chain.path, memo).encode())
    return h.hexdigest()


def take_start(pos: FloatArray, fps: float) -> int:
    """1 when some joint leaves frame 0 (pos (T, J, 3), metres) faster than CALIBRATION_JUMP, else 0:
    a first frame no body moves out of that fast is a calibration pose (CMU's converter T-pose, a
    capture's), not the take."""
    if len(pos) < 2:
        return 0
    return int(np.linalg.norm(pos[1] - pos[0], axis=-1).max() * fps > CALIBRATION_JUMP)


def used_frames(name: str, motion: Motion, frames: tuple[int, int] | None) -> tuple[int, int]:
    """The BVH frames [start, stop) an entry uses: its `frames` (all by default), less a calibration
    first frame (take_start) when they start at the file's first. Errors name the entry."""
    start, stop = frames or (0, motion.num_frames)
    if stop > motion.num_frames:
        raise entry_error(name, f"frames [{start}, {stop}] run past the file's {motion.num_frames} frames")
    if start == 0 and stop > 1:
        start = take_start(motion.slice(0, 2).global_positions(), motion.fps)
    return start, stop


def compile_clip(entry: ClipEntry, settings: LibrarySettings) -> tuple[ClipInfo, FrameFeatures]:
    """Read one clip and compute its features at the library's rate; errors name the clip."""
    motion = _read_entry(entry.name, entry.path, settings)
    try:
        role_map = assign_roles(motion.skeleton, dict(entry.roles) or None)
    except SkeletonError as exc:
        raise entry_error(entry.name, f"its skeleton lacks joint roles the search needs: {exc}") from None
    start, stop = used_frames(entry.name, motion, entry.frames)
    motion = motion.slice(start, stop)
    times = frame_times(motion, settings.fps)
    if len(times) < settings.window:
        raise entry_error(
            entry.name,
            f"{len(times)} frames at {settings.fps:g} fps ({motion.num_frames} in the file at {motion.fps:g} fps) "
            f"is shorter than the {settings.window}-frame search window",
        )
    source_fps = float(motion.fps)
    if not np.isclose(source_fps, settings.fps):
        motion = resample(motion, times)
    features = frame_features(motion, Rig(motion.skeleton, role_map))
    info = ClipInfo(
        entry.name, str(entry.path), entry.reaction_class, source_fps, start, features.num_frames, entry.next,
        roles=role_map,
    )  # fmt: skip
    return info, features


def compile_chain(entry: ChainEntry, settings: LibrarySettings) -> tuple[int, int]:
    """The BVH frames [start, stop) a chained clip plays (used_frames); errors name the clip."""
    return used_frames(entry.name, _read_entry(entry.name, entry.path, settings), entry.frames)


def _read_entry(name: str, path: Path, settings: LibrarySettings) -> Motion:
    """A clip or chain entry's BVH file, read in the library's unit and up axis; errors name it."""
    try:
        return bvh.read_bvh(path, unit=settings.unit, up=settings.up)
    except FileNotFoundError:
        raise entry_error(name, f"file not found: {path}") from None
    except BVHError as exc:
        raise entry_error(name, str(exc)) from None


def compile_library(
    entries: list[ClipEntry], settings: LibrarySettings, chains: list[ChainEntry] | None = None
) -> Library:
    """Compile every clip and chain (no cache)."""
    library = Library.concatenate([compile_clip(e, settings) for e in entries], settings)
    library.chains = {c.name: c.path for c in chains or []}
    library.chain_frames = {c.name: compile_chain(c, settings) for c in chains or []}
    return library


def _save(library: Library, path: Path, key: str) -> None:
    meta = {"key": key, "settings": asdict(library.settings), "clips": [
        {k: v for k, v in vars(c).items() if not k.startswith("_")} for c in library.clips],
        "chain_frames": {name: list(frames) for name, frames in library.chain_frames.items()}}  # fmt: skip
    _save_arrays(
        path, meta=np.array(json.dumps(meta)), pos_local=library.pos_local, heading=library.heading,
        ground=library.ground, rot=library.rot, clip_index=library.clip_index, frame_index=library.frame_index,
    )  # fmt: skip


def _save_arrays(path: Path, **arrays: npt.NDArray[np.generic]) -> None:
    """Write an .npz atomically (a reader never sees half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.replace(path)


def _load(path: Path, key: str) -> Library | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta.get("key") != key:
                return None
            clips = [ClipInfo(**c) for c in meta["clips"]]
            frames = FrameFeatures(data["pos_local"], data["heading"], data["ground"], data["rot"])
            settings = LibrarySettings(**meta["settings"])
            library = Library(clips, settings, frames, data["clip_index"], data["frame_index"])
            library.chain_frames = {name: (int(a), int(b)) for name, (a, b) in meta["chain_frames"].items()}
            return library
    except (OSError, ValueError, KeyError, TypeError):
        return None  # a missing or damaged cache is compiled afresh


def default_cache_dir(source: str | Path) -> Path:
    """`.reactive_anim_cache` beside the manifest (inside the library folder)."""
    source = Path(source)
    return (source.parent if source.suffix == ".toml" else source) / ".reactive_anim_cache"


def load_library(
    source: str | Path,
    settings: LibrarySettings | None = None,
    cache_dir: str | Path | None = None,
    *,
    cache: bool = True,
) -> Library:
    """The compiled library at `source` (folder or .toml), from the cache when unchanged.

    The cache file is `<cache_dir>/library-<key>.npz`. The key needs each clip's content hash;
    `<cache_dir>/file-hashes.json` remembers them by path, size and mtime, so an unchanged library
    is checked from file status alone: no clip is read, let alone parsed. A clip whose bytes change
    changes its size or mtime, is hashed afresh and gives a new key. Errors name the clip at fault.

    The cache only saves time, so it never fails a load: a cache that cannot be written (a
    read-only or full disk) is skipped, and cache=False (no folder to keep one in) reads and writes
    none. `library.cache_path` is the cache file, None when the library is not in one.
    """
    settings = settings or LibrarySettings()
    if settings.window < 1 or not settings.fps > 0:
        raise LibraryError(f"library settings need window >= 1 and fps > 0, got {settings}")
    entries = read_manifest(source)
    chains = read_chain_entries(source)
    if not cache:
        return compile_library(entries, settings, chains)
    cache_dir = Path(cache_dir) if cache_dir is not None else default_cache_dir(source)
    memo_path = cache_dir / "file-hashes.json"
    try:
        stored = json.loads(memo_path.read_text(encoding="utf-8"))
        memo = cast(FileMemo, stored) if isinstance(stored, dict) else {}
    except (OSError, ValueError):
        memo = {}
    before = json.dumps(memo, sort_keys=True)
    key = cache_key(entries, settings, memo, chains)
    if json.dumps(memo, sort_keys=True) != before:
        _try_write(_write_text, memo_path, json.dumps(memo, sort_keys=True))
    path = cache_dir / f"library-{key[:32]}.npz"
    library = _load(path, key) if path.is_file() else None
    if library is not None:
        library.loaded_from_cache = True
    else:
        library = compile_library(entries, settings, chains)
        if not _try_write(_save, library, path, key):
            path = None
    library.cache_path = path
    library.chains = {c.name: c.path for c in chains}
    return library


def _write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


def _try_write(write: Callable[..., None], *args: object) -> bool:
    """Run a cache write; False if the disk refused it (the library is then used uncached)."""
    try:
        write(*args)
    except OSError:
        return False
    return True
