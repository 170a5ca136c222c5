"""Quaternion maths checked against rotation matrices built independently (Rodrigues' formula)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from reactive_anim.core.model import quat

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}


def rodrigues(axis, angle):
    """Rotation matrix about a unit axis, written out without the module under test."""
    x, y, z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


def euler_matrix(angles, order):
    """R = R_order[0] @ R_order[1] @ R_order[2] (BVH channel order composes left to right)."""
    m = np.eye(3)
    for axis, angle in zip(order, angles, strict=True):
        m = m @ rodrigues(AXES[axis], angle)
    return m


def random_quats(rng, n):
    return quat.normalize(rng.normal(size=(n, 4)))


def same_rotation(a, b, tol=1e-9):
    return np.all(quat.angle_between(a, b) < tol)


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def test_from_axis_angle_matches_rodrigues(rng):
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(-2 * np.pi, 2 * np.pi)
        got = quat.to_matrix(quat.from_axis_angle(axis, angle))
        np.testing.assert_allclose(got, rodrigues(axis, angle), atol=1e-12)


def test_mul_is_matrix_product_and_associative(rng):
    a, b, c = (random_quats(rng, 50) for _ in range(3))
    np.testing.assert_allclose(quat.to_matrix(quat.mul(a, b)), quat.to_matrix(a) @ quat.to_matrix(b), atol=1e-12)
    np.testing.assert_allclose(quat.mul(quat.mul(a, b), c), quat.mul(a, quat.mul(b, c)), atol=1e-12)
    np.testing.assert_allclose(quat.mul(a, quat.conj(a)), quat.identity((50,)), atol=1e-12)


def test_mul_broadcasts_over_leading_axes(rng):
    a = random_quats(rng, 6).reshape(2, 3, 4)
    b = random_quats(rng, 3)
    np.testing.assert_allclose(quat.mul(a, b)[1, 2], quat.mul(a[1, 2], b[2]), atol=1e-15)


def test_sandwich_is_the_product_with_the_inverse_broadcast_over_frames(rng):
    """Per-joint rest rotations (J,) over frames of joints (T, J): as action I/O uses it."""
    r = random_quats(rng, 5)
    q = random_quats(rng, 40).reshape(8, 5, 4)
    np.testing.assert_allclose(quat.sandwich(r, q), quat.mul(quat.mul(r, q), quat.conj(r)), atol=1e-12)
    np.testing.assert_allclose(quat.sandwich(quat.conj(r), quat.sandwich(r, q)), q, atol=1e-12)


def test_rotate_agrees_with_to_matrix(rng):
    q = random_quats(rng, 40)
    v = rng.normal(size=(40, 3))
    np.testing.assert_allclose(quat.rotate(q, v), np.einsum("nij,nj->ni", quat.to_matrix(q), v), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(quat.rotate(q, v), axis=-1), np.linalg.norm(v, axis=-1), atol=1e-12)


@pytest.mark.parametrize(
    "axis",
    [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 1, 1], [-1, 2, 0.5], [1e-7, 0, 1]],
    ids=["x", "y", "z", "xy", "xyz", "skew", "near_z"],
)
@pytest.mark.parametrize("angle", [0.0, 1e-9, 0.3, np.pi / 2, np.pi - 1e-9, np.pi], ids=lambda a: f"{a:.3g}")
def test_from_matrix_inverts_to_matrix(axis, angle):
    """Including 180 degrees, where the trace formula alone breaks down."""
    m = rodrigues(axis, angle)
    q = quat.from_matrix(m)
    assert q[0] >= 0.0
    np.testing.assert_allclose(np.linalg.norm(q), 1.0, atol=1e-12)
    np.testing.assert_allclose(quat.to_matrix(q), m, atol=1e-12)
    assert same_rotation(q, quat.from_axis_angle(np.asarray(axis) / np.linalg.norm(axis), angle))


def test_from_matrix_round_trip_random(rng):
    q = random_quats(rng, 200)
    back = quat.from_matrix(quat.to_matrix(q))
    np.testing.assert_allclose(back, np.where(q[:, :1] < 0, -q, q), atol=1e-12)


@pytest.mark.parametrize("order", [*ORDERS, "X", "Z", "YX", "ZY"])
def test_from_euler_is_the_product_of_its_axis_turns_bit_for_bit(order, rng):
    """The shortcut that skips the axis quaternions' zero components changes no bit (BVH files
    written from these rotations must stay byte-identical)."""
    angles = rng.uniform(-np.pi, np.pi, size=(50, len(order)))
    q = quat.identity((50,))
    for k, name in enumerate(order):
        q = quat.mul(q, quat.from_axis_angle(np.eye(3)["XYZ".index(name)], angles[:, k]))
    np.testing.assert_array_equal(quat.from_euler(angles, order), q)


@pytest.mark.parametrize("order", ORDERS)
def test_from_euler_matches_matrix_product(order, rng):
    angles = rng.uniform(-np.pi, np.pi, size=(30, 3))
    expected = np.stack([euler_matrix(a, order) for a in angles])
    np.testing.assert_allclose(quat.to_matrix(quat.from_euler(angles, order)), expected, atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_to_euler_inverts_from_euler_in_the_principal_range(order, rng):
    angles = np.column_stack([rng.uniform(-3.1, 3.1, 100), rng.uniform(-1.5, 1.5, 100), rng.uniform(-3.1, 3.1, 100)])
    np.testing.assert_allclose(quat.to_euler(quat.from_euler(angles, order), order), angles, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_to_euler_rebuilds_any_rotation(order, rng):
    q = random_quats(rng, 200)
    assert same_rotation(quat.from_euler(quat.to_euler(q, order), order), q)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("middle", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-7, -np.pi / 2 + 1e-10])
def test_to_euler_at_gimbal_lock(order, middle):
    angles = np.array([[0.4, middle, -1.1], [-2.0, middle, 0.7], [0.0, middle, 0.0]])
    q = quat.from_euler(angles, order)
    got = quat.to_euler(q, order)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got[:, 1], middle, atol=1e-6)
    assert same_rotation(quat.from_euler(got, order), q)


def test_to_euler_rejects_a_non_permutation():
    with pytest.raises(ValueError, match="permutation of XYZ"):
        quat.to_euler(quat.identity(), "XXY")


def test_angle_between_known_angles_and_antipodes(rng):
    q = random_quats(rng, 50)
    axis = np.array([0.0, 0.6, 0.8])
    for angle in [0.0, 0.5, 2.0, np.pi]:
        turned = quat.mul(q, quat.from_axis_angle(axis, angle))
        np.testing.assert_allclose(quat.angle_between(q, turned), angle, atol=1e-7)
        np.testing.assert_allclose(quat.angle_between(q, -turned), angle, atol=1e-7)
    np.testing.assert_allclose(quat.angle_between(q, -q), 0.0, atol=1e-12)
    # 3 pi / 2 one way is pi / 2 the other way.
    np.testing.assert_allclose(quat.angle_between(q, quat.mul(q, quat.from_axis_angle(axis, 1.5 * np.pi))), np.pi / 2)


def test_slerp_endpoints_and_midpoint(rng):
    a, b = random_quats(rng, 100), random_quats(rng, 100)
    total = quat.angle_between(a, b)
    assert same_rotation(quat.slerp(a, b, 0.0), a)
    assert same_rotation(quat.slerp(a, b, 1.0), b)
    mid = quat.slerp(a, b, 0.5)
    np.testing.assert_allclose(quat.angle_between(a, mid), total / 2, atol=1e-9)
    np.testing.assert_allclose(quat.angle_between(mid, b), total / 2, atol=1e-9)
    quarter = quat.slerp(a, b, np.full(100, 0.25))
    np.testing.assert_allclose(quat.angle_between(a, quarter), total / 4, atol=1e-9)


def test_slerp_takes_the_shorter_arc_and_handles_equal_inputs():
    a = quat.identity()
    b = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.4)
    for other in (b, -b):
        mid = quat.slerp(a, other, 0.5)
        np.testing.assert_allclose(quat.to_matrix(mid), rodrigues([0, 0, 1], 0.2), atol=1e-12)
    same = quat.slerp(b, b, 0.3)
    assert np.all(np.isfinite(same)) and same_rotation(same, b)


def test_make_continuous_removes_sign_flips_and_keeps_rotations(rng):
    # A smooth rotation about a tilted axis, two joints, with random signs.
    t = np.linspace(0.0, 6.0, 300)
    smooth = quat.from_axis_angle(np.array([0.0, 0.6, 0.8]), t)[:, None, :].repeat(2, axis=1)
    flipped = smooth * rng.choice([-1.0, 1.0], size=(300, 2, 1))
    before = flipped.copy()
    fixed = quat.make_continuous(flipped)
    assert np.sum(np.sum(flipped[1:] * flipped[:-1], axis=-1) < 0) > 100  # the input does jump
    assert np.all(np.sum(fixed[1:] * fixed[:-1], axis=-1) > 0)
    np.testing.assert_array_equal(fixed[0], flipped[0])
    assert same_rotation(fixed, flipped)
    np.testing.assert_array_equal(flipped, before)  # a copy, the input is untouched
    assert quat.make_continuous(flipped[:1]).shape == (1, 2, 4)


def test_normalize_keeps_zero_quaternions_finite():
    q = quat.normalize(np.array([[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0]]))
    np.testing.assert_array_equal(q, [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
