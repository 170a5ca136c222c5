"""BVH reader and writer: text <-> Skeleton + Motion (metres, Z up, quaternions).

Reading is two steps so that callers can inspect a file before converting it: `parse_bvh` checks
the file and returns it in its own units and axes (`BVHData`); `to_motion` converts to metres and
Z up. `read_bvh` does both. Every problem raises `BVHError` naming the file and the 1-based line.

Conventions matched to Blender's bundled importer (io_anim_bvh), so the two agree to the millimetre:
- a joint's rotation channels compose left to right (channels "Zrotation Xrotation Yrotation"
  mean R = Rz @ Rx @ Ry), angles in degrees;
- a joint with position channels is placed at the channel values (not OFFSET + values); a missing
  position component counts as 0; the root without position channels sits at its OFFSET;
- Y-up files are turned Z-up by +90 degrees about X: (x, y, z) -> (x, -z, y).

The motion block is parsed in one vectorised pass (`np.loadtxt`); a slow per-line pass runs only
to locate an error.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict, Unpack

import numpy as np

from . import quat
from .arrays import FloatArray
from .errors import BVHError
from .skeleton import Motion, Skeleton

MAX_JOINTS = 1000
MAX_DEPTH = 100
# File units -> metres. "cmu" is the CMU ASF unit (1/0.45 inch) kept by many CMU BVH conversions.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "cmu": 0.0254 / 0.45}
TYPICAL_HEIGHT_M = 1.75
_POSITION = {"xposition": 0, "yposition": 1, "zposition": 2}
_ROTATION = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}
# A number as BVH writes it (ASCII digits, optional exponent; nan/inf are caught as not finite). Python's
# float() alone would also take "1_0" or non-ASCII digits, which the vectorised motion pass does not.
_NUMBER = re.compile(r"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|nan|inf|infinity)", re.IGNORECASE)
# The separators of numbers on a motion line (what both str.split and numpy take as whitespace).
_SPACES = re.compile(r"[ \t\v\f]+")
_OTHER_SPACES = "\x1c\x1d\x1e\x1f"  # ASCII that str.isspace (and loadtxt) take for spaces, a BVH does not
# +90 degrees about X: turns a Y-up file Z-up.
_Y_TO_Z = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)


@dataclass
class Channels:
    """One joint's channels in file order: position axes (0..2) and rotation axis letters, each
    with its column in a motion line (a file may interleave positions and rotations)."""

    position: list[int] = field(default_factory=list[int])
    position_columns: list[int] = field(default_factory=list[int])
    rotation: str = ""
    rotation_columns: list[int] = field(default_factory=list[int])

    @property
    def count(self) -> int:
        return len(self.position) + len(self.rotation)


@dataclass
class BVHData:
    """A checked BVH file in its own units and axes. `values` is (frames, channels), degrees."""

    path: str
    names: list[str]
    parents: list[int]
    offsets: FloatArray
    end_sites: dict[int, FloatArray]
    channels: list[Channels]
    frame_time: float
    values: FloatArray

    @property
    def num_frames(self) -> int:
        return self.values.shape[0]


# ---------------------------------------------------------------------------------------------
# Text -> lines


def _read_source(source: str | Path | bytes, name: str | None) -> tuple[str, str]:
    """Return (label for errors, decoded text). Accepts a path or the file's bytes."""
    if isinstance(source, bytes):
        label, raw = name or "<bytes>", source
    else:
        label = str(source)
        try:
            raw = Path(source).read_bytes()
        except OSError as exc:
            raise BVHError(f"cannot read the file ({exc.strerror or exc})", label) from None
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise BVHError("binary data (NUL byte), not a BVH text file", label, _line_at(raw, nul))
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise BVHError("not UTF-8 text (binary or another encoding)", label, _line_at(raw, exc.start)) from None
    if not text.strip():
        raise BVHError("the file is empty", label, 1)
    return label, text


def _line_at(raw: bytes, offset: int) -> int:
    """1-based line of a byte offset, counting CRLF, CR and LF line ends as the text split does."""
    return raw[:offset].replace(b"\r\n", b"\n").replace(b"\r", b"\n").count(b"\n") + 1


