"""Run existing Webots Python controllers unchanged and headless on the ODE twin.

``run_world(world_path, controller, duration_s, proto_paths)`` loads the world, builds a
:class:`~dualtwin.webots.physics.Simulation` and runs the robots' Python controllers with Webots' project
layout (``worlds/X.wbt`` beside ``controllers/NAME/NAME.py``, NAME = the Robot's ``controller`` field).

As Webots does, every controller runs in its own process (:mod:`dualtwin.webots.controller_host`): its own
``sys.argv = [script, *controllerArgs]``, working directory (its folder), modules and output, with
``from controller import Robot`` answered by proxies of the API objects that live in this process. The
simulation advances only when every controller has called ``step`` (Webots' synchronisation; not waiting for a
robot whose ``synchronization`` is FALSE), and the controllers' output is printed in robot order at each step, so
the same world prints the same bytes.

A Robot a supervisor imports during the run gets its controller as at load (:func:`controller_spec`), started
in its own process and waited for from the next step; a robot removed (or taken out by a reset) has its
controller's step return -1, then that controller ends as after any -1. ``Node.restartController()`` and a new
``controller`` field do both: at the supervisor's next step the robot's controller is told -1 and the one its
field names starts, with the clock going on and none of its devices enabled.

``robot.step`` returns -1 once ``duration_s`` of simulated time has elapsed, counted across
``simulationReset``. As in Webots, a controller that calls ``step`` again after -1 is ended there (exit status
0), and one still running 1 s of real time after its -1 is killed with a warning (Webots' "Forced
termination"). Unlike Webots, a controller that does not call ``step`` for ``step_timeout_s`` seconds of real
time is stopped (exit code 2), so a run always ends, in either isolation. A script that raises has its traceback
printed on stderr and makes the exit code 1 (the other controllers keep running), unless a supervisor called
``simulationQuit(status)`` before: the run then exits with that status, as Webots does. A ``SimulationUnstable``
it lets through (the physics blew up in its step) prints its message on one line instead. ``keys`` names a key
script replayed by ``Keyboard`` (:mod:`dualtwin.webots.keyboard`). Ctrl-C or SIGTERM: the children are killed,
``error: interrupted``, exit code 130.

``isolation="threads"`` keeps the former runtime (every controller a thread of this process, sharing argv,
working directory and modules) as a baseline for the benchmark and a reference the tests compare the processes'
output with; it starts and restarts controllers during the run the same way, as threads. Its step timeout stops
a thread running Python code at once; one blocked in a call that never returns cannot be killed, and is left
behind (a daemon thread) :data:`TERMINATION_GRACE_S` later, so the run still ends. Before its first step, its
clock runs from its Robot's creation (a process's, from its last call of the API, which threads do not see). Robots whose controller is not a Python script
found on disk (C controllers, ``<generic>``, ``<extern>``, ``<none>``) run without a controller: their motors
keep the initial hold (docs/reference/webots-on-ode.md §5.1).
"""

from __future__ import annotations

import ctypes
import linecache
import math
import os
import runpy
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

from dualtwin.errors import DualtwinError
from dualtwin.webots import controller as api
from dualtwin.webots.controller_host import DEFAULT_STEP_TIMEOUT_S, STARTUP_GRACE_S, run_in_processes
from dualtwin.webots.keyboard import KeyScript, load_key_script
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.physics import Simulation, SimulationUnstable
from dualtwin.webots.runtime import NO_CONTROLLER, Controller

SHIM_DIR = Path(__file__).resolve().parent / "shim"
#: Real seconds a controller may keep running after step() returned -1 (Webots waits 1 s, then terminates it).
TERMINATION_GRACE_S = 1.0
#: ``Simulation.extensions`` key of a supervisor's worldLoad/worldReload request: (world path, run clock in s).
WORLD_REQUEST = "world_request"
#: World loads one run may chain (a controller reloading at t = 0 forever would never end otherwise).
MAX_WORLD_LOADS = 100

__all__ = [
    "DEFAULT_STEP_TIMEOUT_S",
    "ControllerSpec",
    "SHIM_DIR",
    "check_duration",
    "check_step_timeout",
    "find_controllers",
    "run_controllers",
    "run_world",
]


@dataclass
class ControllerSpec:
    """A Python controller script bound to one Robot node."""

    robot: Node
    script: Path
    args: list[str]


