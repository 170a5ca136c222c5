"""Reaction library (core/search/library.py, paper 2.4): manifest, compile, cache, errors naming the clip.

Clips are made from the project's own sample walk (sample_clips/walk.bvh) with seeded smooth
changes, written as BVH files into tmp_path, so these tests need no shared mocap.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.classes import CLASS_SLUGS
from reactive_anim.core.model.errors import LibraryError
from reactive_anim.core.model.skeleton import Motion, Skeleton
from reactive_anim.core.search import library as library_module
from reactive_anim.core.search.library import (
    Library,
    LibrarySettings,
    compile_clip,
    load_library,
)
from reactive_anim.core.search.manifest import read_chain_entries, read_chains, read_manifest
from reactive_anim.core.search.search import search
from reactive_anim.core.search.window import Query
from tests.support.mocap import REPO
from tools.devkit.library_clips import make_clip, write_toml


@pytest.fixture
def small_library(tmp_path: Path) -> Path:
    folder = tmp_path / "lib"
    folder.mkdir()
    make_clip(folder / "a.bvh", 1, 120, 60.0)
    make_clip(folder / "b.bvh", 2, 90, 30.0)
    make_clip(folder / "c.bvh", 3, 200, 120.0)
    write_toml(folder, [
        {"file": "a.bvh", "class": "step_back", "next": "c.bvh"},
        {"file": "b.bvh", "class": "step_forward", "frames": [10, 80]},
        {"file": "c.bvh", "class": "step_back"},
    ])  # fmt: skip
    return folder


class CountParses:
    """Counts calls of bvh.parse_bvh (read_bvh goes through it) while patched in."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch):
        self.calls = 0
        original = bvh.parse_bvh

        def counting(*args, **kwargs):
            self.calls += 1
            return original(*args, **kwargs)

        monkeypatch.setattr(bvh, "parse_bvh", counting)


def test_compile_groups_by_class_and_resamples(small_library: Path, tmp_path: Path) -> None:
    lib = load_library(small_library, cache_dir=tmp_path / "cache")
    # Class order first (step_forward before step_back in CLASS_SLUGS), then manifest order.
    assert [c.name for c in lib.clips] == ["b.bvh", "a.bvh", "c.bvh"]
    assert list(lib.class_ranges) == ["step_forward", "step_back"]
    # Resampled to 30 fps: 120 frames at 60 fps span 119/60 s -> 60 frames; 200 at 120 -> 50; 70 at 30 -> 70.
    assert [c.num_frames for c in lib.clips] == [70, 60, 50]
    assert lib.num_frames == 180 and lib.class_ranges["step_back"] == (70, 180)
    assert lib.clip("a.bvh").next == "c.bvh"
    assert lib.clip("b.bvh").source_start == 10 and lib.clip("b.bvh").source_frame(5) == 15
    assert lib.clip("c.bvh").source_frame(5) == pytest.approx(20.0)
    for arr in (lib.pos_local, lib.heading, lib.ground, lib.rot):
        assert arr.dtype == np.float32 and arr.flags.c_contiguous
    assert lib.pos_local.shape == (180, 15, 3) and lib.rot.shape == (180, 15, 4)
    assert np.array_equal(lib.frame_index[70:130], np.arange(60))


def test_subfolders_by_class(tmp_path: Path) -> None:
    for slug, seed in (("sway_balance", 1), ("fall_side_knees", 2)):
        (tmp_path / "lib" / slug).mkdir(parents=True)
        make_clip(tmp_path / "lib" / slug / f"clip{seed}.bvh", seed, 60, 30.0)
    lib = load_library(tmp_path / "lib", cache_dir=tmp_path / "cache")
    assert [c.reaction_class for c in lib.clips] == ["sway_balance", "fall_side_knees"]
    assert [c.name for c in lib.clips] == ["sway_balance/clip1.bvh", "fall_side_knees/clip2.bvh"]


