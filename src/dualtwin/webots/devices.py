"""The solid-state sensors (GPS, gyro, accelerometer, inertial unit) of the controller API, and the table from a
device node type to its API class (the joint devices are in :mod:`dualtwin.webots.joint_devices`).

Moved out of :mod:`dualtwin.webots.controller` (which re-exports them as the Webots API names) so that module
holds the runtime and the ``Robot``/``Supervisor`` classes; devices with more machinery (cameras, ranging,
radio, display, keyboard, touch) already have their own modules.
"""

from __future__ import annotations

import math
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.altimeter import Altimeter
from dualtwin.webots.api_args import finite, warn
from dualtwin.webots.camera import Camera
from dualtwin.webots.compass import Compass
from dualtwin.webots.connector import Connector
from dualtwin.webots.device_base import Device, SampledDevice, SolidSensor
from dualtwin.webots.display import Display
from dualtwin.webots.joint_devices import Motor, PositionSensor
from dualtwin.webots.keyboard import Keyboard
from dualtwin.webots.led import LED
from dualtwin.webots.light_sensor import LightSensor
from dualtwin.webots.pen import Pen
from dualtwin.webots.radar import Radar
from dualtwin.webots.radio import Emitter, Receiver
from dualtwin.webots.ranging import DistanceSensor, Lidar, RangeFinder
from dualtwin.webots.touch import TouchSensor
from dualtwin.webots.vacuum_gripper import VacuumGripper

__all__ = [
    "GPS",
    "SOLID_DEVICE_CLASSES",
    "Accelerometer",
    "Gyro",
    "InertialUnit",
    "Motor",
    "PositionSensor",
    "UnsupportedSensor",
    "device_class",
]

_warn = warn
_finite = finite

_Sampled = SampledDevice
_SolidSensor = SolidSensor


class GPS(_SolidSensor):
    """World position of the device (ENU, metres)."""

    def _read(self) -> None:
        self._values = list(self._pose().t)

    def getValues(self) -> list[float]:
        return list(self._values)

    def getSpeed(self) -> float:
        v = self._robot._sim.solid_velocity(self._record.solid)
        return math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)


class Gyro(_SolidSensor):
    """Angular velocity in the device frame (rad/s)."""

    def _read(self) -> None:
        v = self._robot._sim.solid_velocity(self._record.solid)
        self._values = list(m3.mat_t_vec(self._pose().R, v[3:6]))

    def getValues(self) -> list[float]:
        return list(self._values)


class Accelerometer(_SolidSensor):
    """Proper acceleration in the device frame (m/s²); reads +g upward at rest."""

    def enable(self, samplingPeriod: Any) -> None:
        self._robot._sim.track_acceleration(self._record.solid)
        super().enable(samplingPeriod)

    def _read(self) -> None:
        self._values = list(self._robot._sim.acceleration(self._record.solid))

    def getValues(self) -> list[float]:
        return list(self._values)


class InertialUnit(_SolidSensor):
    """Orientation of the device: roll/pitch/yaw (ENU) and quaternion (x, y, z, w)."""

    def _invalidate(self) -> None:
        self._R: m3.Mat3 | None = None

    def _read(self) -> None:
        self._R = self._pose().R

    def getRollPitchYaw(self) -> list[float]:
        return list(m3.roll_pitch_yaw(self._R)) if self._R is not None else [math.nan] * 3

    def getQuaternion(self) -> list[float]:
        if self._R is None:
            return [math.nan] * 4
        w, x, y, z = m3.quat_from_mat(self._R)
        return [x, y, z, w]


class UnsupportedSensor(_SolidSensor):
    """A sensor the twin does not simulate: enable/disable work, readings are NaN."""

    def _read(self) -> None:
        self._values = [math.nan] * 3

    def getValue(self) -> float:
        return math.nan

    def getValues(self) -> list[float]:
        return list(self._values)


SOLID_DEVICE_CLASSES: dict[str, type[Device]] = {
    "DistanceSensor": DistanceSensor,
    "Lidar": Lidar,
    "RangeFinder": RangeFinder,
    "TouchSensor": TouchSensor,
    "Emitter": Emitter,
    "Receiver": Receiver,
    "Display": Display,
    "Camera": Camera,
    "GPS": GPS,
    "Gyro": Gyro,
    "Accelerometer": Accelerometer,
    "InertialUnit": InertialUnit,
    "LightSensor": LightSensor,
    "Radar": Radar,
    "Connector": Connector,
    "Compass": Compass,
    "Altimeter": Altimeter,
    "LED": LED,
    "VacuumGripper": VacuumGripper,
    "Pen": Pen,
}


def device_class(type_name: str) -> type[Any] | None:
    """The API class that reads a device node type, or None when the twin only returns NaN for it."""
    if type_name in ("RotationalMotor", "LinearMotor"):
        return Motor
    if type_name == "PositionSensor":
        return PositionSensor
    if type_name == "Keyboard":
        return Keyboard
    return SOLID_DEVICE_CLASSES.get(type_name)
