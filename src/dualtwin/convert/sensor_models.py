"""Webots sensor value models in a converted model: ``resolution`` and ``lookupTable`` as numerics per sensor.

Resolution: ``<numeric name="webots_sensor.<sensor>" data="resolution"/>``. Webots quantises a sensor's output
with ``WbMathsUtilities::discretize``, int(v/r + 0.5)·r truncated toward zero, after its lookup table and noise
(``docs/reference/webots-devices.md`` §0.4, on-ode §5.4); ``-1`` (any r <= 0) disables it. MuJoCo sensors have no
resolution, so the converter writes it as a numeric per sensor and the MuJoCo twin applies the rule to its readings
(:func:`dualtwin.twins.mujoco_state.sensor_resolutions`). Written for the devices whose converted MuJoCo reading,
after the lookup table below, is Webots' value before quantisation: PositionSensor (joint position), GPS
(position, its ``accuracy`` being the MuJoCo sensor's noise), Gyro, Accelerometer, Compass and DistanceSensor. Not
for InertialUnit (a quaternion where Webots gives angles) and TouchSensor (lookup table not converted): there the
quantisation step would apply to another quantity.

Lookup table: ``<numeric name="webots_sensor_lut.<sensor>" data="in out noise in out noise ..."/>``, the rows of
the device's ``lookupTable`` (§0.3), applied by the MuJoCo twin to the physical value MuJoCo reads, before the
resolution (:mod:`dualtwin.twins.sensor_tables`). A Gyro, Accelerometer or Compass gets it only when its table
is not empty (an empty table is Webots' identity: nothing is written and the model is as before); each component
goes through it. A DistanceSensor always has one (Webots' default is ``[0 0 0, 0.1 1000 0]``); its rangefinder's
``cutoff`` is the last input D, Webots' ray length, and the twin reads ``lookup(min(d, D))``, a miss reading
``lookup(D)``. An empty DistanceSensor table reads 0 in Webots (§1.4), written as the one row ``0 0 0``. The
rangefinder is one ray along the sensor's axis: exact for a laser and for one-ray generic and sonar sensors
(except a sonar's π/8 echo angle, which MuJoCo does not check); several rays over an ``aperture`` and infra-red's
reflection factor are approximated by that ray, with a warning (:func:`distance_notes`). MuJoCo's ray excludes
only the sensor's own body: it also hits visual geoms and the robot's other bodies, which Webots' generic, sonar
and laser rays do not (they hit boundingObjects outside the robot unless ``selfCollision``).

A Compass reads the world's north (the axis ``WorldInfo.coordinateSystem`` names N: +y in ENU, +x in NUE, +z in
EUN) as a unit vector in its frame (the Webots twin's ``webots.compass``); MuJoCo's ``magnetometer`` reads the
model's magnetic field in its site frame, by default (0, -0.5, 0), which read -0.5 times Webots' vector in ENU. A
converted world with a Compass gets ``<option magnetic>`` = that north, so the two read the same vector.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco

from dualtwin.twins.mujoco_state import SENSOR_NUMERIC
from dualtwin.twins.sensor_tables import LUT_NUMERIC
from dualtwin.webots.lut import table_from_field

__all__ = ["QUANTISED", "TABLED", "add_lookup_table", "add_resolution", "add_sensor_model", "distance_notes", "north"]

#: The devices whose ``resolution`` the converter writes (see the module docstring).
QUANTISED = frozenset({"PositionSensor", "GPS", "Gyro", "Accelerometer", "Compass", "DistanceSensor"})
#: The devices whose ``lookupTable`` the converter writes (see the module docstring).
TABLED = frozenset({"Gyro", "Accelerometer", "Compass", "DistanceSensor"})
#: Webots' DistanceSensor types (case-insensitive; any other string is a sonar, as in Webots).
DISTANCE_TYPES = {"generic": "generic", "infra-red": "infra-red", "infrared": "infra-red", "laser": "laser"}


def add_resolution(spec: mujoco.MjSpec, sensor: str, device: Any) -> None:
    """Write ``device``'s ``resolution`` for the MuJoCo sensor ``sensor`` when it is one of :data:`QUANTISED` and
    the resolution is positive (Webots' default -1, or any value <= 0: no quantisation, nothing written)."""
    if device.type_name in QUANTISED and float(device.get("resolution", -1.0)) > 0:
        spec.add_numeric(name=SENSOR_NUMERIC + sensor, data=[float(device["resolution"])])


def north(world_info: Mapping[str, Any]) -> list[float]:
    """The world's north for its ``coordinateSystem`` (ENU when absent or unknown): the axis named ``N``."""
    system = str(world_info.get("coordinateSystem", "ENU")).upper()
    system = system if system in ("ENU", "NUE", "EUN") else "ENU"
    axis = [0.0, 0.0, 0.0]
    axis[system.index("N")] = 1.0
    return axis


def add_lookup_table(spec: mujoco.MjSpec, sensor: Any, device: Any) -> None:
    """Write ``device``'s ``lookupTable`` for the MuJoCo sensor ``sensor`` (an ``MjsSensor``) and, for a
    DistanceSensor, set the rangefinder's cutoff to the table's last input (module docstring)."""
    if device.type_name not in TABLED:
        return
    rows = table_from_field(device.get("lookupTable"))
    if device.type_name == "DistanceSensor":
        rows = rows or [(0.0, 0.0, 0.0)]  # Webots: an empty table reads 0 (no ray)
        if rows[-1][0] > 0:
            sensor.cutoff = rows[-1][0]
    if rows:
        spec.add_numeric(name=LUT_NUMERIC + sensor.name, data=[v for row in rows for v in row])


def distance_notes(device: Any) -> list[str]:
    """What of a DistanceSensor's value model the one converted ray does not reproduce (empty: nothing)."""
    kind = DISTANCE_TYPES.get(str(device.get("type", "generic")).lower(), "sonar")
    rays, aperture = int(device.get("numberOfRays", 1)), abs(float(device.get("aperture", 1.5708)))
    notes = []
    if kind != "laser" and rays > 1 and aperture > 0:
        notes.append(f"its {rays} rays over aperture {aperture:g} are converted as one ray along its axis "
                     "(Webots combines the rays' distances before its lookupTable)")
    if kind == "infra-red":
        notes.append("infra-red is converted as a ray against all geoms: the hit's red colour and "
                     "redColorSensitivity are not")
    if kind == "sonar":
        notes.append("MuJoCo's ray reads any hit: Webots' sonar ignores echoes more than pi/8 off the surface normal")
    return notes


def add_sensor_model(spec: mujoco.MjSpec, sensor: Any, device: Any, world_info: Mapping[str, Any]) -> None:
    """What the MuJoCo sensor ``sensor`` (an ``MjsSensor``) of the Webots ``device`` needs besides itself: its
    lookup table (:func:`add_lookup_table`), its resolution (:func:`add_resolution`) and, for a Compass, the
    model's magnetic field set to the world's north."""
    add_lookup_table(spec, sensor, device)
    add_resolution(spec, sensor.name, device)
    if device.type_name == "Compass":
        spec.option.magnetic = north(world_info)
