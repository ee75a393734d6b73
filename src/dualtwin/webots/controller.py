"""The subset of Webots' Python controller API used by RL and test controllers, over a :class:`Simulation`.

Timing follows docs/reference/webots-on-ode.md §6: commands issued before ``step(ms)`` act on the physics of that call, the
simulation advances in basic time steps until ``ms`` elapsed, then sensors due for sampling are read
(values reflect the state after the physics step). ``step`` returns -1 once the run's duration is
reached.

Two ways to create the API:

* explicitly on an already built simulation::

      sim = Simulation(load_world(path))
      sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
      while sup.step(32) != -1: ...

* unchanged Webots scripts (``from controller import Supervisor``; ``Supervisor()``) pick the
  module-level *current runtime* installed by :mod:`dualtwin.webots.runner` (or by
  :func:`set_current_runtime`).

Several controllers may share one :class:`Runtime` from different threads: the simulation then advances
only once every registered controller has asked for the next step (Webots' synchronisation).

UNVERIFIED: ``simulationReset()`` takes effect at the next ``step`` call, which then returns at time 0
without advancing the physics; ``Field`` getters return a value set earlier in the same step.

The run's clock (what ``duration_s`` bounds and key scripts refer to) is the simulated time summed across
resets; the step that carries a reset counts its requested duration, as Webots simulates that step before
resetting, so a controller resetting in a loop still reaches the end. After ``step`` returned -1, a runtime
made with ``stop_after_end`` (the runner's) stops a controller at its next ``step`` call, as Webots' library
exits the controller there; a library user's runtime keeps returning -1.

The joint devices and solid-state sensors are in :mod:`dualtwin.webots.devices` (re-exported here under their
Webots API names), the other devices in their own modules.

Numeric arguments go through :mod:`.api_args`: scalars and one-element arrays of any numeric type are taken,
anything else is a ``TypeError`` at the call naming the method.
"""

from __future__ import annotations

import math
from typing import Any

from dualtwin.webots.api_args import as_float, as_int, finite, warn
from dualtwin.webots.battery import install as install_batteries
from dualtwin.webots.camera import Camera
from dualtwin.webots.connector import install as install_connectors
from dualtwin.webots.device_base import Device, SampledDevice
from dualtwin.webots.devices import (
    GPS,
    SOLID_DEVICE_CLASSES,
    Accelerometer,
    Brake,
    Gyro,
    InertialUnit,
    Motor,
    PositionSensor,
    UnsupportedSensor,
)
from dualtwin.webots.display import Display, ImageRef
from dualtwin.webots.keyboard import Keyboard
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.physics import (
    BrakeRec,
    DeviceRec,
    MotorRec,
    PositionSensorRec,
    RobotRec,
    Simulation,
    SimulationUnstable,
)
from dualtwin.webots.propeller import install as install_propellers
from dualtwin.webots.radio import Emitter, Receiver
from dualtwin.webots.ranging import DistanceSensor, Lidar, LidarPoint, RangeFinder
from dualtwin.webots.runtime import (
    SIMULATION_MODE_FAST,
    SIMULATION_MODE_PAUSE,
    SIMULATION_MODE_REAL_TIME,
    ControllerStopped,
    Runtime,
    current_runtime,
    set_current_runtime,
)
from dualtwin.webots.scene_api import ContactPoint, Field, Node, descendants, find_def
from dualtwin.webots.touch import TouchSensor
from dualtwin.webots.track import install as install_tracks
from dualtwin.webots.vacuum_gripper import install as install_vacuum_grippers

__all__ = [
    "Accelerometer",
    "Brake",
    "Camera",
    "ContactPoint",
    "ControllerStopped",
    "Keyboard",
    "Device",
    "Display",
    "DistanceSensor",
    "Emitter",
    "Field",
    "GPS",
    "Gyro",
    "ImageRef",
    "InertialUnit",
    "Lidar",
    "LidarPoint",
    "Motor",
    "Node",
    "PositionSensor",
    "RangeFinder",
    "Receiver",
    "Robot",
    "Runtime",
    "Supervisor",
    "SimulationUnstable",
    "TouchSensor",
    "current_runtime",
    "set_current_runtime",
]


