"""Malformed BVH input: every file in tests/data/malformed must raise BVHError at the exact line.

Each file holds one problem. Most are the same small valid file (3 joints, 12 channels, 2 frames,
25 lines) with one edit; the table gives the 1-based line the error must point at and a fragment of
the message. Inputs too big to commit (over 1000 joints, nesting over 100 deep) are written into
tmp_path by the tests at the end.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from reactive_anim.core.model import bvh
from reactive_anim.core.model.errors import BVHError

MALFORMED = Path(__file__).resolve().parents[1] / "data" / "malformed"

# file name -> (line, message fragment)
CASES = {
    # Not text at all, or no content.
    "empty.bvh": (1, "the file is empty"),
    "whitespace_only.bvh": (1, "the file is empty"),
    "bom_only.bvh": (1, "the file is empty"),
    "binary_junk.bvh": (3, "binary data (NUL byte)"),
    "utf16_encoded.bvh": (1, "binary data (NUL byte)"),
    "latin1_joint_name.bvh": (10, "not UTF-8 text"),
    "latin1_joint_name_cr_line_ends.bvh": (10, "not UTF-8 text"),
    # Structure of the hierarchy.
    "missing_hierarchy.bvh": (1, "expected 'HIERARCHY' at the start of the file, found 'ROOT'"),
    "missing_root.bvh": (2, "expected 'ROOT' after HIERARCHY, found 'JOINT'"),
    "root_without_name.bvh": (2, "a joint name is missing"),
    "joint_without_name.bvh": (6, "a joint name is missing"),
    "missing_open_brace.bvh": (7, "expected '{' after joint 'Spine', found 'OFFSET'"),
    "missing_motion.bvh": (20, "the MOTION section is missing"),
    "truncated_hierarchy.bvh": (12, "the hierarchy ends early: after the OFFSET of joint 'Head'"),
    "unclosed_joint.bvh": (20, "joint 'Hips' opened at line 3 is never closed"),
    "unbalanced_extra_brace.bvh": (21, "unbalanced braces: '}' after the root joint was closed"),
    "second_root.bvh": (21, "unexpected 'ROOT' after the root joint (only one ROOT is supported)"),
    "unexpected_keyword_in_joint.bvh": (10, "unexpected 'JIONT' inside joint 'Spine'"),
    "duplicate_joint.bvh": (10, "duplicate joint name 'Spine' (first at line 6)"),
    # OFFSET.
    "missing_offset.bvh": (8, "expected 'OFFSET' in joint 'Spine', found 'CHANNELS'"),
    "offset_not_a_number.bvh": (8, "OFFSET: 'ten' is not a number"),
    "offset_decimal_comma.bvh": (8, "OFFSET: '0,0' is not a number"),
    "offset_too_few_values.bvh": (8, "OFFSET needs 3 numbers on its line (joint 'Spine')"),
    "offset_too_many_values.bvh": (8, "OFFSET has more than 3 numbers (joint 'Spine')"),
    "offset_nan.bvh": (12, "OFFSET: 'nan' is not a finite number"),
    # CHANNELS.
    "missing_channels.bvh": (9, "expected 'CHANNELS' after the OFFSET of joint 'Spine', found 'JOINT'"),
    "channel_count_not_integer.bvh": (9, "CHANNELS count of joint 'Spine' must be 0 to 6, found 'three'"),
    "channel_count_superscript_digit.bvh": (9, "CHANNELS count of joint 'Spine' must be 0 to 6, found '\u00b3'"),
    "channel_count_too_large.bvh": (5, "CHANNELS count of joint 'Hips' must be 0 to 6, found '7'"),
    "channel_count_negative.bvh": (9, "CHANNELS count of joint 'Spine' must be 0 to 6, found '-3'"),
    "channels_fewer_names_than_count.bvh": (9, "CHANNELS of joint 'Spine' lists fewer names than its count 3"),
    "channels_more_names_than_count.bvh": (9, "CHANNELS of joint 'Spine' lists more names than its count 2"),
    "repeated_channel.bvh": (13, "channel 'Zrotation' repeated on joint 'Head'"),
    "unknown_channel.bvh": (9, "unknown channel name 'Wrotation' on joint 'Spine'"),
    "no_channels_at_all.bvh": (21, "no joint has CHANNELS"),
    # End Site.
    "end_site_without_offset.bvh": (16, "expected 'OFFSET' in End Site of joint 'Head', found '}'"),
    "end_without_site.bvh": (14, "expected 'Site' after 'End' in joint 'Head', found 'Sight'"),
    "end_site_with_channels.bvh": (17, "expected '}' to close the End Site of joint 'Head', found 'CHANNELS'"),
    # Motion header.
    "motion_header_truncated.bvh": (21, "the motion header is truncated: 'Frames:' is missing"),
    "motion_header_without_frame_time.bvh": (22, "the motion header is truncated: 'Frame Time:' is missing"),
    "missing_frames_line.bvh": (22, "expected 'Frames: <count>', found 'Frame Time: 0.033333'"),
    "missing_frame_time.bvh": (23, "expected 'Frame Time: <seconds>', found '0.0 90.0"),
    "frames_without_count.bvh": (22, "expected 'Frames: <count>', found 'Frames:'"),
    "non_integer_frames.bvh": (22, "the frame count '2.0' is not a whole number"),
    "zero_frames.bvh": (22, "the file has 0 frames; at least one is needed"),
    "negative_frames.bvh": (22, "the file has -2 frames"),
    "zero_frame_time.bvh": (23, "Frame Time must be positive, found 0"),
    "negative_frame_time.bvh": (23, "Frame Time must be positive, found -0.033333"),
    "frame_time_not_a_number.bvh": (23, "Frame Time: 'fast' is not a number"),
    # Motion lines.
    "no_frame_lines.bvh": (22, "the motion is truncated: 'Frames: 2' (line 22) but only 0 frame lines"),
    "frames_more_than_lines.bvh": (25, "the motion is truncated: 'Frames: 3' (line 22) but only 2 frame lines"),
    "frames_fewer_than_lines.bvh": (25, "'Frames: 1' (line 22) but more frame lines follow"),
    "text_after_file.bvh": (26, "'Frames: 2' (line 22) but more frame lines follow"),
    "truncated_motion_last_line.bvh": (25, "expected 12 values (one per channel), found 5"),
    "wrong_value_count.bvh": (24, "expected 12 values (one per channel), found 11"),
    "values_shifted_between_lines.bvh": (24, "expected 12 values (one per channel), found 13"),
    "comma_separated_values.bvh": (24, "expected 12 values (one per channel), found 1"),
    "no_break_space_between_values.bvh": (24, "expected 12 values (one per channel), found 11"),
    "unit_separator_between_values.bvh": (24, "expected 12 values (one per channel), found 11"),
    "non_numeric_value.bvh": (24, "value 3: 'abc' is not a number"),
    "underscore_in_number.bvh": (25, "value 2: '9_0' is not a number"),
    "nan_value.bvh": (25, "value 4 is not a finite number (nan)"),
    "inf_value.bvh": (25, "value 12 is not a finite number (-inf)"),
    "overflow_value.bvh": (24, "value 2 is not a finite number (inf)"),
}


def parse_error(source, name=None) -> BVHError:
    with pytest.raises(BVHError) as info:
        bvh.parse_bvh(source, name=name)
    return info.value


def test_every_malformed_file_has_an_expectation():
    on_disk = {p.name for p in MALFORMED.iterdir()}
    assert on_disk == set(CASES), (
        f"files without an expectation: {sorted(on_disk - set(CASES))}; "
        f"expectations without a file: {sorted(set(CASES) - on_disk)}"
    )


@pytest.mark.parametrize("name", sorted(CASES))
def test_malformed_file_raises_at_its_line(name):
    line, fragment = CASES[name]
    path = MALFORMED / name
    err = parse_error(path)
    assert err.path == str(path)
    assert err.line == line, f"{name}: reported line {err.line}, expected {line} ({err.reason})"
    assert fragment in err.reason
    assert str(err).startswith(f"{path}, line {line}: ")


def test_the_unedited_base_file_parses():
    """The cases are one-edit variants of a base file; it must be valid itself, or they prove little.

    text_after_file.bvh is the base file plus one trailing line.
    """
    base = "\n".join((MALFORMED / "text_after_file.bvh").read_text().splitlines()[:-1]) + "\n"
    data = bvh.parse_bvh(base.encode(), name="base.bvh")
    assert data.names == ["Hips", "Spine", "Head"]
    assert data.values.shape == (2, 12)


def test_bytes_source_is_named_by_the_given_label():
    err = parse_error(b"HIERARCHY\nROOT Hips\n{\n", name="upload.bvh")
    assert (err.path, err.line) == ("upload.bvh", 3)
    assert "the hierarchy ends early" in err.reason


def test_missing_file_names_the_path_without_a_line(tmp_path):
    path = tmp_path / "nowhere.bvh"
    err = parse_error(path)
    assert err.path == str(path) and err.line is None
    assert "cannot read the file" in err.reason


# Inputs generated in tmp_path: too big to commit.


def joint_lines(name: str, depth: int, keyword: str = "JOINT") -> list[str]:
    pad = "\t" * depth
    return [
        f"{pad}{keyword} {name}",
        f"{pad}{{",
        f"{pad}\tOFFSET 0.0 1.0 0.0",
        f"{pad}\tCHANNELS 3 Zrotation Xrotation Yrotation",
    ]


def write_bvh(path: Path, hierarchy: list[str], joints: int) -> Path:
    motion = ["MOTION", "Frames: 1", "Frame Time: 0.033333", " ".join(["0.0"] * 3 * joints)]
    path.write_text("\n".join(["HIERARCHY", *hierarchy, *motion]) + "\n")
    return path


def chain(path: Path, joints: int) -> Path:
    """A chain of joints J0 (root, depth 0) .. J{joints-1} (depth joints-1)."""
    hierarchy = joint_lines("J0", 0, "ROOT")
    for d in range(1, joints):
        hierarchy += joint_lines(f"J{d}", d)
    hierarchy += ["\t" * d + "}" for d in reversed(range(joints))]
    return write_bvh(path, hierarchy, joints)


def star(path: Path, joints: int) -> Path:
    """A root Hips with joints-1 children J1 .. J{joints-1}."""
    hierarchy = joint_lines("Hips", 0, "ROOT")
    for k in range(1, joints):
        hierarchy += joint_lines(f"J{k}", 1) + ["\t}"]
    hierarchy.append("}")
    return write_bvh(path, hierarchy, joints)


def line_of(path: Path, text: str) -> int:
    """1-based line of the first line whose stripped text equals `text` (found without the parser)."""
    lines = [line.strip() for line in path.read_text().splitlines()]
    return lines.index(text) + 1


@pytest.mark.parametrize(
    "make, joints, culprit, fragment",
    [
        (star, bvh.MAX_JOINTS + 1, f"JOINT J{bvh.MAX_JOINTS}", f"more than {bvh.MAX_JOINTS} joints"),
        (chain, bvh.MAX_DEPTH + 2, f"JOINT J{bvh.MAX_DEPTH + 1}", f"joints nested more than {bvh.MAX_DEPTH} deep"),
    ],
    ids=["too_many_joints", "absurd_nesting"],
)
def test_generated_limits_are_enforced(tmp_path, make, joints, culprit, fragment):
    path = make(tmp_path / "big.bvh", joints)
    err = parse_error(path)
    assert err.path == str(path)
    assert err.line == line_of(path, culprit)
    assert fragment in err.reason


@pytest.mark.parametrize("make, joints", [(star, bvh.MAX_JOINTS), (chain, bvh.MAX_DEPTH + 1)], ids=["wide", "deep"])
def test_limits_themselves_are_allowed(tmp_path, make, joints):
    """Exactly MAX_JOINTS joints, or exactly MAX_DEPTH deep, parse: the limits are not off by one."""
    assert len(bvh.parse_bvh(make(tmp_path / "big.bvh", joints)).names) == joints
