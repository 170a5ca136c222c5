#!/usr/bin/env python3
"""Build the reactive_anim extension: one zip per platform, made and checked by Blender's own tool.

    python tools/build_extension.py                          # linux-x64, windows-x64, macos-arm64
    python tools/build_extension.py --platform linux-x64     # only some

Each zip holds the add-on package at its root (so `__init__.py` is at the top, as Blender expects),
`blender_manifest.toml` and `wheels/*.whl`: mujoco and onnxruntime with their dependencies for
that platform and for every Python the supported Blender lines embed (tools/requirements/
environments.txt: 3.11 for 4.2-5.0, 3.13 for 5.1-5.2), at the versions pinned in tools/requirements/
(simulation results change between MuJoCo versions, so the zip must carry exactly the pinned one).
One zip serves every line: Blender installs only the wheels whose Python tag matches its own.
numpy is never bundled: Blender ships its own, and a second copy in the extension's site-packages
would shadow it (bpy 5.0.1 needs numpy < 2, 5.2 ships numpy 2). The dependency resolution is
still done against the numpy Blender ships, so a dependency that needs a different numpy fails
here and not on a user's machine.

Wheels are downloaded once per platform and Python into .venv/wheel-cache/<platform>-cp3XX; a
second build with the same pins runs offline. The zip is written by `blender_ext.py build
--split-platforms` (which adds Blender's generated platform table to the manifest) and checked by
`blender_ext.py validate`, both from the bpy wheel of the running interpreter unless
`--blender-ext` names another.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
import zipfile
from dataclasses import dataclass
from importlib.util import find_spec
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # one of the two, typed as the standalone one (pip's is a copy of it)
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name, parse_wheel_filename
    from packaging.version import Version
else:
    try:
        from packaging.requirements import Requirement
        from packaging.utils import canonicalize_name, parse_wheel_filename
        from packaging.version import Version
    except ImportError:  # pip always vendors packaging, so the tool needs nothing pip does not have
        from pip._vendor.packaging.requirements import Requirement
        from pip._vendor.packaging.utils import canonicalize_name, parse_wheel_filename
        from pip._vendor.packaging.version import Version

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIR = REPO / "reactive_anim"
MANIFEST = REPO / "blender_manifest.toml"
# The sample reaction library ships inside the zip as `sample_library/` (the bake's default library;
# blender/bake/bake.py looks for it there), so an installed extension bakes without a checkout.
SAMPLE_LIBRARY = REPO / "sample_clips"
SAMPLE_FILES = ("*.bvh", "library.toml", "README.md")
PYPROJECT = REPO / "pyproject.toml"
REQUIREMENTS = REPO / "tools" / "requirements"
# The supported Blender lines and the Python each embeds; the bundled versions are pinned in the
# newest line's environment of each Python (bpy-<line>.txt).
ENVIRONMENTS = REQUIREMENTS / "environments.txt"
# mujoco-core is the simulator itself (the `mujoco` module); the `mujoco` meta package would add
# mujoco-studio (a viewer with a websocket server), glfw, PyOpenGL and websockets, which a bake never uses.
BUNDLED_ROOTS = ("mujoco-core", "onnxruntime")
# Blender provides these; bundling one would shadow Blender's copy for every add-on.
NEVER_BUNDLED = ("numpy",)
DEFAULT_CACHE = REPO / ".venv" / "wheel-cache"
DEFAULT_DIST = REPO / "dist"
# Development-only files that must never reach a user's Blender.
PACKAGE_IGNORE = ("__pycache__", "*.pyc", "tests", ".*", "*.blend[1-9]")
# Sources whose change makes a built zip stale.
BUILD_INPUTS = (PACKAGE_DIR, MANIFEST, REQUIREMENTS, SAMPLE_LIBRARY, Path(__file__).resolve())

# onnxruntime 1.32.0 publishes macOS arm64 wheels for macosx_14_0 only, so the macOS zip needs
# macOS 14 or newer (Blender itself runs on 11.2+). Raising this lets pip pick wheels that need
# a newer macOS; lowering it makes onnxruntime unresolvable.
MACOS_ARM64_MIN_MAJOR = 14
# Blender 4.2+ Linux builds require glibc 2.28, so every manylinux wheel up to 2_28 runs there.
GLIBC_MINOR_MAX = 28


@dataclass(frozen=True)
class Platform:
    """A Blender platform, the pip tags of the wheels that run on it, and its environment markers."""

    name: str
    pip_tags: tuple[str, ...]
    sys_platform: str
    system: str
    machine: str
    os_name: str

    def markers(self, python: str) -> dict[str, str]:
        """PEP 508 environment of Blender's Python on the target, to evaluate dependency markers."""
        return {
            "python_version": python,
            "python_full_version": f"{python}.0",
            "implementation_name": "cpython",
            "platform_python_implementation": "CPython",
            "sys_platform": self.sys_platform,
            "platform_system": self.system,
            "platform_machine": self.machine,
            "os_name": self.os_name,
            "extra": "",
        }


