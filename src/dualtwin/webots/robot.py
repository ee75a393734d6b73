"""Webots' ``Robot`` class over the headless runtime (timing: docs/reference/webots-on-ode.md §6).

Commands issued before ``step(ms)`` act on the physics of that call; the simulation advances in basic time steps
until ``ms`` elapsed, then sensors due for sampling are read (values reflect the state after the physics step).
``step`` returns -1 once the run's duration is reached; after that, a runtime made with ``stop_after_end`` (the
runner's) stops a controller at its next ``step`` call, as Webots' library exits the controller there.

Like Webots' class, a ``Robot`` carries only Webots' plain attributes (``devices``, ``keyboard``, ``mouse``,
``joystick``) and one name-mangled reference to the runtime's state (:class:`~.robot_link.RobotLink`), so a
controller subclass may set ``self._mode``, ``self._sensors``, ``self.keyboard`` or any other name.

Headless answers where Webots needs its GUI: no robot window (``wwiReceiveText`` is None, ``wwiSendText`` is
dropped), no user input (``waitForUserInputEvent`` returns ``EVENT_NO_EVENT`` at once instead of after
``timeout`` ms of real time), no remote-control or cross-compilation plugin (``setMode`` prints an error and the
robot stays in ``MODE_SIMULATION``). The battery level is :mod:`.battery`'s model.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any, ClassVar

from dualtwin.webots.api_args import as_float, as_int, as_text, error, warn
from dualtwin.webots.battery import battery_sensor
from dualtwin.webots.device_base import Device, bind_host
from dualtwin.webots.joystick import Joystick
from dualtwin.webots.keyboard import Keyboard
from dualtwin.webots.mouse import Mouse
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.physics import Simulation
from dualtwin.webots.robot_link import RobotLink
from dualtwin.webots.runtime import Runtime
from dualtwin.webots.step_hints import advances, step_value

__all__ = ["Robot", "link_of"]


def link_of(robot: Robot) -> RobotLink:
    """The runtime state a Robot is bound to (for the Supervisor and the runner; never a user's attribute)."""
    return robot._Robot__link  # type: ignore[attr-defined,no-any-return]


class _SimulationView:
    """``robot.simulation`` (a dualtwin extension): a non-data descriptor, so a subclass may still assign the name."""

    def __get__(self, robot: Robot | None, owner: type) -> Any:
        return self if robot is None else link_of(robot)._sim


def _deprecated_getter(kind: str) -> Any:
    def getter(self: Robot, name: str) -> Device | None:
        print(f"DEPRECATION: Robot.get{kind} is deprecated, please use Robot.getDevice instead.", file=sys.stderr)
        return self.getDevice(name)

    getter.__name__ = getter.__qualname__ = f"get{kind}"
    getter.__doc__ = f"Deprecated Webots getter: ``getDevice(name)`` plus a DEPRECATION line on stderr ({kind})."
    return getter


class Robot:
    """Webots ``Robot``. ``Robot()`` binds to the runner's robot; keyword-only arguments (a dualtwin extension)
    bind it explicitly.

    Args:
        simulation: the simulation to control; default: the current runtime's.
        robot_node: the Robot node this controller drives; default: the runtime's binding.
        duration: simulated seconds after which ``step`` returns -1 (only with ``simulation``).
        runtime: an explicit shared :class:`Runtime` (for several controllers on one simulation).
    """

    EVENT_QUIT = -1
    EVENT_NO_EVENT = 0
    EVENT_MOUSE_CLICK = 1
    EVENT_MOUSE_MOVE = 2
    EVENT_KEYBOARD = 4
    EVENT_JOYSTICK_BUTTON = 8
    EVENT_JOYSTICK_AXIS = 16
    EVENT_JOYSTICK_POV = 32
    MODE_SIMULATION = 0
    MODE_CROSS_COMPILATION = 1
    MODE_REMOTE_CONTROL = 2

    #: the first Robot of this process (Webots' class attribute)
    created: ClassVar[Robot | None] = None
    #: class attributes a controller process keeps for itself (None there until its first Robot), not this
    #: process's values: see controller_wire.describe_class
    _per_process_attributes: ClassVar[tuple[str, ...]] = ("created",)
    devices: dict[str, Device]
    keyboard: Keyboard
    mouse: Mouse
    joystick: Joystick

    simulation = _SimulationView()

    def __init__(
        self,
        *,
        simulation: Simulation | None = None,
        robot_node: SceneNode | None = None,
        duration: float | None = None,
        runtime: Runtime | None = None,
    ) -> None:
        link = RobotLink(simulation, robot_node, duration, runtime)
        self.__link = link
        if Robot.created is None:
            Robot.created = self
        bind_host(link)
        self.devices = {str(getattr(rec, "name", "")): link._device_for(rec) for rec in link.records()}
        self.keyboard = Keyboard(0)
        self.mouse = Mouse(0)
        self.joystick = Joystick(0)

    def __del__(self) -> None:
        # No contextlib here: at interpreter shutdown module globals may already be None.
        try:  # noqa: SIM105
            self.__link.close()
        except Exception:  # interpreter shutdown: the runtime may already be gone
            pass

    # -- timing

    @advances
    def step(self, time_step: Any = None) -> int:
        """Run the simulation for ``time_step`` ms (default: basicTimeStep); -1 when the run is over."""
        link = self.__link
        ms = link._sim.basic_time_step if time_step is None else as_float(time_step, "Robot.step")
        if not ms >= 0 or math.isinf(ms):
            raise ValueError(f"Robot.step() expects a duration >= 0 ms, got {ms!r}")
        return link.step(ms)

    def stepBegin(self, time_step: Any = None) -> int:
        """First half of ``step``: the commands are sent, the answer is collected by ``stepEnd``."""
        link = self.__link
        ms = link._sim.basic_time_step if time_step is None else as_float(time_step, "Robot.stepBegin")
        if not ms >= 0 or math.isinf(ms):
            raise ValueError(f"Robot.stepBegin() expects a duration >= 0 ms, got {ms!r}")
        link.pending_step = ms
        return -1 if link._runtime.finished else 0

    @advances
    def stepEnd(self) -> int:
        """Second half of ``step``: the simulation runs the duration given to ``stepBegin``; readings arrive."""
        ms = self.__link.pending_step
        self.__link.pending_step = None
        return self.__link.step(self.__link._sim.basic_time_step if ms is None else ms)

    @step_value
    def getBasicTimeStep(self) -> float:
        return self.__link._sim.basic_time_step

    @step_value
    def getTime(self) -> float:
        """The simulated time (s) its last ``step`` returned at (webots-on-ode.md §6: a step returns with the
        values of its end; the controller sees the world only through its steps)."""
        return self.__link.client.time

    def waitForUserInputEvent(self, event_type: Any, timeout: Any) -> int:
        """Headless there is no user input: ``EVENT_NO_EVENT`` at once (Webots waits ``timeout`` ms first)."""
        as_int(event_type, "Robot.waitForUserInputEvent")
        as_int(timeout, "Robot.waitForUserInputEvent")
        return self.EVENT_NO_EVENT

    # -- identity

    def getName(self) -> str:
        return self.__link._rec.name

    def getModel(self) -> str:
        return str(self.__fields().get("model", ""))

    def __fields(self) -> dict[str, Any]:
        """The robot node's fields as the steps executed them: a supervisor's write reaches this controller with the
        step that executes it (webots-on-ode.md §6), whichever request came first in real time."""
        return self.__link._sim.executed_fields(self.__link._rec.node)  # type: ignore[no-any-return]

    def getCustomData(self) -> str:
        """The ``customData`` its last ``step`` answered with, or what it set since: a supervisor's write of the
        field reaches this controller with its next step, not while it computes (webots-on-ode.md §6: a controller
        sees the world through its steps)."""
        return self.__link.client.custom_data

    def setCustomData(self, data: str) -> None:
        link = self.__link
        link.client.custom_data = link._rec.node.fields["customData"] = as_text(data, "Robot.setCustomData")

    def getSupervisor(self) -> bool:
        return self.__link._rec.supervisor

    def getSynchronization(self) -> bool:
        return bool(self.__fields().get("synchronization", True))

    def getProjectPath(self) -> str:
        """The project folder: the parent of the world's ``worlds`` folder."""
        return str(Path(self.getWorldPath()).parent.parent)

    def getWorldPath(self) -> str:
        return str(Path(self.__link._sim.world.path).resolve())

    def getControllerArguments(self) -> list[str]:
        """The robot's ``controllerArgs`` (a dualtwin extension; Webots passes them as ``sys.argv``)."""
        return [str(a) for a in self.__fields().get("controllerArgs", []) or []]

    def getUrdf(self, prefix: str = "") -> str:
        """URDF text of the robot: links for Solids, joints for hinges and sliders (no mass or inertia)."""
        # Imported here: its XML quoting (xml.sax.saxutils) loads urllib.request, http.client and ssl, which a
        # controller that never asks for URDF should not pay for at start-up.
        from dualtwin.webots.urdf import robot_urdf

        return robot_urdf(self.__link._rec.node, self.getName(), str(prefix))

    def getMode(self) -> int:
        return self.MODE_SIMULATION

    def setMode(self, mode: Any, arg: Any) -> None:
        """No remote-control or cross-compilation plugin exists headless: an error, and the mode is unchanged."""
        value = as_int(mode, "Robot.setMode")
        if value != self.MODE_SIMULATION:
            warn(f"Robot.setMode({value}): no remote control plugin available headless; staying in simulation mode")

    # -- robot window (none headless)

    def wwiSendText(self, text: str) -> None:
        """No robot window is open headless: the message is dropped, as Webots drops it without a window."""
        as_text(text, "Robot.wwiSendText")

    def wwiReceiveText(self) -> str | None:
        return None

    # -- battery

    def batterySensorEnable(self, sampling_period: Any) -> None:
        battery_sensor(self.__link).enable(sampling_period)

    def batterySensorDisable(self) -> None:
        battery_sensor(self.__link).disable()

    def batterySensorGetSamplingPeriod(self) -> int:
        return battery_sensor(self.__link).getSamplingPeriod()

    def batterySensorGetValue(self) -> float:
        """The battery's energy (J) at the last sample (:mod:`.battery`); NaN before it or without a battery."""
        sensor = battery_sensor(self.__link)
        sensor._check_enabled("wb_robot_battery_sensor_get_value", "wb_robot_battery_sensor_enable")
        return float(sensor.value)

    # -- devices

    def getDevice(self, name: str) -> Device | None:
        link = self.__link
        rec = link._rec.devices.get(as_text(name, "Robot.getDevice"))
        if rec is None:
            error(f'Device "{name}" was not found on robot "{link._rec.name}".')
            return None
        return link._device_for(rec)

    def getNumberOfDevices(self) -> int:
        return len(self.__link._rec.devices)

    def getDeviceByIndex(self, index: Any) -> Device | None:
        recs = self.__link.records()
        i = as_int(index, "Robot.getDeviceByIndex")
        return self.__link._device_for(recs[i]) if 0 <= i < len(recs) else None

    def getKeyboard(self) -> Keyboard:
        return self.keyboard

    def getMouse(self) -> Mouse:
        return self.mouse

    def getJoystick(self) -> Joystick:
        return self.joystick

    getAccelerometer = _deprecated_getter("Accelerometer")
    getAltimeter = _deprecated_getter("Altimeter")
    getBrake = _deprecated_getter("Brake")
    getCamera = _deprecated_getter("Camera")
    getCompass = _deprecated_getter("Compass")
    getConnector = _deprecated_getter("Connector")
    getDisplay = _deprecated_getter("Display")
    getDistanceSensor = _deprecated_getter("DistanceSensor")
    getEmitter = _deprecated_getter("Emitter")
    getGPS = _deprecated_getter("GPS")
    getGyro = _deprecated_getter("Gyro")
    getInertialUnit = _deprecated_getter("InertialUnit")
    getLED = _deprecated_getter("LED")
    getLidar = _deprecated_getter("Lidar")
    getLightSensor = _deprecated_getter("LightSensor")
    getMotor = _deprecated_getter("Motor")
    getPen = _deprecated_getter("Pen")
    getPositionSensor = _deprecated_getter("PositionSensor")
    getRadar = _deprecated_getter("Radar")
    getRangeFinder = _deprecated_getter("RangeFinder")
    getReceiver = _deprecated_getter("Receiver")
    getSkin = _deprecated_getter("Skin")
    getSpeaker = _deprecated_getter("Speaker")
    getTouchSensor = _deprecated_getter("TouchSensor")

    # -- termination

    def cleanup(self) -> None:
        """Leave the synchronised stepping (the controller is done; a dualtwin extension)."""
        self.__link.close()

    # -- Webots' properties

    basic_time_step = property(lambda self: self.getBasicTimeStep())
    name = property(lambda self: self.getName())
    model = property(lambda self: self.getModel())
    project_path = property(lambda self: self.getProjectPath())
    world_path = property(lambda self: self.getWorldPath())
    supervisor = property(lambda self: self.getSupervisor())
    synchronization = property(lambda self: self.getSynchronization())
    time = property(lambda self: self.getTime())
    number_of_devices = property(lambda self: self.getNumberOfDevices())
    mode = property(lambda self: self.getMode())

    @property
    def custom_data(self) -> str:
        return self.getCustomData()

    @custom_data.setter
    def custom_data(self, data: str) -> None:
        self.setCustomData(data)

    @property
    def battery_sensor_sampling_period(self) -> int:
        return self.batterySensorGetSamplingPeriod()

    @battery_sensor_sampling_period.setter
    def battery_sensor_sampling_period(self, p: Any) -> None:
        self.batterySensorEnable(int(self.getBasicTimeStep()) if p is None else p)
