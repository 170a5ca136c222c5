"""The animator's path through a real Blender window; runs inside Blender (tests/gui/in_root.sh).

    blender --factory-startup --python tests/gui/session.py -- OUT ZIP BVH

Each step is a generator run from a persistent timer, so Blender's event loop (drawing, modal
operators, the bake's worker polling, marker sync) runs between its yields: a step yields a number
of seconds to wait, or a predicate to wait for. Keys the animator presses (Esc, Ctrl+Z,
Ctrl+Shift+Z) are real X key events sent with xdotool, the pointer over the 3D view (with no window
manager, keys go to the window under the pointer). Operators an animator clicks are invoked as
INVOKE_DEFAULT with the real window, area and region as context: Blender gives scripts no way to
find a button's pixels. The add-on under test is the extension zip installed with Blender's own
install operator, never this checkout's package.

What each step saw goes to OUT/steps.json, screenshots (ImageMagick's `import`; Blender's own
screenshot is black under Xvfb) to OUT/*.png; tests/gui/test_window.py judges them and the log.
"""

from __future__ import annotations

import array
import importlib
import json
import subprocess
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Literal

import bpy
import numpy as np
from bpy_extras import view3d_utils
from mathutils import Vector

OUT, ZIP, BVH = (Path(a) for a in sys.argv[sys.argv.index("--") + 1 :][:3])
ADDON = "bl_ext.user_default.reactive_anim"
OPERATORS = "reactive_anim"  # bpy.ops.reactive_anim
STEP_TIMEOUT_S = 600.0  # the first bake compiles the bundled library's cache on 2 cores
Step = Iterator[float | Callable[[], bool]]
ViewAxis = Literal["LEFT", "RIGHT", "BOTTOM", "TOP", "FRONT", "BACK"]  # bpy.ops.view3d.view_axis's type
results: list[dict[str, Any]] = []


def addon(module: str) -> Any:
    """A module of the installed extension (blender.bake, blender.worker, ...)."""
    return importlib.import_module(f"{ADDON}.{module}")


def operator(name: str) -> Callable[..., set[str]]:
    """An operator of the installed extension, bpy.ops.reactive_anim.<name>: made when the extension
    registers, so the bpy type stubs do not have it (the tests' typed tools/devkit/operators.py is
    not on this script's path: it runs in Debian's Blender, which has only the installed zip)."""
    return getattr(getattr(bpy.ops, OPERATORS), name)


# ---------------------------------------------------------------------------------------------
# The window: areas, context, real input, screenshots


def area(kind: str) -> tuple[bpy.types.Window, bpy.types.Area, bpy.types.Region]:
    window = bpy.context.window_manager.windows[0]
    found = max((a for a in window.screen.areas if a.type == kind), key=lambda a: a.width * a.height)
    return window, found, next(r for r in found.regions if r.type == "WINDOW")


def in_view(kind: str = "VIEW_3D") -> Any:
    window, found, region = area(kind)
    return bpy.context.temp_override(window=window, area=found, region=region, screen=window.screen)


def view_3d(found: bpy.types.Area) -> bpy.types.SpaceView3D:
    """The 3D view of an area (as tools/devkit/blender_types.py's, which this script cannot import)."""
    space = found.spaces.active
    assert isinstance(space, bpy.types.SpaceView3D)
    return space


def screen_point(region: bpy.types.Region, x: float, y: float) -> tuple[int, int]:
    """Region pixel (origin bottom left) -> X screen pixel (origin top left); the window is at 0, 0."""
    window = bpy.context.window_manager.windows[0]
    return round(region.x + x), round(window.height - (region.y + y))


def click(operator: Any, how: str = "INVOKE_DEFAULT", **properties: Any) -> set[str]:
    """Run an operator as its button does: in the 3D view, with an undo step of its own (an
    operator a script calls pushes none by default, so Ctrl+Z would undo everything at once)."""
    with in_view():
        return operator(how, True, **properties)