def _number(token: str, label: str, line: int, what: str) -> float:
    if not _NUMBER.fullmatch(token):
        raise BVHError(f"{what}: '{token}' is not a number", label, line)
    value = float(token)
    if not np.isfinite(value):
        raise BVHError(f"{what}: '{token}' is not a finite number", label, line)
    return value


# ---------------------------------------------------------------------------------------------
# HIERARCHY


class _Tokens:
    """The hierarchy's tokens with their line numbers, consumed front to back."""

    def __init__(self, lines: list[str], label: str, end_line: int) -> None:
        self.items = [(tok, n) for n, text in enumerate(lines, 1) for tok in text.split()]
        self.pos = 0
        self.label = label
        self.end_line = end_line  # the line reported when tokens run out (MOTION or last line)

    def peek(self) -> tuple[str | None, int]:
        if self.pos < len(self.items):
            return self.items[self.pos]
        return None, self.end_line

    def take(self, context: str) -> tuple[str, int]:
        tok, line = self.peek()
        if tok is None:
            raise BVHError(f"the hierarchy ends early: {context}", self.label, line)
        self.pos += 1
        return tok, line

    def expect(self, word: str, context: str) -> int:
        tok, line = self.take(context)
        if tok.upper() != word.upper():
            raise BVHError(f"expected '{word}' {context}, found '{tok}'", self.label, line)
        return line


class _HierarchyParser:
    def __init__(self, tokens: _Tokens) -> None:
        self.t = tokens
        self.label = tokens.label
        self.names: list[str] = []
        self.name_lines: dict[str, int] = {}
        self.parents: list[int] = []
        self.offsets: list[tuple[float, float, float]] = []
        self.end_sites: dict[int, FloatArray] = {}
        self.channels: list[Channels] = []
        self.columns = 0

    def parse(self) -> None:
        self.t.expect("HIERARCHY", "at the start of the file")
        root_line = self.t.expect("ROOT", "after HIERARCHY")
        self._joint(parent=-1, depth=0, keyword_line=root_line)
        if self.columns == 0:
            raise BVHError("no joint has CHANNELS, so there is no motion to read", self.label, self.t.end_line)
        tok, line = self.t.peek()
        if tok is not None:
            if tok == "}":
                raise BVHError("unbalanced braces: '}' after the root joint was closed", self.label, line)
            raise BVHError(f"unexpected '{tok}' after the root joint (only one ROOT is supported)", self.label, line)

    def _offset(self, context: str) -> tuple[float, float, float]:
        line = self.t.expect("OFFSET", f"in {context}")
        vals: list[float] = []
        for _ in range(3):
            tok, tok_line = self.t.take(f"OFFSET needs 3 numbers ({context})")
            if tok_line != line:
                raise BVHError(f"OFFSET needs 3 numbers on its line ({context})", self.label, line)
            vals.append(_number(tok, self.label, line, "OFFSET"))
        if self.t.peek()[1] == line and self.t.peek()[0] is not None:
            raise BVHError(f"OFFSET has more than 3 numbers ({context})", self.label, line)
        return vals[0], vals[1], vals[2]

    def _channels(self, joint: str) -> Channels:
        line = self.t.expect("CHANNELS", f"after the OFFSET of joint '{joint}'")
        tok, _ = self.t.take(f"CHANNELS of joint '{joint}'")
        if not re.fullmatch(r"[0-9]+", tok) or int(tok) > 6:
            raise BVHError(f"CHANNELS count of joint '{joint}' must be 0 to 6, found '{tok}'", self.label, line)
        spec = Channels()
        for column in range(self.columns, self.columns + int(tok)):
            name, name_line = self.t.take(f"CHANNELS of joint '{joint}' lists fewer names than its count")
            key = name.lower()
            if name_line != line:
                raise BVHError(f"CHANNELS of joint '{joint}' lists fewer names than its count {tok}", self.label, line)
            if key in _POSITION and _POSITION[key] not in spec.position:
                spec.position.append(_POSITION[key])
                spec.position_columns.append(column)
            elif key in _ROTATION and _ROTATION[key] not in spec.rotation:
                spec.rotation += _ROTATION[key]
                spec.rotation_columns.append(column)
            elif key in _POSITION or key in _ROTATION:
                raise BVHError(f"channel '{name}' repeated on joint '{joint}'", self.label, line)
            else:
                raise BVHError(f"unknown channel name '{name}' on joint '{joint}'", self.label, line)
        nxt, nxt_line = self.t.peek()
        if nxt_line == line and nxt is not None:
            raise BVHError(f"CHANNELS of joint '{joint}' lists more names than its count {tok}", self.label, line)
        self.columns += spec.count
        return spec

    def _joint(self, parent: int, depth: int, keyword_line: int) -> None:
        name, line = self.t.take("a joint name is missing")
        if name in ("{", "}"):
            raise BVHError("a joint name is missing", self.label, keyword_line)
        if depth > MAX_DEPTH:
            raise BVHError(f"joints nested more than {MAX_DEPTH} deep", self.label, line)
        if len(self.names) >= MAX_JOINTS:
            raise BVHError(f"more than {MAX_JOINTS} joints", self.label, line)
        if name in self.name_lines:
            raise BVHError(f"duplicate joint name '{name}' (first at line {self.name_lines[name]})", self.label, line)
        index = len(self.names)
        self.names.append(name)
        self.name_lines[name] = line
        self.parents.append(parent)
        open_line = self.t.expect("{", f"after joint '{name}'")
        self.offsets.append(self._offset(f"joint '{name}'"))
        self.channels.append(self._channels(name))
        while True:
            tok, tok_line = self.t.peek()
            if tok is None:
                raise BVHError(
                    f"unbalanced braces: joint '{name}' opened at line {open_line} is never closed",
                    self.label,
                    tok_line,
                )
            self.t.pos += 1
            if tok == "}":
                return
            if tok.upper() == "JOINT":
                self._joint(index, depth + 1, tok_line)
            elif tok.upper() == "END":
                self._end_site(index, name)
            else:
                raise BVHError(f"unexpected '{tok}' inside joint '{name}'", self.label, tok_line)

    def _end_site(self, index: int, name: str) -> None:
        self.t.expect("Site", f"after 'End' in joint '{name}'")
        self.t.expect("{", f"after 'End Site' of joint '{name}'")
        self.end_sites[index] = np.array(self._offset(f"End Site of joint '{name}'"))
        self.t.expect("}", f"to close the End Site of joint '{name}'")


