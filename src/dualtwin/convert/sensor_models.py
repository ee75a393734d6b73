"""Webots sensor ``resolution`` in a converted model: ``<numeric name="webots_sensor.<sensor>" data="resolution"/>``.

Webots quantises a sensor's output with ``WbMathsUtilities::discretize``, int(v/r + 0.5)·r truncated toward zero,
after its lookup table and noise (``docs/reference/webots-devices.md`` §0.4, on-ode §5.4); ``-1`` (any r <= 0)
disables it. MuJoCo sensors have no resolution, so the converter writes it as a numeric per sensor and the MuJoCo
twin applies the rule to its readings (:func:`dualtwin.twins.mujoco_state.sensor_resolutions`). Written for the
devices whose converted MuJoCo reading is Webots' value before quantisation: PositionSensor (joint position),
GPS (position, its ``accuracy`` being the MuJoCo sensor's noise), Gyro and Accelerometer (an empty lookupTable;
a non-empty one is reported as not converted). Not for InertialUnit (a quaternion where Webots gives angles),
Compass (MuJoCo's magnetometer is a field, Webots' a north vector), DistanceSensor and TouchSensor (lookup
tables not converted): there the quantisation step would apply to another quantity.
"""

from __future__ import annotations

from typing import Any

import mujoco

from dualtwin.twins.mujoco_state import SENSOR_NUMERIC

__all__ = ["QUANTISED", "add_resolution"]

#: The devices whose ``resolution`` the converter writes (see the module docstring).
QUANTISED = frozenset({"PositionSensor", "GPS", "Gyro", "Accelerometer"})


def add_resolution(spec: mujoco.MjSpec, sensor: str, device: Any) -> None:
    """Write ``device``'s ``resolution`` for the MuJoCo sensor ``sensor`` when it is one of :data:`QUANTISED` and
    the resolution is positive (Webots' default -1, or any value <= 0: no quantisation, nothing written)."""
    if device.type_name in QUANTISED and float(device.get("resolution", -1.0)) > 0:
        spec.add_numeric(name=SENSOR_NUMERIC + sensor, data=[float(device["resolution"])])
