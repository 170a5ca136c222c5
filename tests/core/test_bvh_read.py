"""Reading BVH: dialects that must parse, channel layouts, rotation orders, units, up axis, real mocap."""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from reactive_anim.core.model.errors import BVHError
from tests.support.mocap import MOCAP, mocap_files, require_mocap

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
Vec3 = tuple[float, float, float]
Joint = tuple[str, int, Vec3, list[str], Vec3 | None]  # a make_bvh joint: name, parent, offset, channels, end site


# ---------------------------------------------------------------------------------------------
# Helpers: write BVH text from a joint table, with nothing from the module under test.


def make_bvh(joints, rows, frame_time=0.04):
    """BVH text. joints: (name, parent index, offset, channel names, end-site offset or None), parents first."""
    children = {}
    for j, joint in enumerate(joints):
        children.setdefault(joint[1], []).append(j)
    lines = ["HIERARCHY"]

    def numbers(values):
        return " ".join(repr(float(v)) for v in values)

    def emit(j, depth):
        name, parent, offset, channels, end = joints[j]
        pad = "\t" * depth
        lines.extend([f"{pad}{'ROOT' if parent < 0 else 'JOINT'} {name}", f"{pad}{{"])
        lines.append(f"{pad}\tOFFSET {numbers(offset)}")
        lines.append(f"{pad}\tCHANNELS {len(channels)} {' '.join(channels)}".rstrip())
        for child in children.get(j, []):
            emit(child, depth + 1)
        if end is not None:
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET {numbers(end)}", f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    emit(0, 0)
    lines += ["MOTION", f"Frames: {len(rows)}", f"Frame Time: {frame_time!r}"]
    lines += [numbers(row) for row in rows]
    return "\n".join(lines) + "\n"


def parse(text, **kw):
    return bvh.parse_bvh(text.encode("utf-8") if isinstance(text, str) else text, name="test.bvh", **kw)


def load(text, unit: float | str = 1.0, up="Z"):
    """Motion from BVH text; by default without unit or axis conversion, to check channel semantics."""
    return bvh.to_motion(parse(text), unit=unit, up=up)


def q_axis(axis_letter, degrees):
    """Quaternion (w, x, y, z) of a turn about X, Y or Z, written out by hand."""
    half = np.radians(degrees) / 2
    q = np.zeros(4)
    q[0] = np.cos(half)
    q[1 + "XYZ".index(axis_letter)] = np.sin(half)
    return q


def hamilton(a, b):
    aw, av = a[0], a[1:]
    bw, bv = b[0], b[1:]
    return np.concatenate([[aw * bw - av @ bv], aw * bv + bw * av + np.cross(av, bv)])


def q_channels(order, degrees):
    """The rotation of channels `order` with these angles: q_first * q_second * q_third."""
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for axis_letter, angle in zip(order, degrees, strict=True):
        q = hamilton(q, q_axis(axis_letter, angle))
    return q


def assert_same_rotation(a, b, tol=1e-9):
    assert np.max(quat.angle_between(a, b)) < tol


# ---------------------------------------------------------------------------------------------
# A reference file with the unusual cases: positions on a non-root joint, a joint with position
# channels only (in X Z Y order), a joint with no channels, a rotation order per joint, end sites.

POS = ["Xposition", "Yposition", "Zposition"]
REF_JOINTS = [
    ("Hips", -1, (0.0, 90.0, 0.0), POS + ["Zrotation", "Xrotation", "Yrotation"], None),
    ("Chest", 0, (0.0, 30.0, 0.0), POS + ["Yrotation", "Xrotation", "Zrotation"], None),
    ("Head", 1, (0.0, 50.0, 0.0), ["Xrotation", "Zrotation", "Yrotation"], (0.0, 20.0, 0.0)),
    ("Prop", 0, (10.0, 0.0, 0.0), [], (5.0, 0.0, 0.0)),
    ("Leg", 0, (10.0, -45.0, 0.0), ["Xposition", "Zposition", "Yposition"], None),
    ("Foot", 4, (0.0, -45.0, 0.0), ["Zrotation", "Yrotation", "Xrotation"], (0.0, 0.0, 15.0)),
]
REF_ROWS = np.arange(3 * 21, dtype=float).reshape(3, 21) * 1.5 - 20.0
REF = make_bvh(REF_JOINTS, REF_ROWS)