def _is_controller_name(name: str) -> bool:
    # A controller field is a folder name, never a path: Webots looks only in the project's
    # controllers/<name>/ folder, so separators, '.', '..' and control characters are refused.
    return (
        name not in (".", "..")
        and not any(c in name for c in "/\\:")
        and all(c.isprintable() for c in name)
    )


def _controller_script(world_path: Path, robot: Node, name: str) -> Path | None:
    """``controllers/<name>/<name>.py`` of the world's project, or None when absent.

    The world file is data: its ``controller`` field may not reach outside the project's
    ``controllers/`` folder, neither by its spelling nor through a symbolic link.

    Raises:
        DualtwinError: the field is a path, not a controller name, or the script resolves outside.
    """
    where = f"{robot.location}: " if robot.location is not None else f"{world_path}: "
    if not _is_controller_name(name):
        raise DualtwinError(
            f"{where}controller {name!r} is not a controller name: Webots runs "
            "controllers/<name>/<name>.py of the world's project, so the field may not hold a path"
        )
    controllers = world_path.resolve().parent.parent / "controllers"
    script = controllers / name / f"{name}.py"
    if not script.is_file():
        return None
    if not script.resolve().is_relative_to(controllers.resolve()):
        raise DualtwinError(
            f"{where}controller {name!r} resolves to {script.resolve()}, outside the project's "
            f"controllers folder {controllers}: refused"
        )
    return script


def find_controllers(sim: Simulation, world_path: Path, override: Path | None = None) -> list[ControllerSpec]:
    """Python controllers to run, one per robot (see the module docstring for the lookup rules).

    ``override`` replaces the script of the robots whose ``controller`` field equals its stem, or else of
    the first robot that names a controller (or the first robot).
    """
    specs: list[ControllerSpec] = []
    robots = sim.robots
    override_targets: set[int] = set()
    if override is not None:
        override = override.resolve()
        matching = [r for r in robots if r.controller == override.stem]
        if not matching:
            named = [r for r in robots if r.controller not in NO_CONTROLLER]
            matching = named[:1] or robots[:1]
        override_targets = {id(r) for r in matching}
    for robot in robots:
        if id(robot) in override_targets and override is not None:
            specs.append(ControllerSpec(robot.node, override, _controller_args(robot.node)))
            continue
        spec = controller_spec(world_path, robot.node)
        if spec is not None:
            specs.append(spec)
    return specs


def _controller_args(robot: Node) -> list[str]:
    return [str(a) for a in robot.fields.get("controllerArgs", []) or []]


def controller_spec(world_path: Path, robot: Node) -> ControllerSpec | None:
    """The Python controller of one Robot node, from its ``controller`` field, or None: no controller
    (``<none>``, ``<extern>``, ``<generic>``, ``void``, empty) or no script on disk (a warning says so).

    Raises:
        DualtwinError: the field is a path, or its script resolves outside the project's controllers folder.
    """
    name = str(robot.fields.get("controller", ""))
    if name in NO_CONTROLLER:
        return None
    script = _controller_script(world_path, robot, name)
    if script is None:
        robot_name = str(robot.fields.get("name", "robot"))
        print(
            f"Warning: no Python controller '{name}' for robot '{robot_name}' "
            f"(looked for controllers/{name}/{name}.py); it runs without one",
            file=sys.stderr,
        )
        return None
    return ControllerSpec(robot, script, _controller_args(robot))


class _LaterControllers:
    """Where a controller started during the run finds its script: a Robot a supervisor imported, or one whose
    controller it restarted (``Node.restartController``, a new ``controller`` field). As at load, from the
    ``controller`` field; a robot whose field still names what it named at load restarts the script it ran then
    (the ``--controller`` override, if it replaced it). A bad field is one error line, and no controller runs."""

    def __init__(self, world_path: Path, specs: list[ControllerSpec]) -> None:
        self.world_path = world_path.resolve()  # the threads runtime changes the working folder
        self.at_load = {id(s.robot): (str(s.robot.fields.get("controller", "")), s.script) for s in specs}

    def __call__(self, robot: Node) -> tuple[Path, list[str]] | None:
        loaded = self.at_load.get(id(robot))
        if loaded is not None and loaded[0] == str(robot.fields.get("controller", "")):
            return loaded[1], _controller_args(robot)
        try:
            spec = controller_spec(self.world_path, robot)
        except DualtwinError as exc:
            print(f"Error: {exc}", file=sys.stderr)
            return None
        return None if spec is None else (spec.script, spec.args)


# Guards the "is this script still running" flag against the watchdog's asynchronous stop.
_GUARD = threading.Lock()