@dataclass(frozen=True)
class PythonLine:
    """A Python that supported Blender lines embed, and the requirements file that pins its wheels."""

    version: str
    pins_file: Path

    @property
    def tag(self) -> str:
        return "cp" + self.version.replace(".", "")


def _manylinux_x86_64_tags() -> tuple[str, ...]:
    """Newest glibc first, plus the legacy aliases (pip does not expand them for --platform)."""
    modern = tuple(f"manylinux_2_{minor}_x86_64" for minor in range(GLIBC_MINOR_MAX, 4, -1))
    return (*modern, "manylinux2014_x86_64", "manylinux2010_x86_64", "manylinux1_x86_64")


def _macos_arm64_tags() -> tuple[str, ...]:
    """Every macOS arm64 and universal2 tag up to the minimum macOS the zip supports."""
    arm = tuple(f"macosx_{major}_0_arm64" for major in range(MACOS_ARM64_MIN_MAJOR, 10, -1))
    universal = tuple(f"macosx_{major}_0_universal2" for major in range(MACOS_ARM64_MIN_MAJOR, 10, -1))
    legacy_universal = tuple(f"macosx_10_{minor}_universal2" for minor in range(16, 8, -1))
    return (*arm, *universal, *legacy_universal)


PLATFORMS: dict[str, Platform] = {
    p.name: p
    for p in (
        Platform("linux-x64", _manylinux_x86_64_tags(), "linux", "Linux", "x86_64", "posix"),
        Platform("windows-x64", ("win_amd64",), "win32", "Windows", "AMD64", "nt"),
        Platform("macos-arm64", _macos_arm64_tags(), "darwin", "Darwin", "arm64", "posix"),
    )
}


@dataclass(frozen=True)
class Wheel:
    """One downloaded wheel: what it is and what it asks for (from its METADATA)."""

    path: Path
    name: str
    version: Version
    requires: tuple[str, ...]


# ---------------------------------------------------------------------------------------------
# Pins and manifest


def blender_lines() -> dict[str, str]:
    """`line -> Python version` of every supported Blender line (the bpy-<line> environments)."""
    lines: dict[str, str] = {}
    for row in ENVIRONMENTS.read_text().splitlines():
        fields = row.split("#", 1)[0].split()
        if fields and fields[0].startswith("bpy-"):
            lines[fields[0].removeprefix("bpy-")] = fields[1]
    return lines


def python_lines() -> list[PythonLine]:
    """Each Python the supported lines embed, pinned by the newest line that embeds it."""
    newest: dict[str, str] = {}
    for line, python in blender_lines().items():
        if python not in newest or Version(line) > Version(newest[python]):
            newest[python] = line
    return [PythonLine(python, REQUIREMENTS / f"bpy-{line}.txt") for python, line in sorted(newest.items())]


def read_pins(path: Path) -> dict[str, str]:
    """`name -> "name==version"` for every pinned line of a requirements file (comments skipped)."""
    pins: dict[str, str] = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            pins[canonicalize_name(line.split("==", 1)[0])] = line
    return pins


def bundle_requirements(pins_file: Path) -> list[str]:
    """The pinned requirement lines of the packages the zip bundles, failing if one is not pinned."""
    pins = read_pins(pins_file)
    missing = [name for name in BUNDLED_ROOTS if name not in pins]
    if missing:
        raise SystemExit(f"build_extension: {pins_file} pins no version for {', '.join(missing)}")
    return [pins[name] for name in BUNDLED_ROOTS]


def read_manifest() -> dict:
    """The source manifest, checked against pyproject's version so the two cannot drift apart."""
    manifest = tomllib.loads(MANIFEST.read_text())
    project_version = tomllib.loads(PYPROJECT.read_text())["project"]["version"]
    if manifest["version"] != project_version:
        raise SystemExit(
            f"build_extension: {MANIFEST.name} version {manifest['version']} differs from "
            f"pyproject.toml version {project_version}"
        )
    return manifest


