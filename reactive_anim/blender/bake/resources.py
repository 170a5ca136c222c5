"""Where the bake finds its inputs: the bundled sample library, the shipped classifier model, and the
folder where compiled libraries are cached. Opened libraries stay open for the session (keyed by
their content), so a second bake reuses the search index and the clip motions."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import bpy

from ...core.classify.classifier import load_classifier
from ...core.model.errors import ClassifierError, LibraryError
from ...core.react import ReactionClassifier
from ...core.search.library import Library, load_library

PACKAGE_DIR = Path(__file__).resolve().parents[2]  # reactive_anim/ (or the installed extension's folder)
WHOLE_LIBRARY = "impacts without an override search the whole library"


def default_library_path() -> Path | None:
    """The bundled sample library: `<package>/sample_library` in an extension that ships one, else
    the repository's `sample_clips/` when running from a checkout; None if neither exists."""
    for candidate in (PACKAGE_DIR / "sample_library", PACKAGE_DIR.parent / "sample_clips"):
        if (candidate / "library.toml").is_file():
            return candidate
    return None


def default_model_path() -> Path:
    """The shipped classifier model (it may not exist yet: the bake then searches the whole library)."""
    return PACKAGE_DIR / "models" / "reaction_classifier.onnx"


def library_cache_dir() -> Path | None:
    """Where compiled libraries are cached; the one place that decides it. None: nowhere.

    Never inside the library folder, which may be read-only (an installed extension, a shared
    drive): the extension's user folder when running as an installed extension, else Blender's
    user data folder (which follows BLENDER_USER_RESOURCES, so tests stay out of the user's own).
    Where that folder cannot be written (a farm node or a container with a read-only home), a
    folder of this user's in the temporary folder; failing that, None: the library is compiled for
    each bake. Never the current folder (where Blender's own fallback puts it); one warning line.
    """
    user = _user_cache_dir()
    why = _cannot_write(user, own=False) if user else "Blender gives no user folder"
    if not why:
        return user
    problem = f"cannot write the library cache in {user or 'a user folder'} ({why})"
    temp = _temp_cache_dir()
    if temp is not None and not _cannot_write(temp, own=True):
        _warn_once(f"{problem}; caching it in {temp}")
        return temp
    _warn_once(f"{problem}, nor in a temporary folder: the library is compiled for each bake, not cached")
    return None


def _user_cache_dir() -> Path | None:
    """The cache folder Blender gives this extension, not created (Blender's `create=True` prints
    a traceback and returns "", the current folder, when it cannot create it)."""
    package = (__package__ or "").rpartition(".blender")[0]  # "bl_ext.<repo>.reactive_anim" or "reactive_anim"
    if package.startswith("bl_ext."):
        folder = bpy.utils.extension_path_user(package, path="library_cache")
    else:
        folder = bpy.utils.user_resource("DATAFILES", path="reactive_anim/library_cache")
    return Path(folder) if folder else None


def _temp_cache_dir() -> Path | None:
    """`reactive_anim_library_cache-<uid>` in the temporary folder; None if there is none, or it
    is the current folder (tempfile's last resort)."""
    try:
        temp = Path(tempfile.gettempdir()).resolve()
    except OSError:  # no usable temporary folder at all
        return None
    if temp == Path.cwd().resolve():
        return None
    user = os.getuid() if hasattr(os, "getuid") else "user"  # Windows: the temporary folder is the user's own
    return temp / f"reactive_anim_library_cache-{user}"


def _cannot_write(folder: Path, own: bool) -> str:
    """Why `folder` cannot hold the cache ("" if it can): it is made if missing and a file is
    written there. own: it must be this user's (a shared temporary folder, where another user
    could have made it first and left a forged cache)."""
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        if own and hasattr(os, "getuid") and folder.stat().st_uid != os.getuid():
            return f"{folder} belongs to another user"
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc.strerror or str(exc)
    return ""


def _warn_once(message: str) -> None:
    if message not in _WARNED:
        _WARNED.add(message)
        print(f"reactive_anim: warning: {message}", file=sys.stderr)


_WARNED: set[str] = set()


def open_library(path: str | Path | None = None) -> Library:
    """The compiled library at `path` (folder or .toml; "" or None: the bundled sample library)."""
    if not path:
        found = default_library_path()
        if found is None:
            raise LibraryError(
                f"no reaction library was given and none is bundled (looked for {PACKAGE_DIR / 'sample_library'} "
                f"and {PACKAGE_DIR.parent / 'sample_clips'}); choose a library folder"
            )
        path = found
    path = Path(bpy.path.abspath(str(path)))
    if not path.exists():
        raise LibraryError(f"reaction library not found: {path}")
    cache_dir = library_cache_dir()
    library = load_library(path, cache_dir=cache_dir, cache=cache_dir is not None)
    if library.cache_path is None:  # not cached: nothing says whether the files changed since
        return library
    # The same compiled library (its cache file is named by the content key) keeps its search index
    # and clip motions from one bake to the next, instead of building them again.
    return _OPEN_LIBRARIES.setdefault(library.cache_path, library)


_OPEN_LIBRARIES: dict[Path, Library] = {}


def open_classifier(model_path: str | Path | None = None) -> tuple[ReactionClassifier | None, str]:
    """The classifier and a note saying how reaction classes will be chosen.

    model_path "" or None: the shipped model if it exists, else none (the whole library is
    searched). A model path that was asked for must exist (ClassifierError names it).
    """
    if model_path:
        path = Path(bpy.path.abspath(str(model_path)))
        if path.is_dir():
            raise ClassifierError(
                f"classifier model {path} is a folder, not an .onnx file: pick the model file in it, "
                "or clear the Classifier field to use the shipped model"
            )
        if not path.is_file():
            raise ClassifierError(f"classifier model not found: {path}")
    else:
        path = default_model_path()
        if not path.is_file():
            return None, f"no classifier model ({path} is missing): {WHOLE_LIBRARY}"
    return load_classifier(path), f"classifier {path.name}"
