"""Radar and RadarTarget: the Solids with a ``radarCrossSection`` that a radar sees.

Webots' Radar reference, with the radar's x axis forward and z axis up (R2022a+ device frames):

* candidates are the Solids whose ``radarCrossSection`` is > 0, other than the radar and the Solids it is
  mounted on;
* a candidate is in the field of view when its extent (the world box around its bounding objects; its origin
  alone without one) overlaps the radar's ``horizontalFieldOfView`` × ``verticalFieldOfView`` pyramid, as
  Webots' object detection does, so a tall target whose centre is above the beam is still seen;
* ``distance`` is from the radar to the target's origin and must lie in [``minRange``, ``maxRange``];
* ``speed`` is the radial speed of the target relative to the radar (positive moving away); targets slower
  than ``minAbsoluteRadialSpeed`` are dropped, and when ``maxRadialSpeed`` ≥ ``minRadialSpeed`` (the default
  ``-1`` disables it) so are those outside that range;
* ``receiver_power`` (dBm) follows the radar equation
  ``Pt + 2·G + 10·log10(σ·λ² / ((4π)³·R⁴))`` with ``λ = c / frequency``; targets below ``minDetectableSignal``
  are dropped;
* ``azimuth`` is ``atan2(y, x)`` of the target in the radar frame (positive to the radar's left);
* with ``occlusion TRUE`` a ray from the radar to the target's origin that hits another bounding object first
  hides the target. Noise fields (range, speed, angular) are applied with the simulation's noise generator.

Values are computed from the poses after the physics step (Webots' post-physics ray pass).
"""

from __future__ import annotations

import ctypes
import math

import numpy as np

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.physics import GeomRec, Simulation, SolidRec
from dualtwin.webots.ranging import caster_for
from dualtwin.webots.rays import candidate_geoms, geom_list

__all__ = ["Radar", "RadarTarget", "detect_targets"]

SPEED_OF_LIGHT = 299792458.0


class RadarTarget:
    """One detected target (Webots' plain-attribute record)."""

    __webots_value__ = True  # plain data: crosses to a controller process by value

    distance: float  # m
    receiver_power: float  # dBm
    speed: float  # m/s, radial, positive moving away
    azimuth: float  # rad, positive to the radar's left

    def __init__(self, distance: float, receiver_power: float, speed: float, azimuth: float) -> None:
        self.distance = distance
        self.receiver_power = receiver_power
        self.speed = speed
        self.azimuth = azimuth

    def __repr__(self) -> str:
        return (
            f"RadarTarget(distance={self.distance!r}, receiver_power={self.receiver_power!r}, "
            f"speed={self.speed!r}, azimuth={self.azimuth!r})"
        )


