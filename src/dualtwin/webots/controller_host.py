"""One process per controller, as Webots runs them: the parent side.

:func:`run_in_processes` starts every controller script in its own interpreter (:mod:`.controller_process`),
so each has its own ``sys.argv``, working directory (its folder), modules and output, while the API objects
stay here, over the one :class:`Simulation`. Each child is served by one thread of this process that makes
its calls on the real objects, so the threaded :class:`~dualtwin.webots.runtime.Runtime` keeps Webots'
synchronisation: the simulation advances once every controller has asked for the next step.

Output is deterministic: a child's ``print`` travels with its next message, and warnings the API prints on
its behalf are kept with it; everything is written in robot order each time the simulation advances (every
controller is then waiting in ``step``, so all it printed before has arrived), and at the end.

A Robot a supervisor imports during the run, or one whose controller it restarts, starts its controller the same
way (:meth:`_Host.add`, called by the runtime when the supervisor next steps): the runtime expects one more
controller at once, so that step waits for it, and the watching thread starts the child (a child dies with the
thread that started it, and the supervisor's serving thread may end first). A restarted robot's former
controller is told -1 at its step and ends as after any -1.

The main thread watches the children:

* one still running :data:`TERMINATION_GRACE_S` after its ``step`` returned -1 is killed, with a warning
  (Webots' forced termination; the exit code stays 0);
* one that does not call ``step`` for ``step_timeout_s`` wall-clock seconds (0: never checked, like Webots)
  is killed with one line on stderr; the run ends (the others' ``step`` returns -1) with exit code 2. The clock
  runs from its last ``step`` or, before its first, from its last call of the API; until its first call at all
  (the script's own imports: PyTorch alone can take longer than the timeout on a busy machine) it may take
  :data:`STARTUP_GRACE_S`. A robot whose ``synchronization`` is FALSE holds no one up, so its clock runs only
  while the simulation waits for it (no synchronized controller left);
* Ctrl-C or SIGTERM kills and reaps every child and returns 130 (the caller says ``error: interrupted``; the command line catches its own SIGINT first).

A child that crashes prints its traceback (through its stderr) and makes the exit code 1; the others keep
running, as in Webots. Once a supervisor called ``simulationQuit(status)``, a child's end no longer decides the
code: Webots exits with that status. Children die with this process (``PR_SET_PDEATHSIG``) and are always reaped.
"""

from __future__ import annotations

import contextlib
import functools
import os
import pickle
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

from dualtwin.errors import DualtwinError
from dualtwin.webots import controller as api
from dualtwin.webots.controller_process import SPIN_US, Wire
from dualtwin.webots.controller_wire import HandleTable, plain
from dualtwin.webots.device_base import Device
from dualtwin.webots.nodes import Node as SceneNode

__all__ = ["CHILD_SCRIPT", "DEFAULT_STEP_TIMEOUT_S", "TERMINATION_GRACE_S", "ProcessResult", "run_in_processes"]

CHILD_SCRIPT = Path(__file__).resolve().parent / "controller_process.py"
#: Real seconds a controller may keep running after step() returned -1 (Webots waits 1 s, then kills it).
TERMINATION_GRACE_S = 1.0
#: Default wall-clock seconds a controller may run without calling step() (``--step-timeout``).
DEFAULT_STEP_TIMEOUT_S = 5.0
_POLL_S = 0.02
#: Robot methods that run the simulation: their answer brings the subscribed getters' values.
_STEPS = frozenset({"step", "stepEnd"})
_FLAT = frozenset({float, int, bool, str, type(None)})
#: Real seconds a controller that reported its exit may take to shut its interpreter down before it is killed.
EXIT_GRACE_S = 2.0


def _exports() -> dict[str, type]:
    return {name: getattr(api, name) for name in api.__all__ if isinstance(getattr(api, name), type)}


#: Wall-clock seconds a controller may take before its first call of the API (its imports), when a step timeout
#: is set: at least this, or the step timeout if longer.
STARTUP_GRACE_S = 60.0


