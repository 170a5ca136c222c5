"""Where the bake finds its inputs: the bundled sample library, the shipped classifier model, and the
folder where compiled libraries are cached. Opened libraries stay open for the session (keyed by
their content), so a second bake reuses the search index and the clip motions."""

from __future__ import annotations

from pathlib import Path

import bpy

from ..core.classifier import load_classifier
from ..core.errors import ClassifierError, LibraryError
from ..core.library import Library, load_library
from ..core.react import ReactionClassifier

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # reactive_anim/ (or the installed extension's folder)
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


def library_cache_dir() -> Path:
    """Where compiled libraries are cached; the one place that decides it.

    Never inside the library folder, which may be read-only (an installed extension, a shared
    drive): the extension's user folder when running as an installed extension, else Blender's
    user data folder (which follows BLENDER_USER_RESOURCES, so tests stay out of the user's own).
    """
    package = (__package__ or "").rpartition(".")[0]  # "bl_ext.<repo>.reactive_anim" or "reactive_anim"
    if package.startswith("bl_ext."):
        return Path(bpy.utils.extension_path_user(package, path="library_cache", create=True))
    return Path(bpy.utils.user_resource("DATAFILES", path="reactive_anim/library_cache", create=True))


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
    library = load_library(path, cache_dir=library_cache_dir())
    # The same compiled library (its cache file is named by the content key) keeps its search index
    # and clip motions from one bake to the next, instead of building them again.
    return _OPEN_LIBRARIES.setdefault(library.cache_path or path, library)


_OPEN_LIBRARIES: dict[Path, Library] = {}


def open_classifier(model_path: str | Path | None = None) -> tuple[ReactionClassifier | None, str]:
    """The classifier and a note saying how reaction classes will be chosen.

    model_path "" or None: the shipped model if it exists, else none (the whole library is
    searched). A model path that was asked for must exist (ClassifierError names it).
    """
    if model_path:
        path = Path(bpy.path.abspath(str(model_path)))
        if not path.is_file():
            raise ClassifierError(f"classifier model not found: {path}")
    else:
        path = default_model_path()
        if not path.is_file():
            return None, f"no classifier model ({path} is missing): {WHOLE_LIBRARY}"
    return load_classifier(path), f"classifier {path.name}"