def test_second_load_reads_only_the_cache(small_library: Path, tmp_path: Path, monkeypatch) -> None:
    parses = CountParses(monkeypatch)
    first = load_library(small_library, cache_dir=tmp_path / "cache")
    assert parses.calls == 3 and not first.loaded_from_cache
    second = load_library(small_library, cache_dir=tmp_path / "cache")
    assert parses.calls == 3, "an unchanged library must not parse any BVH file again"
    assert second.loaded_from_cache and second.cache_path == first.cache_path
    for name in ("pos_local", "heading", "ground", "rot", "clip_index", "frame_index"):
        assert np.array_equal(getattr(first, name), getattr(second, name))
    assert [vars(c) for c in first.clips] == [vars(c) for c in second.clips]


def test_second_load_reads_no_clip_bytes(small_library: Path, tmp_path: Path, monkeypatch) -> None:
    """Timing-free evidence: after the first load, reading any clip file fails, yet the second
    load succeeds from the cache (the clips' hashes are remembered by size and mtime)."""
    first = load_library(small_library, cache_dir=tmp_path / "cache")
    original = Path.read_bytes

    def refuse(self: Path) -> bytes:
        if self.suffix == ".bvh":
            raise AssertionError(f"{self.name} was read on a cached load")
        return original(self)

    monkeypatch.setattr(Path, "read_bytes", refuse)
    monkeypatch.setattr(bvh, "parse_bvh", lambda *a, **k: pytest.fail("a BVH file was parsed on a cached load"))
    second = load_library(small_library, cache_dir=tmp_path / "cache")
    assert second.loaded_from_cache and np.array_equal(first.pos_local, second.pos_local)


def test_editing_a_clip_or_the_manifest_invalidates(small_library: Path, tmp_path: Path, monkeypatch) -> None:
    cache = tmp_path / "cache"
    first = load_library(small_library, cache_dir=cache)
    make_clip(small_library / "c.bvh", 99, 200, 120.0)  # same name, new content
    parses = CountParses(monkeypatch)
    edited = load_library(small_library, cache_dir=cache)
    assert parses.calls == 3 and not edited.loaded_from_cache
    assert edited.cache_path != first.cache_path
    a, b = edited.class_ranges["step_back"]
    assert not np.allclose(first.pos_local[a:b], edited.pos_local[a:b])
    # The manifest and the settings are part of the key too.
    text = (small_library / "library.toml").read_text().replace('"step_forward"', '"sway_balance"')
    (small_library / "library.toml").write_text(text)
    assert not load_library(small_library, cache_dir=cache).loaded_from_cache
    assert not load_library(small_library, LibrarySettings(window=6), cache_dir=cache).loaded_from_cache
    assert load_library(small_library, LibrarySettings(window=6), cache_dir=cache).loaded_from_cache


def test_damaged_cache_is_rebuilt(small_library: Path, tmp_path: Path) -> None:
    lib = load_library(small_library, cache_dir=tmp_path / "cache")
    assert lib.cache_path is not None
    lib.cache_path.write_bytes(b"not an npz")
    again = load_library(small_library, cache_dir=tmp_path / "cache")
    assert not again.loaded_from_cache and np.array_equal(again.rot, lib.rot)


def test_a_cache_that_cannot_be_written_does_not_fail_the_load(small_library: Path, tmp_path: Path) -> None:
    """A read-only disk (here, as root, a cache folder under a regular file: it cannot be made)."""
    (tmp_path / "a_file").write_text("")
    lib = load_library(small_library, cache_dir=tmp_path / "a_file" / "cache")
    again = load_library(small_library, cache_dir=tmp_path / "a_file" / "cache")
    assert lib.cache_path is None and not again.loaded_from_cache and np.array_equal(again.rot, lib.rot)


def test_no_cache_reads_and_writes_none(small_library: Path, tmp_path: Path, monkeypatch) -> None:
    cached = load_library(small_library, cache_dir=tmp_path / "cache")
    before = sorted((tmp_path / "cache").iterdir())
    parses = CountParses(monkeypatch)
    lib = load_library(small_library, cache_dir=tmp_path / "cache", cache=False)
    assert parses.calls == 3 and not lib.loaded_from_cache and lib.cache_path is None
    assert np.array_equal(lib.rot, cached.rot) and lib.chains == cached.chains
    assert sorted((tmp_path / "cache").iterdir()) == before
    assert sorted(p.name for p in small_library.iterdir()) == ["a.bvh", "b.bvh", "c.bvh", "library.toml"]


# ---------------------------------------------------------------------------------------------
# Errors name the clip