class _Link:
    """One controller process and the thread of this process that serves it."""

    def __init__(self, index: int, robot: SceneNode, script: Path, args: list[str], table: HandleTable) -> None:
        self.index = index
        self.robot = robot
        self.script = script
        self.args = args
        self.table = table
        self.out: list[tuple[int, str]] = []
        self.proc: subprocess.Popen[bytes] | None = None
        self.wire: Wire | None = None
        self.thread: threading.Thread | None = None
        self.in_step = False
        self.last_active = time.monotonic()
        self.heard = False  # any request arrived (the script got past its imports)
        self.stepped = False  # a step() returned
        self.ended_at: float | None = None  # wall time at which step() returned -1
        self.exit_code: int | None = None  # as the child reported it
        self.stopped: str | None = None  # why the parent killed it: "forced" or "timeout"
        #: it ended once a supervisor had called simulationQuit: its exit status is not the run's
        self.after_quit = False
        self.deferred: BaseException | None = None  # raised by a queued command, reported at the next call
        #: the marked getters the child reads, (handle, name) -> bound method, in the child's order: their
        #: values go with every step's answer
        self.subscribed: dict[tuple[int, str], Any] = {}
        self.robot_object: api.Robot | None = None
        #: bound methods of the buffered commands, by (handle, name): found once, not each step
        self.commands: dict[tuple[int, str], Any] = {}
        self.done = threading.Event()


class _Output(threading.local):
    link: _Link | None = None
    capture: list[str] | None = None


class _Router:
    """``sys.stdout``/``sys.stderr`` during a run: what a serving thread prints belongs to its controller."""

    def __init__(self, fd: int, real: TextIO, state: _Output, runtime: api.Runtime) -> None:
        self._fd = fd
        self._real = real
        self._state = state
        self._runtime = runtime

    def write(self, text: str) -> int:
        state = self._state
        if state.capture is not None:
            state.capture.append(text)
        elif state.link is not None and not self._runtime.advancing:
            state.link.out.append((self._fd, text))
        else:
            self._real.write(text)
        return len(text)

    def flush(self) -> None:
        self._real.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)


def spin_budget_us(controllers: int) -> float:
    """How long each side of a controller's channel polls before it sleeps (:meth:`Wire.spin`), for a run of
    ``controllers`` controller processes: ``SPIN_US`` where there is a core for each of them and one for the
    simulation, else 0 (while the simulation steps, every controller waits: where they outnumber the cores, the
    polling ones take the cores it needs; measured on 2 cores under load, 4 polling controllers ran 4x slower
    than sleeping ones), or what ``DUALTWIN_CONTROLLER_SPIN_US`` says (0 turns polling off)."""
    text = os.environ.get("DUALTWIN_CONTROLLER_SPIN_US")
    if text is not None:
        try:
            value = float(text)
        except ValueError:
            value = -1.0
        if not 0 <= value <= 1e6:
            raise DualtwinError(f"DUALTWIN_CONTROLLER_SPIN_US={text!r}: expected microseconds from 0 to 1000000")
        return value
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return SPIN_US if controllers + 1 <= cores else 0.0


class ProcessResult:
    """How a run of controller processes ended."""

    def __init__(self, code: int, interrupted: bool) -> None:
        self.code = code
        self.interrupted = interrupted


