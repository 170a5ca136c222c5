"""The demo's filmstrip: frames around each impact rendered by Blender, composed into one PNG.

Each tile is a real render of the scene's camera (Workbench: material colours, studio light and
outlines, fast and headless; if Workbench cannot render here, Cycles on the CPU at a few samples).
Blender's stamp burns the frame number and a caption (impact, class, which moment) into each tile,
so no font code is needed here; numpy puts the tiles in a grid, one row per impact, and Blender's
image API writes the PNG.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import bpy
import numpy as np

from tools.devkit.blender_types import as_buffer

from . import scene as demo_scene

TILE_SIZE = (320, 240)  # pixels
GAP = 4  # pixels of white between tiles
CYCLES_SAMPLES = 8


@dataclass(frozen=True)
class Tile:
    """One picture: the timeline frame, the caption stamped on it, and where the camera stands: a
    ground direction (x, y) from the followed character (None: where the scene has it)."""

    frame: int
    caption: str
    view: tuple[float, float] | None = None


def configure(scene: bpy.types.Scene, engine: str = "BLENDER_WORKBENCH") -> None:
    """Small renders with the frame number and a note stamped in; Workbench in solid material colours."""
    render = scene.render
    render.engine = engine  # pyright: ignore[reportAttributeAccessIssue]
    render.resolution_x, render.resolution_y = TILE_SIZE
    render.resolution_percentage = 100
    render.film_transparent = False
    render.image_settings.file_format = "PNG"
    render.image_settings.color_mode = "RGB"
    render.use_stamp = True
    for prop in render.bl_rna.properties:  # every stamp field off but the frame number and the note
        if prop.identifier.startswith("use_stamp_"):
            setattr(render, prop.identifier, prop.identifier in ("use_stamp_frame", "use_stamp_note"))
    render.stamp_font_size = 13
    render.stamp_background = (0.0, 0.0, 0.0, 0.6)
    if engine == "BLENDER_WORKBENCH":
        shading = scene.display.shading
        shading.light = "STUDIO"
        shading.color_type = "MATERIAL"
        shading.show_object_outline = True
        shading.show_cavity = False
        scene.display.render_aa = "8"
    else:
        scene.cycles.device = "CPU"  # pyright: ignore[reportAttributeAccessIssue]
        scene.cycles.samples = CYCLES_SAMPLES  # pyright: ignore[reportAttributeAccessIssue]
        scene.cycles.use_denoising = False  # pyright: ignore[reportAttributeAccessIssue]


def render_tile(scene: bpy.types.Scene, tile: Tile, path: Path) -> np.ndarray:
    """Render `tile` to `path` and return its pixels (H, W, 4), top row first, 0..1."""
    if tile.view is not None and scene.camera is not None:
        demo_scene.place_camera(scene.camera, tile.view)
    scene.frame_set(tile.frame)
    scene.render.stamp_note_text = tile.caption
    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(str(path))  # with the stamp, and without a log line
    if not path.is_file():
        raise RuntimeError(f"{scene.render.engine} wrote no image for frame {tile.frame}")
    return _read_png(path)


def _read_png(path: Path) -> np.ndarray:
    image = bpy.data.images.load(str(path))
    try:
        width, height = image.size
        pixels = np.empty(width * height * 4, dtype=np.float32)
        assert isinstance(image.pixels, bpy.types.bpy_prop_array)  # what it is (the type stubs say float)
        image.pixels.foreach_get(as_buffer(pixels))
    finally:
        bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1]


def _blank(pixels: np.ndarray) -> bool:
    """An image of one colour (a failed render that still wrote a file)."""
    return float(np.ptp(pixels[..., :3])) < 1e-3


def render_filmstrip(scene: bpy.types.Scene, rows: Sequence[Sequence[Tile]], out_path: Path) -> str:
    """Render every tile and write the grid (a row per impact) to `out_path`; returns the engine used."""
    write_png(compose(render_rows(scene, rows)), out_path)
    return scene.render.engine


def render_rows(scene: bpy.types.Scene, rows: Sequence[Sequence[Tile]]) -> list[list[np.ndarray]]:
    """Every tile's pixels, row by row; the camera is put back afterwards.

    Workbench first; if its first tile fails or comes out blank, everything is rendered with Cycles.
    """
    configure(scene)
    camera = scene.camera
    saved = (camera.location.copy(), camera.rotation_euler.copy()) if camera is not None else None
    with tempfile.TemporaryDirectory(prefix="reactive_anim_demo_tiles_") as folder:
        pictures: list[list[np.ndarray]] = []
        for r, row in enumerate(rows):
            pictures.append([])
            for t, tile in enumerate(row):
                path = Path(folder) / f"tile_{r:02d}_{t:02d}.png"
                pixels = _first_tile(scene, tile, path) if r == t == 0 else render_tile(scene, tile, path)
                pictures[-1].append(pixels)
    if camera is not None and saved is not None:
        camera.location, camera.rotation_euler = saved
    return pictures


def _first_tile(scene: bpy.types.Scene, tile: Tile, path: Path) -> np.ndarray:
    try:
        pixels = render_tile(scene, tile, path)
        if not _blank(pixels):
            return pixels
    except RuntimeError:
        pass
    configure(scene, "CYCLES")
    return render_tile(scene, tile, path)


def compose(pictures: list[list[np.ndarray]]) -> np.ndarray:
    """The tiles in a grid on white, GAP pixels apart: (H, W, 4), top row first."""
    height, width = pictures[0][0].shape[:2]
    columns = max(len(row) for row in pictures)
    sheet = np.ones((len(pictures) * (height + GAP) + GAP, columns * (width + GAP) + GAP, 4), dtype=np.float32)
    for r, row in enumerate(pictures):
        for c, pixels in enumerate(row):
            top, left = GAP + r * (height + GAP), GAP + c * (width + GAP)
            sheet[top : top + height, left : left + width] = pixels
    sheet[..., 3] = 1.0
    return sheet


def write_png(pixels: np.ndarray, path: Path) -> None:
    """Write (H, W, 4) pixels, top row first, as a PNG through Blender's image API."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.new("demo filmstrip", width, height, alpha=False)
    try:
        assert isinstance(image.pixels, bpy.types.bpy_prop_array)  # what it is (the type stubs say float)
        image.pixels.foreach_set(as_buffer(np.ascontiguousarray(pixels[::-1]).ravel()))
        path.parent.mkdir(parents=True, exist_ok=True)
        image.filepath_raw = str(path)
        image.file_format = "PNG"
        image.save()
    finally:
        bpy.data.images.remove(image)