def test_reference_file_structure():
    data = parse(REF)
    assert data.names == ["Hips", "Chest", "Head", "Prop", "Leg", "Foot"]
    assert data.parents == [-1, 0, 1, 0, 0, 4]
    np.testing.assert_array_equal(data.offsets, [j[2] for j in REF_JOINTS])
    assert sorted(data.end_sites) == [2, 3, 5]
    np.testing.assert_array_equal(data.end_sites[5], [0.0, 0.0, 15.0])
    np.testing.assert_array_equal(data.values, REF_ROWS)
    assert data.frame_time == 0.04 and data.num_frames == 3
    chest, prop, leg = data.channels[1], data.channels[3], data.channels[4]
    assert (chest.position, chest.position_columns) == ([0, 1, 2], [6, 7, 8])
    assert (chest.rotation, chest.rotation_columns) == ("YXZ", [9, 10, 11])
    assert prop.count == 0
    assert (leg.position, leg.position_columns, leg.rotation) == ([0, 2, 1], [15, 16, 17], "")
    assert data.channels[5].rotation_columns == [18, 19, 20]


def indent_mixed(text):
    """Re-indent every line with a different mix of tabs and spaces, and add trailing blanks."""
    out = []
    for n, line in enumerate(text.split("\n")):
        depth = len(line) - len(line.lstrip("\t"))
        out.append(("\t " if n % 2 else "  \t") * depth + line.strip() + (" \t" if n % 3 == 0 else ""))
    return "\n".join(out)


def mixed_line_ends(text):
    lines = text.split("\n")
    return "".join(line + ("\r\n" if n % 2 else "\n") for n, line in enumerate(lines[:-1]))


def lower_keywords(text):
    for word in ["HIERARCHY", "ROOT", "JOINT", "OFFSET", "CHANNELS", "End Site", "MOTION", "Frames:", "Frame Time:"]:
        text = text.replace(word, word.lower())
    return re.sub(r"[XYZ](position|rotation)", lambda m: m.group(0).lower(), text)


DIALECTS = {
    "crlf": lambda t: t.replace("\n", "\r\n"),
    "cr_only": lambda t: t.replace("\n", "\r"),
    "lf_mixed_with_crlf": mixed_line_ends,
    "utf8_bom": lambda t: "\ufeff" + t,
    "bom_crlf_windows_export": lambda t: "\ufeff" + t.replace("\n", "\r\n"),
    "spaces_not_tabs": lambda t: t.replace("\t", "    "),
    "mixed_indentation_and_trailing_blanks": indent_mixed,
    "blank_lines_everywhere": lambda t: t.replace("\n", "\n\n"),
    "no_final_newline": lambda t: t.rstrip("\n"),
    "lowercase_keywords": lower_keywords,
    "several_values_spaces_and_tabs": lambda t: re.sub(r"(?<=\d) (?=-?\d)", " \t  ", t),
}


@pytest.mark.parametrize("dialect", sorted(DIALECTS))
def test_dialects_parse_like_the_reference(dialect):
    text = DIALECTS[dialect](REF)
    assert text != REF
    data, ref = parse(text), parse(REF)
    assert data.names == ref.names and data.parents == ref.parents and data.channels == ref.channels
    np.testing.assert_array_equal(data.offsets, ref.offsets)
    assert data.end_sites.keys() == ref.end_sites.keys()
    for j in ref.end_sites:
        np.testing.assert_array_equal(data.end_sites[j], ref.end_sites[j])
    np.testing.assert_array_equal(data.values, ref.values)
    assert data.frame_time == ref.frame_time


def test_position_channels_place_the_joint_at_their_values():
    """Positions on any joint replace its OFFSET (io_anim_bvh convention); missing axes count as 0."""
    m = load(REF)
    v = REF_ROWS
    np.testing.assert_array_equal(m.root_pos, v[:, 0:3])
    assert m.local_pos is not None
    np.testing.assert_array_equal(m.local_pos[:, 1], v[:, 6:9])  # Chest: X Y Z
    np.testing.assert_array_equal(m.local_pos[:, 4], v[:, [15, 17, 16]])  # Leg: columns X Z Y
    np.testing.assert_array_equal(m.local_pos[:, 2], np.broadcast_to(REF_JOINTS[2][2], (3, 3)))  # Head: OFFSET