def press(keys: str, kind: str = "VIEW_3D") -> None:
    """A real key press from X, the pointer over the middle of an area."""
    _window, _found, region = area(kind)
    x, y = screen_point(region, region.width / 2, region.height / 2)
    subprocess.run(["xdotool", "mousemove", str(x), str(y)], check=True)
    subprocess.run(["xdotool", "key", "--delay", "50", keys], check=True)


def screenshot(name: str) -> Path:
    """The whole screen as X shows it, after Blender has drawn everything pending."""
    with in_view():
        bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)
    path = OUT / f"{name}.png"
    subprocess.run(["import", "-window", "root", str(path)], check=True)
    return path


def arrow_color_pixels(png: Path, box: tuple[int, int, int, int]) -> int:
    """How many pixels inside `box` (x0, y0, x1, y1, top-left origin) have the overlay's orange."""
    image = bpy.data.images.load(str(png))
    assert isinstance(image.pixels, bpy.types.bpy_prop_array)  # what it is (the type stubs say float)
    pixels = array.array("f", bytes(4 * image.size[0] * image.size[1] * 4))  # float32, as Blender holds them
    image.pixels.foreach_get(pixels)
    rgb = np.frombuffer(pixels, dtype=np.float32).reshape(image.size[1], image.size[0], 4)
    rgb = rgb[::-1, :, :3]  # Blender stores rows bottom-up
    bpy.data.images.remove(image)
    x0, y0, x1, y1 = box
    patch = rgb[max(y0, 0) : y1, max(x0, 0) : x1]
    orange = (patch[..., 0] > 0.75) & (patch[..., 1] > 0.3) & (patch[..., 1] < 0.75) & (patch[..., 2] < 0.35)
    return int(orange.sum())


# ---------------------------------------------------------------------------------------------
# What the file holds, to compare before and after


def character() -> bpy.types.Object:
    return next(ob for ob in bpy.data.objects if ob.type == "ARMATURE" and not ob.name.endswith(".preview"))


def snapshot() -> dict[str, Any]:
    scene = bpy.context.scene
    action = character().animation_data.action
    assert action is not None
    return {
        "actions": sorted(a.name for a in bpy.data.actions),
        "objects": sorted(ob.name for ob in bpy.data.objects),
        "assigned": action.name,
        "markers": sorted((m.name, m.frame) for m in scene.timeline_markers),
        "range": [scene.frame_start, scene.frame_end],
    }


def impact_markers() -> list[bpy.types.TimelineMarker]:
    impacts = addon("blender.impacts.impacts")
    return [m for m in bpy.context.scene.timeline_markers if impacts.is_impact_marker(m)]


def not_running() -> bool:
    return addon("blender.bake.worker").running() is None


def check(condition: bool, what: str, **seen: Any) -> None:
    if not condition:
        raise AssertionError(f"{what}: {json.dumps(seen, default=str)}")


# ---------------------------------------------------------------------------------------------
# The steps, in the order an animator takes them


def install() -> Step:
    press("Escape")  # the first-start splash (Quick Setup) takes every key until it is closed
    yield 0.5
    result = bpy.ops.extensions.package_install_files(filepath=str(ZIP), repo="user_default", enable_on_install=True)
    yield 1.0
    check(result == {"FINISHED"}, "install", result=result)
    check(ADDON in bpy.context.preferences.addons, "enabled", addons=list(bpy.context.preferences.addons.keys()))
    check(hasattr(bpy.types, "REACTIVE_ANIM_PT_main"), "the Reactions panel is registered")


def import_bvh() -> Step:
    result = click(operator("import_bvh"), "EXEC_DEFAULT", filepath=str(BVH))  # invoke: a file browser
    yield 0.5
    check(result == {"FINISHED"}, "import", result=result)
    armature = character()
    check(armature.animation_data is not None and armature.animation_data.action is not None, "an action")