# ---------------------------------------------------------------------------------------------
# MOTION


def _find_motion_line(lines: list[str]) -> int | None:
    for i, text in enumerate(lines):
        if text.strip().upper() == "MOTION":
            return i
    return None


def _motion_header(lines: list[str], start: int, label: str) -> tuple[int, float, int]:
    """Parse 'Frames:' and 'Frame Time:' after MOTION; return (frames, frame_time, first data line index)."""
    i = start + 1
    header: list[tuple[list[str], int]] = []
    while len(header) < 2:
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            missing = "Frames:" if not header else "Frame Time:"
            last = header[-1][1] if header else start + 1
            raise BVHError(f"the motion header is truncated: '{missing}' is missing", label, last)
        header.append((lines[i].split(), i + 1))
        i += 1
    (frames_tok, frames_line), (time_tok, time_line) = header
    if len(frames_tok) != 2 or frames_tok[0].lower() != "frames:":
        raise BVHError(f"expected 'Frames: <count>', found '{' '.join(frames_tok)}'", label, frames_line)
    if not re.fullmatch(r"[+-]?[0-9]+", frames_tok[1]):
        raise BVHError(f"the frame count '{frames_tok[1]}' is not a whole number", label, frames_line)
    frames = int(frames_tok[1])
    if frames <= 0:
        raise BVHError(f"the file has {frames} frames; at least one is needed", label, frames_line)
    if len(time_tok) != 3 or time_tok[0].lower() != "frame" or time_tok[1].lower() != "time:":
        raise BVHError(f"expected 'Frame Time: <seconds>', found '{' '.join(time_tok)}'", label, time_line)
    frame_time = _number(time_tok[2], label, time_line, "Frame Time")
    if frame_time <= 0:
        raise BVHError(f"Frame Time must be positive, found {time_tok[2]}", label, time_line)
    return frames, frame_time, i


