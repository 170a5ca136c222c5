"""Writing BVH: read -> write -> read gives the same motion, in every rotation order, unit and up axis."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from reactive_anim.core.model import bvh, quat
from tests.support.mocap import require_mocap

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
TOL = 1e-5  # metres and radians

# Several files of each dataset: CMU (cgspeed, ZYX, CMU units), Bandai Namco (positions on every
# joint, ZXY, both datasets), CMU via iClone (about 100 joints, both layouts).
REAL = [
    "cmu/90_18.bvh",
    "cmu/91_59.bvh",
    "bandai_namco/dataset-1/dataset-1_walk_normal_002.bvh",
    "bandai_namco/dataset-2/dataset-2_run_normal_001.bvh",
    "cmu_iclone/002_03.bvh",
    "cmu_iclone/007_12.bvh",
]


def assert_same_motion(a, b, tol=TOL):
    assert b.skeleton.names == a.skeleton.names
    np.testing.assert_array_equal(b.skeleton.parents, a.skeleton.parents)
    np.testing.assert_allclose(b.skeleton.offsets, a.skeleton.offsets, atol=tol)
    assert b.skeleton.end_sites.keys() == a.skeleton.end_sites.keys()
    for j, tip in a.skeleton.end_sites.items():
        np.testing.assert_allclose(b.skeleton.end_sites[j], tip, atol=tol)
    assert b.fps == pytest.approx(a.fps, rel=1e-6)
    assert b.num_frames == a.num_frames
    np.testing.assert_allclose(b.root_pos, a.root_pos, atol=tol)
    assert (b.local_pos is None) == (a.local_pos is None)
    if a.local_pos is not None:
        np.testing.assert_allclose(b.local_pos[:, 1:], a.local_pos[:, 1:], atol=tol)
    assert np.max(quat.angle_between(a.local_rot, b.local_rot)) < tol
    np.testing.assert_allclose(b.global_positions(), a.global_positions(), atol=tol)


def round_trip(tmp_path, motion, read_unit="cm", read_up="Y", **write_options):
    path = tmp_path / "out.bvh"
    bvh.write_bvh(path, motion, **write_options)
    return bvh.read_bvh(path, unit=read_unit, up=read_up)


@pytest.mark.mocap
@pytest.mark.parametrize("relative", REAL)
def test_real_file_round_trip(tmp_path, relative):
    original = bvh.read_bvh(require_mocap(relative))
    assert_same_motion(original, round_trip(tmp_path, original))


@pytest.fixture(scope="module")
def cmu_motion():
    return bvh.read_bvh(require_mocap("cmu/91_59.bvh"))


@pytest.mark.mocap
@pytest.mark.parametrize("order", ORDERS)
def test_round_trip_in_every_rotation_order(tmp_path, cmu_motion, order):
    again = round_trip(tmp_path, cmu_motion, rotation_order=order)
    assert_same_motion(cmu_motion, again)
    data = bvh.parse_bvh(tmp_path / "out.bvh")
    assert {ch.rotation for ch in data.channels} == {order}
    assert data.channels[0].position == [0, 1, 2] and data.channels[1].position == []


@pytest.mark.mocap
@pytest.mark.parametrize(
    "unit, up",
    [("m", "Y"), ("mm", "Y"), ("in", "Y"), ("cmu", "Y"), ("cm", "Z"), ("m", "Z"), (0.05, "Y"), (0.002, "Z")],
)
def test_round_trip_in_other_units_and_up_axes(tmp_path, cmu_motion, unit, up):
    again = round_trip(tmp_path, cmu_motion, read_unit=unit, read_up=up, unit=unit, up=up)
    assert_same_motion(cmu_motion, again)
    # The file really is in that unit and axis: its raw offsets are the metres, turned and divided.
    data = bvh.parse_bvh(tmp_path / "out.bvh")
    scale = bvh.UNITS[unit] if isinstance(unit, str) else unit
    raw = data.offsets * scale
    if up == "Y":
        raw = np.column_stack([raw[:, 0], -raw[:, 2], raw[:, 1]])  # file (x, y, z) -> world (x, -z, y)
    np.testing.assert_allclose(raw, cmu_motion.skeleton.offsets, atol=TOL)


@pytest.mark.mocap
@pytest.mark.parametrize("unit", ["m", "cm", "mm", "in"])
def test_written_unit_is_detected_on_reading(tmp_path, cmu_motion, unit):
    again = round_trip(tmp_path, cmu_motion, read_unit="auto", unit=unit)
    assert_same_motion(cmu_motion, again)


@pytest.mark.mocap
def test_per_joint_positions_survive_and_are_written_as_six_channels(tmp_path):
    original = bvh.read_bvh(require_mocap("bandai_namco/dataset-1/dataset-1_walk_normal_002.bvh"))
    assert original.local_pos is not None
    # The per-joint translations are animated, not just the rest offsets: a check that could fail.
    assert np.ptp(original.local_pos[:, 1:], axis=0).max() > 1e-4
    round_trip(tmp_path, original)
    data = bvh.parse_bvh(tmp_path / "out.bvh")
    assert all(ch.count == 6 for ch in data.channels)
