"""Small 3-D rigid-transform helpers on plain tuples (build-time and query-time, not per step).

Rotations are row-major 3×3 matrices stored as 9-tuples; vectors are 3-tuples. Plain floats keep these
helpers cheap for the handful of transforms a world needs and avoid numpy scalar overhead in
supervisor queries.

Why this is not :mod:`dualtwin.geometry` (the numpy home of rotations, same conventions): on 3-vectors numpy's
per-call overhead costs more than the arithmetic. Measured on this machine (loaded, ``timeit``, best of 3):
axis-angle -> matrix 1.3 µs here against 3.6 µs for ``geometry.axis_angle_matrix``, matrix x vector 0.36 µs
against 1.3 µs for ``R @ v``, matrix -> quaternion 0.41 µs against 2.7 µs for ``geometry.quat_from_matrix``.
The physics engine, the controller's devices and the supervisor API call these per body per step. The results
also differ from geometry's in the last bits (other operation order, no sign canonicalisation in
:func:`quat_from_mat`), and the Webots twin's logs are kept byte-identical, so the two stay separate.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

Vec3 = tuple[float, float, float]
Mat3 = tuple[float, float, float, float, float, float, float, float, float]

IDENTITY: Mat3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
ZERO: Vec3 = (0.0, 0.0, 0.0)


def rot_axis_angle(rotation: Sequence[float]) -> Mat3:
    """Matrix of a VRML axis-angle rotation ``(x, y, z, angle)``; the axis is normalised.

    As Webots does (docs/reference/webots-on-ode.md §3.1). A zero axis yields the identity (Webots rejects
    such rotations; UNVERIFIED which value it keeps).
    """
    x, y, z, a = (float(v) for v in rotation)
    n = math.sqrt(x * x + y * y + z * z)
    if n == 0.0 or a == 0.0:
        return IDENTITY
    x, y, z = x / n, y / n, z / n
    c, s = math.cos(a), math.sin(a)
    t = 1.0 - c
    return (
        c + t * x * x, t * x * y - s * z, t * x * z + s * y,
        t * x * y + s * z, c + t * y * y, t * y * z - s * x,
        t * x * z - s * y, t * y * z + s * x, c + t * z * z,
    )  # fmt: skip


def mat_mul(a: Sequence[float], b: Sequence[float]) -> Mat3:
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7], a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6], a[3] * b[1] + a[4] * b[4] + a[5] * b[7], a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7], a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )  # fmt: skip


def mat_t(a: Sequence[float]) -> Mat3:
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


def mat_vec(a: Sequence[float], v: Sequence[float]) -> Vec3:
    return (
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
        a[6] * v[0] + a[7] * v[1] + a[8] * v[2],
    )


def mat_t_vec(a: Sequence[float], v: Sequence[float]) -> Vec3:
    return (
        a[0] * v[0] + a[3] * v[1] + a[6] * v[2],
        a[1] * v[0] + a[4] * v[1] + a[7] * v[2],
        a[2] * v[0] + a[5] * v[1] + a[8] * v[2],
    )


def add(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a: Sequence[float], s: float) -> Vec3:
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a: Sequence[float]) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def normalized(a: Sequence[float]) -> Vec3:
    n = norm(a)
    if n == 0.0:
        return (0.0, 0.0, 0.0)
    return (a[0] / n, a[1] / n, a[2] / n)


class Pose:
    """A rigid transform ``x_parent = R · x_local + t``."""

    __slots__ = ("R", "t")

    def __init__(self, R: Sequence[float] = IDENTITY, t: Sequence[float] = ZERO) -> None:
        self.R: Mat3 = tuple(float(v) for v in R)  # type: ignore[assignment]
        self.t: Vec3 = (float(t[0]), float(t[1]), float(t[2]))

    @staticmethod
    def from_fields(translation: Sequence[float] | None, rotation: Sequence[float] | None) -> Pose:
        t = translation if translation is not None else ZERO
        R = rot_axis_angle(rotation) if rotation is not None else IDENTITY
        return Pose(R, t)

    def __mul__(self, other: Pose) -> Pose:
        return Pose(mat_mul(self.R, other.R), add(mat_vec(self.R, other.t), self.t))

    def inverse(self) -> Pose:
        Rt = mat_t(self.R)
        return Pose(Rt, scale(mat_vec(Rt, self.t), -1.0))

    def apply(self, p: Sequence[float]) -> Vec3:
        return add(mat_vec(self.R, p), self.t)

    def rotate(self, v: Sequence[float]) -> Vec3:
        return mat_vec(self.R, v)

    def __repr__(self) -> str:
        return f"Pose(R={self.R}, t={self.t})"


def axis_angle_from_mat(m: Sequence[float]) -> tuple[float, float, float, float]:
    """VRML axis-angle ``(x, y, z, angle)`` of a rotation matrix, angle in [0, π]."""
    cos_a = max(-1.0, min(1.0, (m[0] + m[4] + m[8] - 1.0) * 0.5))
    angle = math.acos(cos_a)
    x, y, z = m[7] - m[5], m[2] - m[6], m[3] - m[1]
    n = math.sqrt(x * x + y * y + z * z)
    if n > 1e-9:
        return (x / n, y / n, z / n, angle)
    if angle < 1e-6:
        return (0.0, 0.0, 1.0, 0.0)
    # angle ≈ π: axis from the diagonal of (R + I) / 2
    xx, yy, zz = (m[0] + 1.0) / 2.0, (m[4] + 1.0) / 2.0, (m[8] + 1.0) / 2.0
    if xx >= yy and xx >= zz:
        x = math.sqrt(max(xx, 0.0))
        y, z = (m[1] + m[3]) / (4.0 * x), (m[2] + m[6]) / (4.0 * x)
    elif yy >= zz:
        y = math.sqrt(max(yy, 0.0))
        x, z = (m[1] + m[3]) / (4.0 * y), (m[5] + m[7]) / (4.0 * y)
    else:
        z = math.sqrt(max(zz, 0.0))
        x, y = (m[2] + m[6]) / (4.0 * z), (m[5] + m[7]) / (4.0 * z)
    n = math.sqrt(x * x + y * y + z * z)
    return (x / n, y / n, z / n, angle)


def quat_from_mat(m: Sequence[float]) -> tuple[float, float, float, float]:
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix."""
    tr = m[0] + m[4] + m[8]
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        return (0.25 * s, (m[7] - m[5]) / s, (m[2] - m[6]) / s, (m[3] - m[1]) / s)
    if m[0] > m[4] and m[0] > m[8]:
        s = math.sqrt(1.0 + m[0] - m[4] - m[8]) * 2.0
        return ((m[7] - m[5]) / s, 0.25 * s, (m[1] + m[3]) / s, (m[2] + m[6]) / s)
    if m[4] > m[8]:
        s = math.sqrt(1.0 + m[4] - m[0] - m[8]) * 2.0
        return ((m[2] - m[6]) / s, (m[1] + m[3]) / s, 0.25 * s, (m[5] + m[7]) / s)
    s = math.sqrt(1.0 + m[8] - m[0] - m[4]) * 2.0
    return ((m[3] - m[1]) / s, (m[2] + m[6]) / s, (m[5] + m[7]) / s, 0.25 * s)