def test_partial_position_channels_and_root_without_positions():
    joints = [
        ("Hips", -1, (1.0, 2.0, 3.0), ["Yrotation"], None),
        ("Slider", 0, (7.0, 8.0, 9.0), ["Xposition", "Yposition"], (0.0, 1.0, 0.0)),
    ]
    m = load(make_bvh(joints, [[30.0, 4.0, 5.0], [-30.0, 6.0, 7.0]]))
    np.testing.assert_array_equal(m.root_pos, [[1.0, 2.0, 3.0]] * 2)  # no position channels: at OFFSET
    assert m.local_pos is not None
    np.testing.assert_array_equal(m.local_pos[:, 1], [[4.0, 5.0, 0.0], [6.0, 7.0, 0.0]])
    assert_same_rotation(m.local_rot[:, 0], np.stack([q_axis("Y", 30.0), q_axis("Y", -30.0)]))


def test_joints_without_rotation_channels_stay_at_rest():
    m = load(REF)
    np.testing.assert_array_equal(m.local_rot[:, 3], quat.identity((3,)))  # Prop, 0 channels
    np.testing.assert_array_equal(m.local_rot[:, 4], quat.identity((3,)))  # Leg, positions only


@pytest.mark.parametrize("up", ["Z", "Y"])
def test_every_rotation_order_per_joint(up):
    """A chain with one joint per order, all in one file; each joint's rotation is built by hand."""
    rng = np.random.default_rng(3)
    joints: list[Joint] = [
        (f"J{k}_{order}", k - 1, (0.0, 1.0, 0.0), [f"{c}rotation" for c in order], None)
        for k, order in enumerate(ORDERS)
    ]
    joints[-1] = joints[-1][:4] + ((0.0, 1.0, 0.0),)
    angles = rng.uniform(-170.0, 170.0, size=(4, 6, 3))
    angles[0, :, 1] = 90.0  # gimbal lock in frame 0
    m = load(make_bvh(joints, angles.reshape(4, 18)), up=up)
    # A Y-up file's rotations are seen from Z-up axes: conjugated by +90 degrees about X.
    to_world = q_axis("X", 90.0) if up == "Y" else q_axis("X", 0.0)
    for f in range(4):
        for k, order in enumerate(ORDERS):
            expected = hamilton(hamilton(to_world, q_channels(order, angles[f, k])), to_world * [1, -1, -1, -1])
            assert_same_rotation(m.local_rot[f, k], expected)


def test_rotation_channels_interleaved_with_positions():
    channels = ["Zrotation", "Xposition", "Yrotation", "Yposition", "Xrotation", "Zposition"]
    m = load(make_bvh([("Hips", -1, (0.0, 0.0, 0.0), channels, (0.0, 1.0, 0.0))], [[10.0, 1.0, 20.0, 2.0, 30.0, 3.0]]))
    np.testing.assert_array_equal(m.root_pos, [[1.0, 2.0, 3.0]])
    assert_same_rotation(m.local_rot[0, 0], q_channels("ZYX", [10.0, 20.0, 30.0]))


# ---------------------------------------------------------------------------------------------
# Units and up axis.

# A 1.75 m figure in metres, Y up: feet end sites at the floor, head end site at 1.75 m.
BODY = [
    ("Hips", -1, (0.0, 0.95, 0.0), POS + ["Zrotation", "Xrotation", "Yrotation"], None),
    ("Spine", 0, (0.0, 0.3, 0.02), ["Zrotation", "Xrotation", "Yrotation"], None),
    ("Head", 1, (0.0, 0.35, -0.01), ["Zrotation", "Xrotation", "Yrotation"], (0.0, 0.15, 0.0)),
    ("LeftLeg", 0, (0.1, -0.5, 0.0), ["Zrotation", "Xrotation", "Yrotation"], None),
    ("LeftFoot", 3, (0.0, -0.4, 0.03), ["Zrotation", "Xrotation", "Yrotation"], (0.0, -0.05, 0.1)),
]
BODY_ROWS = np.array(
    [
        [0.1, 0.95, -0.2, 5.0, 10.0, 15.0] + [7.0, -3.0, 12.0] * 4,
        [0.3, 0.93, 0.4, -5.0, 20.0, 45.0] + [-20.0, 8.0, 1.0] * 4,
    ]
)


