"""How a world is oriented (``WorldInfo.coordinateSystem``) and where it is on Earth (``gpsCoordinateSystem``,
``gpsReference``): what the InertialUnit and the GPS need to report in the world's conventions.

``coordinateSystem`` names the world axes: ``"ENU"`` (x East, y North, z Up: Webots' default since R2022a),
``"NUE"`` (x North, y Up, z East: worlds from before R2022a) or ``"EUN"`` (x East, y Up). The *reference
frame* of an orientation sensor is the world's x axis as forward, its up axis as z and y completing a right-
handed frame (ENU: the world frame itself; NUE/EUN: x, −z, y). The InertialUnit reads its own rotation in that
frame, with its own axes read the same way, i.e. the world rotation conjugated by the reference frame: a
device turned about the world's vertical axis reads a pure yaw in every coordinate system.

GPS in ``WGS84`` mode converts the local position to latitude/longitude (degrees) and altitude (m) around
``gpsReference`` (the geographic position of the world origin) on the WGS84 ellipsoid, with its meridian and
prime-vertical radii of curvature at the reference latitude (a local tangent plane: exact to first order,
which is what a world a few kilometres across needs).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from dualtwin.webots import _math3 as m3

__all__ = ["Axes", "axes", "in_reference_frame", "reference_frame", "to_wgs84"]

_WGS84_A = 6378137.0  # m, semi-major axis
_WGS84_E2 = 6.69437999014e-3  # first eccentricity squared


class Axes:
    """Unit vectors of East, North and Up in the world frame of one coordinate system."""

    def __init__(self, east: m3.Vec3, north: m3.Vec3, up: m3.Vec3) -> None:
        self.east, self.north, self.up = east, north, up


def axes(coordinate_system: str) -> Axes:
    """East/North/Up of ``"ENU"``, ``"NUE"`` or ``"EUN"`` (anything else reads as ENU, Webots' default)."""
    cs = coordinate_system.upper()
    if cs == "NUE":
        return Axes((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    if cs == "EUN":
        return Axes((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
    return Axes((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def reference_frame(coordinate_system: str) -> m3.Mat3:
    """Row-major rotation whose columns are the reference frame's x (world x), y (up × x) and z (up)."""
    up = axes(coordinate_system).up
    x = (1.0, 0.0, 0.0)
    y = m3.cross(up, x)
    return (x[0], y[0], up[0], x[1], y[1], up[1], x[2], y[2], up[2])


def in_reference_frame(R: Sequence[float], coordinate_system: str) -> m3.Mat3:
    """A world rotation read in the coordinate system's reference frame (``Pᵀ·R·P``)."""
    P = reference_frame(coordinate_system)
    return m3.mat_mul(m3.mat_t(P), m3.mat_mul(R, P))


def to_wgs84(position: Sequence[float], reference: Sequence[float], coordinate_system: str) -> list[float]:
    """``[latitude°, longitude°, altitude m]`` of a world position, the world origin being at ``reference``."""
    ax = axes(coordinate_system)
    east, north, up = m3.dot(position, ax.east), m3.dot(position, ax.north), m3.dot(position, ax.up)
    lat0, lon0, alt0 = (float(v) for v in reference)
    phi = math.radians(lat0)
    w = 1.0 - _WGS84_E2 * math.sin(phi) ** 2
    prime_vertical = _WGS84_A / math.sqrt(w)
    meridian = _WGS84_A * (1.0 - _WGS84_E2) / w**1.5
    lat = lat0 + math.degrees(north / (meridian + alt0))
    cos_phi = math.cos(phi)
    lon = lon0 + (math.degrees(east / ((prime_vertical + alt0) * cos_phi)) if abs(cos_phi) > 1e-12 else 0.0)
    return [lat, lon, alt0 + up]