class _Host:
    def __init__(self, runtime: api.Runtime, step_timeout_s: float) -> None:
        self.runtime = runtime
        self.step_timeout_s = step_timeout_s
        self.exports = _exports()
        self.roles: dict[type, str] = {api.Robot: "robot", Device: "device"}
        self.links: list[_Link] = []
        self.state = _Output()
        self.real_out = sys.stdout
        self.real_err = sys.stderr
        self.changed = threading.Event()
        self._described: tuple[set[type], list[dict[str, Any]]] | None = None
        self.stopping = False  # stop_all began: no controller starts any more
        self._adding = threading.Lock()
        self._to_start: list[_Link] = []
        self.spin_us = 0.0  # set when the controllers are known (run_in_processes, add)

    # -- output

    def emit(self) -> None:
        """Write what every controller printed so far, in robot order."""
        for link in self.links:
            n = len(link.out)
            if not n:
                continue
            chunk = link.out[:n]
            del link.out[:n]
            for fd, text in chunk:
                (self.real_out if fd == 1 else self.real_err).write(text)
        self.real_out.flush()
        self.real_err.flush()

    # -- start

    def start(self, link: _Link) -> None:
        # two pipes rather than a socketpair: a message costs a third less CPU each way
        from_parent, to_child = os.pipe()  # (read end, write end)
        from_child, to_parent = os.pipe()
        try:
            link.proc = subprocess.Popen(
                [sys.executable, str(CHILD_SCRIPT), str(from_parent), str(to_parent), str(os.getpid())],
                pass_fds=(from_parent, to_parent), cwd=link.script.parent, stdin=subprocess.DEVNULL,
            )
        except BaseException:
            for fd in (to_child, from_child):
                os.close(fd)
            raise
        finally:
            for fd in (from_parent, to_parent):
                os.close(fd)
        link.wire = Wire(from_child, to_child)
        link.wire.spin(self.spin_us)
        if self._described is None:  # the API's shape, described once for every child
            first = link.table
            for cls in self.exports.values():
                first.describe(cls)
            self._described = (set(first.described), first.take_descriptions())
        else:
            link.table.described = set(self._described[0])
        start = {
            "classes": self._described[1], "exports": list(self.exports), "doc": api.__doc__,
            "script": str(link.script), "args": link.args, "spin_us": self.spin_us,
        }
        link.wire.send(pickle.dumps(start, protocol=pickle.HIGHEST_PROTOCOL))
        link.last_active = time.monotonic()
        link.thread = threading.Thread(target=self.serve, args=(link,), name=f"controller-{link.index}", daemon=True)
        link.thread.start()

    def add(self, robot: SceneNode, script: Path, args: list[str]) -> None:
        """Start the controller of a Robot imported (or restarted) while the run goes on: the step waits for it."""
        with self._adding:
            if self.stopping:
                return
            link = _Link(len(self.links), robot, script, args, HandleTable(self.exports, self.roles))
            self.runtime.expect_another(robot)
            self.links.append(link)
            spin_us = spin_budget_us(len(self.links))
            if spin_us < self.spin_us:  # now more controllers than cores: this side stops polling (the
                self.spin_us = spin_us  # children started before keep their budget, which adapts to long waits)
                for other in self.links:
                    if other.wire is not None:
                        other.wire.spin(spin_us)
            # started by the watching thread, which lives as long as the run: a child dies with the thread that
            # started it (PR_SET_PDEATHSIG), and the importing controller's serving thread may end first
            self._to_start.append(link)
        self.changed.set()

    # -- serving one child

    def serve(self, link: _Link) -> None:
        runtime = self.runtime
        runtime.bind_thread(link.robot)
        self.state.link = link
        wire = link.wire
        assert wire is not None
        try:
            while True:
                try:
                    frame = wire.receive()
                except OSError:
                    frame = None
                if frame is None:
                    break
                message = link.table.loads(frame)
                if not link.stepped:
                    link.last_active = time.monotonic()  # before the first step, any call shows progress
                link.heard = True
                pending, subscriptions, dropped = message[-3], message[-2], message[-1]
                if pending:
                    self._run_pending(link, pending)
                if subscriptions or dropped:
                    self._subscribe(link, subscriptions, dropped)
                op = message[0]
                if op == "out":
                    continue
                if op == "exit":
                    link.exit_code = message[1]
                    break
                reply = self._answer(link, op, message[1:-3])
                try:
                    wire.send(reply)
                except OSError:
                    break
        finally:
            self.state.link = None
            link.after_quit = runtime.exit_status is not None
            runtime.thread_done()
            link.done.set()
            self.changed.set()

    def _run_pending(self, link: _Link, pending: list[tuple[Any, ...]]) -> None:
        """The child's output and buffered commands, in its order (a command's warning lands between)."""
        out = link.out
        commands = link.commands
        for entry in pending:
            if len(entry) == 2:
                out.append(entry)
                continue
            handle, name, args = entry
            try:
                command = commands.get((handle, name))
                if command is None:
                    command = commands[handle, name] = getattr(link.table.objects[handle], name)
                command(*args)
            except Exception as exc:  # a marked command does not raise; should one, it is not lost
                if link.deferred is None:
                    link.deferred = exc

    def _answer(self, link: _Link, op: str, body: tuple[Any, ...]) -> bytes:
        table = link.table
        try:
            if link.deferred is not None:
                error, link.deferred = link.deferred, None
                raise error
            fresh: tuple[list[Any], list[int]] | bool | None = None
            if op == "call":
                handle, name, args, kwargs = body
                target = table.objects[handle]
                if name in _STEPS and isinstance(target, api.Robot):
                    link.in_step = True
                    try:
                        value: Any = getattr(target, name)(*args, **kwargs)
                    finally:
                        # progress first: the watchdog reads in_step and last_active without a lock, and must not
                        # see the step ended with the time from before it
                        link.last_active = time.monotonic()
                        link.stepped = True
                        link.in_step = False
                    if value == -1 and link.ended_at is None:
                        link.ended_at = time.monotonic()
                    fresh = self._fresh(link)
                else:
                    value = getattr(target, name)(*args, **kwargs)
            elif op == "read":
                handle, name = body
                printed = len(link.out)
                value = getattr(table.objects[handle], name)()
                if len(link.out) != printed:
                    fresh = False  # it printed (a disabled sensor's error): the child must not keep the value
                    # for this step's later reads, which print again as in a thread
            elif op == "new":
                key, args, kwargs = body
                cls = self.exports[key]
                if issubclass(cls, api.Robot) and self.runtime.robot_gone(link.robot):
                    raise api.ControllerStopped  # removed before its controller made its Robot: it ends there
                if issubclass(cls, api.Robot) and link.robot_object is not None:
                    # Webots' library says so and keeps the first one: a second Robot would never step
                    print("Error: only one Robot instance can be created per controller process.", file=sys.stderr)
                    obj = link.robot_object
                else:
                    obj = cls(*args, **kwargs)
                    if isinstance(obj, api.Robot):
                        link.robot_object = obj
                handle, _ = table.handle(obj)
                value = (handle, table.public_attrs(obj))
            elif op == "get":
                handle, name = body
                value = getattr(table.objects[handle], name)
            elif op == "set":
                handle, name, new = body
                setattr(table.objects[handle], name, new)
                value = None
            elif op == "static":
                key, name, args, kwargs = body
                value = getattr(self.exports[key], name)(*args, **kwargs)
            else:
                raise RuntimeError(f"unknown request {op!r}")
            return table.dumps("ok", value, fresh)
        except SystemExit as exc:  # ControllerStopped: Webots' library ends the controller here
            link.last_active = time.monotonic()
            return table.dumps("err", ("exit", type(exc).__name__, "", exc.code))
        except Exception as exc:  # with the built-in class it derives from: the child's class derives from it too
            return table.dumps("err", ("error", type(exc).__name__, str(exc), None, *_error_details(exc)))

    def _subscribe(self, link: _Link, keys: list[tuple[int, str]], dropped: list[tuple[int, str]]) -> None:
        for key in dropped:
            del link.subscribed[key]
        objects = link.table.objects
        for key in keys:
            link.subscribed[key] = getattr(objects[key[0]], key[1])

    def _fresh(self, link: _Link) -> tuple[list[Any], list[int]]:
        """The subscribed getters' values now, for the child's step answer: ``(values, missing)``, where
        ``missing`` lists the getters left to the child's own read: one that warns (so the warning comes at
        its call, as in a thread), raises, or returns anything but plain data."""
        values: list[Any] = []
        missing: list[int] = []
        captured: list[str] = []
        state = self.state
        state.capture = captured
        try:
            for index, getter in enumerate(link.subscribed.values()):
                try:
                    value = getter()
                except Exception:
                    value = None
                    missing.append(index)
                else:
                    if captured:
                        captured.clear()
                        missing.append(index)
                    elif type(value) not in _FLAT and not plain(value):
                        value = None
                        missing.append(index)
                values.append(value)
        finally:
            state.capture = None
        return values, missing

    # -- watching

    def watch(self) -> None:
        """Until every controller ended: forced termination after -1 and the step timeout."""
        while not all(link.done.is_set() for link in self.links):
            self.changed.wait(_POLL_S)
            self.changed.clear()
            while self._to_start:
                link = self._to_start.pop(0)
                if self.runtime.claim_start(link.robot):
                    self.start(link)
                else:  # its robot was removed in the step it was imported: Webots never runs it
                    link.exit_code = 0
                    link.done.set()
            now = time.monotonic()
            for link in self.links:
                if link.done.is_set() or link.stopped is not None:
                    continue
                if link.ended_at is not None and now - link.ended_at >= TERMINATION_GRACE_S:
                    link.stopped = "forced"
                    link.out.append((2, f"Warning: controller {link.script.name} was still running "
                                        f"{TERMINATION_GRACE_S:g} s after step() returned -1: forced termination\n"))
                    self._kill(link)
                elif link.heard and not self.runtime.waits_for(link.robot):
                    # nothing waits for its steps (synchronization FALSE): it holds no one up, and its time
                    # without a step counts from when the simulation starts waiting for it
                    link.last_active = now
                elif (self.step_timeout_s > 0 and not link.in_step and link.ended_at is None
                        and now - link.last_active >= self._allowed(link)):
                    link.stopped = "timeout"
                    link.out.append((2, f"Error: controller {link.script.name} did not call step() for "
                                        f"{self.step_timeout_s:g} s of real time (--step-timeout): stopped\n"))
                    self._kill(link)
                    self.runtime.finish()

    def _allowed(self, link: _Link) -> float:
        return self.step_timeout_s if link.heard else max(self.step_timeout_s, STARTUP_GRACE_S)

    def _kill(self, link: _Link) -> None:
        if link.proc is not None and link.proc.poll() is None:
            link.proc.kill()

    def stop_all(self, finishing: bool = False) -> None:
        """Kill and reap every child, then let the serving threads go (idempotent).

        ``finishing``: the run ended normally, so a child that said it exits gets a moment to finish its own
        interpreter shutdown (files it left open are flushed there) before it is killed.
        """
        with self._adding:
            self.stopping = True
        deadline = time.monotonic() + EXIT_GRACE_S
        for link in self.links:
            if finishing and link.proc is not None and link.exit_code is not None:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    link.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            self._kill(link)
        for link in self.links:
            if link.proc is not None:
                link.proc.wait()
        self.runtime.finish()
        for link in self.links:
            if link.thread is not None:
                link.thread.join(timeout=10.0)
            if link.wire is not None:
                link.wire.close()

    def code(self) -> int:
        for link in self.links:
            if link.stopped == "timeout":
                return 2
        for link in self.links:
            if link.stopped == "forced" or link.after_quit:
                # (once a supervisor quit with a status, Webots exits with it whatever a controller then does: its
                # traceback is output, the caller gives the status)
                continue
            code = link.exit_code
            if code is None:  # died without saying how: killed by a signal, or the interpreter failed
                returned = link.proc.returncode if link.proc is not None else None
                code = returned if returned not in (None, 0) and returned > 0 else 1
            if code:
                return code
        return 0


