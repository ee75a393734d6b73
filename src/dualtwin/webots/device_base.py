"""Base classes of controller-side devices: a named device, Webots' sampling protocol, Solid-mounted sensors.

They live apart from :mod:`.controller` so device modules (ranging, touch, radio, display) can build on them
without importing the runtime; :mod:`.controller` re-exports them.
"""

from __future__ import annotations

import math
import sys
import threading
import weakref
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol, TypeVar

from dualtwin.webots import _math3 as m3
from dualtwin.webots.api_args import as_int
from dualtwin.webots.node_types import node_type_of
from dualtwin.webots.physics import DeviceRec, RobotRec, Simulation
from dualtwin.webots.physics.edit_stamps import note_edit, stamps_of, written_since
from dualtwin.webots.step_hints import step_value


class DeviceHost(Protocol):
    """What a device needs of the robot that owns it: its clock, its simulation, its record and its device
    tables. A Protocol, so the device modules never import the robot modules (which import them). The host is
    the runtime's per-controller state (:class:`dualtwin.webots.robot_link.RobotLink`), never the user's
    ``Robot`` object, so a ``Robot`` subclass can use any attribute name."""

    @property
    def _sim(self) -> Simulation: ...

    @property
    def _sensors(self) -> dict[int, Sensor]: ...

    @property
    def _runtime(self) -> Any: ...  # the runtime's node ids (a Camera's recognised objects carry them)

    @property
    def _rec(self) -> RobotRec: ...

    def _device_for(self, rec: Any) -> Device: ...

    def _binding_for(self, key: str | int) -> DeviceBinding | None: ...

    #: objects sampled at each step that are not devices (keyboards, mice, joysticks, motions)
    inputs: list[Any]

    #: called with a step's duration (ms) when the controller asks for it, before the simulation runs it
    step_listeners: list[Callable[[float], None]]

    def getTime(self) -> float: ...  # noqa: N802 - Webots' method name

    def getBasicTimeStep(self) -> float: ...  # noqa: N802 - Webots' method name


__all__ = [
    "Device", "DeviceBinding", "DeviceHost", "SampledDevice", "Sensor", "SolidSensor", "api_property", "bind_host",
    "current_host", "install_sampler", "register_in_world_order", "sample_due", "world_order",
]


def api_property(getter: str | None, setter: str | None = None) -> property:
    """A Webots property (``motor.max_velocity``) that calls its getter and setter *by name*, so a subclass that
    overrides the method (a Track's motor, sensor or brake) serves the property too: ``property(getX)`` would keep
    the base class's function, and every subclass would have to declare its properties again."""
    def fget(self: Any) -> Any:
        return getattr(self, str(getter))()

    def fset(self: Any, value: Any) -> None:
        getattr(self, str(setter))(value)

    # the controller process serves the property as it serves the method of that name (controller_wire._marked)
    fget.__api_method__ = getter  # type: ignore[attr-defined]
    fset.__api_method__ = setter  # type: ignore[attr-defined]
    return property(fget if getter else None, fset if setter else None)


class DeviceBinding(NamedTuple):
    """What the runtime hands a device class instead of Webots' name or tag: the owning host, the device's
    name, its record in the simulation and its tag (1-based index among the robot's devices)."""

    host: DeviceHost
    name: str
    record: Any
    tag: int


_Config = TypeVar("_Config")
_NONE: frozenset[str] = frozenset()

_local = threading.local()
_process_hosts: list[weakref.ref[Any]] = []  # the process's first robot (weakly: tests make many)


def bind_host(host: DeviceHost) -> None:
    """Make ``host`` the robot that ``Motor("name")``-style constructors in this thread refer to (Webots has one
    robot per controller process; threads stand in for processes where several controllers share one)."""
    _local.host = host
    if not _process_hosts or _process_hosts[0]() is None:
        _process_hosts[:] = [weakref.ref(host)]


def current_host() -> DeviceHost:
    host = getattr(_local, "host", None) or (_process_hosts[0]() if _process_hosts else None)
    if host is None:
        raise RuntimeError("no Robot in this controller: create the Robot (or Supervisor) first")
    return host


