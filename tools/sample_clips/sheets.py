"""Contact sheets: a stick figure per sampled frame, side and front view, as a PNG per group of
clips (no plotting library needed: numpy draws, zlib packs). Not committed; for looking at clips.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from reactive_anim.core.model.skeleton import Motion

from .catalogue import CLIPS, LOCOMOTION, REACTIONS, reaction_class
from .getups import GETUPS
from .skeleton import end_site_position

SHEET_CELL = (150, 200)  # width, height in pixels of one view
SHEET_SCALE = 95.0  # pixels per metre


def png_bytes(image: np.ndarray) -> bytes:
    """An RGB uint8 image (H, W, 3) as PNG bytes."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    h, w, _ = image.shape
    raw = b"".join(b"\x00" + image[row].tobytes() for row in range(h))
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw, 9))
        + chunk(b"IEND", b"")
    )


def draw_line(image: np.ndarray, a: np.ndarray, b: np.ndarray, colour: tuple[int, int, int]) -> None:
    """A line two pixels wide from pixel a to pixel b (x, y), clipped to the image."""
    n = int(np.max(np.abs(b - a))) * 2 + 2
    pts = np.round(a + (b - a) * np.linspace(0, 1, n)[:, None]).astype(int)
    for dx in (0, 1):
        for dy in (0, 1):
            x, y = pts[:, 0] + dx, pts[:, 1] + dy
            ok = (x >= 0) & (x < image.shape[1]) & (y >= 0) & (y < image.shape[0])
            image[y[ok], x[ok]] = colour


def _pixel(point: np.ndarray, centre: np.ndarray, view: int, origin: tuple[float, float]) -> np.ndarray:
    """Where a world point lands in a view (0: side, facing right; 1: front), around the pelvis
    `centre`, `origin` the view's pixel under the pelvis on the floor line."""
    across = -(point[1] - centre[1]) if view == 0 else (point[0] - centre[0])
    return np.array([origin[0] + SHEET_SCALE * across, origin[1] - SHEET_SCALE * point[2]])


def contact_sheet(motions: dict[str, Motion], columns: int = 8) -> np.ndarray:
    """Rows of clips, `columns` evenly spaced frames each; per frame a side view (facing right)
    and a front view. Left limbs blue, right red, trunk black, floor grey."""
    cw, ch = SHEET_CELL
    image = np.full((ch * len(motions), 2 * cw * columns, 3), 255, dtype=np.uint8)
    for row, motion in enumerate(motions.values()):
        sk = motion.skeleton
        pos, rot = motion.global_transforms()
        tips = {j: end_site_position(sk, pos, rot, j) for j in sk.end_sites}
        for col, frame in enumerate(np.linspace(0, motion.num_frames - 1, columns).round().astype(int)):
            for view in range(2):
                ox, oy = (2 * col + view) * cw, row * ch
                floor_y = oy + ch - 12
                image[floor_y, ox + 4 : ox + cw - 4] = (170, 170, 170)
                image[oy : oy + ch, ox + cw - 1] = (220, 220, 220) if view == 0 else (120, 120, 120)
                centre, origin = pos[frame, 0], (ox + cw / 2, floor_y)
                for j in range(1, sk.num_joints):
                    name = sk.names[j]
                    colour = {".L": (40, 90, 220), ".R": (220, 50, 40)}.get(name[-2:], (0, 0, 0))
                    joint = _pixel(pos[frame, j], centre, view, origin)
                    draw_line(image, _pixel(pos[frame, sk.parents[j]], centre, view, origin), joint, colour)
                    if j in tips:
                        draw_line(image, joint, _pixel(tips[j][frame], centre, view, origin), colour)
    return image


def write_contact_sheets(out_dir: Path) -> list[Path]:
    """One PNG per reaction class, one for the get-ups and one for locomotion, into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    groups: dict[str, list[str]] = {"locomotion": list(LOCOMOTION), "getups": list(GETUPS)}
    for name in REACTIONS:
        groups.setdefault(reaction_class(name), []).append(name)
    written = []
    for group, names in groups.items():
        path = out_dir / f"{group}.png"
        path.write_bytes(png_bytes(contact_sheet({n: CLIPS[n]() for n in names})))
        written.append(path)
    return written