def set_toml_array(text: str, key: str, values: list[str]) -> str:
    """Replace the top-level `key = [...]` array of a TOML text, keeping the rest byte for byte."""
    pattern = re.compile(rf"^{re.escape(key)}\s*=\s*\[[^\]]*\]", re.MULTILINE)
    if not pattern.search(text):
        raise SystemExit(f"build_extension: {MANIFEST.name} has no top-level '{key} = [...]' to fill in")
    if key == "platforms":
        body = "[" + ", ".join(json.dumps(v) for v in values) + "]"
    else:
        body = "[\n" + "".join(f"  {json.dumps(v)},\n" for v in values) + "]"
    return pattern.sub(lambda _match: f"{key} = {body}", text, count=1)


def zip_path(output_dir: Path, manifest: dict, platform: str) -> Path:
    """Where `blender_ext.py build --split-platforms` writes a platform's zip (it uses `linux_x64`)."""
    return output_dir / f"{manifest['id']}-{manifest['version']}-{platform.replace('-', '_')}.zip"


def newest_input_mtime() -> float:
    """The latest modification time among the files a zip is built from."""
    newest = 0.0
    for root in BUILD_INPUTS:
        files = [root] if root.is_file() else [p for p in root.rglob("*") if p.is_file()]
        for path in files:
            if "__pycache__" not in path.parts:
                newest = max(newest, path.stat().st_mtime)
    return newest


def is_up_to_date(zip_file: Path) -> bool:
    """True when the zip exists and is newer than the package, the manifest, the pins and this tool."""
    return zip_file.is_file() and zip_file.stat().st_mtime > newest_input_mtime()


# ---------------------------------------------------------------------------------------------
# Wheels: download, then choose what to bundle


def pip_download(
    platform: Platform, python: PythonLine, requirements: list[str], constraints: list[str], dest: Path
) -> None:
    """Let pip resolve and fetch binary wheels for the target (files already in `dest` are reused)."""
    dest.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as handle:
        handle.write("\n".join(constraints) + "\n")
    try:
        command = [
            sys.executable,
            "-m",
            "pip",
            "download",
            "--disable-pip-version-check",
            "--progress-bar",
            "off",
            "--only-binary=:all:",
            "--python-version",
            python.version,
            "--implementation",
            "cp",
            *(arg for tag in platform.pip_tags for arg in ("--platform", tag)),
            "--constraint",
            handle.name,
            "--dest",
            str(dest),
            *requirements,
        ]
        print(f"[{platform.name} {python.tag}] pip download {' '.join(requirements)}", flush=True)
        completed = subprocess.run(command, capture_output=True, text=True)
    finally:
        os.unlink(handle.name)
    if completed.returncode != 0:
        output = completed.stdout + completed.stderr
        raise SystemExit(f"build_extension: pip download for {platform.name} {python.tag} failed:\n{output}")


def read_wheel(path: Path) -> Wheel:
    """Name, version and Requires-Dist of a wheel, read from its METADATA without installing it."""
    name, version, _build, _tags = parse_wheel_filename(path.name)
    with zipfile.ZipFile(path) as archive:
        metadata_name = next(n for n in archive.namelist() if re.fullmatch(r"[^/]+\.dist-info/METADATA", n))
        metadata = archive.read(metadata_name).decode("utf-8", "replace")
    header = metadata.split("\n\n", 1)[0]
    requires = tuple(line.split(":", 1)[1].strip() for line in header.splitlines() if line.startswith("Requires-Dist:"))
    return Wheel(path, canonicalize_name(name), version, requires)


def resolve_bundle(wheels: list[Wheel], roots: list[str], markers: dict[str, str]) -> list[Wheel]:
    """The wheels reachable from `roots` through dependencies that apply on the target.

    Walking the graph (instead of taking every file pip saved) leaves out numpy and anything pulled
    in only for numpy, and ignores stale versions a cache kept from older pins: for each name the
    newest cached version that satisfies the requirement is taken, which is what pip resolved.
    """
    by_name: dict[str, list[Wheel]] = {}
    for wheel in wheels:
        by_name.setdefault(wheel.name, []).append(wheel)
    chosen: dict[str, Wheel] = {}
    pending = [Requirement(root) for root in roots]
    while pending:
        requirement = pending.pop()
        name = canonicalize_name(requirement.name)
        if requirement.marker is not None and not requirement.marker.evaluate(markers):
            continue
        if name in NEVER_BUNDLED or name in chosen:
            continue
        candidates = [w for w in by_name.get(name, []) if requirement.specifier.contains(w.version, prereleases=True)]
        if not candidates:
            raise SystemExit(f"build_extension: no downloaded wheel satisfies '{requirement}'")
        chosen[name] = max(candidates, key=lambda w: w.version)
        pending.extend(Requirement(r) for r in chosen[name].requires)
    return sorted(chosen.values(), key=lambda w: w.name)