def roll_pitch_yaw(m: Sequence[float]) -> tuple[float, float, float]:
    """Webots InertialUnit angles (ENU): R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    pitch = -math.asin(max(-1.0, min(1.0, m[6])))
    roll = math.atan2(m[7], m[8])
    yaw = math.atan2(m[3], m[0])
    return (roll, pitch, yaw)


def normalize_angle(angle: float, center: float = 0.0) -> float:
    """Shift ``angle`` by whole turns into ``(center - π, center + π]``."""
    two_pi = 2.0 * math.pi
    if not math.isfinite(angle) or abs(angle - center) > 1e6:
        # The loop below would never end (inf) or take ~1e299 turns (1e300): such an angle has lost every digit
        # of its remainder; NaN lets the physics report the state as unstable instead of hanging.
        return math.nan
    if abs(center) > 1e15:
        # whole turns are below the resolution of so large a centre (1e308: center ± π is center, and the loops
        # below never ended, found by fuzzing a joint loaded at position 1e308): nothing to unwrap
        return angle
    while angle > center + math.pi:
        angle -= two_pi
    while angle <= center - math.pi:
        angle += two_pi
    return angle


def is_positive_definite3(m: Sequence[float]) -> bool:
    """Sylvester's criterion on a symmetric 3×3 matrix (row-major 9 values)."""
    d1 = m[0]
    d2 = m[0] * m[4] - m[1] * m[3]
    d3 = (
        m[0] * (m[4] * m[8] - m[5] * m[7])
        - m[1] * (m[3] * m[8] - m[5] * m[6])
        + m[2] * (m[3] * m[7] - m[4] * m[6])
    )
    return d1 > 0.0 and d2 > 0.0 and d3 > 0.0