class Device:
    """Webots ``Device``: a named robot device. ``Cls(name)`` with a device name or tag builds a new handle on
    that device of this controller's robot (as in Webots); the robot's own handles come from ``getDevice``.

    As in Webots, where the controller library keeps a device's state per device, every handle of one device
    shares its state (sampling period, values, queues): a handle built by the user is a new object whose
    attributes are those of the robot's own handle (``_owner``), so enabling one enables the other."""

    _owner: Any  # the robot's own handle on this device (itself for that one), of its class or a base of it
    #: the Webots API class a simulation-specific subclass stands for (a Track's motor is a ``Motor``), so that
    #: ``Motor(name)`` on such a device gives a handle of the subclass
    _webots_class: type[Device] | None = None

    def __init__(self, name: Any) -> None:
        binding: DeviceBinding | None
        if isinstance(name, DeviceBinding):
            binding = name
        else:
            if isinstance(name, bool) or not isinstance(name, (str, int)):
                raise TypeError(f"{type(self).__name__}() expects a device name (str) or tag (int), got {name!r}")
            binding = current_host()._binding_for(name)
            if binding is not None:
                owner = binding.host._device_for(binding.record)
                upgrade = getattr(type(owner), "_webots_class", None) is type(self)
                if isinstance(self, type(owner)) or upgrade:
                    if upgrade:  # Motor("belt") on a Track's motor: a handle of the device's own class
                        self.__class__ = type(owner)
                    self.__dict__ = owner.__dict__  # one device, one state (its _owner stays the robot's handle)
                    return
        if binding is None:
            raise ValueError(f"{type(self).__name__}(): no device {name!r} on this robot")
        self._owner = self
        self._robot: DeviceHost = binding.host
        self._name = binding.name
        self._record = binding.record
        self._tag = binding.tag
        self._setup()

    def _binding(self) -> DeviceBinding:
        """This handle's binding, to build a companion device (a presence sensor) on the same device."""
        return DeviceBinding(self._robot, self._name, self._record, self._tag)

    def _setup(self) -> None:
        """Per-class initialisation from ``self._record`` (device classes override this, not ``__init__``, so
        every class keeps Webots' constructor signature)."""

    def _edit_stamp(self, name: str | None = None) -> int:
        """How many times a supervisor wrote this device's node (its field ``name`` if given), or a reset restored
        it (:mod:`.physics.edit_stamps`). Devices ask at every sample: the table is kept, the ask is a look-up."""
        key: int | None = self.__dict__.get("_stamp_key")
        if key is None:  # (the table and the node's key are kept: the ask is one look-up)
            self._stamps: dict[Any, int] = stamps_of(self._robot._sim)
            key = self._stamp_key = id(self._record.node)
        return self._stamps.get(key if name is None else (key, name), 0)

    def _fields(self) -> dict[str, Any]:
        """The device node's fields as the steps executed them (what :meth:`_configured` builds and
        :meth:`_fields_changed`'s readers read): a supervisor's write reaches the device with the step that
        executes it (webots-on-ode.md §6), also when the device is first read between the write and that step."""
        return self._robot._sim.executed_fields(self._record.node)  # type: ignore[no-any-return]

    def _configured(self, key: str, build: Callable[[], _Config]) -> _Config:
        """What the device derives from its node's fields (``build()``), kept under ``key`` and derived again after
        a supervisor wrote one of them (or a reset restored them): Webots' device ``update*`` slots, which act
        on the device from the next step and configure its controller again."""
        stamp = self._edit_stamp()
        kept = self.__dict__.get(key)
        if kept is None or kept[0] != stamp:
            kept = self.__dict__[key] = (stamp, build())
        return kept[1]  # type: ignore[no-any-return]

    def _own_field(self, name: str, value: Any) -> Any:
        """A setting the controller makes that Webots keeps in the device's field (an Emitter's ``setChannel``
        "modifies the channel field"): written there and counted as a write of it, so that the device reads the field
        again when a ``simulationReset`` restores it (before, the device kept the controller's channel while its field
        read the load's). ``value`` is returned."""
        self._record.node.fields[name] = value
        note_edit(self._robot._sim, self._record.node, name)
        return value

    def _fields_changed(self, names: tuple[str, ...]) -> frozenset[str]:
        """Which of the fields ``names`` a supervisor wrote since this device last read them (all of them at the
        first read), or a reset restored: the fields whose Webots ``update*`` slot runs. A setting the controller
        changed (an Emitter's ``setChannel``) stays until its own field is written."""
        stamp = self._edit_stamp()  # (the table and the node's key, kept)
        seen: dict[Any, int] | None = self.__dict__.get("_fields_seen")
        if seen is None:
            self._fields_seen: dict[Any, int] = {}
            seen = self._fields_seen
        elif seen.get(self._stamp_key) == stamp:  # (the per-sample case, without a call)
            return _NONE
        return written_since(self._stamps, self._record.node, names, seen, never=-1)

    def getName(self) -> str:
        return self._name

    def getModel(self) -> str:
        node = getattr(self._record, "node", None)
        return str(node.fields.get("model", "")) if node is not None else ""

    def getNodeType(self) -> int:
        """Webots' node-type number (compare with ``Node.ROTATIONAL_MOTOR``, ``Node.DISTANCE_SENSOR``...)."""
        node = getattr(self._record, "node", None)
        return node_type_of(node.type_name) if node is not None else 0

    name = property(lambda self: self.getName())
    model = property(lambda self: self.getModel())
    node_type = property(lambda self: self.getNodeType())


