"""Rotations: the one home for converting between the forms dualtwin meets (numpy, no physics state).

Conventions (every helper keeps to them):

* **Webots axis-angle** (VRML ``SFRotation``): ``(x, y, z, angle)``, right-handed, angle in radians. Webots
  normalises the axis before use, so the helpers do too; a zero axis or a zero angle is the identity.
* **Matrices** are 3x3 numpy arrays with ``x_parent = R @ x_local`` (Webots' ``getOrientation`` gives the same
  matrix as 9 row-major values, which the helpers also accept where noted).
* **Quaternions** are MuJoCo's ``(w, x, y, z)``, scalar first. ``q`` and ``-q`` are the same rotation; the
  *canonical* one has ``w >= 0`` (states compare by value, so one sign is chosen). ROS messages order
  ``(x, y, z, w)``: only :func:`rpy_from_quat` takes that order, as its keyword names say.
* **Rotation vectors** are ``axis * angle`` with the angle in ``[0, pi]``.

Why there are two matrix -> quaternion routines: :func:`quat_from_matrix` is Shepperd's method in plain floats
with the sign made canonical (the twins' state reads call it every control period), while
:func:`mujoco_quat` is MuJoCo's own ``mju_mat2Quat``. The converter and the MuJoCo-side scene builders use the
latter so the quaternion written into an MJCF is bit for bit the one MuJoCo itself would compute; the two agree
to rounding (and up to sign) but not bit for bit, and the converter's output is kept byte-identical.

The physics engine's hot loops keep their own pure-Python tuple math (:mod:`dualtwin.webots._math3`): on
3-vectors numpy's per-call overhead costs more than the arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "axis_angle_from_matrix",
    "axis_angle_from_quat",
    "axis_angle_from_rotvec",
    "axis_angle_matrix",
    "canonical_quat",
    "matrix_from_quat",
    "mujoco_quat",
    "quat_from_matrix",
    "quat_tuple",
    "relative_rotation_vectors",
    "rotation_about",
    "rotation_vector",
    "rpy_from_matrix",
    "rpy_from_quat",
]

FloatArray = npt.NDArray[np.float64]


def axis_angle_matrix(rotation: Sequence[float]) -> FloatArray:
    """Matrix of a Webots axis-angle ``(x, y, z, angle)``; the axis is normalised first (as ODE/Webots do).

    An axis shorter than 1e-12 or a zero angle gives the identity (Webots rejects a zero axis; which value it
    keeps instead is UNVERIFIED).
    """
    x, y, z, angle = (float(v) for v in rotation)
    n = math.sqrt(x * x + y * y + z * z)
    if n < 1e-12 or angle == 0.0:
        return np.eye(3)
    x, y, z = x / n, y / n, z / n
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array([
        [x * x * C + c, x * y * C - z * s, x * z * C + y * s],
        [y * x * C + z * s, y * y * C + c, y * z * C - x * s],
        [z * x * C - y * s, z * y * C + x * s, z * z * C + c],
    ])


def rotation_about(axis: Sequence[float] | FloatArray, angle: float) -> FloatArray:
    """Matrix of a rotation by ``angle`` about a *unit* ``axis`` (not normalised here: callers hold unit axes)."""
    x, y, z = (float(v) for v in axis)
    c, s, t = math.cos(angle), math.sin(angle), 1.0 - math.cos(angle)
    return np.array([[c + t * x * x, t * x * y - s * z, t * x * z + s * y],
                     [t * x * y + s * z, c + t * y * y, t * y * z - s * x],
                     [t * x * z - s * y, t * y * z + s * x, c + t * z * z]])


def quat_tuple(m: Sequence[float]) -> tuple[float, float, float, float]:
    """Canonical unit quaternion ``(w, x, y, z)`` of 9 row-major floats (Shepperd's method), as a tuple.

    Plain floats: the twins' state reads call it every control period.
    """
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    trace = m00 + m11 + m22
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    sign = -1.0 / n if q[0] < 0 else 1.0 / n
    return q[0] * sign, q[1] * sign, q[2] * sign, q[3] * sign


def quat_from_matrix(rotation: Any) -> FloatArray:
    """Canonical unit quaternion ``(w, x, y, z)`` (``w >= 0``) of a 3x3 matrix or 9 row-major values."""
    values = rotation if isinstance(rotation, tuple | list) else np.asarray(rotation, dtype=float).ravel().tolist()
    return np.array(quat_tuple(tuple(float(v) for v in values)))


def mujoco_quat(R: Any) -> FloatArray:
    """MuJoCo's own quaternion ``(w, x, y, z)`` of a 3x3 matrix (``mju_mat2Quat``; the sign is not canonical).

    For values written into MuJoCo models: they are then exactly what MuJoCo computes from the matrix.
    """
    import mujoco  # deferred: most users of this module never build a MuJoCo model

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def canonical_quat(q: Any) -> FloatArray:
    """Normalised, with ``w >= 0`` (q and -q are the same rotation; one sign makes states comparable)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q)
    return -q if q[0] < 0 else q