def _corners(sim: Simulation, solid: SolidRec) -> list[m3.Vec3]:
    """World corners of the box around the Solid's bounding objects (its origin when it has none)."""
    lib = ode.load()
    aabb = (ctypes.c_double * 6)()
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for g in solid.geoms:
        if g.is_plane:
            continue
        lib.dGeomGetAABB(g.ptr, aabb)
        for i in range(3):
            lo[i] = min(lo[i], aabb[2 * i])
            hi[i] = max(hi[i], aabb[2 * i + 1])
    if not math.isfinite(lo[0]):
        return [sim.solid_world_pose(solid).t]
    return [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


def _overlaps(angles: list[float], half: float) -> bool:
    return min(angles) <= half and max(angles) >= -half


def _in_view(local_corners: list[m3.Vec3], half_h: float, half_v: float) -> bool:
    if len(local_corners) == 1:
        x, y, z = local_corners[0]
        return abs(math.atan2(y, x)) <= half_h and abs(math.atan2(z, math.hypot(x, y))) <= half_v
    if all(c[0] <= 0.0 for c in local_corners):
        return False  # entirely behind the radar
    front = [c for c in local_corners if c[0] > 0.0]
    # a box straddling the radar's plane spans every angle on the sides it reaches
    azimuths = [math.atan2(c[1], c[0]) for c in front]
    elevations = [math.atan2(c[2], c[0]) for c in front]
    if len(front) < len(local_corners):
        ys = [c[1] for c in local_corners]
        zs = [c[2] for c in local_corners]
        azimuths += [math.pi / 2] if max(ys) > 0 else []
        azimuths += [-math.pi / 2] if min(ys) < 0 else []
        elevations += [math.pi / 2] if max(zs) > 0 else []
        elevations += [-math.pi / 2] if min(zs) < 0 else []
    return _overlaps(azimuths, half_h) and _overlaps(elevations, half_v)


def _occluded(sim: Simulation, radar: SolidRec, target: SolidRec, origin: m3.Vec3, delta: m3.Vec3) -> bool:
    distance = m3.norm(delta)
    if distance == 0.0:
        return False
    body = target.body

    def build() -> list[GeomRec]:
        return [g for g in candidate_geoms(sim, radar.robot) if g.solid is not target and (body is None or g.body is not body)]

    geoms = geom_list(sim, ("radar", id(radar.robot), id(target)), build)
    if not geoms:
        return False
    hits = caster_for(sim).cast(
        np.array([origin], dtype=float), np.array([m3.scale(delta, 1.0 / distance)]), distance, geoms, normals=False
    )
    return bool(np.isfinite(hits.distance[0])) and float(hits.distance[0]) < distance - 1e-9


def detect_targets(sim: Simulation, radar: SolidRec) -> list[RadarTarget]:
    """The targets ``radar`` sees now (module docstring), nearest first."""
    f = radar.node.fields
    pose = sim.solid_world_pose(radar)
    rv = sim.solid_velocity(radar)[:3]
    half_h = float(f.get("horizontalFieldOfView", 0.78)) / 2.0
    half_v = float(f.get("verticalFieldOfView", 0.1)) / 2.0
    min_range, max_range = float(f.get("minRange", 1.0)), float(f.get("maxRange", 50.0))
    min_abs = float(f.get("minAbsoluteRadialSpeed", 0.0))
    min_speed, max_speed = float(f.get("minRadialSpeed", 1.0)), float(f.get("maxRadialSpeed", -1.0))
    frequency = float(f.get("frequency", 24.0)) * 1e9
    wavelength = SPEED_OF_LIGHT / frequency if frequency > 0 else math.inf
    power = float(f.get("transmittedPower", 1.0))
    gain = float(f.get("antennaGain", 20.0))
    min_signal = float(f.get("minDetectableSignal", -100.0))
    occlusion = bool(f.get("occlusion", False))
    noise = (float(f.get("rangeNoise", 0.0)), float(f.get("speedNoise", 0.0)), float(f.get("angularNoise", 0.0)))
    skip = {id(s) for s in radar.carriers()}
    inverse = pose.inverse()
    found: list[RadarTarget] = []
    for solid in sim.solids:
        sigma = float(solid.node.fields.get("radarCrossSection", 0.0) or 0.0)
        if sigma <= 0.0 or id(solid) in skip:
            continue
        origin = sim.solid_world_pose(solid).t
        delta = m3.sub(origin, pose.t)
        distance = m3.norm(delta)
        if not min_range <= distance <= max_range or distance == 0.0:
            continue
        if not _in_view([inverse.apply(c) for c in _corners(sim, solid)], half_h, half_v):
            continue
        tv = sim.solid_velocity(solid)[:3]
        speed = m3.dot(m3.sub(tv, rv), delta) / distance
        if abs(speed) < min_abs or (max_speed >= min_speed and not min_speed <= speed <= max_speed):
            continue
        ratio = sigma * wavelength**2 / ((4.0 * math.pi) ** 3 * distance**4)
        received = power + 2.0 * gain + 10.0 * math.log10(ratio) if ratio > 0 else -math.inf
        if received < min_signal:
            continue
        if occlusion and _occluded(sim, radar, solid, pose.t, delta):
            continue
        local = inverse.apply(origin)
        azimuth = math.atan2(local[1], local[0])
        rng = sim.rng
        if noise[0] > 0:
            distance += rng.gauss(0.0, noise[0])
        if noise[1] > 0:
            speed += rng.gauss(0.0, noise[1])
        if noise[2] > 0:
            azimuth += rng.gauss(0.0, noise[2])
        found.append(RadarTarget(distance, received, speed, azimuth))
    found.sort(key=lambda t: t.distance)
    return found


class Radar(SolidSensor):
    """Webots ``Radar``: ``getTargets()`` after each sample (module docstring)."""

    def _invalidate(self) -> None:
        self._targets: list[RadarTarget] = []

    def _read(self) -> None:
        self._targets = detect_targets(self._robot._sim, self._record.solid)

    def _field(self, name: str, default: float) -> float:
        return float(self._record.node.fields.get(name, default))

    def getTargets(self) -> list[RadarTarget]:
        self._check_enabled("wb_radar_get_targets")
        return [RadarTarget(t.distance, t.receiver_power, t.speed, t.azimuth) for t in self._targets]

    def getNumberOfTargets(self) -> int:
        self._check_enabled("wb_radar_get_number_of_targets")
        return len(self._targets)

    def getMinRange(self) -> float:
        return self._field("minRange", 1.0)

    def getMaxRange(self) -> float:
        return self._field("maxRange", 50.0)

    def getHorizontalFov(self) -> float:
        return self._field("horizontalFieldOfView", 0.78)

    def getVerticalFov(self) -> float:
        return self._field("verticalFieldOfView", 0.1)

    max_range = property(getMaxRange)
    min_range = property(getMinRange)
    horizontal_fov = property(getHorizontalFov)
    vertical_fov = property(getVerticalFov)
    number_of_targets = property(getNumberOfTargets)
