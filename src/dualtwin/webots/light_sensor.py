"""LightSensor: the irradiance the world's lights send onto the sensor, through its lookup table.

What Webots documents (LightSensor, SpotLight, PointLight reference pages), computed per light ``k`` with the
sensor axis ``x`` and ``d`` the distance from the light to the sensor:

* ``E_k = on_k · att_k · spot_k · (ambientIntensity_k + intensity_k · max(0, cos θ_k)) · colour_k``,
  ``θ_k`` the angle between the sensor's x axis and the direction to the light (for a DirectionalLight,
  the direction opposite to the light's ``direction``, a world direction wherever the light sits: Webots'
  DirectionalLight page gives it "in the global coordinate system");
* ``att_k = 1`` for a DirectionalLight, ``1 / (a1 + a2·d + a3·d²)`` for the ``attenuation`` (a1, a2, a3) of a
  Point/SpotLight, and 0 beyond the light's ``radius``;
* ``spot_k`` (SpotLight only) with ``α`` the angle between the spot's ``direction`` and the light-to-sensor
  vector: 1 within ``beamWidth``, 0 beyond ``cutOffAngle``, linear in between (VRML's fall-off);
* ``on_k`` and ``colour_k``: the light's ``on`` and ``color`` fields, or for a light an LED drives the LED's
  state (off at 0, else on in the LED's colour: :mod:`.led_lights`); with ``occlusion TRUE`` ``on_k`` is 0 when
  a ray from the sensor to the light hits a bounding object first (the Solid carrying the light and the
  sensor's own robot, unless it has selfCollision, are not obstacles);
* the colour is weighted by ``colorFilter`` and the three channels averaged, so white light through the
  default white filter counts once; then the lookup table (default ``[0 0 0, 1 1000 0]``) and ``resolution``.

Rays use the bodies' poses after the physics step, as Webots' post-physics ray pass does.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dualtwin.webots import _math3 as m3
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.led_lights import light_state
from dualtwin.webots.lights import LightSource, light_sources
from dualtwin.webots.lut import Table, discretize, lookup, table_from_field
from dualtwin.webots.physics import GeomRec, Simulation
from dualtwin.webots.ranging import caster_for
from dualtwin.webots.rays import candidate_geoms, geom_list
from dualtwin.webots.step_hints import step_value

__all__ = ["LightSensor", "irradiance"]

_DEFAULT_TABLE: Table = [(0.0, 0.0, 0.0), (1.0, 1000.0, 0.0)]


def _spot_factor(direction: m3.Vec3, cut: float, beam: float, to_sensor: m3.Vec3) -> float:
    alpha = math.acos(max(-1.0, min(1.0, m3.dot(direction, to_sensor))))
    if alpha > cut:
        return 0.0
    if alpha <= beam or cut <= beam:
        return 1.0
    return (cut - alpha) / (cut - beam)


def _visible(sim: Simulation, light: LightSource, origin: m3.Vec3, toward: m3.Vec3, length: float, robot: Any) -> bool:
    def build() -> list[GeomRec]:
        return [
            g
            for g in candidate_geoms(sim, robot)
            if light.solid is None
            or (g.solid is not light.solid and (g.body is None or g.body is not light.solid.body))
        ]

    geoms = geom_list(sim, ("light", id(robot), id(light.node)), build)
    if not geoms:
        return True
    hits = caster_for(sim).cast(
        np.array([origin], dtype=float), np.array([toward], dtype=float), length, geoms, normals=False
    )
    return not bool(np.isfinite(hits.distance[0]))


def irradiance(sim: Simulation, pose: m3.Pose, colour_filter: Any, occlusion: bool, robot: Any) -> float:
    """Total filtered irradiance at a sensor of world pose ``pose`` (see the module docstring)."""
    axis = m3.normalized(pose.rotate((1.0, 0.0, 0.0)))
    filt = [float(c) for c in colour_filter]
    total = 0.0
    for light in light_sources(sim):
        node = light.node
        f = node.fields
        on, colour = light_state(sim, node, light.led)
        if not on:
            continue
        lp = light.world_pose(sim)
        if node.type_name == "DirectionalLight":
            # Webots' DirectionalLight page: its direction is "in the global coordinate system", so the Solid or
            # Pose it sits in does not turn it (VRML's is in the local frame; Webots' is not)
            toward = m3.normalized(m3.scale(f.get("direction", (0.0, 0.0, -1.0)), -1.0))
            distance = math.inf
            factor = 1.0
        else:
            location = lp.apply(f.get("location", (0.0, 0.0, 0.0)))
            delta = m3.sub(location, pose.t)
            distance = m3.norm(delta)
            if distance > float(f.get("radius", 100.0)):
                continue
            toward = m3.scale(delta, 1.0 / distance) if distance > 0 else axis
            a1, a2, a3 = (float(v) for v in f.get("attenuation", (1.0, 0.0, 0.0)))
            denominator = a1 + a2 * distance + a3 * distance * distance
            factor = 1.0 / denominator if denominator > 0 else 0.0
            if node.type_name == "SpotLight":
                spot = lp.rotate(m3.normalized(f.get("direction", (0.0, 0.0, -1.0))))
                cut, beam = float(f.get("cutOffAngle", 0.785398)), float(f.get("beamWidth", 1.570796))
                factor *= _spot_factor(spot, cut, beam, m3.scale(toward, -1.0))
        if factor == 0.0:
            continue
        light_level = float(f.get("ambientIntensity", 0.0)) + float(f.get("intensity", 1.0)) * max(
            0.0, m3.dot(axis, toward)
        )
        if light_level <= 0.0:
            continue
        if occlusion and not _visible(sim, light, pose.t, toward, min(distance, 1e6), robot):
            continue
        total += factor * light_level * sum(c * w for c, w in zip(colour, filt, strict=False)) / 3.0
    return total


class LightSensor(SolidSensor):
    """Webots ``LightSensor``: ``getValue()`` is the lookup-table output of the irradiance (module docstring)."""

    def _invalidate(self) -> None:
        self._value = math.nan

    def _fields(self) -> dict[str, Any]:
        return self._record.node.fields  # type: ignore[no-any-return]

    def _table(self) -> Table:
        raw = self._fields().get("lookupTable")
        return _DEFAULT_TABLE if raw is None else table_from_field(raw)

    def _read(self) -> None:
        sim = self._robot._sim
        f = self._fields()
        e = irradiance(
            sim, self._pose(), f.get("colorFilter", (1.0, 1.0, 1.0)), bool(f.get("occlusion", False)),
            self._record.solid.robot,
        )  # fmt: skip
        self._value = discretize(lookup(self._table(), e, sim.rng), float(f.get("resolution", -1.0)))

    @step_value
    def getValue(self) -> float:
        self._check_enabled("wb_light_sensor_get_value")
        return self._value

    def getLookupTable(self) -> list[float]:
        return [v for row in self._table() for v in row]

    value = property(getValue)
    lookup_table = property(getLookupTable)
