"""Webots sensor ``resolution`` in a converted model: ``<numeric name="webots_sensor.<sensor>" data="resolution"/>``.

Webots quantises a sensor's output with ``WbMathsUtilities::discretize``, int(v/r + 0.5)·r truncated toward zero,
after its lookup table and noise (``docs/reference/webots-devices.md`` §0.4, on-ode §5.4); ``-1`` (any r <= 0)
disables it. MuJoCo sensors have no resolution, so the converter writes it as a numeric per sensor and the MuJoCo
twin applies the rule to its readings (:func:`dualtwin.twins.mujoco_state.sensor_resolutions`). Written for the
devices whose converted MuJoCo reading is Webots' value before quantisation: PositionSensor (joint position),
GPS (position, its ``accuracy`` being the MuJoCo sensor's noise), Gyro and Accelerometer (an empty lookupTable;
a non-empty one is reported as not converted). Not for InertialUnit (a quaternion where Webots gives angles),
Compass, DistanceSensor and TouchSensor (lookup tables not converted): there the quantisation step would apply to
another quantity.

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

__all__ = ["QUANTISED", "add_resolution", "add_sensor_model", "north"]

#: The devices whose ``resolution`` the converter writes (see the module docstring).
QUANTISED = frozenset({"PositionSensor", "GPS", "Gyro", "Accelerometer"})


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


def add_sensor_model(spec: mujoco.MjSpec, sensor: str, device: Any, world_info: Mapping[str, Any]) -> None:
    """What the MuJoCo sensor ``sensor`` of the Webots ``device`` needs besides itself: its resolution
    (:func:`add_resolution`) and, for a Compass, the model's magnetic field set to the world's north."""
    add_resolution(spec, sensor, device)
    if device.type_name == "Compass":
        spec.option.magnetic = north(world_info)