def body_in(scale):
    """BODY written in a unit of `scale` metres: offsets, end sites and position channels divided."""
    joints = [
        (n, p, np.divide(off, scale), ch, None if end is None else np.divide(end, scale)) for n, p, off, ch, end in BODY
    ]
    rows = BODY_ROWS.copy()
    rows[:, :3] /= scale
    return make_bvh(joints, rows)


def assert_same_motion(a, b, atol):
    np.testing.assert_allclose(a.skeleton.offsets, b.skeleton.offsets, atol=atol)
    assert a.skeleton.end_sites.keys() == b.skeleton.end_sites.keys()
    for j in a.skeleton.end_sites:
        np.testing.assert_allclose(a.skeleton.end_sites[j], b.skeleton.end_sites[j], atol=atol)
    np.testing.assert_allclose(a.root_pos, b.root_pos, atol=atol)
    np.testing.assert_allclose(a.global_positions(), b.global_positions(), atol=atol)
    assert_same_rotation(a.local_rot, b.local_rot, tol=atol)


@pytest.mark.parametrize("unit", ["m", "cm", "mm", "in", "cmu"])
def test_unit_detection_gives_the_same_metres(unit):
    metres = load(body_in(1.0), unit="m", up="Y")
    text = body_in(bvh.UNITS[unit])
    assert bvh.unit_scale(parse(text)) == bvh.UNITS[unit]
    assert_same_motion(load(text, unit="auto", up="Y"), metres, atol=1e-9)
    np.testing.assert_allclose(metres.skeleton.rest_positions()[2, 2], 0.95 + 0.3 + 0.35, atol=1e-12)  # head, Z up
    np.testing.assert_allclose(metres.root_pos[:, 2], BODY_ROWS[:, 1], atol=1e-12)


def test_unit_override_by_name_and_by_number():
    text = body_in(0.01)
    auto = load(text, unit="auto", up="Y")
    assert_same_motion(load(text, unit="cm", up="Y"), auto, atol=1e-12)
    assert_same_motion(load(text, unit=0.01, up="Y"), auto, atol=1e-12)
    as_metres = load(text, unit="m", up="Y")
    np.testing.assert_allclose(as_metres.skeleton.offsets, auto.skeleton.offsets * 100.0, atol=1e-9)
    np.testing.assert_allclose(load(text, unit=0.5, up="Y").root_pos, auto.root_pos * 50.0, atol=1e-9)


@pytest.mark.parametrize(
    "unit, fragment", [("furlong", "unknown unit 'furlong'"), (0.0, "must be positive"), (-0.01, "must be positive")]
)
def test_bad_unit_override(unit, fragment):
    with pytest.raises(BVHError, match=re.escape(fragment)) as info:
        load(body_in(0.01), unit=unit)
    assert info.value.path == "test.bvh"


def test_bad_up_axis():
    with pytest.raises(BVHError, match="up axis must be 'Y' or 'Z', got 'X'"):
        load(REF, up="X")


def test_all_zero_offsets_need_a_unit():
    text = make_bvh([("Hips", -1, (0.0, 0.0, 0.0), ["Zrotation"], (0.0, 0.0, 0.0))], [[1.0]])
    with pytest.raises(BVHError, match="units cannot be guessed"):
        load(text, unit="auto")
    assert load(text, unit="cm").num_frames == 1