def add_impacts() -> Step:
    """Pose Mode, the hit bone active, the view looking along the push, +; then Aim from View."""
    armature = character()
    _window, view, _region = area("VIEW_3D")
    view_3d(view).show_region_ui = True  # the sidebar; its Reactions tab is the fourth down its edge
    yield 0.5
    sidebar = next(r for r in view.regions if r.type == "UI")
    x, top = screen_point(sidebar, sidebar.width - 8, sidebar.height)
    subprocess.run(["xdotool", "mousemove", str(x), str(top + 172), "click", "1"], check=True)
    with in_view():
        bpy.context.view_layer.objects.active = armature
        bpy.ops.object.mode_set("EXEC_DEFAULT", True, mode="POSE")
    hits: tuple[tuple[int, str, float, ViewAxis], ...] = ((60, "chest", 80.0, "FRONT"), (150, "pelvis", 350.0, "LEFT"))
    for frame, bone, strength, view_axis in hits:
        bpy.context.scene.frame_set(frame)
        rig_data = character().data  # looked up again: an undo step may have rebuilt the armature's data
        assert isinstance(rig_data, bpy.types.Armature)
        bones = rig_data.bones
        for other in bones:
            other.select = other.name == bone
        bones.active = bones[bone]
        with in_view():
            bpy.ops.view3d.view_axis(type=view_axis)
        yield 0.3
        result = click(operator("add_impact"), strength=strength)
        check(result == {"FINISHED"}, "add impact", result=result)
        yield 0.2
    markers = impact_markers()
    data = [addon("blender.impacts.impacts").impact_data(m) for m in markers]
    added = [(m.frame, d.bone) for m, d in zip(markers, data, strict=True)]
    check(added == [(60, "chest"), (150, "pelvis")], "two impacts where the animator put them", added=added)
    check(
        np.allclose(data[0].direction, (0, 1, 0), atol=1e-3), "FRONT view pushes along +Y", got=list(data[0].direction)
    )
    check(
        np.allclose(data[1].direction, (1, 0, 0), atol=1e-3), "LEFT view pushes along +X", got=list(data[1].direction)
    )
    # Aim the second impact from behind the character instead (it is the list's active row).
    with in_view():
        bpy.ops.view3d.view_axis(type="BACK")
    yield 0.3
    result = click(operator("aim_impact"))
    check(result == {"FINISHED"}, "aim", result=result)
    check(np.allclose(data[1].direction, (0, -1, 0), atol=1e-3), "BACK view aims along -Y", got=list(data[1].direction))
    with in_view():
        bpy.ops.object.mode_set("EXEC_DEFAULT", True, mode="OBJECT")
    yield from look_at_character("RIGHT")
    screenshot("impacts")


def look_at_character(view_axis: ViewAxis, bone: str = "pelvis") -> Step:
    """The 3D view looks along an axis at a bone of the character as it is posed now."""
    armature = character()
    with in_view():
        for ob in bpy.context.view_layer.objects:
            ob.select_set(ob == armature)
        bpy.context.view_layer.objects.active = armature
        bpy.ops.view3d.view_axis(type=view_axis)
    yield 0.3
    region_3d = view_3d(area("VIEW_3D")[1]).region_3d
    region_3d.view_location = armature.matrix_world @ armature.pose.bones[bone].head
    region_3d.view_distance = 3.5
    yield 0.5


def escape_cancels_a_long_bake() -> Step:
    """Twelve more impacts make a bake of some seconds; Esc right after it starts changes nothing."""
    extra = []
    for k in range(12):
        click(
            operator("add_impact"),
            armature_name=character().name, bone="chest", frame=20 + 18 * k, direction=(0, 1, 0), strength=60.0,
        )  # fmt: skip
        extra.append(impact_markers()[-1].name)
    before = snapshot()
    result = click(operator("bake"))
    check(result == {"RUNNING_MODAL"}, "the bake runs modal in a window", result=result)
    yield 0.2
    check(not not_running(), "still running when Esc is pressed")
    press("Escape")
    yield not_running
    yield 0.5
    check(snapshot() == before, "Esc left the file as it was", before=before, after=snapshot())
    for name in extra:
        marker = bpy.context.scene.timeline_markers[name]
        click(operator("remove_impact"), uid=addon("blender.impacts.impacts").impact_data(marker).uid)
    check(len(impact_markers()) == 2, "extra impacts removed")