def _motion_values(
    lines: list[str], first: int, frames: int, columns: int, *, frames_line: int, label: str
) -> FloatArray:
    """The (frames, columns) block, vectorised; on any mismatch a per-line pass names the line."""
    numbered = [(n, text) for n, text in enumerate(lines[first:], first + 1) if text.strip()]
    if len(numbered) > frames:
        raise BVHError(
            f"'Frames: {frames}' (line {frames_line}) but more frame lines follow; the first extra one is here",
            label,
            numbered[frames][0],
        )
    values = _number_table(numbered, columns)
    if values is not None:
        bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
        if bad.size:
            row = int(bad[0])
            col = int(np.flatnonzero(~np.isfinite(values[row]))[0])
            raise BVHError(f"value {col + 1} is not a finite number ({values[row, col]})", label, numbered[row][0])
        if len(numbered) < frames:
            last = numbered[-1][0] if numbered else frames_line
            raise BVHError(
                f"the motion is truncated: 'Frames: {frames}' (line {frames_line}) "
                f"but only {len(numbered)} frame lines",
                label,
                last,
            )
        return values
    _locate_motion_error(numbered, columns, label)
    raise BVHError("the motion block cannot be read as numbers", label, numbered[0][0] if numbered else frames_line)


def _number_table(numbered: list[tuple[int, str]], columns: int) -> FloatArray | None:
    """The lines as a (lines, columns) array in one C pass, or None where they cannot be read so
    (a token that is not a number, a line with another count of values). numpy's loadtxt checks
    every line's count as it parses; it is also faster than fromstring on the joined text and gives
    the same numbers bit for bit."""
    if not numbered:
        return np.empty((0, columns))
    block = "\n".join(text for _, text in numbered)
    if not block.isascii() or any(c in block for c in _OTHER_SPACES):
        return None  # loadtxt would split there too; the per-line pass names the character
    try:
        values = np.loadtxt(io.StringIO(block), dtype=np.float64, comments=None, ndmin=2)
    except ValueError:
        return None
    return values if values.shape == (len(numbered), columns) else None


def _locate_motion_error(numbered: list[tuple[int, str]], columns: int, label: str) -> None:
    for line, text in numbered:
        tokens = _SPACES.split(text.strip(" \t\v\f"))
        if len(tokens) != columns:
            raise BVHError(f"expected {columns} values (one per channel), found {len(tokens)}", label, line)
        for k, tok in enumerate(tokens):
            _number(tok, label, line, f"value {k + 1}")


# ---------------------------------------------------------------------------------------------
# Public API


def parse_bvh(source: str | Path | bytes, name: str | None = None) -> BVHData:
    """Check and parse a BVH file (path or bytes) without converting units or axes."""
    label, text = _read_source(source, name)
    if "\r" in text:  # one scan; the two replacements would copy the whole text twice
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    # Problems found at the end of the file are reported at its last line with text on it.
    last_line = max((n for n, line in enumerate(lines, 1) if line.strip()), default=1)
    motion_at = _find_motion_line(lines)
    hierarchy_lines = lines if motion_at is None else lines[:motion_at]
    end_line = last_line if motion_at is None else motion_at + 1
    parser = _HierarchyParser(_Tokens(hierarchy_lines, label, end_line))
    parser.parse()
    if motion_at is None:
        raise BVHError("the MOTION section is missing", label, last_line)
    frames, frame_time, first = _motion_header(lines, motion_at, label)
    frames_line = next(n for n in range(motion_at + 2, len(lines) + 1) if lines[n - 1].strip())
    values = _motion_values(lines, first, frames, parser.columns, frames_line=frames_line, label=label)
    return BVHData(
        path=label,
        names=parser.names,
        parents=parser.parents,
        offsets=np.array(parser.offsets, dtype=np.float64),
        end_sites=parser.end_sites,
        channels=parser.channels,
        frame_time=frame_time,
        values=values,
    )


