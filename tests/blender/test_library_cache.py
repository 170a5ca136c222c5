"""Where compiled libraries are cached (resources.library_cache_dir): the user folder, else this
user's folder in the temporary folder, else nowhere; never the current folder.

Tests run as root, where a chmod'ed folder is still writable; a folder that cannot be made (its
path runs under a regular file) fails for root too, through the same code a read-only disk takes.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from reactive_anim.blender.bake import resources


@pytest.fixture
def unwritable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A regular file: no folder can be made under it. The test runs in an empty current folder."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    monkeypatch.setattr(resources, "_WARNED", set())
    return blocker


def test_the_cache_is_in_blenders_user_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("BLENDER_USER_RESOURCES", str(tmp_path / "user"))
    assert resources.library_cache_dir() == tmp_path / "user" / "datafiles" / "reactive_anim" / "library_cache"
    assert (tmp_path / "user" / "datafiles" / "reactive_anim" / "library_cache").is_dir()
    assert capsys.readouterr().err == ""


def test_a_read_only_user_folder_caches_in_the_temporary_folder(unwritable, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("BLENDER_USER_RESOURCES", str(unwritable / "user"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "temp"))
    cache = tmp_path / "temp" / f"reactive_anim_library_cache-{os.getuid()}"
    assert resources.library_cache_dir() == cache
    assert resources.library_cache_dir() == cache  # the warning is said once
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("reactive_anim: warning: cannot write the library cache in ")
    assert err[0].endswith(f"(Not a directory); caching it in {cache}")
    assert cache.is_dir() and (cache.stat().st_mode & 0o777) == 0o700  # others cannot plant a cache there
    assert not list(Path.cwd().iterdir())


def test_with_nowhere_to_write_the_library_is_compiled_uncached(unwritable, monkeypatch, capsys):
    monkeypatch.setenv("BLENDER_USER_RESOURCES", str(unwritable / "user"))
    monkeypatch.setattr(tempfile, "tempdir", str(unwritable / "temp"))
    assert resources.library_cache_dir() is None
    library = resources.open_library()
    assert library.clips and library.cache_path is None and not library.loaded_from_cache
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"reactive_anim: warning: cannot write the library cache in {unwritable}/user/datafiles/reactive_anim/"
        "library_cache (Not a directory), nor in a temporary folder: the library is compiled for each bake, not cached"
    ]
    assert not list(Path.cwd().iterdir())


def test_the_current_folder_is_never_the_temporary_cache(unwritable, monkeypatch):
    """tempfile's last resort, when no temporary folder can be written, is the current folder."""
    monkeypatch.setenv("BLENDER_USER_RESOURCES", str(unwritable / "user"))
    monkeypatch.setattr(tempfile, "tempdir", str(Path.cwd()))
    assert resources.library_cache_dir() is None
    assert not list(Path.cwd().iterdir())
