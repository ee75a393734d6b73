"""How a world is oriented (``WorldInfo.coordinateSystem``) and where it is on Earth (``gpsCoordinateSystem``,
``gpsReference``): what the InertialUnit and the GPS need to report in the world's conventions.

``coordinateSystem`` names the world axes, a letter per axis: ``"ENU"`` (x East, y North, z Up: Webots' default
since R2022a), ``"NUE"`` (x North, y Up, z East: worlds from before R2022a) or ``"EUN"`` (x East, y Up, z North:
the letters, as the Compass reads them, so that a world has one north for its Compass and its GPS, even though
East × Up is then +North, the mirror of the Earth's frame). The *reference
frame* of an orientation sensor is the world's x axis as forward, its up axis as z and y completing a right-
handed frame (ENU: the world frame itself; NUE/EUN: x, −z, y). The InertialUnit reads its own rotation in that
frame, with its own axes read the same way, i.e. the world rotation conjugated by the reference frame: a
device turned about the world's vertical axis reads a pure yaw in every coordinate system.

``gpsReference`` is the world origin expressed in the GPS coordinate system (Webots' WorldInfo manual). In
``local`` mode it is an offset added to the position. In ``WGS84`` mode it is the origin's latitude, longitude
(degrees) and altitude (m), and Webots goes through a Universal Transverse Mercator projection: the reference
becomes UTM easting/northing in its own zone, the position's east/north components are added to them as grid
metres, and the sum is projected back to latitude/longitude on the WGS84 ellipsoid; the altitude is the
reference's plus the up component. Grid metres are not ground metres: a displacement is scaled by 1/k (k ≈
0.9996 near the central meridian) and turned by the grid convergence (about Δλ·sin φ) — what a local tangent
plane at the reference misses. The projection uses the USGS series (Snyder, *Map Projections — A Working
Manual*, 1987, eqs. 8-9 to 8-25), the textbook form most UTM converters use.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from dualtwin.webots import _math3 as m3

__all__ = ["Axes", "axes", "gps_position", "in_reference_frame", "reference_frame", "to_wgs84"]

_WGS84_A = 6378137.0  # m, semi-major axis
_WGS84_E2 = 6.69437999014e-3  # first eccentricity squared


class Axes:
    """Unit vectors of East, North and Up in the world frame of one coordinate system."""

    def __init__(self, east: m3.Vec3, north: m3.Vec3, up: m3.Vec3) -> None:
        self.east, self.north, self.up = east, north, up


def axes(coordinate_system: str) -> Axes:
    """East/North/Up of ``"ENU"``, ``"NUE"`` or ``"EUN"``: the axis each letter stands at (anything else reads as
    ENU, Webots' default)."""
    return _AXES.get(coordinate_system.upper(), _AXES["ENU"])


def _letters(coordinate_system: str) -> Axes:
    unit = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    return Axes(unit[coordinate_system.index("E")], unit[coordinate_system.index("N")],
                unit[coordinate_system.index("U")])


#: the three systems' axes, made once: a Compass asks at every sample
_AXES = {cs: _letters(cs) for cs in ("ENU", "NUE", "EUN")}


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


def gps_position(position: Sequence[float], reference: Sequence[float], coordinate_system: str,
                 wgs84: bool) -> list[float]:
    """What a GPS reports for a world position: ``position + gpsReference`` (local) or :func:`to_wgs84`."""
    if wgs84:
        return to_wgs84(position, reference, coordinate_system)
    return [float(p) + float(r) for p, r in zip(position, reference, strict=True)]


def to_wgs84(position: Sequence[float], reference: Sequence[float], coordinate_system: str) -> list[float]:
    """``[latitude°, longitude°, altitude m]`` of a world position, the world origin being at ``reference``."""
    ax = axes(coordinate_system)
    east, north, up = m3.dot(position, ax.east), m3.dot(position, ax.north), m3.dot(position, ax.up)
    lat0, lon0, alt0 = (float(v) for v in reference)
    zone = _utm_zone(lat0, lon0)
    easting, northing = _to_utm(lat0, lon0, zone)
    lat, lon = _from_utm(easting + east, northing + north, zone, south=lat0 < 0)
    return [lat, lon, alt0 + up]


_K0 = 0.9996  # UTM scale on the central meridian
_E2P = _WGS84_E2 / (1.0 - _WGS84_E2)  # second eccentricity squared
_M1 = 1.0 - _WGS84_E2 / 4 - 3 * _WGS84_E2**2 / 64 - 5 * _WGS84_E2**3 / 256
_M2 = 3 * _WGS84_E2 / 8 + 3 * _WGS84_E2**2 / 32 + 45 * _WGS84_E2**3 / 1024
_M3 = 15 * _WGS84_E2**2 / 256 + 45 * _WGS84_E2**3 / 1024
_M4 = 35 * _WGS84_E2**3 / 3072


def _utm_zone(lat: float, lon: float) -> int:
    """The UTM zone of a point, with the Norway (32V) and Svalbard (31X-37X) exceptions."""
    lon = (lon + 180.0) % 360.0 - 180.0
    zone = int((lon + 180.0) // 6.0) + 1
    if 56.0 <= lat < 64.0 and 3.0 <= lon < 12.0:
        zone = 32
    if 72.0 <= lat < 84.0:
        for west, east, z in ((0.0, 9.0, 31), (9.0, 21.0, 33), (21.0, 33.0, 35), (33.0, 42.0, 37)):
            if west <= lon < east:
                zone = z
    return min(zone, 60)


def _central_meridian(zone: int) -> float:
    return math.radians((zone - 1) * 6 - 180 + 3)


def _to_utm(lat: float, lon: float, zone: int) -> tuple[float, float]:
    """Easting and northing (m) of a latitude/longitude in ``zone`` (Snyder 8-9 to 8-15)."""
    phi = math.radians(lat)
    sin_phi, cos_phi, tan_phi = math.sin(phi), math.cos(phi), math.tan(phi)
    n = _WGS84_A / math.sqrt(1.0 - _WGS84_E2 * sin_phi**2)
    t = tan_phi**2
    c = _E2P * cos_phi**2
    a = cos_phi * (math.radians((lon + 180.0) % 360.0 - 180.0) - _central_meridian(zone))
    m = _WGS84_A * (_M1 * phi - _M2 * math.sin(2 * phi) + _M3 * math.sin(4 * phi) - _M4 * math.sin(6 * phi))
    easting = _K0 * n * (a + (1 - t + c) * a**3 / 6 + (5 - 18 * t + t**2 + 72 * c - 58 * _E2P) * a**5 / 120)
    northing = _K0 * (m + n * tan_phi * (a**2 / 2 + (5 - t + 9 * c + 4 * c**2) * a**4 / 24
                                        + (61 - 58 * t + t**2 + 600 * c - 330 * _E2P) * a**6 / 720))
    return easting + 500000.0, northing + (10000000.0 if lat < 0 else 0.0)


def _from_utm(easting: float, northing: float, zone: int, south: bool) -> tuple[float, float]:
    """Latitude and longitude (degrees) of UTM coordinates in ``zone`` (Snyder 8-18 to 8-25)."""
    x = easting - 500000.0
    y = northing - (10000000.0 if south else 0.0)
    mu = y / _K0 / (_WGS84_A * _M1)
    r = math.sqrt(1.0 - _WGS84_E2)
    e1 = (1.0 - r) / (1.0 + r)
    phi1 = (mu + (3 * e1 / 2 - 27 * e1**3 / 32) * math.sin(2 * mu)
            + (21 * e1**2 / 16 - 55 * e1**4 / 32) * math.sin(4 * mu)
            + (151 * e1**3 / 96) * math.sin(6 * mu) + (1097 * e1**4 / 512) * math.sin(8 * mu))
    sin1, cos1, tan1 = math.sin(phi1), math.cos(phi1), math.tan(phi1)
    w = 1.0 - _WGS84_E2 * sin1**2
    n1 = _WGS84_A / math.sqrt(w)
    r1 = _WGS84_A * (1.0 - _WGS84_E2) / w**1.5
    t1 = tan1**2
    c1 = _E2P * cos1**2
    d = x / (n1 * _K0)
    phi = phi1 - (n1 * tan1 / r1) * (d**2 / 2 - (5 + 3 * t1 + 10 * c1 - 4 * c1**2 - 9 * _E2P) * d**4 / 24
                                     + (61 + 90 * t1 + 298 * c1 + 45 * t1**2 - 252 * _E2P - 3 * c1**2) * d**6 / 720)
    lam = (d - (1 + 2 * t1 + c1) * d**3 / 6
           + (5 - 2 * c1 + 28 * t1 - 3 * c1**2 + 8 * _E2P + 24 * t1**2) * d**5 / 120) / cos1
    return math.degrees(phi), math.degrees(_central_meridian(zone) + lam)