def unit_scale(data: BVHData, unit: str | float = "auto") -> float:
    """Metres per file unit: given by name or number, or guessed from the rest pose's size.

    The guess takes the unit that makes the rest pose's largest extent (about body height, or arm
    span in a T-pose) closest to 1.75 m on a log scale.
    """
    if not isinstance(unit, str):
        if not unit > 0:
            raise BVHError(f"unit scale must be positive, got {unit}", data.path)
        return float(unit)
    if unit != "auto":
        if unit not in UNITS:
            raise BVHError(f"unknown unit '{unit}'; use one of {', '.join(UNITS)} or a number", data.path)
        return UNITS[unit]
    extent = Skeleton(data.names, np.asarray(data.parents), data.offsets, dict(data.end_sites)).rest_extent()
    if extent <= 0:
        raise BVHError("every OFFSET is zero, so the units cannot be guessed; give the unit", data.path)
    return min(UNITS.values(), key=lambda s: abs(np.log(extent * s / TYPICAL_HEIGHT_M)))


def to_motion(data: BVHData, unit: str | float = "auto", up: str = "Y") -> Motion:
    """Convert a parsed file to metres, Z up, quaternions."""
    if up.upper() not in ("Y", "Z"):
        raise BVHError(f"up axis must be 'Y' or 'Z', got '{up}'", data.path)
    scale = unit_scale(data, unit)
    axis_q = _Y_TO_Z if up.upper() == "Y" else quat.identity()
    count, frames = len(data.names), data.num_frames
    offsets = data.offsets * scale
    local_rot = quat.identity((frames, count))
    # Positions: the rest offsets, where a joint has position channels its channels (the others 0);
    # every joint's kept only where a joint below the root moves, else the root's alone.
    rest = quat.rotate(axis_q, offsets)
    moving = [(j, ch) for j, ch in enumerate(data.channels) if ch.position]
    animated_pos = any(j > 0 for j, _ in moving)
    kept = count if animated_pos else 1
    positions = np.broadcast_to(rest[:kept], (frames, kept, 3)).copy()
    for j, ch in moving:
        raw = np.zeros((frames, 3))
        raw[:, ch.position] = data.values[:, ch.position_columns] * scale
        positions[:, j] = quat.rotate(axis_q, raw)
    # Rotations: one vectorised conversion per distinct rotation order (usually one for all joints).
    for order in {ch.rotation for ch in data.channels if ch.rotation}:
        joints = [j for j, ch in enumerate(data.channels) if ch.rotation == order]
        columns = [data.channels[j].rotation_columns for j in joints]
        local_rot[:, joints] = quat.from_euler(np.radians(data.values[:, columns]), order)
    # Change of axes: conjugate rotations (a turn about X before and after: mul's values, fewer
    # products), rotate vectors.
    if up.upper() == "Y":
        c, s = _Y_TO_Z[0], _Y_TO_Z[1]
        local_rot = quat.turn_after(quat.turn_before(local_rot, 0, c, s), 0, c, -s)
    end_sites = {j: quat.rotate(axis_q, off * scale) for j, off in data.end_sites.items()}
    skeleton = Skeleton(data.names, np.asarray(data.parents), rest, end_sites)
    return Motion(
        skeleton=skeleton,
        fps=1.0 / data.frame_time,
        root_pos=positions[:, 0].copy(),
        local_rot=quat.normalize(local_rot),
        local_pos=positions if animated_pos else None,
    )


def read_bvh(path: str | Path, unit: str | float = "auto", up: str = "Y") -> Motion:
    """Read a BVH file into a Motion in metres, Z up (see `to_motion`)."""
    return to_motion(parse_bvh(path), unit=unit, up=up)


# ---------------------------------------------------------------------------------------------
# Writer