class Sensor(Device):
    """Webots ``Sensor``: a device with the enable/sampling-period protocol (``WbSensor``,
    docs/reference/webots-devices.md §0.1).

    ``enable(p)`` at time t₀ makes a sample due at every basic time step where at least ``p`` ms passed since the
    last one (t₀ + p, t₀ + 2p, ... when ``p`` is a multiple of basicTimeStep; a period that is not drifts as in
    Webots). Samples are taken *during* ``Robot.step``, at the end of the basic step where they fall due
    (:func:`install_sampler` registers the simulation hook), so after ``step(k·basicTimeStep)`` a sensor reads
    the state at the last multiple of its period, not the state after the step, and a supervisor edit made
    at a sampling instant shows only in the next sample. Devices that need the state of every basic step
    (a GPS speed, an accelerometer) set ``_tracks_steps`` and get :meth:`_each_step`. Devices sampled
    together (rays) name a ``_batch_sampler(sim, devices)``.

    As in Webots, a sensor built by the user from a name string enables itself (``sampling_period``, or the
    basic time step when None); handles from ``getDevice`` or built from a tag start disabled."""

    _tracks_steps = False
    _batch_sampler: Any = None
    _sampled = False  # a sample reached the controller's cache (see enable)

    def __init__(self, name: Any, sampling_period: Any = None) -> None:
        super().__init__(name)
        if self._owner is not self:  # another handle on a device whose state exists: only a name enables it
            if isinstance(name, str):
                self.enable(int(self._robot.getBasicTimeStep()) if sampling_period is None else sampling_period)
            return
        self._period = 0
        self._last_sample: float | None = None
        self._enabled_at = 0.0
        if isinstance(name, str):
            self._invalidate()
            period = self._robot.getBasicTimeStep() if sampling_period is None else sampling_period
            self.enable(int(period) if sampling_period is None else period)

    def enable(self, p: Any) -> None:
        period = as_int(p, f"{type(self).__name__}.enable")
        if period < 0:  # Webots: an error, and the sensor keeps its period (webots-devices.md §0.2)
            print(f"Error: {type(self).__name__}.enable() called with a negative sampling period ({period}).",
                  file=sys.stderr)
            return
        if period == 0:
            self.disable()
            return
        self._period = period
        self._enabled_at = self._robot.getTime()
        self._last_sample = None
        if not self._sampled:
            # Webots' libController caches the last values it received and enable() does not touch that cache
            # (webots-devices.md §0.2): a sensor re-enabled, or given a new period, reads its last sample until
            # the next one, never NaN again.
            self._invalidate()
        install_sampler(self._robot)
        # sampled once, whichever handle enabled it, and in the robot's device order (Webots' scene-tree order)
        # whatever order the controller enabled them in: noise draws come from the simulation's one generator,
        # so the order decides every value
        register_in_world_order(self._robot._sensors, self._owner)
        if self._tracks_steps:
            self._start_tracking()

    def disable(self) -> None:
        self._period = 0
        self._robot._sensors.pop(id(self._owner), None)

    @step_value
    def getSamplingPeriod(self) -> int:
        return self._period

    def _check_enabled(self, function: str, enable: str | None = None) -> None:
        """Webots' libController when a disabled sensor is read through the C ``function``: an error line on
        stderr naming the ``enable`` function (by default ``function``'s device prefix + ``_enable``); the caller
        still returns its cached value (NaN until the first sample), never raises (webots-devices.md §0.2)."""
        if self._period <= 0:
            enable = enable or function.split("_get_")[0] + "_enable"
            print(f"Error: {function}() called for a disabled device! Please use: {enable}().", file=sys.stderr)

    @property
    def sampling_period(self) -> int:
        return self.getSamplingPeriod()

    @sampling_period.setter
    def sampling_period(self, p: Any) -> None:
        self.enable(0 if p is None else p)

    def _due(self, now: float) -> bool:
        since = self._enabled_at if self._last_sample is None else self._last_sample
        return (now - since) * 1000.0 >= self._period - 1e-6

    def _sample(self, now: float) -> None:
        self._last_sample = now
        self._sampled = True
        self._read()

    def _invalidate(self) -> None:
        raise NotImplementedError

    def _read(self) -> None:
        raise NotImplementedError

    def _start_tracking(self) -> None:
        """Record the state at enable time (the first step's 'previous' state)."""

    def _each_step(self) -> None:
        """Record the state of this basic step (called before any sample of the step)."""


