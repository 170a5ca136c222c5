"""Keep impacts in step with the timeline's markers.

An impact IS its marker (impacts.py): moving the marker moves the impact's frame, deleting it
removes the impact, with nothing to copy. What needs watching: a duplicated marker (Shift+D in the
timeline) copies the impact's properties, uid included, and two impacts must never share a uid
(the copy gets a new one); and the panel and the viewport arrows must redraw when markers move.
Blender sends no msgbus or depsgraph notification when a marker is dragged, so a `bpy.app.timers`
poll looks about 4 times a second (a loop over the markers: microseconds), and persistent
load_post / undo_post / redo_post handlers look right after a file load, undo or redo. Before a
file load (load_pre) a running bake stops, its result would have nowhere to go.
"""

from __future__ import annotations

import uuid
from typing import Any

import bpy
from bpy.app.handlers import persistent

from ..bake import worker
from ..ui import overlay
from . import impacts

POLL_SECONDS = 0.25

_seen: dict[str, tuple[tuple[str, int], ...]] = {}  # scene name -> (uid, frame) of its impact markers
_warned = False


def sync_scene(scene: bpy.types.Scene) -> bool:
    """Give duplicated markers new uids; True if the scene's impacts changed since the last look."""
    last_frames = dict(_seen.get(scene.name, ()))
    sharing: dict[str, list[bpy.types.TimelineMarker]] = {}
    for marker in scene.timeline_markers:
        uid = impacts.impact_data(marker).uid
        if uid:
            sharing.setdefault(uid, []).append(marker)
    for uid, markers in sharing.items():
        if len(markers) > 1:
            keeper = _original(markers, last_frames.get(uid))
            for marker in markers:
                if marker != keeper:
                    impacts.impact_data(marker).uid = uuid.uuid4().hex
    now = tuple((impacts.impact_data(m).uid, m.frame) for m in scene.timeline_markers if impacts.is_impact_marker(m))
    changed = _seen.get(scene.name) != now
    _seen[scene.name] = now
    return changed


def _original(markers: list[bpy.types.TimelineMarker], last_frame: int | None) -> bpy.types.TimelineMarker:
    """Of markers sharing a uid, the one that keeps it: the one still at the frame last seen, else one
    not selected (Blender selects the copies it makes), else the last (Blender adds copies first)."""
    at_frame = [m for m in markers if m.frame == last_frame]
    if len(at_frame) == 1:
        return at_frame[0]
    unselected = [m for m in markers if not m.select]
    return unselected[-1] if unselected else markers[-1]


def sync_all() -> bool:
    changed = False
    for scene in bpy.data.scenes:
        changed |= sync_scene(scene)
    if changed:
        overlay.tag_redraw()
    return changed


def _poll() -> float:
    """The timer: look again in POLL_SECONDS. An error must not end the timer (Blender drops a
    timer that raises): it is printed once."""
    global _warned
    try:
        sync_all()
    except Exception as exc:
        if not _warned:
            _warned = True
            print(f"reactive_anim: the impact marker watch failed and goes on: {exc!r}")
    return POLL_SECONDS


@persistent
def _after_undo(*_args: Any) -> None:
    sync_all()


@persistent
def _before_load(*_args: Any) -> None:
    worker.cancel_running()  # its result would have nowhere to go


@persistent
def _after_load(*_args: Any) -> None:
    _seen.clear()
    sync_all()


_HANDLERS = (
    (bpy.app.handlers.load_pre, _before_load),
    (bpy.app.handlers.load_post, _after_load),
    (bpy.app.handlers.undo_post, _after_undo),
    (bpy.app.handlers.redo_post, _after_undo),
)


def register() -> None:
    for handlers, handler in _HANDLERS:
        if handler not in handlers:
            handlers.append(handler)
    if not bpy.app.timers.is_registered(_poll):
        bpy.app.timers.register(_poll, first_interval=POLL_SECONDS, persistent=True)


def unregister() -> None:
    if bpy.app.timers.is_registered(_poll):
        bpy.app.timers.unregister(_poll)
    for handlers, handler in _HANDLERS:
        if handler in handlers:
            handlers.remove(handler)
    _seen.clear()