def format_bvh(
    motion: Motion, rotation_order: str = "ZXY", unit: str | float = "cm", up: str = "Y", decimals: int = 6
) -> str:
    """BVH text for a Motion: root with 6 channels, other joints 3 (6 when the motion has local_pos).

    Written in the given unit (default centimetres) and up axis (default Y), the common BVH dialect.
    """
    if up.upper() not in ("Y", "Z"):
        raise BVHError(f"up axis must be 'Y' or 'Z', got '{up}'")
    if isinstance(unit, str) and unit not in UNITS:
        raise BVHError(f"unknown unit '{unit}'; use one of {', '.join(UNITS)} or a number")
    order = rotation_order.upper()
    quat.to_euler(quat.identity(), order)  # rejects anything but a permutation of XYZ
    scale = UNITS[unit] if isinstance(unit, str) else float(unit)
    to_file = quat.conj(_Y_TO_Z) if up.upper() == "Y" else quat.identity()
    tiny = 0.5 * 10.0**-decimals

    def file_vectors(v: FloatArray) -> FloatArray:
        out = quat.rotate(to_file, v) / scale
        out[np.abs(out) < tiny] = 0.0  # no "-0.000000"
        return out

    lines = ["HIERARCHY"]
    _hierarchy_lines(motion, 0, order, file_vectors=file_vectors, number=f"%.{decimals}f", lines=lines)
    local_rot = quat.mul(quat.mul(to_file, motion.local_rot), quat.conj(to_file))
    block = _motion_block(motion, np.degrees(quat.to_euler(local_rot, order)), file_vectors)
    block[np.abs(block) < tiny] = 0.0
    lines += ["MOTION", f"Frames: {motion.num_frames}", f"Frame Time: {motion.frame_time:.9g}"]
    row_format = " ".join([f"%.{decimals}f"] * block.shape[1])
    lines += [row_format % tuple(row) for row in block]
    return "\n".join(lines) + "\n"


def _hierarchy_lines(
    motion: Motion,
    joint: int,
    order: str,
    *,
    file_vectors: Callable[[FloatArray], FloatArray],
    number: str,
    lines: list[str],
    depth: int = 0,
) -> None:
    """Append one joint's block (and its children's, recursively) to `lines`."""
    sk = motion.skeleton
    pad = "\t" * depth
    offset = " ".join(number % v for v in file_vectors(sk.offsets[joint]))
    rotations = " ".join(f"{c}rotation" for c in order)
    channels = f"6 Xposition Yposition Zposition {rotations}" if _writes_position(motion, joint) else f"3 {rotations}"
    lines += [
        f"{pad}{'ROOT' if joint == 0 else 'JOINT'} {sk.names[joint]}",
        f"{pad}{{",
        f"{pad}\tOFFSET {offset}",
        f"{pad}\tCHANNELS {channels}",
    ]
    for child in sk.children(joint):
        _hierarchy_lines(motion, child, order, file_vectors=file_vectors, number=number, lines=lines, depth=depth + 1)
    if joint in sk.end_sites:
        tip = " ".join(number % v for v in file_vectors(sk.end_sites[joint]))
        lines += [f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {tip}", f"{pad}\t}}"]
    lines.append(f"{pad}}}")


def _writes_position(motion: Motion, joint: int) -> bool:
    return joint == 0 or motion.local_pos is not None


def _motion_block(
    motion: Motion, euler_degrees: FloatArray, file_vectors: Callable[[FloatArray], FloatArray]
) -> FloatArray:
    """(T, channels) values in the hierarchy's channel order: per joint [positions] + rotations."""
    translations = file_vectors(motion.joint_offsets())
    translations[:, 0] = file_vectors(motion.root_pos)
    columns: list[FloatArray] = []
    for j in range(motion.skeleton.num_joints):
        if _writes_position(motion, j):
            columns.append(translations[:, j])
        columns.append(euler_degrees[:, j])
    return np.concatenate(columns, axis=1)


class FormatOptions(TypedDict, total=False):
    """The keyword options of `format_bvh`, so `write_bvh` passes on only those, each typed."""

    rotation_order: str
    unit: str | float
    up: str
    decimals: int


def write_bvh(path: str | Path, motion: Motion, **options: Unpack[FormatOptions]) -> None:
    """Write a Motion as a BVH file; options as `format_bvh`."""
    Path(path).write_text(format_bvh(motion, **options), encoding="utf-8", newline="\n")