def test_unknown_class_slug_names_the_clip(tmp_path: Path) -> None:
    make_clip(tmp_path / "a.bvh", 1, 60, 30.0)
    write_toml(tmp_path, [{"file": "a.bvh", "class": "fall_down_stairs"}])
    with pytest.raises(LibraryError, match=r"clip 'a\.bvh'.*unknown reaction class 'fall_down_stairs'"):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_unknown_class_folder_names_the_clip(tmp_path: Path) -> None:
    (tmp_path / "lib" / "tumble").mkdir(parents=True)
    make_clip(tmp_path / "lib" / "tumble" / "x.bvh", 1, 60, 30.0)
    with pytest.raises(LibraryError, match=r"clip 'tumble/x\.bvh'.*'tumble' is not a reaction class"):
        load_library(tmp_path / "lib", cache_dir=tmp_path / "cache")


def test_missing_file_names_the_clip(tmp_path: Path) -> None:
    make_clip(tmp_path / "a.bvh", 1, 60, 30.0)
    write_toml(tmp_path, [{"file": "a.bvh", "class": "step_back"}, {"file": "gone.bvh", "class": "step_back"}])
    with pytest.raises(LibraryError, match=r"clip 'gone\.bvh': file not found"):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_class_with_no_clips_when_asked(small_library: Path, tmp_path: Path) -> None:
    lib = load_library(small_library, cache_dir=tmp_path / "cache")
    with pytest.raises(LibraryError, match=r"no clips of class 'fall_forward_roll'.*step_forward \(1 clips\)"):
        lib.require_class("fall_forward_roll")
    with pytest.raises(LibraryError, match=r"unknown reaction class 'falling'"):
        lib.require_class("falling")


