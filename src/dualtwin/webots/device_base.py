"""Base classes of controller-side devices: a named device, Webots' sampling protocol, Solid-mounted sensors.

They live apart from :mod:`.controller` so device modules (ranging, touch, radio, display) can build on them
without importing the runtime; :mod:`.controller` re-exports them.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from dualtwin.webots import _math3 as m3
from dualtwin.webots.api_args import as_int
from dualtwin.webots.physics import DeviceRec, RobotRec, Simulation


class DeviceHost(Protocol):
    """What a device needs of the ``Robot`` that owns it: its clock, its simulation, its record and its
    device tables. A Protocol, so the device modules never import :mod:`.controller` (which imports them)."""

    @property
    def _sim(self) -> Simulation: ...

    @property
    def _sensors(self) -> dict[int, SampledDevice]: ...

    @property
    def _rec(self) -> RobotRec: ...

    def _device_for(self, rec: Any) -> Device: ...

    def getTime(self) -> float: ...  # noqa: N802 - Webots' method name


__all__ = ["Device", "DeviceHost", "SampledDevice", "SolidSensor"]


class Device:
    """A named robot device."""

    def __init__(self, robot: DeviceHost, name: str, record: Any) -> None:
        self._robot = robot
        self._name = name
        self._record = record

    def getName(self) -> str:
        return self._name

    def getModel(self) -> str:
        node = getattr(self._record, "node", None)
        return str(node.fields.get("model", "")) if node is not None else ""

    def getNodeType(self) -> str:
        node = getattr(self._record, "node", None)
        return node.type_name if node is not None else ""


class SampledDevice(Device):
    """A sensor with Webots' enable/sampling-period protocol (docs/reference/webots-on-ode.md §5.4)."""

    def __init__(self, robot: DeviceHost, name: str, record: Any) -> None:
        super().__init__(robot, name, record)
        self._period = 0
        self._last_sample: float | None = None
        self._enabled_at = 0.0

    def enable(self, samplingPeriod: Any) -> None:
        period = as_int(samplingPeriod, f"{type(self).__name__}.enable")
        if period <= 0:
            self.disable()
            return
        self._period = period
        self._enabled_at = self._robot.getTime()
        self._last_sample = None
        self._invalidate()
        self._robot._sensors[id(self)] = self

    def disable(self) -> None:
        self._period = 0
        self._robot._sensors.pop(id(self), None)

    def getSamplingPeriod(self) -> int:
        return self._period

    def _due(self, now: float) -> bool:
        since = self._enabled_at if self._last_sample is None else self._last_sample
        return (now - since) * 1000.0 >= self._period - 1e-6

    def _sample(self, now: float) -> None:
        self._last_sample = now
        self._read()

    def _invalidate(self) -> None:
        raise NotImplementedError

    def _read(self) -> None:
        raise NotImplementedError


class SolidSensor(SampledDevice):
    _record: DeviceRec

    def _invalidate(self) -> None:
        self._values: list[float] = [math.nan] * 3

    def _pose(self) -> m3.Pose:
        return self._robot._sim.solid_world_pose(self._record.solid)


class KinematicMotor(Device):
    """Webots' Motor API for a motor that drives a kinematic state (a propeller's spin, a track's belt) instead
    of an ODE joint row. The state (``_state()``) holds ``multiplier``, ``max_velocity``, ``target_position``,
    ``target_velocity`` and ``acceleration``; velocities are multiplied and clipped as Webots clips them."""

    def _state(self) -> Any:
        return self._record

    def setVelocity(self, velocity: Any) -> None:
        from dualtwin.webots.api_args import as_float, finite, warn

        state = self._state()
        v = as_float(velocity, "Motor.setVelocity")
        if not finite(v):
            return
        v *= state.multiplier
        if abs(v) > state.max_velocity:
            warn(f"'{self._name}': requested velocity {v} exceeds maxVelocity {state.max_velocity}")
            v = math.copysign(state.max_velocity, v)
        state.target_velocity = v

    def setAcceleration(self, acceleration: Any) -> None:
        from dualtwin.webots.api_args import as_float, finite

        a = as_float(acceleration, "Motor.setAcceleration")
        if finite(a):
            self._state().acceleration = a

    def getTargetPosition(self) -> float:
        return float(self._state().target_position)

    def getVelocity(self) -> float:
        return float(self._state().target_velocity)

    def getMaxVelocity(self) -> float:
        return float(self._state().max_velocity)

    def getAcceleration(self) -> float:
        return float(self._state().acceleration)

    def getMultiplier(self) -> float:
        return float(self._state().multiplier)