class _ScriptResult:
    def __init__(self, script: Path) -> None:
        self.script = script
        self.code = 0
        self.running = False
        self.forced = False
        #: wall time at which the step timeout stopped it (None: it was not)
        self.timed_out_at: float | None = None
        self.thread: int | None = None
        self.controller: Controller | None = None
        #: it ended once a supervisor had called simulationQuit: its exit status is not the run's
        self.after_quit = False


def _run_script(runtime: api.Runtime, spec: ControllerSpec, result: _ScriptResult) -> None:
    result.controller = runtime.bind_thread(spec.robot)
    saved_argv = sys.argv
    result.thread = threading.get_ident()
    try:
        try:
            sys.argv = [str(spec.script), *spec.args]
            with _GUARD:
                result.running = True
            runpy.run_path(str(spec.script), run_name="__main__")
        finally:
            with _GUARD:  # from here on the watchdog leaves this thread alone
                result.running = False
    except api.ControllerStopped:
        if result.timed_out_at is not None:
            result.code = 2  # (its line was printed when it was stopped)
        elif result.forced:
            print(
                f"Warning: controller {spec.script.name} was still running {TERMINATION_GRACE_S:g} s after "
                "step() returned -1: forced termination",
                file=sys.stderr,
            )
    except SystemExit as exc:
        code = exc.code
        if code not in (None, 0):
            result.code = code if isinstance(code, int) else 1
            if not isinstance(code, int):
                print(code, file=sys.stderr)
    except SimulationUnstable as exc:  # the physics blew up: one line, as from a controller process
        print(f"Error: {exc}", file=sys.stderr)
        result.code = 1
    except BaseException as exc:  # the controller's own error is its output, like in the Webots console
        traceback.print_exception(type(exc), exc, _script_frames(exc.__traceback__), file=sys.stderr)
        result.code = 1
    finally:
        sys.argv = saved_argv
        result.after_quit = runtime.exit_status is not None
        runtime.thread_done()


def _script_frames(tb: TracebackType | None) -> TracebackType | None:
    """The traceback from the script's first frame on, as Python prints it for ``python NAME.py`` (and as a
    controller process prints it): how this thread started the script is no business of it."""
    while tb is not None and (tb.tb_frame.f_code.co_filename == __file__
                              or tb.tb_frame.f_code.co_filename.startswith("<frozen ")):
        tb = tb.tb_next
    return tb


def check_duration(duration_s: float | None) -> None:
    """Refuse a run length that is not a finite number of seconds > 0 (NaN would run forever).

    Raises:
        DualtwinError: naming the ``--duration`` option, which is where users give it.
    """
    if duration_s is None:
        return
    if isinstance(duration_s, bool) or not isinstance(duration_s, (int, float)):
        raise DualtwinError(f"--duration: expected a number of seconds, got {duration_s!r}")
    if not math.isfinite(duration_s) or duration_s <= 0:
        raise DualtwinError(f"--duration: must be a finite number of seconds > 0, got {duration_s:g}")


def check_step_timeout(step_timeout_s: float) -> None:
    """Refuse a step timeout that is not a finite number of seconds >= 0.

    Raises:
        DualtwinError: naming the ``--step-timeout`` option.
    """
    if isinstance(step_timeout_s, bool) or not isinstance(step_timeout_s, (int, float)):
        raise DualtwinError(f"--step-timeout: expected a number of seconds, got {step_timeout_s!r}")
    if not math.isfinite(step_timeout_s) or step_timeout_s < 0:
        raise DualtwinError(
            f"--step-timeout: must be a finite number of seconds >= 0 (0: no limit), got {step_timeout_s:g}"
        )