SampledDevice = Sensor  # the name the device modules used before Webots' ``Sensor``


def sample_due(host: DeviceHost, now: float, every: bool = False) -> None:
    """Sample ``host``'s enabled sensors that are due at ``now`` (the end of a basic time step); with ``every``,
    all of them (after a simulation reset)."""
    sensors = list(host._sensors.values())
    for sensor in sensors:
        if sensor._tracks_steps:
            sensor._each_step()
    batches: dict[Any, list[Sensor]] = {}
    for sensor in sensors:
        if not every and not sensor._due(now):
            continue
        if sensor._batch_sampler is None:
            sensor._sample(now)
        else:
            sensor._last_sample = now
            sensor._sampled = True
            batches.setdefault(sensor._batch_sampler, []).append(sensor)
    for sampler, devices in batches.items():
        sampler(host._sim, devices)


_registering = threading.Lock()  # controllers (threads of this process) register robots and devices concurrently


def install_sampler(host: DeviceHost) -> None:
    """Make the simulation sample ``host``'s sensors at the end of every basic step (once per host)."""
    sim = host._sim
    with _registering:
        hosts: list[DeviceHost] | None = sim.extensions.get("sampled_hosts")
        if hosts is None:
            hosts = sim.extensions["sampled_hosts"] = []
            registered = hosts

            def sample_all() -> None:
                now = sim.time
                for h in registered:
                    if h._sensors:
                        sample_due(h, now)

            sim.sample_hooks.append(sample_all)
        if not any(h is host for h in hosts):
            # robots in world order, not in the order their controllers first enabled a sensor: with one process
            # (or thread) per controller that order is a race, and the robots share the noise generator
            hosts[:] = sorted([*hosts, host], key=world_order)


class _Placed(Protocol):
    """Anything bound to one robot of the world (a device host, the runtime's robot of a controller)."""

    @property
    def _rec(self) -> RobotRec: ...


def world_order(host: _Placed) -> int:
    """Where ``host``'s robot comes in the world (its Solid's index in the scene tree): the order in which
    Webots updates robots and their devices, and so the order in which the robots of a world draw noise,
    exchange packets, are sampled and are reset here, however their controllers are scheduled."""
    return host._rec.solid.index


def register_in_world_order(table: dict[int, Any], device: Device) -> None:
    """Add a device handle to a table keyed by ``id``, keeping the table in world order (robot, then device
    tag). The table object stays the same: the simulation's hooks iterate it."""
    with _registering:  # the controllers' threads of this process register their devices concurrently
        table[id(device)] = device
        ordered = sorted(table.items(), key=lambda item: (world_order(item[1]._robot), item[1]._tag))
        table.clear()
        table.update(ordered)


class SolidSensor(Sensor):
    _record: DeviceRec

    def _invalidate(self) -> None:
        self._values: list[float] = [math.nan] * 3

    def _pose(self) -> m3.Pose:
        return self._robot._sim.solid_world_pose(self._record.solid)