state: dict[str, Any] = {}


def bake() -> Step:
    state["before"] = snapshot()
    result = click(operator("bake"))
    check(result == {"RUNNING_MODAL"}, "bake", result=result)
    yield not_running
    yield 0.5
    armature = character()
    action = armature.animation_data.action
    assert action is not None
    check(action.name.endswith(".reacted"), "the reacted action is assigned", assigned=action.name)
    scene = bpy.context.scene
    first, last = action.frame_range
    check(scene.frame_start <= first and scene.frame_end >= last, "play shows the whole reaction",
          range=[scene.frame_start, scene.frame_end], action=[first, last])  # fmt: skip
    state["baked"] = snapshot()
    scene.frame_set(170)
    screenshot("baked")


def undo_redo() -> Step:
    press("ctrl+z")
    yield 1.0
    check(snapshot()["assigned"] == state["before"]["assigned"], "Ctrl+Z undid the bake", now=snapshot())
    check(snapshot()["range"] == state["before"]["range"], "Ctrl+Z restored the frame range", now=snapshot())
    press("ctrl+shift+z")
    yield 1.0
    check(snapshot()["assigned"] == state["baked"]["assigned"], "Ctrl+Shift+Z redid it", now=snapshot())


def preview_discard_accept() -> Step:
    click(operator("clear_bake"))
    yield 0.3
    cleared = snapshot()
    for ending in ("discard", "accept"):
        result = click(operator("preview"))
        check(result == {"RUNNING_MODAL"}, "preview", result=result)
        yield not_running
        yield 0.5
        ghost = bpy.data.objects.get(character().name + ".preview")
        check(ghost is not None, "a ghost shows the preview", objects=snapshot()["objects"])
        check(snapshot()["assigned"] == cleared["assigned"], "the character keeps its own action")
        if ending == "discard":
            screenshot("preview")
            click(operator("discard_preview"))
            yield 0.3
            check(snapshot() == cleared, "Discard leaves no trace", before=cleared, after=snapshot())
        else:
            click(operator("accept_preview"))
            yield 0.3
            check(snapshot()["assigned"].endswith(".reacted"), "Accept makes it the bake", now=snapshot())
            check(".preview" not in " ".join(snapshot()["objects"]), "the ghost is gone")


def drag_and_duplicate_a_marker() -> Step:
    impacts = addon("blender.impacts.impacts")
    scene = bpy.context.scene
    first = impact_markers()[0]
    for m in scene.timeline_markers:
        m.select = m == first
    with in_view("DOPESHEET_EDITOR"):
        bpy.ops.marker.move(frames=10)
    yield 0.6
    check(first.frame == 70, "moved", frame=first.frame)
    with in_view("DOPESHEET_EDITOR"):
        bpy.ops.marker.duplicate(frames=30)
    yield 0.8  # marker sync's poll gives the copy its own uid
    uids = [impacts.impact_data(m).uid for m in impact_markers()]
    check(len(uids) == 3 and len(set(uids)) == 3, "the duplicate is an impact of its own", uids=uids)


def save_and_reload() -> Step:
    path = OUT / "session.blend"
    before = snapshot()
    with in_view():
        bpy.ops.wm.save_as_mainfile(filepath=str(path))
    yield 0.5
    bpy.ops.wm.open_mainfile(filepath=str(path))
    yield 1.5
    check(snapshot() == before, "reloaded as saved", before=before, after=snapshot())