def test_y_up_file_becomes_z_up():
    joints = [
        ("Hips", -1, (1.0, 2.0, 3.0), POS + ["Yrotation"], None),
        ("Tip", 0, (0.0, 1.0, 0.0), [], (0.5, 0.0, -2.0)),
    ]
    text = make_bvh(joints, [[4.0, 5.0, 6.0, 90.0]])
    y_up, z_up = load(text, up="Y"), load(text, up="Z")
    # (x, y, z) in the file -> (x, -z, y): +Y in the file is +Z in the world.
    np.testing.assert_allclose(y_up.skeleton.offsets, [[1.0, -3.0, 2.0], [0.0, 0.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(y_up.skeleton.end_sites[1], [0.5, 2.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(y_up.root_pos, [[4.0, -6.0, 5.0]], atol=1e-15)
    np.testing.assert_allclose(z_up.skeleton.offsets, [[1.0, 2.0, 3.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(z_up.root_pos, [[4.0, 5.0, 6.0]])
    # A turn about the file's up axis is a turn about world Z: +X swings to +Y.
    assert_same_rotation(y_up.local_rot[0, 0], q_axis("Z", 90.0))
    assert_same_rotation(z_up.local_rot[0, 0], q_axis("Y", 90.0))
    # Forward kinematics: the Tip (1 up in the file) is above the root.
    np.testing.assert_allclose(y_up.global_positions()[0, 1] - y_up.root_pos[0], [0.0, 0.0, 1.0], atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Real motion capture (../shared/mocap, test-only data).

MOCAP_FILES = mocap_files()
MOCAP_PARAMS = [pytest.param(p, id=str(p.relative_to(MOCAP)), marks=pytest.mark.mocap) for p in MOCAP_FILES] or [
    pytest.param(None, marks=pytest.mark.skip(reason=f"real mocap not available: {MOCAP} is absent (test-only data)"))
]


def raw_counts(path):
    """Joints, End Sites, channels, frames, frame time, first and last frame: from the raw text alone."""
    lines = [line.strip() for line in path.read_bytes().decode("utf-8-sig").splitlines()]
    words = [line.split() for line in lines]
    joints = sum(1 for w in words if w and w[0] in ("ROOT", "JOINT"))
    end_sites = sum(1 for w in words if w[:2] == ["End", "Site"])
    channels = sum(int(w[1]) for w in words if w and w[0] == "CHANNELS")
    frames_at = next(n for n, w in enumerate(words) if w and w[0] == "Frames:")
    frame_time = float(words[frames_at + 1][2])
    data = [w for w in words[frames_at + 2 :] if w]
    first, last = (np.array(w, dtype=float) for w in (data[0], data[-1]))
    return joints, end_sites, channels, int(words[frames_at][1]), frame_time, first, last


@pytest.mark.parametrize("path", MOCAP_PARAMS)
def test_real_mocap_parses(path):
    joints, end_sites, channels, frames, frame_time, first, last = raw_counts(path)
    data = bvh.parse_bvh(path)
    assert len(data.names) == joints
    assert len(data.end_sites) == end_sites
    assert data.values.shape == (frames, channels)
    assert data.frame_time == frame_time
    np.testing.assert_array_equal(data.values[0], first)
    np.testing.assert_array_equal(data.values[-1], last)
    motion = bvh.to_motion(data)
    assert np.all(np.isfinite(motion.global_positions()))
    assert (motion.local_pos is not None) == ("bandai_namco" in path.parts)


@pytest.mark.mocap
@pytest.mark.parametrize(
    "relative, unit",
    [
        ("cmu/90_18.bvh", "cmu"),
        ("bandai_namco/dataset-1/dataset-1_walk_normal_002.bvh", "cm"),
        ("cmu_iclone/007_01.bvh", "cm"),
    ],
)
def test_real_mocap_unit_is_detected(relative, unit):
    assert bvh.unit_scale(bvh.parse_bvh(require_mocap(relative))) == bvh.UNITS[unit]


@pytest.mark.mocap
def test_forward_kinematics_on_a_standing_cmu_frame():
    """CMU 90_18: standing at frame 1 (frame 0 is the converter's T-pose), lying on the back at the end."""
    motion = bvh.read_bvh(require_mocap("cmu/90_18.bvh"))
    names = motion.skeleton.names
    pos = motion.global_positions()
    z = {name: pos[:, names.index(name), 2] for name in ["Head", "Hips", "LeftFoot", "RightFoot", "LeftToeBase"]}
    standing, lying = 1, motion.num_frames - 1
    assert z["Head"][standing] > z["Hips"][standing] + 0.3
    assert z["Hips"][standing] > max(z["LeftFoot"][standing], z["RightFoot"][standing]) + 0.6
    assert 1.2 < z["Head"][standing] - z["LeftToeBase"][standing] < 2.0  # a person's height, in metres
    assert abs(z["Head"][lying] - z["Hips"][lying]) < 0.2
    assert motion.fps == pytest.approx(120.0, rel=1e-4)