def test_clip_shorter_than_the_window_names_the_clip(tmp_path: Path) -> None:
    make_clip(tmp_path / "long.bvh", 1, 60, 30.0)
    make_clip(tmp_path / "short.bvh", 2, 12, 60.0)  # 12 frames at 60 fps -> 6 at 30 < 8
    write_toml(tmp_path, [{"file": "long.bvh", "class": "step_back"}, {"file": "short.bvh", "class": "step_back"}])
    message = r"clip 'short\.bvh': 6 frames at 30 fps \(12 in the file at 60 fps\) is shorter than the 8-frame"
    with pytest.raises(LibraryError, match=message):
        load_library(tmp_path, cache_dir=tmp_path / "cache")
    # A frame range can make a clip too short as well.
    write_toml(tmp_path, [{"file": "long.bvh", "class": "step_back", "frames": [0, 5]}])
    with pytest.raises(LibraryError, match=r"clip 'long\.bvh'.*shorter than the 8-frame"):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_skeleton_without_roles_names_the_clip(tmp_path: Path) -> None:
    skeleton = Skeleton(
        ["Hips", "Spine", "Head"], np.asarray([-1, 0, 1]), np.asarray([[0, 0, 1.0], [0, 0, 0.3], [0, 0, 0.4]])
    )
    frames = 30
    motion = Motion(skeleton, 30.0, np.zeros((frames, 3)), quat.identity((frames, 3)))
    bvh.write_bvh(tmp_path / "stick.bvh", motion)
    write_toml(tmp_path, [{"file": "stick.bvh", "class": "sway_balance"}])
    message = r"clip 'stick\.bvh': its skeleton lacks joint roles the search needs: .*hip_l"
    with pytest.raises(LibraryError, match=message):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_unreadable_bvh_names_the_clip(tmp_path: Path) -> None:
    (tmp_path / "bad.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    write_toml(tmp_path, [{"file": "bad.bvh", "class": "sway_balance"}])
    with pytest.raises(LibraryError, match=r"clip 'bad\.bvh': .*bad\.bvh, line"):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_manifest_errors_name_the_clip(tmp_path: Path) -> None:
    make_clip(tmp_path / "a.bvh", 1, 60, 30.0)
    cases = [
        (
            {"file": "a.bvh", "class": "step_back", "next": "b.bvh"},
            r"clip 'a\.bvh': next = 'b\.bvh' is neither a \[\[clip\]\] nor",
        ),
        ({"file": "a.bvh", "class": "step_back", "frames": [5, 2]}, r"clip 'a\.bvh': frames \[5, 2\] is not a range"),
        (
            {"file": "a.bvh", "class": "step_back", "frames": [0, 500]},
            r"clip 'a\.bvh': frames \[0, 500\] run past the file's 60 frames",
        ),
        ({"file": "a.bvh", "class": "step_back", "speed": 2}, r"clip 'a\.bvh': unknown keys speed"),
    ]
    for clip, message in cases:
        write_toml(tmp_path, [clip])
        with pytest.raises(LibraryError, match=message):
            load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_role_overrides_per_clip(tmp_path: Path) -> None:
    make_clip(tmp_path / "a.bvh", 1, 60, 30.0)
    write_toml(tmp_path, [{"file": "a.bvh", "class": "step_back", "roles": {"ankle_l": "toe.L"}}])
    entries = read_manifest(tmp_path)
    assert dict(entries[0].roles) == {"ankle_l": "toe.L"}
    plain = tmp_path / "plain"
    plain.mkdir()
    write_toml(plain, [{"file": str(tmp_path / "a.bvh"), "class": "step_back"}])
    a = load_library(tmp_path, cache_dir=tmp_path / "c1")
    b = load_library(plain / "library.toml", cache_dir=tmp_path / "c2")
    ankle_l = 13  # SEARCH_ROLES index
    assert not np.allclose(a.pos_local[:, ankle_l], b.pos_local[:, ankle_l])  # the left ankle moved to the toe
    others = [j for j in range(15) if j != ankle_l]
    assert np.allclose(a.pos_local[:, others], b.pos_local[:, others])


def test_class_slugs_are_the_papers_ten_then_the_side_steps() -> None:
    assert CLASS_SLUGS == (
        "step_forward", "steps_forward", "step_back", "steps_back", "sway_balance",
        "fall_forward_roll", "fall_forward_hands", "fall_backward_sit", "fall_backward_hands", "fall_side_knees",
        "step_left", "step_right",
    )  # fmt: skip


def test_next_may_name_a_chained_clip_that_is_not_searched(tmp_path: Path) -> None:
    make_clip(tmp_path / "fall.bvh", 1, 60, 30.0)
    make_clip(tmp_path / "getup.bvh", 2, 60, 30.0)
    (tmp_path / "library.toml").write_text(
        '[[clip]]\nfile = "fall.bvh"\nclass = "fall_backward_sit"\nnext = "getup.bvh"\n\n'
        '[[chain]]\nfile = "getup.bvh"\n',
        encoding="utf-8",
    )
    lib = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert [c.name for c in lib.clips] == ["fall.bvh"]  # the get-up is no search candidate
    assert lib.clip("fall.bvh").next == "getup.bvh"
    assert read_chains(tmp_path) == {"getup.bvh": tmp_path / "getup.bvh"}
    # The bake plays the get-up: editing it gives the library a new cache key, so a kept Library
    # (the Blender layer keeps one per key) is never served with the old get-up.
    old = lib.clip_motion("getup.bvh", 30.0)
    make_clip(tmp_path / "getup.bvh", 3, 60, 30.0)
    edited = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert edited.cache_path != lib.cache_path
    assert not np.array_equal(edited.clip_motion("getup.bvh", 30.0).local_rot, old.local_rot)
    (tmp_path / "getup.bvh").unlink()
    with pytest.raises(LibraryError, match=r"clip 'getup\.bvh': file not found"):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_the_sample_library_loads(tmp_path: Path) -> None:
    """The project's own clips (sample_clips/) form a library: every class, 3+ clips each."""
    folder = REPO / "sample_clips"
    lib = load_library(folder, cache_dir=tmp_path / "cache")
    chains = read_chains(folder)
    for slug in CLASS_SLUGS:
        assert sum(c.reaction_class == slug for c in lib.clips) >= 3, slug
    assert all(c.next is None or c.next in chains for c in lib.clips)
    assert all(c.next is not None for c in lib.clips if c.reaction_class.startswith("fall_"))


def test_a_library_builds_its_search_index_once(small_library: Path, tmp_path: Path, monkeypatch) -> None:
    """The search index (window summaries, the tree, the strategy per scope) is built on the first
    search of a Library and reused by every later one (a bake searches once per impact)."""
    lib = load_library(small_library, cache_dir=tmp_path / "cache")
    query = Query(lib.features(5, 5 + lib.window))
    first = search(lib, query)

    def no_rebuild(*args, **kwargs):
        raise AssertionError("search index built again")

    monkeypatch.setattr(library_module, "build_index", no_rebuild)
    assert search(lib, query) == first


# ---------------------------------------------------------------------------------------------
# Chains take frames; a calibration first frame is never searched or played


def _write_manifest(folder: Path, clips: list[str], chains: list[str]) -> Path:
    """A library.toml of [[clip]] and [[chain]] tables given as TOML bodies."""
    text = "".join(f"[[clip]]\n{body}\n\n" for body in clips) + "".join(f"[[chain]]\n{body}\n\n" for body in chains)
    path = folder / "library.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _opening_on_a_calibration_pose(path: Path, seed: int, drop: float = 0.8) -> Motion:
    """A clip whose first frame is a calibration pose: every joint at rest (a T-pose) and `drop`
    metres lower, as CMU's converter frames are; the take follows. Written to `path`; returns the
    take (what must be played)."""
    make_clip(path, seed, 61, 30.0)
    take = bvh.read_bvh(path)
    rest = quat.identity((1, take.skeleton.num_joints))
    local_pos = None if take.local_pos is None else take.local_pos[:1]
    pose = Motion(take.skeleton, take.fps, take.root_pos[:1] - np.array([0.0, 0.0, drop]), rest, local_pos)
    bvh.write_bvh(path, pose.concat(take))
    return take


def test_a_chain_takes_frames_like_a_clip(tmp_path: Path) -> None:
    """`[[chain]] frames = [start, end]` (BVH frames, end exclusive, as a clip's): the get-up plays
    those frames only; they are part of the cache key and kept with the cache."""
    make_clip(tmp_path / "fall.bvh", 1, 60, 30.0)
    make_clip(tmp_path / "getup.bvh", 2, 60, 30.0)
    _write_manifest(tmp_path, ['file = "fall.bvh"\nclass = "fall_backward_sit"\nnext = "getup.bvh"'],
                    ['file = "getup.bvh"\nframes = [12, 50]'])  # fmt: skip
    lib = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert [(c.name, c.frames) for c in read_chain_entries(tmp_path)] == [("getup.bvh", (12, 50))]
    assert lib.chain_frames == {"getup.bvh": (12, 50)}
    played, file = lib.clip_motion("getup.bvh", 30.0), bvh.read_bvh(tmp_path / "getup.bvh")
    assert np.array_equal(played.root_pos, file.root_pos[12:50])
    assert np.array_equal(played.local_rot, file.local_rot[12:50])
    cached = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert cached.loaded_from_cache and cached.chain_frames == lib.chain_frames
    assert np.array_equal(cached.clip_motion("getup.bvh", 30.0).local_rot, played.local_rot)
    _write_manifest(tmp_path, ['file = "fall.bvh"\nclass = "fall_backward_sit"\nnext = "getup.bvh"'],
                    ['file = "getup.bvh"\nframes = [20, 50]'])  # fmt: skip
    moved = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert not moved.loaded_from_cache and moved.chain_frames == {"getup.bvh": (20, 50)}
    assert np.array_equal(moved.clip_motion("getup.bvh", 30.0).root_pos, file.root_pos[20:50])


@pytest.mark.parametrize(
    ("chain", "message"),
    [
        ("frames = [5, 2]", r"clip 'getup\.bvh': frames \[5, 2\] is not a range"),
        ("frames = [0, 500]", r"clip 'getup\.bvh': frames \[0, 500\] run past the file's 60 frames"),
        ("frames = [1.5, 30]", r"clip 'getup\.bvh': frames must be \[start, end\] integers"),
        ("frames = [3]", r"clip 'getup\.bvh': frames must be \[start, end\] integers"),
        ("speed = 2", r"clip 'getup\.bvh': unknown keys speed in \[\[chain\]\] of .*library\.toml"),
    ],
)
def test_a_chains_frames_are_checked_as_a_clips_and_errors_name_it(tmp_path: Path, chain: str, message: str) -> None:
    make_clip(tmp_path / "fall.bvh", 1, 60, 30.0)
    make_clip(tmp_path / "getup.bvh", 2, 60, 30.0)
    _write_manifest(tmp_path, ['file = "fall.bvh"\nclass = "fall_backward_sit"\nnext = "getup.bvh"'],
                    [f'file = "getup.bvh"\n{chain}'])  # fmt: skip
    with pytest.raises(LibraryError, match=message):
        load_library(tmp_path, cache_dir=tmp_path / "cache")


def test_a_calibration_first_frame_is_never_searched_or_played(tmp_path: Path) -> None:
    """A clip and a chain whose first frame is a calibration pose (0.8 m in a frame: 24 m/s, over
    the 20 m/s of library.take_start, the rule casting.py reads a character's floor by): the
    library compiles them from their second frame, exactly as if `frames` said so, and the bake
    reads them from there. A first frame left at a walking pace stays (5 cm lower: 1.5 m/s)."""
    fall = _opening_on_a_calibration_pose(tmp_path / "fall.bvh", 1)
    getup = _opening_on_a_calibration_pose(tmp_path / "getup.bvh", 2)
    _opening_on_a_calibration_pose(tmp_path / "stepped.bvh", 3, drop=0.05)
    _write_manifest(tmp_path, ['file = "fall.bvh"\nclass = "fall_backward_sit"\nnext = "getup.bvh"',
                               'file = "stepped.bvh"\nclass = "step_back"'], ['file = "getup.bvh"'])  # fmt: skip
    lib = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert lib.clip("fall.bvh").source_start == 1 and lib.clip("stepped.bvh").source_start == 0
    assert lib.chain_frames == {"getup.bvh": (1, 62)}
    for name, take in (("fall.bvh", fall), ("getup.bvh", getup)):
        played = lib.clip_motion(name, 30.0)
        assert np.array_equal(played.root_pos, take.root_pos) and np.array_equal(played.local_rot, take.local_rot)
    # Searched from frame 1: the features are those of the same file listed from its frame 1.
    listed = tmp_path / "listed"
    listed.mkdir()
    _write_manifest(listed, [f'file = "{tmp_path / "fall.bvh"}"\nclass = "fall_backward_sit"\nframes = [1, 62]'], [])
    reference = load_library(listed, cache_dir=tmp_path / "cache")
    a, b = lib.class_ranges["fall_backward_sit"]
    assert np.array_equal(lib.pos_local[a:b], reference.pos_local) and np.array_equal(lib.rot[a:b], reference.rot)
    # `frames` from the file's first frame drop it too; from a later frame nothing is dropped.
    _write_manifest(tmp_path, ['file = "fall.bvh"\nclass = "fall_backward_sit"\nframes = [0, 40]'],
                    ['file = "getup.bvh"\nframes = [0, 30]'])  # fmt: skip
    cut = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert cut.clip("fall.bvh").source_start == 1 and cut.chain_frames == {"getup.bvh": (1, 30)}
    _write_manifest(tmp_path, ['file = "fall.bvh"\nclass = "fall_backward_sit"\nframes = [3, 40]'],
                    ['file = "getup.bvh"\nframes = [3, 30]'])  # fmt: skip
    later = load_library(tmp_path, cache_dir=tmp_path / "cache")
    assert later.clip("fall.bvh").source_start == 3 and later.chain_frames == {"getup.bvh": (3, 30)}


def test_a_library_assembled_by_hand_plays_its_chains_without_the_calibration_frame(tmp_path: Path) -> None:
    """A Library made from compiled clips (benchmarks do) and given chains afterwards finds a
    chain's frames when the bake first reads it, by the same rule."""
    make_clip(tmp_path / "fall.bvh", 1, 60, 30.0)
    getup = _opening_on_a_calibration_pose(tmp_path / "getup.bvh", 2)
    entry = read_manifest(write_toml(tmp_path, [{"file": "fall.bvh", "class": "fall_backward_sit"}]))[0]
    lib = Library.concatenate([compile_clip(entry, LibrarySettings())], LibrarySettings())
    lib.chains = {"getup.bvh": tmp_path / "getup.bvh"}
    assert np.array_equal(lib.clip_motion("getup.bvh", 30.0).root_pos, getup.root_pos)