def run_world(
    world_path: str | os.PathLike[str],
    controller: str | os.PathLike[str] | None = None,
    duration_s: float | None = None,
    proto_paths: tuple[str | os.PathLike[str], ...] | list[str | os.PathLike[str]] = (),
    keys: str | os.PathLike[str] | None = None,
    *,
    step_timeout_s: float = DEFAULT_STEP_TIMEOUT_S,
    isolation: str = "process",
) -> int:
    """Run a world's Python controllers headless; return the exit code (0 = success).

    Args:
        world_path: the ``.wbt`` file.
        controller: a script replacing the robot's controller (see :func:`find_controllers`).
        duration_s: simulated seconds to run (across resets); ``None`` runs until every controller returns.
        proto_paths: extra PROTO search directories.
        keys: a key script for ``Keyboard`` (format in :mod:`dualtwin.webots.keyboard`).
        step_timeout_s: real seconds a controller may run without calling ``step`` (0: no limit).
        isolation: ``"process"`` (one process per controller, as Webots) or ``"threads"`` (the former
            in-process runtime, kept as a benchmark baseline).

    Raises:
        DualtwinError: a bad duration, step timeout, key script, world or controller field (before anything
            runs).
    """
    from dualtwin.webots import load_world

    check_duration(duration_s)
    check_step_timeout(step_timeout_s)
    script = load_key_script(Path(keys)) if keys is not None else None
    path = Path(world_path)
    world = load_world(path, proto_paths)
    with _warnings_as_lines():
        return _run_loaded(world, path, proto_paths, controller, duration_s, script, step_timeout_s, isolation)


@contextmanager
def _warnings_as_lines() -> Iterator[None]:
    """The simulation's warnings (its build, a supervisor's edit it cannot carry out) printed as the world's own
    are, one ``Warning: ...`` line each as Webots prints them, not Python's ``file:line: UserWarning`` with the
    source line under it. Each is shown once per place it is raised from, per run: a second run in the same
    process (a script or a test running two worlds) reports its own world's warnings again, which Python's
    once-per-process registry would hide (changing the filters, as entering this does, clears it)."""

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: object = None, line: str | None = None) -> None:
        if filename.startswith(_PACKAGE):
            print(f"Warning: {message}", file=sys.stderr)
            return
        # a controller thread's own warning: as its interpreter prints it where Webots starts it (and a controller
        # process does), ``file:line: Category: text`` and the source line
        source = (line if line is not None else linecache.getline(filename, lineno)).strip()
        sys.stderr.write(f"{filename}:{lineno}: {category.__name__}: {message}\n" + (f"  {source}\n" if source else ""))

    with warnings.catch_warnings():
        # this package's warnings once per place; a script's (and its libraries') under the interpreter's filters,
        # as in a process of its own (a ResourceWarning, a library's DeprecationWarning stay silent)
        warnings.filterwarnings("default", module=r"dualtwin\.")
        warnings.showwarning = show
        yield


def _run_loaded(world: World, path: Path, proto_paths: tuple[str | os.PathLike[str], ...] | list[str | os.PathLike[str]],
                controller: str | os.PathLike[str] | None, duration_s: float | None, script: KeyScript | None,
                step_timeout_s: float, isolation: str) -> int:
    """:func:`run_world` once its first world is loaded (and for each world a supervisor loads after it)."""
    from dualtwin.webots import load_world

    for _ in range(MAX_WORLD_LOADS + 1):
        for message in world.warnings:
            print(f"Warning: {message}", file=sys.stderr)
        sim = Simulation(world)
        try:
            specs = find_controllers(sim, path, Path(controller) if controller is not None else None)
            if not specs and duration_s is None:
                print("Error: no Python controller to run and no duration given", file=sys.stderr)
                return 2
            code = run_controllers(
                sim, specs, duration_s, keys=script, step_timeout_s=step_timeout_s, isolation=isolation
            )
            request = sim.extensions.get(WORLD_REQUEST)
        finally:
            sim.close()
        if code != 0 or request is None:
            return code
        # Supervisor.worldLoad/worldReload: Webots loads that world and starts its controllers afresh; the run
        # goes on for what is left of its duration (the override script, if any, still replaces its controller)
        path, elapsed = request
        if duration_s is not None:
            duration_s -= elapsed
            if duration_s <= 1e-9:
                return 0
        try:
            world = load_world(path, proto_paths)
        except DualtwinError as exc:
            print(f"Error: worldLoad: {exc}", file=sys.stderr)
            return 1
    print(f"Error: worldLoad: {MAX_WORLD_LOADS} worlds loaded in one run; stopped", file=sys.stderr)
    return 1


_PACKAGE = str(Path(__file__).resolve().parents[1])  # the dualtwin package's folder