def matrix_from_quat(q: Any) -> FloatArray:
    """3x3 rotation matrix of a quaternion ``(w, x, y, z)`` (normalised first)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rotation_vector(rotation: Any) -> FloatArray:
    """Rotation vector (axis x angle, angle in [0, pi]) of a 3x3 matrix or 9 row-major values."""
    q = quat_from_matrix(rotation)
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-15:
        return 2.0 * q[1:]
    return q[1:] / s * 2.0 * math.atan2(s, float(q[0]))


def axis_angle_from_matrix(rotation: Any) -> list[float]:
    """Webots axis-angle ``[x, y, z, angle]`` (angle in [0, pi]) of a 3x3 matrix; the identity is ``[0, 0, 1, 0]``."""
    q = quat_from_matrix(rotation)
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-300:
        return [0.0, 0.0, 1.0, 0.0]
    return [*(q[1:] / s), 2.0 * math.atan2(s, float(q[0]))]


def axis_angle_from_quat(q: Any) -> tuple[float, float, float, float]:
    """Webots axis-angle ``(x, y, z, angle)`` of a unit quaternion ``(w, x, y, z)`` with ``angle = 2 acos(w)``.

    The identity (within 1e-9 of it) is ``(0, 0, 1, 0)``. The angle lies in [0, 2 pi] and keeps the
    quaternion's sign; :func:`axis_angle_from_matrix` gives the [0, pi] form. (``acos`` loses digits near the
    identity where ``atan2`` does not; kept as it is because generated worlds written from it must not change.)
    """
    w = max(-1.0, min(1.0, float(q[0])))
    angle = 2.0 * math.acos(w)
    s = math.sqrt(max(1.0 - w * w, 0.0))
    if s < 1e-9:
        return (0.0, 0.0, 1.0, 0.0)
    return (float(q[1] / s), float(q[2] / s), float(q[3] / s), angle)


def axis_angle_from_rotvec(vector: Any) -> list[float]:
    """Webots axis-angle ``[x, y, z, angle]`` of a rotation vector; a vector shorter than 1e-12 is the identity."""
    vector = np.asarray(vector, dtype=float)
    angle = float(np.linalg.norm(vector))
    if angle < 1e-12:
        return [0.0, 0.0, 1.0, 0.0]
    return [*(float(v) for v in vector / angle), angle]


def relative_rotation_vectors(qa: FloatArray, qb: FloatArray) -> FloatArray:
    """Rotation vectors of ``R_b R_a^T`` for rows of quaternions ``(w, x, y, z)`` (angle in [0, pi])."""
    qa = qa / np.linalg.norm(qa, axis=1, keepdims=True)
    qb = qb / np.linalg.norm(qb, axis=1, keepdims=True)
    w1, v1 = qb[:, :1], qb[:, 1:]
    w2, v2 = qa[:, :1], -qa[:, 1:]  # conjugate of a
    w = w1 * w2 - np.sum(v1 * v2, axis=1, keepdims=True)
    v = w1 * v2 + w2 * v1 + np.cross(v1, v2)
    sign = np.where(w < 0, -1.0, 1.0)
    w, v = w * sign, v * sign
    s = np.linalg.norm(v, axis=1, keepdims=True)
    small = s < 1e-15
    factor = np.where(small, 2.0, 2.0 * np.arctan2(s, w) / np.where(small, 1.0, s))
    result: FloatArray = v * factor
    return result


def rpy_from_matrix(R: Any, angle: str) -> float:
    """Roll, pitch or yaw (rad) of a 3x3 matrix, Z-Y-X Euler angles: ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    Pitch from ``atan2`` (not ``asin``), which keeps its digits near +-pi/2.
    """
    if angle == "yaw":
        return math.atan2(float(R[1, 0]), float(R[0, 0]))
    if angle == "pitch":
        return math.atan2(-float(R[2, 0]), math.hypot(float(R[2, 1]), float(R[2, 2])))
    return math.atan2(float(R[2, 1]), float(R[2, 2]))


def rpy_from_quat(*, x: float, y: float, z: float, w: float, angle: str) -> float:
    """Roll, pitch or yaw (rad; ZYX convention as ROS' tf2 ``getRPY``) of a quaternion given by component."""
    if angle == "yaw":
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    if angle == "pitch":
        return math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