_warn = warn
_finite = finite


# ------------------------------------------------------------------------------------------ robot


class Robot:
    """Webots ``Robot``.

    Args:
        simulation: the simulation to control; default: the current runtime's.
        robot_node: the Robot node this controller drives; default: the runtime's binding.
        duration: simulated seconds after which ``step`` returns -1 (only with ``simulation``).
        runtime: an explicit shared :class:`Runtime` (for several controllers on one simulation).
    """

    def __init__(
        self,
        simulation: Simulation | None = None,
        robot_node: SceneNode | None = None,
        duration: float | None = None,
        runtime: Runtime | None = None,
    ) -> None:
        if runtime is None:
            if simulation is not None:
                runtime = Runtime(simulation, duration, robot_node)
            else:
                runtime = current_runtime()
                if runtime is None:
                    raise RuntimeError(
                        "no Webots-twin runtime: pass simulation=... or run the script through "
                        "dualtwin.webots.runner.run_world"
                    )
        self._runtime = runtime
        self._sim = runtime.simulation
        node = robot_node if robot_node is not None else runtime.robot_node_for_thread()
        rec = next((r for r in self._sim.robots if r.node is node), None)
        if rec is None:
            raise ValueError("robot_node is not a Robot of this simulation")
        self._rec: RobotRec = rec
        install_propellers(self._sim)  # propeller and track motors become devices of their robot
        install_tracks(self._sim)
        install_connectors(self._sim)  # docking and suction run in the physics even if no controller asks
        install_vacuum_grippers(self._sim)
        install_batteries(self._sim)
        self._devices: dict[int, Device] = {}
        self._sensors: dict[int, SampledDevice] = {}
        self._keyboard: Keyboard | None = None
        self._mode = runtime.mode
        self._client = runtime.register(self)

    # -- timing

    def step(self, duration: Any = None) -> int:
        """Run the simulation for ``duration`` ms (default: basicTimeStep); -1 when the run is over."""
        ms = self._sim.basic_time_step if duration is None else as_float(duration, "Robot.step")
        if not ms >= 0 or math.isinf(ms):
            raise ValueError(f"Robot.step() expects a duration >= 0 ms, got {ms!r}")
        result = self._runtime.advance(self._client, ms)
        self._mode = self._runtime.mode  # simulationGetMode() reports the mode at the last step
        # sensors were sampled during the step, at the basic steps where they fell due (device_base)
        if self._keyboard is not None:
            self._keyboard._after_step(self._sim.time, self._runtime.clock)
        return result

    def _after_reset(self) -> None:
        for sensor in self._sensors.values():
            sensor._enabled_at = 0.0
            sensor._last_sample = None
            sensor._invalidate()
        if self._keyboard is not None:
            self._keyboard._after_reset()

    def getKeyboard(self) -> Keyboard:
        """The keyboard (disabled until ``enable``); headless it reads the run's key script, or nothing."""
        if self._keyboard is None:
            self._keyboard = Keyboard(self, self._runtime.keys)
        return self._keyboard

    @property
    def keyboard(self) -> Keyboard:
        return self.getKeyboard()

    def getBasicTimeStep(self) -> float:
        return self._sim.basic_time_step

    @property
    def simulation(self) -> Simulation:
        """The simulation this controller drives (dualtwin extension, not part of the Webots API)."""
        return self._sim

    def getTime(self) -> float:
        return self._sim.time

    # -- identity

    def getName(self) -> str:
        return self._rec.name

    def getModel(self) -> str:
        return str(self._rec.node.fields.get("model", ""))

    def getCustomData(self) -> str:
        return str(self._rec.node.fields.get("customData", ""))

    def setCustomData(self, data: str) -> None:
        self._rec.node.fields["customData"] = str(data)

    def getSupervisor(self) -> bool:
        return self._rec.supervisor

    def getSynchronization(self) -> bool:
        return bool(self._rec.node.fields.get("synchronization", True))

    def getControllerArguments(self) -> list[str]:
        return [str(a) for a in self._rec.node.fields.get("controllerArgs", []) or []]

    # -- devices

    def getDevice(self, name: str) -> Device | None:
        rec = self._rec.devices.get(name)
        if rec is None:
            _warn(f'Device "{name}" was not found on robot "{self._rec.name}".')
            return None
        return self._device_for(rec)

    def getNumberOfDevices(self) -> int:
        return len(self._rec.devices)

    def getDeviceByIndex(self, index: int) -> Device | None:
        recs = list(self._rec.devices.values())
        return self._device_for(recs[index]) if 0 <= index < len(recs) else None

    def _device_for(self, rec: Any) -> Device:
        dev = self._devices.get(id(rec))
        if dev is None:
            if isinstance(rec, MotorRec):
                dev = Motor(self, rec.name, rec)
            elif isinstance(rec, PositionSensorRec):
                dev = PositionSensor(self, rec.name, rec)
            elif isinstance(rec, BrakeRec):
                dev = Brake(self, rec.name, rec)
            elif isinstance(rec, DeviceRec):
                cls = SOLID_DEVICE_CLASSES.get(rec.type_name, UnsupportedSensor)
                dev = cls(self, rec.name, rec)
                if isinstance(dev, SampledDevice):
                    dev._invalidate()
            elif hasattr(rec, "api_class"):  # devices simulated by their own module (propeller motors)
                dev = rec.api_class(self, rec.name, rec)
            else:
                dev = Device(self, str(getattr(rec, "name", "")), rec)
            self._devices[id(rec)] = dev
        return dev

    # -- termination

    def cleanup(self) -> None:
        """Leave the synchronised stepping (the controller is done)."""
        self._runtime.unregister(self._client)

    def __del__(self) -> None:
        try:
            if self._client.active:
                self._runtime.unregister(self._client)
        except Exception:
            pass