def _error_details(exc: BaseException) -> tuple[str, tuple[Any, ...] | None]:
    """The built-in class ``exc`` derives from, and its arguments where they are plain data that the built-in class
    words as ``exc`` is worded (a KeyError's key): the child raises it with the same ``args``; else None, and the
    child raises it with its text."""
    builtin = next(b for b in type(exc).__mro__ if b.__module__ == "builtins")
    try:
        if plain(exc.args) and str(builtin(*exc.args)) == str(exc):
            return builtin.__name__, exc.args
    except Exception:  # the built-in class does not take these arguments
        pass
    return builtin.__name__, None


@contextmanager
def _routed(host: _Host) -> Iterator[None]:
    saved = sys.stdout, sys.stderr
    host.real_out, host.real_err = saved
    sys.stdout = _Router(1, saved[0], host.state, host.runtime)  # type: ignore[assignment]
    sys.stderr = _Router(2, saved[1], host.state, host.runtime)  # type: ignore[assignment]
    try:
        yield
    finally:
        sys.stdout, sys.stderr = saved


@contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM stops the run like Ctrl-C (main thread only: signals are delivered there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _start_imported(
    host: _Host, resolve: Callable[[SceneNode], tuple[Path, list[str]] | None], robot: SceneNode
) -> None:
    found = resolve(robot)
    if found is not None:
        host.add(robot, *found)


def run_in_processes(
    runtime: api.Runtime,
    specs: list[tuple[SceneNode, Path, list[str]]],
    step_timeout_s: float,
    resolve: Callable[[SceneNode], tuple[Path, list[str]] | None] | None = None,
) -> ProcessResult:
    """Run each (robot node, script, controllerArgs) as a controller process on ``runtime``'s simulation.
    ``resolve`` gives the (script, controllerArgs) of a Robot a supervisor imports, or whose controller it
    restarts, during the run (None: it runs without a controller); its controller then starts as the others did.

    Returns:
        The exit code (0; the first controller's non-zero exit status in robot order; 1 for a crash; 2 for a
        step timeout) and whether the run was interrupted (then the code is 130).
    """
    host = _Host(runtime, step_timeout_s)
    exported = host.exports
    host.links = [
        _Link(i, robot, script, args, HandleTable(exported, host.roles))
        for i, (robot, script, args) in enumerate(specs)
    ]
    runtime.expect(len(host.links))
    host.spin_us = spin_budget_us(len(host.links))
    runtime.sync_hook = host.emit
    if resolve is not None:
        runtime.controller_starter = functools.partial(_start_imported, host, resolve)
    interrupted = False
    with _sigterm_interrupts(), _routed(host):
        try:
            finished = False
            try:
                for link in host.links:
                    host.start(link)
                host.watch()
                finished = True
            finally:
                host.stop_all(finishing=finished)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            runtime.sync_hook = None
            runtime.controller_starter = None
            host.emit()
    if interrupted:
        return ProcessResult(130, True)
    return ProcessResult(host.code(), False)