def platform_wheels(platform: Platform, cache_root: Path, refresh: bool) -> list[Path]:
    """The wheel files to bundle for one platform, for every Python of the supported lines.

    A pure-Python wheel that both Pythons need is bundled once (same file name, same file).
    """
    unique: dict[str, Path] = {}
    for python in python_lines():
        for wheel in python_wheels(platform, python, cache_root, refresh):
            unique.setdefault(wheel.name, wheel)
    return sorted(unique.values(), key=lambda wheel: wheel.name)


def python_wheels(platform: Platform, python: PythonLine, cache_root: Path, refresh: bool) -> list[Path]:
    """The wheel files to bundle for one platform and Python, downloading only when the pins changed."""
    pins = read_pins(python.pins_file)
    requirements = bundle_requirements(python.pins_file)
    constraints = [pins[name] for name in NEVER_BUNDLED if name in pins]
    cache = cache_root / f"{platform.name}-{python.tag}"
    stamp = cache / "resolved.json"
    key = {"requirements": requirements, "constraints": constraints, "pip_tags": list(platform.pip_tags)}
    if not refresh and stamp.is_file():
        recorded = json.loads(stamp.read_text())
        files = [cache / name for name in recorded["bundle"]]
        if recorded["key"] == key and all(f.is_file() for f in files):
            print(f"[{platform.name} {python.tag}] wheels from cache {cache} (offline)", flush=True)
            return files
    pip_download(platform, python, requirements, constraints, cache)
    bundle = resolve_bundle(
        [read_wheel(p) for p in sorted(cache.glob("*.whl"))], requirements, platform.markers(python.version)
    )
    stamp.write_text(json.dumps({"key": key, "bundle": [w.path.name for w in bundle]}, indent=1) + "\n")
    return [w.path for w in bundle]


# ---------------------------------------------------------------------------------------------
# Blender's extension tool


def find_blender_ext(explicit: str | None) -> Path:
    """blender_ext.py from the bpy wheel of this interpreter (found without importing bpy)."""
    if explicit:
        return Path(explicit).resolve()
    spec = find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("build_extension: bpy is not installed here; pass --blender-ext PATH/blender_ext.py")
    bpy_dir = Path(next(iter(spec.submodule_search_locations)))
    found = sorted(bpy_dir.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        raise SystemExit(f"build_extension: no blender_ext.py under {bpy_dir}; pass --blender-ext")
    return found[-1]


def valid_tags_file(blender_ext: Path) -> Path | None:
    """Blender's own list of valid tags (`_bpy_internal/extensions/tags.py`), so tags get checked too."""
    scripts = blender_ext.parents[3]
    tags = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    return tags if tags.is_file() else None


def run_blender_ext(blender_ext: Path, *args: str) -> str:
    """Run one blender_ext.py command; its output is the verdict, so it is returned (and failure stops)."""
    tags = valid_tags_file(blender_ext)
    tag_args = ["--valid-tags", str(tags)] if tags else []
    completed = subprocess.run([sys.executable, str(blender_ext), *args, *tag_args], capture_output=True, text=True)
    output = (completed.stdout + completed.stderr).strip()
    if completed.returncode != 0:
        raise SystemExit(f"build_extension: blender_ext {args[0]} failed:\n{output}")
    return output


# ---------------------------------------------------------------------------------------------
# Staging and building


def stage(stage_dir: Path, platform: str, wheels: list[Path]) -> list[str]:
    """Lay out the zip's contents: the package at the root, the sample library, the filled-in
    manifest, the wheels."""
    shutil.copytree(PACKAGE_DIR, stage_dir, ignore=shutil.ignore_patterns(*PACKAGE_IGNORE))
    library = stage_dir / "sample_library"
    library.mkdir()
    for pattern in SAMPLE_FILES:
        for path in sorted(SAMPLE_LIBRARY.glob(pattern)):
            shutil.copy2(path, library / path.name)
    (stage_dir / "wheels").mkdir()
    for wheel in wheels:
        shutil.copy2(wheel, stage_dir / "wheels" / wheel.name)
    entries = [f"./wheels/{wheel.name}" for wheel in wheels]
    text = set_toml_array(MANIFEST.read_text(), "wheels", entries)
    (stage_dir / MANIFEST.name).write_text(set_toml_array(text, "platforms", [platform]))
    return entries


def check_zip_wheels(zip_file: Path, expected: list[str]) -> None:
    """Fail if Blender's per-platform filter dropped a wheel (it reads platforms from file names)."""
    with zipfile.ZipFile(zip_file) as archive:
        present = sorted("./" + n for n in archive.namelist() if n.startswith("wheels/") and n.endswith(".whl"))
    if present != sorted(expected):
        raise SystemExit(f"build_extension: {zip_file.name} holds wheels {present}, expected {sorted(expected)}")


def build_platform(
    platform: Platform, manifest: dict, blender_ext: Path, output_dir: Path, cache_root: Path, refresh: bool
) -> tuple[Path, list[Path]]:
    """Build and validate one platform's zip; returns it and the wheels it bundles."""
    wheels = platform_wheels(platform, cache_root, refresh)
    output_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"reactive_anim_stage_{platform.name}_") as temp:
        stage_dir = Path(temp) / "stage"
        entries = stage(stage_dir, platform.name, wheels)
        print(
            run_blender_ext(
                blender_ext,
                "build",
                "--source-dir",
                str(stage_dir),
                "--output-dir",
                str(output_dir),
                "--split-platforms",
            ),
            flush=True,
        )
    zip_file = zip_path(output_dir, manifest, platform.name)
    check_zip_wheels(zip_file, entries)
    print(f"[{platform.name}] validate: {run_blender_ext(blender_ext, 'validate', str(zip_file))}", flush=True)
    return zip_file, wheels


