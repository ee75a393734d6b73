"""The solid-state sensors (GPS, gyro, accelerometer, inertial unit) of the controller API, and the table from a
device node type to its API class (the joint devices are in :mod:`dualtwin.webots.joint_devices`).

Moved out of :mod:`dualtwin.webots.controller` (which re-exports them as the Webots API names) so that module
holds the runtime and the ``Robot``/``Supervisor`` classes; devices with more machinery (cameras, ranging,
radio, display, keyboard, touch) already have their own modules.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.altimeter import Altimeter
from dualtwin.webots.api_args import finite, warn
from dualtwin.webots.camera import Camera
from dualtwin.webots.compass import Compass
from dualtwin.webots.connector import Connector
from dualtwin.webots.device_base import Device, SampledDevice, SolidSensor
from dualtwin.webots.display import Display
from dualtwin.webots.joint_devices import Brake, Motor, PositionSensor
from dualtwin.webots.keyboard import Keyboard
from dualtwin.webots.led import LED
from dualtwin.webots.light_sensor import LightSensor
from dualtwin.webots.lut import Table, discretize, lookup, table_from_field
from dualtwin.webots.pen import Pen
from dualtwin.webots.radar import Radar
from dualtwin.webots.radio import Emitter, Receiver
from dualtwin.webots.ranging import DistanceSensor, Lidar, RangeFinder
from dualtwin.webots.step_hints import step_value
from dualtwin.webots.touch import TouchSensor
from dualtwin.webots.vacuum_gripper import VacuumGripper
from dualtwin.webots.world_frame import gps_position, in_reference_frame

__all__ = [
    "GPS",
    "SOLID_DEVICE_CLASSES",
    "Accelerometer",
    "Brake",
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


def _lut_axes(device: _TableSensor, vector: Sequence[float]) -> list[float]:
    """Webots' per-axis post-processing of a 3-vector sensor: a disabled axis (``xAxis``/``yAxis``/``zAxis``
    FALSE) reads NaN, the others go through the ``lookupTable`` (interpolation, multiplicative noise) and the
    ``resolution``."""
    fields = device._record.node.fields
    table = device._table()
    resolution = float(fields.get("resolution", -1.0))
    rng = device._robot._sim.rng
    out = []
    for flag, v in zip(("xAxis", "yAxis", "zAxis"), vector, strict=True):
        if not fields.get(flag, True):
            out.append(math.nan)
            continue
        out.append(discretize(lookup(table, float(v), rng), resolution))
    return out


class _TableSensor(_SolidSensor):
    """A sensor with a ``lookupTable`` field (empty: the identity, without noise)."""

    _c_values = ""  # the C getter of ``getValues`` (named in the error line of a disabled read)

    def _table(self) -> Table:
        # read again after a supervisor's edit of the table (Webots' updateLookupTable), from the next sample on
        return self._configured("_table_cache",
                                lambda: table_from_field(self._fields().get("lookupTable", [])))

    def getLookupTable(self) -> list[float]:
        return [v for row in self._table() for v in row]

    @property
    def lookup_table(self) -> list[float]:
        return self.getLookupTable()

    @step_value
    def getValues(self) -> list[float]:
        self._check_enabled(self._c_values)
        return list(self._values)

    @property
    def value(self) -> list[float]:
        return self.getValues()


class GPS(_SolidSensor):
    """Position of the device's origin in the world (``LOCAL``, metres, the world's own axes, offset by
    ``gpsReference``) or, when ``WorldInfo.gpsCoordinateSystem`` is ``"WGS84"``, latitude/longitude (degrees)
    and altitude through UTM around ``gpsReference`` (:mod:`.world_frame`); ``accuracy`` adds Gaussian noise (m)
    and ``resolution`` rounds.
    Speed: the device origin's displacement over the last basic time step (``getSpeedVector``, world axes,
    and its norm ``getSpeed``), rounded to ``speedResolution``. Everything reads NaN until the first sample."""

    LOCAL = 0
    WGS84 = 1
    _tracks_steps = True

    def _invalidate(self) -> None:
        self._values = [math.nan] * 3
        self._speed_vector = [math.nan] * 3
        self._start_tracking()

    def _start_tracking(self) -> None:
        self._position_now = self._pose().t
        self._position_before = self._position_now

    def _each_step(self) -> None:
        self._position_before = self._position_now
        self._position_now = self._pose().t

    def _world_info(self) -> dict[str, Any]:
        info = self._robot._sim.world.world_info()
        return info.fields if info is not None else {}

    def getCoordinateSystem(self) -> int:
        return self.WGS84 if str(self._world_info().get("gpsCoordinateSystem", "local")) == "WGS84" else self.LOCAL

    @property
    def coordinate_system(self) -> int:
        return self.getCoordinateSystem()

    def _read(self) -> None:
        sim = self._robot._sim
        fields = self._record.node.fields
        position = list(self._position_now)
        accuracy = float(fields.get("accuracy", 0.0))
        if accuracy > 0:
            position = [p + sim.rng.gauss(0.0, accuracy) for p in position]
        reference = self._world_info().get("gpsReference", (0.0, 0.0, 0.0))
        position = gps_position(position, reference, sim.coordinate_system, self.getCoordinateSystem() == self.WGS84)
        resolution = float(fields.get("resolution", -1.0))
        self._values = [discretize(p, resolution) for p in position]
        speed_resolution = float(fields.get("speedResolution", -1.0))
        velocity = m3.scale(m3.sub(self._position_now, self._position_before), 1.0 / sim.dt)
        self._speed_vector = [discretize(v, speed_resolution) for v in velocity]

    @step_value
    def getValues(self) -> list[float]:
        self._check_enabled("wb_gps_get_values")
        return list(self._values)

    @property
    def value(self) -> list[float]:
        return self.getValues()

    @step_value
    def getSpeed(self) -> float:
        self._check_enabled("wb_gps_get_speed")
        return m3.norm(self._speed_vector) if all(math.isfinite(v) for v in self._speed_vector) else math.nan

    @property
    def speed(self) -> float:
        return self.getSpeed()

    @step_value
    def getSpeedVector(self) -> list[float]:
        self._check_enabled("wb_gps_get_speed_vector")
        return list(self._speed_vector)

    @property
    def speed_vector(self) -> list[float]:
        return self.getSpeedVector()

    @staticmethod
    def convertToDegreesMinutesSeconds(decimalDegrees: Any) -> str:
        """Degrees, minutes and seconds of a decimal angle, written as Webots writes them (``46° 30′ 0″``)."""
        value = float(decimalDegrees)
        degrees = int(value)
        minutes_f = abs(value - degrees) * 60.0
        minutes = int(minutes_f)
        seconds = (minutes_f - minutes) * 60.0
        return f"{degrees}° {minutes}′ {seconds:g}″"


class Gyro(_TableSensor):
    """Angular velocity of the body carrying the device, in the device's frame (rad/s), per axis through the
    lookup table and resolution; NaN for a disabled axis."""

    _c_values = "wb_gyro_get_values"

    def _read(self) -> None:
        sim = self._robot._sim
        w = sim.angular_velocity(self._record.solid)
        self._values = _lut_axes(self, m3.mat_t_vec(self._pose().R, w))


class Accelerometer(_TableSensor):
    """Proper acceleration of the device's origin in its own frame (m/s²; +g upward at rest).

    The device origin is a point of the body carrying it: its velocity is the body's CoM velocity plus
    ω × lever arm (``dBodyGetPointVel``), followed basic step by basic step; the acceleration is its change over
    the last step, minus gravity, rotated into the device frame. A device away from the centre of mass of a
    rotating body therefore reads the centripetal (ω × (ω × r)) and tangential (α × r) terms of where it is
    mounted. Then lookup table and resolution per axis; NaN for a disabled axis."""

    _tracks_steps = True
    _c_values = "wb_accelerometer_get_values"

    def _invalidate(self) -> None:
        self._values = [math.nan] * 3
        self._start_tracking()

    def _start_tracking(self) -> None:
        self._velocity_now = self._robot._sim.point_velocity(self._record.solid)
        self._velocity_before = self._velocity_now

    def _each_step(self) -> None:
        self._velocity_before = self._velocity_now
        self._velocity_now = self._robot._sim.point_velocity(self._record.solid)

    def _read(self) -> None:
        sim = self._robot._sim
        a = m3.scale(m3.sub(self._velocity_now, self._velocity_before), 1.0 / sim.dt)
        self._values = _lut_axes(self, m3.mat_t_vec(self._pose().R, m3.sub(a, sim.gravity)))


class InertialUnit(_SolidSensor):
    """Orientation of the device in the world's reference frame (:mod:`.world_frame`: ENU as is, NUE/EUN with
    their up axis as z): roll/pitch/yaw (``R = Rz(yaw)·Ry(pitch)·Rx(roll)``) and the quaternion (x, y, z, w).

    ``noise`` is relative to each angle's half-range, as Webots applies it: every sample adds
    noise·π·N(0, 1) to roll and yaw and noise·π/2·N(0, 1) to pitch (drawn in that order from the world's random
    generator, seeded by ``randomSeed``); roll and yaw are wrapped back into [−π, π] and the quaternion is the
    noisy angles'. A disabled axis (``xAxis`` → roll, ``yAxis`` → pitch, ``zAxis`` → yaw) reads NaN;
    ``resolution`` rounds the angles."""

    def _invalidate(self) -> None:
        self._angles: tuple[float, float, float] | None = None

    def _read(self) -> None:
        R = in_reference_frame(self._pose().R, self._robot._sim.coordinate_system)
        roll, pitch, yaw = m3.roll_pitch_yaw(R)
        noise = self.getNoise()
        if noise > 0:
            rng = self._robot._sim.rng
            roll = m3.normalize_angle(roll + noise * math.pi * rng.gauss(0.0, 1.0))
            pitch += noise * math.pi / 2 * rng.gauss(0.0, 1.0)
            yaw = m3.normalize_angle(yaw + noise * math.pi * rng.gauss(0.0, 1.0))
        self._angles = (roll, pitch, yaw)

    @step_value
    def getRollPitchYaw(self) -> list[float]:
        self._check_enabled("wb_inertial_unit_get_roll_pitch_yaw")
        if self._angles is None:
            return [math.nan] * 3
        fields = self._fields()  # (as the steps executed them: webots-on-ode.md §6)
        resolution = float(fields.get("resolution", -1.0))
        return [
            discretize(a, resolution) if fields.get(flag, True) else math.nan
            for flag, a in zip(("xAxis", "yAxis", "zAxis"), self._angles, strict=True)
        ]

    @property
    def roll_pitch_yaw(self) -> list[float]:
        return self.getRollPitchYaw()

    @step_value
    def getQuaternion(self) -> list[float]:
        self._check_enabled("wb_inertial_unit_get_quaternion")
        if self._angles is None:
            return [math.nan] * 4
        roll, pitch, yaw = self._angles
        R = m3.mat_mul(m3.rot_axis_angle((0.0, 0.0, 1.0, yaw)),
                       m3.mat_mul(m3.rot_axis_angle((0.0, 1.0, 0.0, pitch)), m3.rot_axis_angle((1.0, 0.0, 0.0, roll))))
        w, x, y, z = m3.quat_from_mat(R)
        return [x, y, z, w]

    @property
    def quaternion(self) -> list[float]:
        return self.getQuaternion()

    def getNoise(self) -> float:
        return float(self._fields().get("noise", 0.0))

    @property
    def noise(self) -> float:
        return self.getNoise()


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
    if type_name == "Brake":
        return Brake
    if type_name == "Keyboard":
        return Keyboard
    if type_name == "Recognition":
        return Camera  # a Camera's recognition field: the camera reports the objects
    return SOLID_DEVICE_CLASSES.get(type_name)
