"""The library's manifest (`library.toml`): which BVH files are clips of which class, their frame
ranges, role overrides and chained get-ups, read and checked before any file is (errors name the
entry and what is wrong with it). The format is in library.py's docstring and docs/library.md."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from ..model.classes import CLASS_SLUGS
from ..model.errors import LibraryError

MANIFEST_NAME = "library.toml"


@dataclass(frozen=True)
class ClipEntry:
    """One clip as the manifest gives it (before reading the file)."""

    name: str  # the manifest's `file` value; names the clip in errors and matches
    path: Path
    reaction_class: str
    frames: tuple[int, int] | None = None
    next: str | None = None
    roles: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class ChainEntry:
    """One chained clip (a get-up) as the manifest gives it: reached only through a clip's `next`."""

    name: str  # the manifest's `file` value, as `next` names it
    path: Path
    frames: tuple[int, int] | None = None


def entry_error(name: str, message: str) -> LibraryError:
    return LibraryError(f"clip '{name}': {message}")


def read_manifest(source: str | Path) -> list[ClipEntry]:
    """Clip entries of a library: a library.toml (or a folder holding one), else class sub-folders."""
    source = Path(source)
    toml_path = source if source.suffix == ".toml" else source / MANIFEST_NAME
    if toml_path.is_file():
        return _read_toml(toml_path)
    if not source.is_dir():
        raise LibraryError(f"no reaction library at {source}: neither a folder nor a {MANIFEST_NAME}")
    entries: list[ClipEntry] = []
    for sub in sorted(p for p in source.iterdir() if p.is_dir()):
        if sub.name.startswith("."):
            continue
        for path in sorted(sub.glob("*.bvh")):
            name = f"{sub.name}/{path.name}"
            if sub.name not in CLASS_SLUGS:
                classes = ", ".join(CLASS_SLUGS)
                raise entry_error(name, f"folder '{sub.name}' is not a reaction class; classes are: {classes}")
            entries.append(ClipEntry(name, path, sub.name))
    if not entries:
        raise LibraryError(f"no clips in {source}: write a {MANIFEST_NAME} or put BVH files in folders named by class")
    return entries


def _read_toml(toml_path: Path) -> list[ClipEntry]:
    try:
        data = tomllib.loads(toml_path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise LibraryError(f"{toml_path}: not a valid TOML file: {exc}") from None
    clips = _toml_list(data.get("clip", []))
    if clips is None or not clips:
        raise LibraryError(f"{toml_path}: no [[clip]] tables")
    entries: list[ClipEntry] = []
    names: set[str] = set()
    for k, item in enumerate(clips, 1):
        table = _toml_table(item)
        name = str(table.get("file", "")) if table is not None else ""
        if table is None or not name:
            raise LibraryError(f"{toml_path}: [[clip]] number {k} has no 'file'")
        unknown = set(table) - {"file", "class", "frames", "next", "roles"}
        if unknown:
            raise entry_error(name, f"unknown keys {', '.join(sorted(unknown))} in {toml_path}")
        slug = table.get("class")
        if not isinstance(slug, str) or slug not in CLASS_SLUGS:
            raise entry_error(name, f"unknown reaction class {slug!r}; classes are: {', '.join(CLASS_SLUGS)}")
        frames = _frame_range(name, table.get("frames"))
        if name in names:
            raise entry_error(name, f"listed twice in {toml_path}")
        names.add(name)
        path = Path(name) if Path(name).is_absolute() else toml_path.parent / name
        given_roles = table.get("roles", {})
        overrides = _toml_table(given_roles)
        if overrides is None:
            raise entry_error(name, f"roles must be a table of role = joint name, got {given_roles!r}")
        # Read as given: a `next` that names no clip (a non-string included) is refused below, a role
        # whose value names no joint by assign_roles when the clip is compiled.
        next_clip = cast(str | None, table.get("next"))
        roles = cast(dict[str, str], overrides)
        entries.append(ClipEntry(name, path, slug, frames, next_clip, tuple(sorted(roles.items()))))
    chains = _chain_entries(toml_path, data)
    for entry in entries:
        if entry.next is not None and entry.next not in names and entry.next not in chains:
            raise entry_error(
                entry.name, f"next = {entry.next!r} is neither a [[clip]] nor a [[chain]] of this library"
            )
    return entries


def _frame_range(name: str, frames: object) -> tuple[int, int] | None:
    """An entry's `frames` ([start, end]: BVH frames, start inclusive, end exclusive) checked; errors
    name the entry. (Past the file's end is checked when the file is read: used_frames.)"""
    if frames is None:
        return None
    values = _toml_list(frames)
    ints = [v for v in values if type(v) is int] if values is not None else []
    if values is None or len(values) != 2 or len(ints) != 2:
        raise entry_error(name, f"frames must be [start, end] integers, got {frames!r}")
    start, end = ints
    if not 0 <= start < end:
        raise entry_error(name, f"frames [{start}, {end}] is not a range (need 0 <= start < end)")
    return start, end


def _toml_list(value: object) -> list[object] | None:
    """A TOML array (its items of any TOML type), None for any other value."""
    return cast(list[object], value) if isinstance(value, list) else None


def _toml_table(value: object) -> dict[str, object] | None:
    """A TOML table (its keys strings, its values of any TOML type), None for any other value."""
    return cast(dict[str, object], value) if isinstance(value, dict) else None


def _chain_entries(toml_path: Path, data: dict[str, object]) -> dict[str, ChainEntry]:
    """The [[chain]] tables: clips played only after another (get-ups), name -> entry (an existing
    file, its optional frames checked as a clip's are)."""
    chains = _toml_list(data.get("chain", []))
    if chains is None:
        raise LibraryError(f"{toml_path}: 'chain' must be a list of [[chain]] tables")
    out: dict[str, ChainEntry] = {}
    for k, item in enumerate(chains, 1):
        table = _toml_table(item)
        name = str(table.get("file", "")) if table is not None else ""
        if table is None or not name:
            raise LibraryError(f"{toml_path}: [[chain]] number {k} has no 'file'")
        unknown = set(table) - {"file", "frames"}
        if unknown:
            raise entry_error(name, f"unknown keys {', '.join(sorted(unknown))} in [[chain]] of {toml_path}")
        frames = _frame_range(name, table.get("frames"))
        if name in out:
            raise entry_error(name, f"listed twice as a [[chain]] in {toml_path}")
        path = Path(name) if Path(name).is_absolute() else toml_path.parent / name
        if not path.is_file():
            raise entry_error(name, f"file not found: {path}")
        out[name] = ChainEntry(name, path, frames)
    return out


def read_chain_entries(source: str | Path) -> list[ChainEntry]:
    """The chained clips (get-ups) a library's manifest lists, in manifest order."""
    source = Path(source)
    toml_path = source if source.suffix == ".toml" else source / MANIFEST_NAME
    if not toml_path.is_file():
        return []
    try:
        data = tomllib.loads(toml_path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise LibraryError(f"{toml_path}: not a valid TOML file: {exc}") from None
    return list(_chain_entries(toml_path, data).values())


def read_chains(source: str | Path) -> dict[str, Path]:
    """The chained clips (get-ups) a library's manifest lists, by the name `next` uses."""
    return {c.name: c.path for c in read_chain_entries(source)}
