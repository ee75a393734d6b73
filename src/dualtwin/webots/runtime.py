"""The stepping of one :class:`Simulation` for one or more controllers (Webots' synchronisation).

Timing follows docs/reference/webots-on-ode.md §6: commands issued before ``step(ms)`` act on the physics of that
call, the simulation advances in basic time steps until ``ms`` elapsed, then sensors due for sampling are read.
Several controllers may share one :class:`Runtime`: the simulation then advances only once every registered
controller whose robot's ``synchronization`` is TRUE has asked for the next step (§1.6 step 1). Moved out of
:mod:`dualtwin.webots.controller`, which keeps the ``Robot``/``Supervisor`` classes and re-exports these names.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

from dualtwin.webots.api_args import warn
from dualtwin.webots.device_base import world_order
from dualtwin.webots.keyboard import KeyScript
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.physics import RobotRec, Simulation
from dualtwin.webots.scene_api import descendants

__all__ = [
    "NO_CONTROLLER",
    "SIMULATION_MODE_FAST",
    "SIMULATION_MODE_PAUSE",
    "SIMULATION_MODE_REAL_TIME",
    "Controller",
    "ControllerStopped",
    "Runtime",
    "RuntimeRobot",
    "current_runtime",
    "set_current_runtime",
]

_warn = warn

#: Real seconds a restart waits for a controller of the same robot that is still starting (a process takes tens of
#: milliseconds to come up), so that it can end it; then it goes on without.
START_WAIT_S = 10.0

#: ``controller`` field values that start no controller (C controllers aside, as Webots: none, extern, generic).
NO_CONTROLLER = frozenset({"", "<none>", "<generic>", "<extern>", "void"})


class RuntimeRobot(Protocol):
    """What the runtime needs of a controller's Robot (typed structurally so this module needs no Robot)."""

    @property
    def _rec(self) -> RobotRec: ...  # its robot (device_base.world_order: its place in the world)

    def _after_reset(self) -> None: ...

    def _release(self) -> None: ...

    def _controller_ended(self) -> None: ...


# ------------------------------------------------------------------------------------------ runtime


SIMULATION_MODE_PAUSE = 0
SIMULATION_MODE_REAL_TIME = 1
SIMULATION_MODE_FAST = 2


class ControllerStopped(SystemExit):
    """Raised in a controller that calls ``step`` again after it returned -1: Webots ends it there."""

    def __init__(self) -> None:
        super().__init__(0)


def _custom_data(robot: RuntimeRobot) -> str:
    return str(robot._rec.node.fields.get("customData", ""))


class _Client:
    __slots__ = ("robot", "target", "waiting", "active", "ended_at", "thread", "controller", "running", "cut",
                 "synced", "time", "outcome", "mode", "custom_data")

    def __init__(self, robot: RuntimeRobot, controller: Controller | None) -> None:
        self.robot = robot
        self.target = 0.0
        self.waiting = False
        self.active = True
        self.ended_at: float | None = None  # monotonic wall time at which step() returned -1
        self.thread = threading.get_ident()
        self.controller = controller
        self.running = True  # its controller has not ended (its thread id may be reused once it has)
        self.cut = False  # ended by a supervisor while it waited in a step that had not reached its end
        #: its robot's ``synchronization`` field: the simulation waits for its step only if True (§1.6 step 1)
        self.synced = bool(robot._rec.node.fields.get("synchronization", True))
        #: the simulated time its last step answered with (what its getTime reads) and that step's value: both
        #: fixed when the simulation answers it (Runtime._answer), however late its thread then wakes
        self.time = 0.0
        self.outcome = 0
        self.mode = SIMULATION_MODE_FAST  # the simulation mode at that answer (what simulationGetMode reads)
        #: its robot's ``customData`` at that answer (what getCustomData reads until its next step, unless it sets
        #: it itself): Webots' libController keeps the string it last got; a supervisor's write of the field reaches
        #: the robot with the answer of the step it was applied in (WbRobot::updateData -> C_ROBOT_DATA)
        self.custom_data = _custom_data(robot)


