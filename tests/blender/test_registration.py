"""register() as an interactive Blender runs it: inside RestrictBlend, every part included.

`addon_utils.enable` calls an add-on's register() inside `bpy_restrict_state.RestrictBlend`, where
`bpy.data` and `bpy.context` are stand-ins without the blend-file's collections: reading one there
is "Exception in module register()" in every real Blender window, and the classes registered
before it stay registered. Background mode used to skip the viewport overlay's registration, the
part that read `bpy.data.window_managers`, so no headless test saw it: this test runs all of
register() under the restriction, the window-only parts included.
"""

from __future__ import annotations

import importlib

import bpy
import pytest

import reactive_anim
from reactive_anim.blender import registry
from reactive_anim.blender.impacts import marker_sync
from reactive_anim.blender.ui import overlay


@pytest.fixture
def restrict_blend(monkeypatch):
    """Blender's own RestrictBlend, applied to the `bpy` the add-on imports, with the parts of
    register() that only run where there are windows included (the overlay's draw handler).

    In a real Blender there is one `bpy` module; the bpy wheel has two (the compiled module that
    `import bpy` gives, and the scripts' package that bpy_restrict_state imported), so the context
    manager is pointed at the one the add-on sees.
    """
    monkeypatch.setattr(overlay, "has_windows", lambda: True)
    try:
        restrict_state = importlib.import_module("_bpy_restrict_state")  # Blender 5.0+
    except ImportError:
        restrict_state = importlib.import_module("bpy_restrict_state")
    monkeypatch.setattr(restrict_state, "_bpy", bpy)
    yield restrict_state.RestrictBlend
    # Back to a background registration for the other tests: no draw handler is left installed.
    monkeypatch.undo()
    reactive_anim.unregister()
    reactive_anim.register()


def _registered() -> list[str]:
    return [cls.__name__ for cls in registry.CLASSES if _is_registered(cls)]


def _is_registered(cls: type) -> bool:
    """Blender's `is_registered`, a property of the metaclass of every class Blender registers (the
    type stubs give it to operators and panels only, not to property groups, lists and menus)."""
    return cls.is_registered


def test_register_inside_restrict_blend_reads_no_blend_data(empty_scene, restrict_blend):
    reactive_anim.unregister()
    assert _registered() == [] and overlay._handle is None
    try:
        with restrict_blend():
            assert not hasattr(bpy.data, "window_managers")  # the restriction is real
            reactive_anim.register()
    except Exception:
        pytest.fail("register() failed inside RestrictBlend (what enabling in a Blender window does)")
    finally:
        if not _registered():
            reactive_anim.register()  # leave the session's add-on registered for the other tests
    assert _registered() == [cls.__name__ for cls in registry.CLASSES]
    assert overlay._handle is not None, "the viewport overlay's draw handler was not installed"
    assert bpy.app.timers.is_registered(marker_sync._poll)


def test_unregister_then_register_again_leaves_one_of_each(empty_scene, restrict_blend):
    """Disabling and enabling again (Preferences toggles, script reloads) installs nothing twice."""
    reactive_anim.unregister()
    assert overlay._handle is None and not bpy.app.timers.is_registered(marker_sync._poll)
    with restrict_blend():
        reactive_anim.register()
    assert overlay._handle is not None
    assert [h for h in bpy.app.handlers.load_post if h is marker_sync._after_load] == [marker_sync._after_load]
