"""The runtime's state of one controller's robot: what a ``Robot`` object is bound to, kept outside it.

Webots' ``Robot`` class keeps almost nothing on the object (its plain attributes ``devices``, ``keyboard``,
``mouse``, ``joystick``), so a controller subclass may use any attribute name (``self._mode``, ``self._sensors``,
``self._devices``...). Here the runtime's state lives in a :class:`RobotLink`: the ``Robot`` holds one
name-mangled reference to it, and devices, keyboards and scene handles are bound to the link, never to the
user's object. The link advances the runtime on ``step`` and samples the enabled sensors and keyboards.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from dualtwin.webots.api_args import as_int
from dualtwin.webots.battery import install as install_batteries
from dualtwin.webots.connector import install as install_connectors
from dualtwin.webots.device_base import Device, DeviceBinding, Sensor, bind_host, sample_due
from dualtwin.webots.devices import SOLID_DEVICE_CLASSES, Brake, Motor, PositionSensor, UnsupportedSensor
from dualtwin.webots.gui_devices import Speaker
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.physics import BrakeRec, DeviceRec, MotorRec, PositionSensorRec, RobotRec, Simulation
from dualtwin.webots.propeller import install as install_propellers
from dualtwin.webots.runtime import ControllerStopped, Runtime, current_runtime
from dualtwin.webots.scene_api import Node
from dualtwin.webots.track import install as install_tracks
from dualtwin.webots.vacuum_gripper import install as install_vacuum_grippers

__all__ = ["RobotLink"]

#: device nodes the twin does not simulate but whose Webots class answers headless (getDevice returns that class)
_HEADLESS_DEVICE_CLASSES: dict[str, type[Device]] = {"Speaker": Speaker}


class RobotLink:
    """One controller's binding to the runtime: simulation, robot record, device objects, enabled sensors.

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
        if runtime.robot_gone(node):
            raise ControllerStopped  # a supervisor removed its robot before this controller made its Robot
        rec = next((r for r in self._sim.robots if r.node is node), None)
        if rec is None:
            raise ValueError("robot_node is not a Robot of this simulation")
        self._rec: RobotRec = rec
        install_propellers(self._sim)  # propeller and track motors become devices of their robot
        install_tracks(self._sim)
        install_connectors(self._sim)  # docking and suction run in the physics even if no controller asks
        install_vacuum_grippers(self._sim)
        # a robot whose battery runs out ends its controller (the runtime's, whichever thread steps)
        install_batteries(self._sim).power_off_listeners[id(runtime)] = runtime.power_off
        self._devices: dict[int, Device] = {}
        self._sensors: dict[int, Sensor] = {}
        #: objects stepped with the robot that are not sensors (keyboards, mice, joysticks)
        self.inputs: list[Any] = []
        #: called with a step's duration (ms) when the controller asks for it, before the simulation runs it (what
        #: the controller library does at wb_robot_step: an Emitter's baud budget)
        self.step_listeners: list[Callable[[float], None]] = []
        self.mode = runtime.mode
        self.pending_step: float | None = None  # stepBegin's duration, run by stepEnd
        self.movie_failed = False
        bind_host(self)
        self.client = runtime.register(self)

    # -- what devices and scene handles need (DeviceHost, SceneHost)

    def getTime(self) -> float:  # noqa: N802 - the DeviceHost protocol
        return self._sim.time

    def getBasicTimeStep(self) -> float:  # noqa: N802
        return self._sim.basic_time_step

    def getFromId(self, id: Any) -> Node | None:  # noqa: A002, N802 - the SceneHost protocol
        wanted = as_int(id, "Supervisor.getFromId")
        if wanted == 0:
            return self.root()
        node = self._runtime.node_ids()[1].get(wanted)
        if node is None or not any(n is node for top in self._sim.world.nodes for n in top.walk()):
            # a deleted node (Node.remove, or a node imported before a simulationReset) keeps its id, which no
            # other node ever takes, but no longer exists: as getFromDef no longer finds it, getFromId does not
            return None
        return Node(self, node)

    def root(self) -> Node:
        root = Node(self, SceneNode("Group", {"children": self._sim.world.nodes}))
        root._is_root = True
        return root

    # -- devices

    def records(self) -> list[Any]:
        return list(self._rec.devices.values())

    def _binding_for(self, key: str | int) -> DeviceBinding | None:
        recs = self.records()
        if isinstance(key, int):
            if not 1 <= key <= len(recs):
                return None
            rec = recs[key - 1]
        else:
            rec = self._rec.devices.get(key)
            if rec is None:
                return None
        return DeviceBinding(self, str(getattr(rec, "name", key)), rec, recs.index(rec) + 1)

    def _device_for(self, rec: Any) -> Device:
        dev = self._devices.get(id(rec))
        if dev is None:
            recs = self.records()
            binding = DeviceBinding(self, str(getattr(rec, "name", "")), rec, recs.index(rec) + 1 if rec in recs else 0)
            if isinstance(rec, MotorRec):
                dev = Motor(binding)
            elif isinstance(rec, PositionSensorRec):
                dev = PositionSensor(binding)
            elif isinstance(rec, BrakeRec):
                dev = Brake(binding)
            elif isinstance(rec, DeviceRec):
                cls = SOLID_DEVICE_CLASSES.get(rec.type_name) or _HEADLESS_DEVICE_CLASSES.get(rec.type_name)
                dev = (cls or UnsupportedSensor)(binding)
                if isinstance(dev, Sensor):
                    dev._invalidate()
            elif hasattr(rec, "api_class"):  # devices simulated by their own module (propeller motors)
                dev = rec.api_class(binding)
            else:
                dev = Device(binding)
            self._devices[id(rec)] = dev
        return dev

    # -- stepping

    def step(self, ms: float) -> int:
        for listener in self.step_listeners:
            listener(ms)
        result = self._runtime.advance(self.client, ms)
        # simulationGetMode() reports the mode of the last step's answer (webots-devices.md §11.2), not a change
        # another supervisor made once its step was answered
        self.mode = self.client.mode
        # sensors were sampled during the step, at the basic steps where they fell due (device_base)
        for item in self.inputs:
            item._after_step(self._sim.time, self._runtime.clock)
        return result

    def _after_reset(self) -> None:
        # Webots resets every sensor's sampling clock (its last update set far in the past): each enabled sensor
        # is due at once, so the step that returns at t = 0 reads the reset state, and the next sample comes one
        # period later. The controller's readings are never NaN again (its library keeps the last values).
        now = self._sim.time
        for sensor in self._sensors.values():
            sensor._enabled_at = now
            sensor._last_sample = None
            sensor._invalidate()
        sample_due(self, now, every=True)
        for item in self.inputs:
            item._after_reset()

    def _release(self) -> None:
        """Its controller was restarted: its sensors and inputs are no longer sampled (the next controller's
        devices start disabled, as a fresh controller's do). Each sensor is disabled, not only forgotten: some
        drive the simulation while enabled (a rotating Lidar turns its head, a bumper TouchSensor watches its
        contacts), which the ended controller's handle must no longer do."""
        for sensor in list(self._sensors.values()):
            sensor.disable()
        self._sensors.clear()
        self.inputs.clear()

    def _controller_ended(self) -> None:
        """Its controller's thread ends (called in that thread): devices let go of what belongs to it."""
        for device in list(self._devices.values()):
            ended = getattr(device, "_controller_ended", None)
            if ended is not None:
                ended()

    def close(self) -> None:
        if self.client.active:
            self._runtime.unregister(self.client)