def _watch(runtime: api.Runtime, results: list[_ScriptResult], stop: threading.Event, step_timeout_s: float) -> None:
    """Terminate controllers still running ``TERMINATION_GRACE_S`` real seconds after their -1, and stop one that
    does not call ``step`` for ``step_timeout_s`` (0: never), as the processes' host does
    (:mod:`dualtwin.webots.controller_host`): one line, the run ends (the others' steps return -1), exit code 2."""
    # wall time from which a controller nothing waits for (synchronization FALSE) counts its time without a step
    waited_from: dict[int, float] = {}
    while not stop.wait(0.02):
        now = time.monotonic()
        ended_threads = set()
        for thread, ended in runtime.ended_clients():
            ended_threads.add(thread)
            if now - ended < TERMINATION_GRACE_S:
                continue
            for result in list(results):
                with _GUARD:
                    if result.thread == thread and result.running and not result.forced:
                        result.forced = True
                        _stop_thread(thread)
        if step_timeout_s > 0:
            for result in list(results):
                if result.thread not in ended_threads:
                    _check_step_timeout(runtime, result, step_timeout_s, now, waited_from)


def _check_step_timeout(runtime: api.Runtime, result: _ScriptResult, step_timeout_s: float, now: float,
                        waited_from: dict[int, float]) -> None:
    controller = result.controller
    if controller is None or controller.in_step or result.timed_out_at is not None or not result.running:
        return
    heard = controller.arrived  # it made its Robot (past its imports)
    if heard and controller.robot_node is not None and not runtime.waits_for(controller.robot_node):
        waited_from[id(result)] = now  # it holds no one up
        return
    since = max(controller.progress, waited_from.get(id(result), 0.0))
    allowed = step_timeout_s if heard else max(step_timeout_s, STARTUP_GRACE_S)
    if now - since < allowed:
        return
    with _GUARD:
        if not result.running:
            return
        result.timed_out_at = now
    print(f"Error: controller {result.script.name} did not call step() for {step_timeout_s:g} s of real time "
          "(--step-timeout): stopped", file=sys.stderr)
    # the run ends before the thread is stopped: its end would otherwise let the others step on without it
    runtime.finish()
    with _GUARD:
        if result.running and result.thread is not None:
            # a script running Python code stops at once; one blocked in a call that does not return is left
            # behind once the grace is over (_Threads.join), as its process would be killed
            _stop_thread(result.thread)


def _stop_thread(thread: int) -> None:
    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread), ctypes.py_object(api.ControllerStopped))


def run_controllers(
    sim: Simulation,
    specs: list[ControllerSpec],
    duration_s: float | None,
    keys: KeyScript | None = None,
    *,
    step_timeout_s: float = DEFAULT_STEP_TIMEOUT_S,
    isolation: str = "process",
) -> int:
    """Run controller scripts on an already built simulation (left open for inspection).

    Returns:
        The exit code: 0, the first non-zero ``SystemExit`` code, 1 if a script raised, 2 if one was stopped
        by the step timeout, 130 if the run was interrupted (Ctrl-C, SIGTERM).
    """
    later = _LaterControllers(Path(sim.world.path), specs)
    if isolation == "threads":
        return _run_in_threads(sim, specs, duration_s, keys, later, step_timeout_s)
    if isolation != "process":
        raise ValueError(f"isolation must be 'process' or 'threads', got {isolation!r}")
    runtime = api.Runtime(sim, duration_s, keys=keys, stop_after_end=True)
    previous_runtime = api.current_runtime()
    api.set_current_runtime(runtime)
    try:
        result = run_in_processes(runtime, [(s.robot, s.script, s.args) for s in specs], step_timeout_s, later)
        if not result.interrupted:
            return _finish(sim, runtime, duration_s, result.code)
    except KeyboardInterrupt:  # while the world runs on without controllers
        pass
    finally:
        api.set_current_runtime(previous_runtime)
    print("error: interrupted", file=sys.stderr)  # the command line's words for a stop
    return 130


def _finish(sim: Simulation, runtime: api.Runtime, duration_s: float | None, code: int) -> int:
    if code == 0 and duration_s is not None and not runtime.finished:
        # controllers returned early: Webots keeps simulating without them
        try:
            while runtime.clock < duration_s - 1e-9:
                sim.step()
        except SimulationUnstable as exc:
            print(f"Error: {exc}", file=sys.stderr)
            code = 1
    if code == 0 and runtime.exit_status is not None:
        code = runtime.exit_status
    return code