def overlay_arrow_is_drawn() -> Step:
    """At an impact's frame its orange arrow is on screen at the hit bone; far from it, it is not."""
    armature = character()
    marker = impact_markers()[0]
    data = addon("blender.impacts.impacts").impact_data(marker)
    view_3d(area("VIEW_3D")[1]).show_region_ui = False  # the whole view for the character
    counts = {}
    for frame in (marker.frame, marker.frame + 60):
        bpy.context.scene.frame_set(frame)
        yield from look_at_character("RIGHT", data.bone)
        armature.select_set(False)  # the selection outline is orange too
        yield 0.3
        _window, view, region = area("VIEW_3D")
        bone = armature.pose.bones[data.bone]
        tip = armature.matrix_world @ ((bone.head + bone.tail) / 2)
        if frame == marker.frame:
            length = addon("blender.ui.overlay").arrow_length(data.strength)
            tail = tip - Vector(data.direction).normalized() * length
            ends = [view3d_utils.location_3d_to_region_2d(region, view_3d(view).region_3d, p) for p in (tip, tail)]
            points = [screen_point(region, p.x, p.y) for p in ends]
            xs, ys = [p[0] for p in points], [p[1] for p in points]
            box = (min(xs) - 12, min(ys) - 12, max(xs) + 12, max(ys) + 12)
            state["box"] = box
        shot = "overlay_at_impact" if frame == marker.frame else "overlay_away"
        counts[frame] = arrow_color_pixels(screenshot(shot), state["box"])
    state["overlay"] = counts
    check(counts[marker.frame] >= 40, "the arrow's orange near the hit bone", counts=counts, box=state["box"])
    check(counts[marker.frame + 60] * 4 < counts[marker.frame], "not drawn far from its frame", counts=counts)


STEPS = (
    install,
    import_bvh,
    add_impacts,
    escape_cancels_a_long_bake,
    bake,
    undo_redo,
    preview_discard_accept,
    drag_and_duplicate_a_marker,
    save_and_reload,
    overlay_arrow_is_drawn,
)


# ---------------------------------------------------------------------------------------------
# The driver


class Driver:
    """Advances one step at a time from a timer; the first failure ends the session."""

    def __init__(self) -> None:
        self.steps = list(STEPS)
        self.current: Step | None = None
        self.started = 0.0
        self.waiting: Callable[[], bool] | None = None

    def tick(self) -> float | None:
        try:
            return self._advance()
        except Exception:
            self._record(ok=False, error=traceback.format_exc())
            return self._finish()

    def _advance(self) -> float | None:
        if self.waiting is not None:
            if not self.waiting():
                if time.monotonic() - self.started > STEP_TIMEOUT_S:
                    raise TimeoutError(f"waited over {STEP_TIMEOUT_S} s")
                return 0.1
            self.waiting = None
        if self.current is None:
            if not self.steps:
                return self._finish()
            self.current, self.started = self.steps[0](), time.monotonic()
        try:
            wait = next(self.current)
        except StopIteration:
            self._record(ok=True)
            self.steps.pop(0)
            self.current = None
            return 0.1
        if callable(wait):
            self.waiting = wait
            return 0.1
        return float(wait)

    def _record(self, ok: bool, error: str = "") -> None:
        name = self.steps[0].__name__ if self.steps else "driver"
        seconds = round(time.monotonic() - self.started, 2)
        results.append({"step": name, "ok": ok, "seconds": seconds, "error": error})
        print(f"GUI STEP {name}: {'ok' if ok else 'FAILED'} ({seconds} s)", flush=True)
        if error:
            print(error, flush=True)

    def _finish(self) -> None:
        record = {"steps": results, "state": state, "blender": bpy.app.version_string}
        (OUT / "steps.json").write_text(json.dumps(record, indent=1, default=str))
        bpy.ops.wm.quit_blender()
        return None


OUT.mkdir(parents=True, exist_ok=True)
driver = Driver()
bpy.app.timers.register(driver.tick, first_interval=2.0, persistent=True)
print(f"GUI session: Blender {bpy.app.version_string}, Python {sys.version.split()[0]}", flush=True)