class Controller:
    """One controller taking part in the synchronisation (a runner's thread, or a controller process's
    serving thread). An object, not a thread id: ids of ended threads are reused by new ones, which made the
    start-up barrier count two controllers as one and wait forever (issue 26.3)."""

    __slots__ = ("robot_node", "arrived", "clients", "removed", "in_step", "progress")

    def __init__(self, robot_node: SceneNode | None) -> None:
        self.robot_node = robot_node
        self.arrived = False
        self.clients: list[_Client] = []
        #: a supervisor removed its robot or restarted its controller: its next (or current) step returns -1
        self.removed = False
        #: for the threads runner's step timeout: whether it waits in a step (then the others hold it, not its own
        #: script), and the wall time (time.monotonic) of its last sign of progress: its start, its Robot made, a
        #: step returned
        self.in_step = False
        self.progress = time.monotonic()


class Runtime:
    """Owns the stepping of one :class:`Simulation` for one or more controllers.

    Args:
        simulation: the simulation to drive.
        duration_s: simulated seconds after which ``step`` returns -1 (``None``: unlimited), counted
            across ``simulationReset``.
        robot_node: the robot a no-argument ``Robot()``/``Supervisor()`` binds to (default: first robot).
        keys: scripted key presses for ``Keyboard`` (``None``: no key is ever pressed).
        stop_after_end: a ``step`` call after -1 raises :class:`ControllerStopped` (the runner's choice).
    """

    def __init__(
        self,
        simulation: Simulation,
        duration_s: float | None = None,
        robot_node: SceneNode | None = None,
        *,
        keys: KeyScript | None = None,
        stop_after_end: bool = False,
    ) -> None:
        self.simulation = simulation
        self.duration_s = duration_s
        self.keys = keys
        self.stop_after_end = stop_after_end
        self.elapsed_before_reset = 0.0
        self._mode = SIMULATION_MODE_FAST
        self._pace: tuple[float, float] | None = None  # (wall, clock) at which REAL_TIME pacing started
        self._said_real_time = False
        #: called (under the lock) when every controller waits, just before the simulation advances
        self.sync_hook: Callable[[], None] | None = None
        #: True while the simulation advances (output then belongs to no controller)
        self.advancing = False
        self._node_ids: dict[int, int] | None = None
        self._id_nodes: dict[int, SceneNode] = {}
        self.default_robot_node = robot_node
        self._cond = threading.Condition()
        self._clients: list[_Client] = []
        self._reset_requested = False
        self._reset_by: _Client | None = None
        self._reset_at: float | None = None  # a reset was asked for at this step's end (run clock, s)
        self.finished = False
        self._thread_controller = threading.local()
        self.error: BaseException | None = None
        self.exit_status: int | None = None
        #: a world a supervisor asked to load (worldLoad/worldReload); the runner runs it after this one ends
        self.world_request: Path | None = None
        # start-up barrier: stepping waits until every expected controller has registered a Robot or
        # ended, so all controllers start at t = 0 like in Webots
        self._expected = 0
        self._controllers: list[Controller] = []
        #: starts the controller of a Robot from its ``controller`` field, for a Robot a supervisor imported or
        #: whose controller it restarts (set by the runner; None: nothing starts, a warning says so)
        self.controller_starter: Callable[[SceneNode], None] | None = None
        #: (robot, restart) a supervisor asked for since the last step: started when it next steps (or ends)
        self._to_start: list[tuple[SceneNode, bool]] = []
        #: robot node id -> (run clock, controller) of its controller's last start on request (see _start_requested)
        self._started_at: dict[int, tuple[float, str]] = {}
        #: robot node id -> controllers started for it during the run that have not yet taken part (bind_thread)
        self._starting: dict[int, int] = {}
        self._gone_nodes: dict[int, SceneNode] = {}  # removed robots' subtrees (kept, so their ids stay theirs)
        # the simulation executes the supervisors' queued writes of a step in their scene-tree order (§6)
        simulation.extensions["request_order"] = self._request_order

    @property
    def mode(self) -> int:
        return self._mode

    @mode.setter
    def mode(self, value: int) -> None:
        with self._cond:
            if value == SIMULATION_MODE_REAL_TIME and self._mode != SIMULATION_MODE_REAL_TIME:
                self._pace = (time.monotonic(), self.clock)
                if not self._said_real_time:
                    self._said_real_time = True
                    _warn("real-time mode: the run is paced to the wall clock (headless, nothing is drawn)")
            elif value != SIMULATION_MODE_REAL_TIME:
                self._pace = None
            self._mode = value

    def expect(self, n: int) -> None:
        """Hold the first step until ``n`` controllers (see :meth:`bind_thread`) registered a Robot or ended."""
        self._expected = n

    def expect_another(self, robot_node: SceneNode | None = None) -> None:
        """One more controller joins the run (a Robot imported at run time, a restarted controller): the next step
        waits for it too. ``robot_node``: its robot, whose restart then waits for it to take part (see
        :meth:`_start_requested`) before it can end it."""
        with self._cond:
            self._expected = max(self._expected, len(self._controllers)) + 1
            if robot_node is not None:
                self._starting[id(robot_node)] = self._starting.get(id(robot_node), 0) + 1

    def robot_gone(self, robot_node: SceneNode) -> bool:
        """Whether a supervisor removed this robot during the run."""
        return id(robot_node) in self._gone_nodes

    def waits_for(self, robot_node: SceneNode) -> bool:
        """Whether the simulation waits for the steps of this robot's controller: its ``synchronization`` is TRUE,
        or no synchronized controller is left to drive the simulation (see :meth:`_maybe_advance`). The flag is the
        one :meth:`_maybe_advance` goes by, read when the controller made its Robot (:class:`_Client`), not the
        field now: a supervisor's later write must not tell the step timeout otherwise than the synchronisation
        (it would never stop a controller the simulation still waits for, or stop one nothing waits for)."""
        # read without the lock, which the physics holds while it runs: the watching thread asks every few
        # hundredths of a second and must not wait for a long step (a stale answer is corrected at the next ask)
        clients = list(self._clients)
        own = [c for c in clients if c.robot._rec.node is robot_node]
        # (before its controller made its Robot, the field is what the flag will be read from)
        synced = own[-1].synced if own else bool(robot_node.fields.get("synchronization", True))
        return synced or not any(c.active and c.synced for c in clients)

    def claim_start(self, robot_node: SceneNode) -> bool:
        """Whether the controller of an imported robot (see :meth:`expect_another`) may start now: False if its
        robot was removed before, and then the run no longer waits for it."""
        with self._cond:
            if id(robot_node) not in self._gone_nodes:
                return True
            self._started(robot_node)
            self._expected -= 1
            self._maybe_advance()
            self._cond.notify_all()
            return False

    def start_controllers(self, robots: list[SceneNode]) -> None:
        """Robots a supervisor imported: each starts its controller, which steps with the others from the next
        step, as Webots starts an imported robot's controller. Like every supervisor request, it is carried out
        when the supervisor next steps (or ends): a robot it removes before that never runs."""
        with self._cond:
            self._to_start.extend((node, False) for node in robots)

    def restart_controller(self, robot_node: SceneNode) -> None:
        """``Node.restartController()`` or a new ``controller`` field: when the supervisor next steps (or ends),
        the robot's controller is ended (its step returns -1, then it ends as after any -1) and the one its
        ``controller`` field names now starts, stepping with the others from that step; time goes on."""
        with self._cond:
            self._to_start.append((robot_node, True))

    def _start_requested(self) -> None:
        """Carry out the imports' starts and the restarts requested since the last step (called by any controller
        as it steps or ends, so before the simulation can advance). All of it under the condition: the
        simulation cannot advance between a restarted controller's end and its successor's start. A robot asked
        for twice in one step starts one controller, also when the requests come from two supervisors, each
        carried out as its author steps."""
        if not self._to_start:  # the common case, read without the lock (a request comes before its step)
            return
        with self._cond:
            if not self._to_start:
                return
            requested, self._to_start = self._to_start, []
            robots: dict[int, tuple[SceneNode, bool]] = {}
            for node, restart in requested:
                previous = robots.get(id(node))
                robots[id(node)] = (node, restart or (previous is not None and previous[1]))
            for node, restart in robots.values():
                if self.robot_gone(node) or self.finished:
                    continue
                name = str(node.fields.get("controller", ""))
                if restart and self._started_at.get(id(node)) == (self.clock, name):
                    # this controller was already started for this step, at another supervisor's request: each
                    # robot has one controller, and the one just started has not run yet (two controllers ran
                    # side by side when the first was still starting in its process)
                    continue
                self._started_at[id(node)] = (self.clock, name)
                if self.controller_starter is None:
                    what = "restarted" if restart else "started"
                    _warn(f"the controller of robot '{node.fields.get('name', 'robot')}' is not {what}: only a "
                          f"runner (dualtwin webots run, run_world) starts controllers ('{name}')")
                    continue
                if restart:
                    self._wait_started(node)
                    self._end_controllers_of({id(node)}, gone=False, advance=False)
                if name not in NO_CONTROLLER:
                    self.controller_starter(node)  # the runtime expects it before this returns
            self._maybe_advance()
            self._cond.notify_all()

    def end_controllers(self, top: SceneNode, *, advance: bool = True) -> None:
        """A supervisor removed ``top``: the controllers of the robots in it are told -1 at their step (now if
        they wait in it) and leave the synchronisation, as Webots ends a deleted robot's controller. Not
        ``advance``: called during a physics step (a self-removal at the step's end), nothing else is stepped."""
        nodes = {id(n): n for n in top.walk()}
        with self._cond:
            self._gone_nodes.update(nodes)  # a controller not started yet never starts
            self._end_controllers_of(set(nodes), gone=True, advance=advance)

    def power_off(self, robot_node: SceneNode) -> None:
        """``robot_node``'s battery ran out (called by the battery hook during a physics step): its controller's
        step returns -1 and it leaves the synchronisation, as Webots terminates that controller. Robots nested in
        it keep theirs (each robot has its own battery)."""
        with self._cond:
            self._end_controllers_of({id(robot_node)}, gone=True, advance=False)
            for client in self._clients:  # a Robot made by a script using the API directly (no controller)
                if client.controller is None and client.active and client.robot._rec.node is robot_node:
                    client.active = False
                    client.cut = client.waiting
                    self._answer(client)

    def _end_controllers_of(self, robots: set[int], *, gone: bool, advance: bool = True) -> None:
        """Tell the controllers of these robot nodes -1 at their step and take them out of the synchronisation;
        a restart (``gone`` False) also stops their sensors, so the next controller finds none enabled."""
        with self._cond:
            for controller in self._controllers:
                if controller.robot_node is None or id(controller.robot_node) not in robots or controller.removed:
                    continue
                controller.removed = True
                controller.arrived = True  # the start-up barrier no longer waits for it
                for client in controller.clients:
                    client.active = False
                    client.cut = client.waiting
                    self._answer(client)
                    if not gone:
                        client.robot._release()
            if advance:
                self._maybe_advance()
                self._cond.notify_all()

    def _end_orphans(self) -> None:
        """End the controllers whose robot is no longer in the scene tree (caller holds the condition)."""
        present: set[int] = set()
        for top in self.simulation.world.nodes:
            present.update(id(n) for n in top.walk())
        for controller in self._controllers:
            node = controller.robot_node
            if node is not None and id(node) not in present and not controller.removed:
                self.end_controllers(node)

    def thread_done(self) -> None:
        """The calling thread's controller ended: release its Robots from the synchronisation."""
        self._start_requested()  # what it asked for in its last step
        ended: list[RuntimeRobot] = []
        with self._cond:
            controller = getattr(self._thread_controller, "controller", None)
            if controller is not None:
                ended = [client.robot for client in controller.clients]
                controller.arrived = True
                for client in controller.clients:
                    client.active = False
                    client.waiting = False
                    client.running = False
                controller.clients = []
                self._thread_controller.controller = None
            self._maybe_advance()
            self._cond.notify_all()
        for robot in ended:  # in this thread, which its devices' thread-bound resources belong to
            robot._controller_ended()

    def finish(self) -> None:
        """End the run: every controller's ``step`` returns -1 (now if it waits, else at its next call)."""
        with self._cond:
            self.finished = True
            for c in self._clients:
                self._answer(c)
            self._cond.notify_all()

    # -- robot binding for argument-less constructors

    def bind_thread(self, robot_node: SceneNode) -> Controller:
        """Make the calling thread one controller, whose ``Robot()`` refers to ``robot_node``."""
        controller = Controller(robot_node)
        with self._cond:
            if id(robot_node) in self._gone_nodes:  # its robot was removed before its process started
                controller.removed = controller.arrived = True
            self._controllers.append(controller)
            self._started(robot_node)
        self._thread_controller.controller = controller
        return controller

    def _wait_started(self, robot_node: SceneNode) -> None:
        """Wait until the controllers started for ``robot_node`` at earlier requests take part (caller holds the
        condition): one still starting (its process not yet up) must be ended by a restart too, and it takes part
        within moments."""
        key = id(robot_node)
        self._cond.wait_for(lambda: not self._starting.get(key), timeout=START_WAIT_S)

    def _started(self, robot_node: SceneNode) -> None:
        """A controller counted by :meth:`expect_another` for ``robot_node`` took part (or never will: its robot is
        gone); caller holds the condition."""
        count = self._starting.get(id(robot_node), 0)
        if count:
            self._starting[id(robot_node)] = count - 1
            self._cond.notify_all()

    def _request_order(self) -> int:
        """The scene-tree place (robot Solid index) of the robot whose controller runs in the calling thread; 0 for
        a thread bound to no controller (a script using the API directly)."""
        controller = getattr(self._thread_controller, "controller", None)
        node = controller.robot_node if controller is not None else None
        solid = self.simulation.solid_for(node) if node is not None else None
        return solid.index if solid is not None else 0

    def robot_node_for_thread(self) -> SceneNode:
        controller = getattr(self._thread_controller, "controller", None)
        node = (controller.robot_node if controller is not None else None) or self.default_robot_node
        if node is None:
            if not self.simulation.robots:
                raise RuntimeError("the world has no Robot node")
            node = self.simulation.robots[0].node
        return node

    def register(self, robot: RuntimeRobot) -> _Client:
        with self._cond:
            controller = getattr(self._thread_controller, "controller", None)
            client = _Client(robot, controller)
            client.target = client.time = self.simulation.time
            client.mode = self._mode
            if controller is not None and controller.removed:
                client.active = False  # its robot was removed before it made its Robot: its step returns -1
            self._clients.append(client)
            if controller is not None:
                # its sign of progress before it counts as arrived: the step timeout's watch, which reads both without
                # the lock, must never see it arrived with the time of its start (its imports may have taken longer
                # than the timeout, which holds from its Robot on)
                controller.progress = time.monotonic()
                controller.arrived = True
                controller.clients.append(client)
                # the start-up barrier may open now: the others' first steps must not wait for this one's first
                # step as well, which a robot whose synchronization is FALSE may take any time to make
                self._maybe_advance()
                self._cond.notify_all()
            return client

    def unregister(self, client: _Client) -> None:
        with self._cond:
            client.active = False
            client.waiting = False
            self._maybe_advance()
            self._cond.notify_all()

    def request_reset(self, client: _Client | None = None) -> None:
        """Reset the simulation at ``client``'s next step (as Webots carries a supervisor's request with its step
        message); None: at the next step of any controller."""
        self._reset_requested = True
        self._reset_by = client

    @property
    def clock(self) -> float:
        """Simulated seconds since the run started, across resets (what ``duration_s`` bounds)."""
        return self.elapsed_before_reset + self.simulation.time

    def _limit_reached(self) -> bool:
        return self.duration_s is not None and self.clock >= self.duration_s - 1e-9

    def _end(self, client: _Client) -> int:
        self.finished = True
        if client.ended_at is None:
            client.ended_at = time.monotonic()
        return -1

    @staticmethod
    def _removed(client: _Client) -> bool:
        return client.controller is not None and client.controller.removed

    @staticmethod
    def _end_removed(client: _Client) -> int:
        # only this controller ends; the run goes on (a second step then ends it, as after any -1)
        client.ended_at = time.monotonic()
        return -1

    def ended_clients(self) -> list[tuple[int, float]]:
        """(thread id, wall time of the -1) of controllers that were told the run is over (or that their robot
        was removed or their controller restarted)."""
        with self._cond:
            return [(c.thread, c.ended_at) for c in self._clients if c.ended_at is not None and c.running]

    def node_ids(self) -> tuple[dict[int, int], dict[int, SceneNode]]:
        """Webots-style unique ids: the root is 0, then every node of the scene tree in pre-order."""
        if self._node_ids is None:
            ids: dict[int, int] = {}
            nodes: dict[int, SceneNode] = {}
            stack = list(reversed(self.simulation.world.nodes))
            while stack:
                node = stack.pop()
                if id(node) in ids:
                    continue  # a USE'd node is one node, as in Webots
                ids[id(node)] = len(ids) + 1
                nodes[ids[id(node)]] = node
                stack.extend(reversed(descendants(node)))
            self._node_ids, self._id_nodes = ids, nodes
        return self._node_ids, self._id_nodes

    def advance(self, client: _Client, duration_ms: float) -> int:
        """Advance the shared simulation by ``duration_ms`` for ``client`` (blocking until done)."""
        controller = client.controller
        if controller is None:
            return self._advance(client, duration_ms)
        controller.in_step = True
        try:
            return self._advance(client, duration_ms)
        finally:
            # the time of its return before it leaves the step: the step timeout's watch, which reads both without
            # the lock, must never see it out of a step that lasted longer than the timeout with that step's start
            controller.progress = time.monotonic()
            controller.in_step = False

    def _advance(self, client: _Client, duration_ms: float) -> int:
        sim = self.simulation
        self._start_requested()  # a supervisor's imports and restarts act on this step
        with self._cond:
            if client.ended_at is not None:
                if self.stop_after_end:
                    raise ControllerStopped()
                return -1
            if not client.active:
                # it left the stepping (Robot.cleanup): nothing would ever advance it again, so say the end at once
                # rather than wait forever (Webots allows no API call after wb_robot_cleanup)
                return -1
            if self._removed(client):
                return self._end_removed(client)
            if self.finished or self._limit_reached():
                return self._end(client)
            if self.mode == SIMULATION_MODE_PAUSE and duration_ms == 0:
                client.time, client.mode = sim.time, self._mode
                return 0  # step(0) exchanges commands without time passing, even paused
            n = max(1, math.ceil(duration_ms / sim.basic_time_step - 1e-9))
            by = self._reset_by
            client.target = sim.time + n * sim.basic_time_step / 1000.0
            if self._reset_requested and (by is None or by is client or not by.active):
                # Webots applies the request at the end of the step that carries it, once every controller has
                # sent its own step: that step counts in the run's clock, then the world is reset and every
                # controller's step returns at t = 0 (_maybe_advance), however the controllers were scheduled
                self._reset_requested = False
                self._reset_at = client.target
            client.waiting = True
            self._maybe_advance()
            while client.waiting and not self.finished and self.error is None:
                self._cond.wait()
            if self.error is not None:
                err, self.error = self.error, None
                raise err
            self._answer(client)  # (the run ended while it waited)
            if client.cut:  # (a step that reached its end before the supervisor's request still counts)
                return self._end_removed(client)
            return self._end(client) if client.outcome == -1 else 0

    def _answer(self, client: _Client) -> None:
        """Release ``client`` from the step it waits in (caller holds the condition). Its controller reads the
        time (and simulation mode) of this answer until its next step, as a Webots controller reads the time its
        last step message brought: once nothing waits for it (its robot removed, its controller restarted, its
        synchronization FALSE) the simulation goes on while it runs, and reading the live clock gave a time its
        step never reached, which varied with the scheduling (and a step answered 0 said -1 if its thread woke
        late)."""
        if client.waiting:
            client.time, client.mode = self.simulation.time, self._mode
            client.custom_data = _custom_data(client.robot)
            # the step that reaches the run's end says -1; one answered before stays 0 even if its thread wakes
            # only once the run is over (nothing waits for a removed robot's controller: the others run on)
            client.outcome = -1 if self.finished or self._limit_reached() else 0
        client.waiting = False

    def _reset_now(self, waiting: list[_Client]) -> None:
        """The requested simulationReset, every active controller waiting in its step (caller holds the
        condition): the world goes back to its saved state and every waiting step returns at t = 0."""
        assert self._reset_at is not None
        self.elapsed_before_reset += self._reset_at
        self._reset_at = None
        self.simulation.reset()
        # robots in world order (their sensors draw noise from one generator), not in the order the controllers
        # happened to start
        for c in sorted(self._clients, key=lambda c: world_order(c.robot)):
            c.target = 0.0
            c.robot._after_reset()
        for c in waiting:
            self._answer(c)
        self._end_orphans()  # the reset took the robots a supervisor imported out of the scene
        for c in waiting:
            c.cut = c.cut or self._removed(c)  # their step says -1
        self._cond.notify_all()

    def _maybe_advance(self) -> None:
        # caller holds the condition; steps when every active synchronized controller is waiting (synchronisation)
        if sum(c.arrived for c in self._controllers) < self._expected:
            return
        active = [c for c in self._clients if c.active]
        # Webots waits for the robots whose synchronization is TRUE (webots-on-ode.md §1.6 step 1): one with FALSE
        # does not hold the others, and its step returns once the time it asked for has passed. With no
        # synchronized controller left, the others' steps drive the simulation (headless, nothing else runs it)
        driving = [c for c in active if c.synced] or active
        if not driving or not all(c.waiting for c in driving):
            return
        waiting = [c for c in active if c.waiting]
        if self.mode == SIMULATION_MODE_PAUSE:
            # every controller waits for time to pass and headless nobody presses play: the run is over
            _warn("a controller paused the simulation and, headless, nothing can resume it: the run ends")
            self.finished = True
            for c in waiting:
                self._answer(c)
            self._cond.notify_all()
            return
        sim = self.simulation
        if self._reset_at is not None and (sim.time >= self._reset_at - 1e-9 or sim.unstable):
            # (diverged physics cannot run the step that carries the request: the reset is what recovers it)
            self._reset_now(waiting)
            return
        target = min(c.target for c in driving)
        if self.sync_hook is not None:
            self.sync_hook()
        self.advancing = True
        try:
            while sim.time < target - 1e-9:
                if self._limit_reached() or self.finished:
                    break
                sim.step()
                if self._pace is not None:
                    wall, clock = self._pace
                    delay = wall + (self.clock - clock) - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
        except BaseException as exc:
            self.error = exc
            for c in waiting:
                self._answer(c)
            self._cond.notify_all()
            return
        finally:
            self.advancing = False
        if self._reset_at is not None and sim.time >= self._reset_at - 1e-9 and not self.finished:
            # the step that carries the request has run to its end (a controller stepping less at a time went on
            # stepping meanwhile): the world is reset now, and every step waiting returns at t = 0
            self._reset_now(waiting)
            return
        for c in active:
            if c.target <= sim.time + 1e-9 or self._limit_reached() or self.finished:
                self._answer(c)
        self._cond.notify_all()


_CURRENT: Runtime | None = None


def set_current_runtime(runtime: Runtime | None) -> None:
    """Install the runtime used by argument-less ``Robot()``/``Supervisor()`` (the runner does this)."""
    global _CURRENT
    _CURRENT = runtime


def current_runtime() -> Runtime | None:
    return _CURRENT