class _Threads:
    """The controller threads of a threads run: those of the load, then those started during it (a Robot a
    supervisor imported, a restarted controller), which the run waits for from the step they start at."""

    def __init__(self, runtime: api.Runtime, later: Callable[[Node], tuple[Path, list[str]] | None]) -> None:
        self.runtime = runtime
        self.later = later
        self.results: list[_ScriptResult] = []
        self.threads: list[threading.Thread] = []
        self._lock = threading.Lock()
        self._closed = False

    def thread(self, spec: ControllerSpec, claim: bool = False) -> threading.Thread:
        result = _ScriptResult(spec.script)
        target = self._claimed if claim else _run_script
        thread = threading.Thread(target=target, args=(self.runtime, spec, result),
                                  name=f"controller-{len(self.threads)}", daemon=True)
        with self._lock:
            self.results.append(result)
            self.threads.append(thread)
        return thread

    def start_later(self, robot: Node) -> None:
        """The runtime's ``controller_starter``: the robot's controller joins the run from the current step."""
        found = self.later(robot)
        if found is None:
            return
        with self._lock:
            if self._closed:
                return
            self.runtime.expect_another(robot)
        self.thread(ControllerSpec(robot, *found), claim=True).start()

    @staticmethod
    def _claimed(runtime: api.Runtime, spec: ControllerSpec, result: _ScriptResult) -> None:
        if runtime.claim_start(spec.robot):  # its robot may have been removed since
            _run_script(runtime, spec, result)

    def join(self) -> None:
        """Wait for every controller thread, those started meanwhile too; then no more start. One the step timeout
        stopped is waited for :data:`TERMINATION_GRACE_S` at most: blocked in a call that never returns, it cannot
        be stopped (a thread cannot be killed), and it is left behind (a daemon thread) rather than hang the run."""
        joined = 0
        while True:
            with self._lock:
                if joined == len(self.threads):
                    self._closed = True
                    return
                thread, result = self.threads[joined], self.results[joined]
            while thread.ident is None:  # (one a supervisor's import added is started right after it is listed)
                time.sleep(0.001)
            while thread.is_alive():
                thread.join(0.05)
                stopped = result.timed_out_at
                if stopped is not None and time.monotonic() - stopped >= TERMINATION_GRACE_S:
                    break
            joined += 1

    def code(self) -> int:
        if any(r.timed_out_at is not None for r in self.results):
            return 2  # as the processes' run: the step timeout's code comes first
        # once a supervisor quit with a status, Webots exits with it whatever the controllers then do (a traceback
        # is output in the console): an end after the quit does not decide the code (_finish gives the status)
        return next((r.code for r in self.results if r.code != 0 and not r.after_quit), 0)


def _run_in_threads(
    sim: Simulation, specs: list[ControllerSpec], duration_s: float | None, keys: KeyScript | None,
    later: Callable[[Node], tuple[Path, list[str]] | None], step_timeout_s: float,
) -> int:
    """The former runtime: every controller a thread of this process (shared argv, cwd and modules)."""
    runtime = api.Runtime(sim, duration_s, keys=keys, stop_after_end=True)
    runtime.expect(len(specs))
    threads = _Threads(runtime, later)
    runtime.controller_starter = threads.start_later
    stop_watch = threading.Event()
    watchdog = threading.Thread(target=_watch, args=(runtime, threads.results, stop_watch, step_timeout_s),
                                daemon=True)
    watchdog.start()
    saved_cwd = os.getcwd()
    saved_path = list(sys.path)
    # each controller thread sets sys.argv to its own and puts back what it found, which may be another
    # controller's: the caller's is restored here, whichever thread ended last
    saved_argv = list(sys.argv)
    saved_module = sys.modules.pop("controller", None)
    previous_runtime = api.current_runtime()
    api.set_current_runtime(runtime)
    sys.path.insert(0, str(SHIM_DIR))
    code = 0
    try:
        if specs:
            folders = {s.script.parent for s in specs}
            if len(folders) > 1:
                print(
                    "Warning: controllers live in different folders; the working directory is "
                    f"{specs[0].script.parent}",
                    file=sys.stderr,
                )
            os.chdir(specs[0].script.parent)
            # every controller in a thread of its own, the only one too: the step timeout can leave one that
            # blocks behind, which this thread could not do with its own
            for t in [threads.thread(s) for s in specs]:
                t.start()
        threads.join()
        code = _finish(sim, runtime, duration_s, threads.code())
    except BaseException:  # Ctrl-C while it waits: the controller threads' steps return -1 rather than wait on
        runtime.finish()
        raise
    finally:
        stop_watch.set()
        watchdog.join()
        runtime.controller_starter = None
        os.chdir(saved_cwd)
        sys.path[:] = saved_path
        sys.argv = saved_argv
        sys.modules.pop("controller", None)
        if saved_module is not None:
            sys.modules["controller"] = saved_module
        api.set_current_runtime(previous_runtime)
    return code