class Supervisor(Robot):
    """Webots ``Supervisor``: a Robot with scene-tree access (§6)."""

    SIMULATION_MODE_PAUSE = SIMULATION_MODE_PAUSE
    SIMULATION_MODE_REAL_TIME = SIMULATION_MODE_REAL_TIME
    SIMULATION_MODE_FAST = SIMULATION_MODE_FAST

    def simulationGetMode(self) -> int:
        """The mode at the last ``step`` (Webots caches it there)."""
        return self._mode

    def simulationSetMode(self, mode: Any) -> None:
        """Headless, REAL_TIME and FAST both run as fast as possible; PAUSE ends a run nobody can resume."""
        value = as_int(mode, "Supervisor.simulationSetMode")
        if value not in (SIMULATION_MODE_PAUSE, SIMULATION_MODE_REAL_TIME, SIMULATION_MODE_FAST):
            _warn(f"Supervisor.simulationSetMode(): unknown mode {value}; ignored")
            return
        self._runtime.mode = value

    def getFromId(self, id: Any) -> Node | None:  # noqa: A002 - Webots' parameter name
        """The node with this unique id (see :meth:`Node.getId`), or None."""
        wanted = as_int(id, "Supervisor.getFromId")
        if wanted == 0:
            return self.getRoot()
        node = self._runtime.node_ids()[1].get(wanted)
        return Node(self, node) if node is not None else None

    def getRoot(self) -> Node:
        root = Node(self, SceneNode("Group", {"children": list(self._sim.world.nodes)}))
        root._is_root = True
        return root

    def getSelf(self) -> Node:
        return Node(self, self._rec.node)

    def getFromDef(self, name: str) -> Node | None:
        """Node by DEF name; ``"A.B"`` scopes B inside A; PROTO internals are not searched."""
        scope: list[SceneNode] = list(self._sim.world.nodes)
        found: SceneNode | None = None
        for part in name.split("."):
            found = None
            for top in scope:
                found = find_def(top, part)
                if found is not None:
                    break
            if found is None:
                return None
            scope = descendants(found)
        return Node(self, found) if found is not None else None

    def simulationReset(self) -> None:
        """Restore the load state at the next ``step`` (controllers keep running)."""
        self._runtime.request_reset()

    def simulationResetPhysics(self) -> None:
        self._sim.reset_physics()

    def simulationQuit(self, status: Any) -> None:
        code = as_int(status, "Supervisor.simulationQuit")
        self._runtime.finished = True
        self._runtime.exit_status = code