def update_source_manifest(all_wheels: list[Path], platforms: list[str]) -> None:
    """Keep the repo manifest's `wheels`/`platforms` equal to what a full build bundled."""
    text = MANIFEST.read_text()
    entries = sorted({f"./wheels/{wheel.name}" for wheel in all_wheels})
    updated = set_toml_array(set_toml_array(text, "wheels", entries), "platforms", platforms)
    if updated != text:
        MANIFEST.write_text(updated)
        print(f"updated {MANIFEST.relative_to(REPO)}: {len(entries)} wheels, platforms {platforms}")


def build(
    platforms: list[str],
    blender_ext: str | None = None,
    output_dir: Path = DEFAULT_DIST,
    cache_root: Path = DEFAULT_CACHE,
    refresh: bool = False,
) -> dict[str, Path]:
    """Build the named platforms' zips; a build of every platform also refreshes the repo manifest."""
    manifest = read_manifest()
    tool = find_blender_ext(blender_ext)
    print(f"blender_ext: {tool}", flush=True)
    built: dict[str, Path] = {}
    every_wheel: list[Path] = []
    for name in platforms:
        zip_file, wheels = build_platform(PLATFORMS[name], manifest, tool, output_dir, cache_root, refresh)
        built[name] = zip_file
        every_wheel += wheels
        sizes = ", ".join(f"{w.name} {w.stat().st_size / 1e6:.1f} MB" for w in wheels)
        print(f"[{name}] {zip_file.name}: {zip_file.stat().st_size / 1e6:.1f} MB; wheels: {sizes}", flush=True)
    if sorted(platforms) == sorted(PLATFORMS):
        update_source_manifest(every_wheel, list(PLATFORMS))
    return built


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0] if __doc__ else None)
    parser.add_argument(
        "--platform",
        action="append",
        choices=sorted(PLATFORMS),
        help="build only this platform (repeatable); default: all",
    )
    parser.add_argument("--blender-ext", help="path of blender_ext.py (default: from this interpreter's bpy)")
    parser.add_argument("--output-dir", type=Path, default=DEFAULT_DIST)
    parser.add_argument("--cache-dir", type=Path, default=DEFAULT_CACHE, help="wheel cache root")
    parser.add_argument("--refresh", action="store_true", help="ask pip again even if the cache matches the pins")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    platforms = args.platform or list(PLATFORMS)
    build(platforms, args.blender_ext, args.output_dir.resolve(), args.cache_dir.resolve(), args.refresh)
    print(f"built {len(platforms)} zip(s) in {time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
