"""dualtwin.geometry: each conversion against an independent implementation (scipy, MuJoCo) and its inverse."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dualtwin import geometry as g

RNG = np.random.default_rng(7)
ROTATIONS = [(*RNG.normal(size=3), float(RNG.uniform(-2 * math.pi, 2 * math.pi))) for _ in range(50)]
# angles near pi and exact half turns reach the non-trace branches of the quaternion routines
ROTATIONS += [(1.0, 0.0, 0.0, math.pi), (0.0, 1.0, 0.0, math.pi), (0.0, 0.0, 2.0, -math.pi), (1.0, 1.0, 0.0, 3.1)]


def _scipy_matrix(rotation: tuple[float, ...]) -> np.ndarray:
    axis = np.asarray(rotation[:3]) / np.linalg.norm(rotation[:3])
    return Rotation.from_rotvec(axis * rotation[3]).as_matrix()


@pytest.mark.parametrize("rotation", ROTATIONS)
def test_axis_angle_matrix_matches_scipy_and_round_trips(rotation: tuple[float, ...]) -> None:
    R = g.axis_angle_matrix(rotation)
    np.testing.assert_allclose(R, _scipy_matrix(rotation), atol=1e-12)
    axis = np.asarray(rotation[:3]) / np.linalg.norm(rotation[:3])
    np.testing.assert_allclose(g.rotation_about(axis, rotation[3]), R, atol=1e-12)
    back = g.axis_angle_from_matrix(R)
    assert 0.0 <= back[3] <= math.pi + 1e-12
    np.testing.assert_allclose(g.axis_angle_matrix(back), R, atol=1e-9)
    np.testing.assert_allclose(g.axis_angle_matrix(g.axis_angle_from_rotvec(g.rotation_vector(R))), R, atol=1e-9)


@pytest.mark.parametrize("rotation", ROTATIONS)
def test_quaternions_agree_with_mujoco_and_scipy(rotation: tuple[float, ...]) -> None:
    R = g.axis_angle_matrix(rotation)
    q = g.quat_from_matrix(R)
    assert q[0] >= 0.0 and math.isclose(float(np.linalg.norm(q)), 1.0, rel_tol=1e-12)
    np.testing.assert_allclose(q, g.canonical_quat(g.mujoco_quat(R)), atol=1e-12)
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    np.testing.assert_allclose(q, g.canonical_quat([w, x, y, z]), atol=1e-12)
    np.testing.assert_allclose(g.matrix_from_quat(-q), R, atol=1e-12)
    assert g.quat_tuple(tuple(R.ravel().tolist())) == tuple(q)


def test_identity_and_degenerate_inputs() -> None:
    np.testing.assert_array_equal(g.axis_angle_matrix((0.0, 0.0, 0.0, 1.0)), np.eye(3))
    np.testing.assert_array_equal(g.axis_angle_matrix((1.0, 0.0, 0.0, 0.0)), np.eye(3))
    assert g.axis_angle_from_matrix(np.eye(3)) == [0.0, 0.0, 1.0, 0.0]
    assert g.axis_angle_from_rotvec([0.0, 0.0, 0.0]) == [0.0, 0.0, 1.0, 0.0]
    # control: a real rotation is not reported as the identity
    assert g.axis_angle_from_rotvec([0.0, 0.5, 0.0]) == [0.0, 1.0, 0.0, 0.5]


def test_relative_rotation_vectors_match_scipy() -> None:
    a = Rotation.random(20, random_state=1)
    b = Rotation.random(20, random_state=2)
    qa = np.roll(a.as_quat(), 1, axis=1)
    qb = np.roll(b.as_quat(), 1, axis=1)
    expected = (b * a.inv()).as_rotvec()
    np.testing.assert_allclose(g.relative_rotation_vectors(qa, qb), expected, atol=1e-10)
    np.testing.assert_allclose(g.relative_rotation_vectors(qa, qa), 0.0, atol=1e-7)


def test_rpy_from_quat_matches_scipy_zyx() -> None:
    for rot in Rotation.random(20, random_state=3):
        x, y, z, w = rot.as_quat()
        yaw, pitch, roll = rot.as_euler("ZYX")
        got = [g.rpy_from_quat(x=x, y=y, z=z, w=w, angle=a) for a in ("roll", "pitch", "yaw")]
        np.testing.assert_allclose(got, [roll, pitch, yaw], atol=1e-9)


def test_rpy_from_matrix_matches_scipy_zyx_and_the_quaternion_form() -> None:
    for rot in Rotation.random(20, random_state=4):
        yaw, pitch, roll = rot.as_euler("ZYX")
        R = rot.as_matrix()
        got = [g.rpy_from_matrix(R, a) for a in ("roll", "pitch", "yaw")]
        np.testing.assert_allclose(got, [roll, pitch, yaw], atol=1e-9)
        x, y, z, w = rot.as_quat()
        np.testing.assert_allclose(got, [g.rpy_from_quat(x=x, y=y, z=z, w=w, angle=a)
                                         for a in ("roll", "pitch", "yaw")], atol=1e-9)
