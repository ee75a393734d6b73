"""The child side of a controller process: one Webots Python controller in its own interpreter.

``dualtwin webots run`` starts one process per controller, as Webots does, with this file as its main script
(by path, so the child imports only the standard library: a child starts in a few tens of milliseconds). The
parent (:mod:`dualtwin.webots.controller_host`) keeps the real API objects over the simulation; this side
builds a ``controller`` module whose classes are proxies generated from the parent's description of the real
classes (same names, methods with the same signatures, read-only or settable properties, class constants,
plain instance attributes), then runs the controller script with its own ``sys.argv``, working directory,
module state and output.

Wire protocol (both directions): frames of a 4-byte big-endian length and a pickle. API objects cross as
handles (pickle persistent ids), plain data by value. As Webots' libController does, a steady control loop
costs one message each way per ``step`` (the parent's methods are marked in :mod:`.step_hints`):

* a buffered command (``motor.setVelocity(1.0)``: a marked method called with its exact number of arguments
  of the marked types) is queued, in order with the controller's output, and sent with the next message;
  any other call (a supervisor edit, ``enable``, an argument of another type) sends what is queued first, so
  the order of effects is the one the script wrote, and errors surface at the call;
* a marked getter (a sensor reading, the clock) is read at most once per step through the parent: its key
  joins the subscriptions sent with the next ``step``, whose answer brings the fresh value of every
  subscribed getter; the cache is dropped at each step and by any call that goes to the parent other than a
  read (a buffered command drops the values that echo commands, such as a motor's target). A subscription
  not read for :data:`SWEEP_STEPS` steps is dropped (a node handle got anew each step does not pile up).

The controller's ``sys.stdout``/``sys.stderr`` travel on the same channel, so the parent can print every
controller's output in robot order at each synchronisation point (deterministic output). SIGINT is ignored
here (the parent stops its children) and the child dies with its parent (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import atexit
import builtins
import codecs
import contextlib
import inspect
import io
import os
import pickle
import runpy
import select
import signal
import struct
import sys
import time
import types
from typing import Any

_LENGTH = struct.Struct("!I")
#: Output kept in the child before it is sent although no line ended (characters).
OUTPUT_CHUNK = 1 << 16
#: Steps between two sweeps of the subscriptions: one not read since the last sweep is dropped.
SWEEP_STEPS = 64
#: Receive buffer of a :class:`Wire` (bytes; it grows for a larger frame).
RECEIVE_BUFFER = 1 << 16
#: A waiting side that expects its answer sooner than this polls for it (microseconds; see :meth:`Wire.spin`).
SPIN_US = 250
_MISSING = object()
#: An int argument of a buffered command is queued only within a C int: beyond, a command that takes a whole number
#: raises (LED.set(10**20): Webots' ctypes cannot pass it), and the error must come at the call, as in a thread.
_C_INT_MIN, _C_INT_MAX = -(1 << 31), (1 << 31) - 1


class Wire:
    """Frames over a pair of stream file descriptors (two pipes; or one socket, both ways).

    A frame is written with one ``write``; reads go into one preallocated buffer (``readv``), so a message
    costs one system call each way and allocates nothing (a large ``os.read`` would map and unmap its
    buffer on every call)."""

    def __init__(self, fd: int, out_fd: int | None = None) -> None:
        self.fd = fd
        self.out_fd = fd if out_fd is None else out_fd
        self._buffer = bytearray(RECEIVE_BUFFER)
        self._view = memoryview(self._buffer)
        self._start = 0  # unread bytes are self._buffer[self._start:self._end]
        self._end = 0
        self._spin_s = 0.0
        self._typical_wait_s = 0.0
        self._poll: Any = None

    def spin(self, microseconds: float) -> None:
        """Poll for a frame for up to ``microseconds`` before sleeping in the kernel (0: always sleep).

        The two sides of a controller step in turns, and each turn is short (tens of microseconds on a small
        world). A side that sleeps in ``read`` must be woken by the other's ``write``; on a virtual machine that
        wake-up, from an idle core, costs more than the turn itself (about 20 us each way on 2 cores). A side
        that polls is awake when the frame lands. It polls only while the waits it measured stay shorter than
        the budget (a slow world or a slow controller: it sleeps at once, no core is burnt), and yields its core
        between polls, so controllers that outnumber the cores still let the simulation run.

        A wire that reads and writes one descriptor (a socket) never polls: its writes must stay blocking."""
        self._spin_s = max(0.0, microseconds) * 1e-6 if self.fd != self.out_fd else 0.0
        if self._spin_s and self._poll is None:
            os.set_blocking(self.fd, False)
            self._poll = select.poll()
            self._poll.register(self.fd, select.POLLIN)

    def send(self, data: bytes) -> None:
        """Length and payload in one ``writev`` (no copy of the payload to join them)."""
        header = _LENGTH.pack(len(data))
        written = os.writev(self.out_fd, (header, data))
        if written < len(header) + len(data):  # a large frame on a full pipe: the rest, as it drains
            view = memoryview(header + data)[written:]
            while view:
                view = view[os.write(self.out_fd, view):]

    def receive(self) -> bytes | None:
        """One frame's payload, or None when the other side closed the channel."""
        while True:
            buffer, start, end = self._buffer, self._start, self._end
            need = _LENGTH.size
            if end - start >= need:
                need += _LENGTH.unpack_from(buffer, start)[0]
                if end - start >= need:
                    frame = bytes(self._view[start + _LENGTH.size:start + need])  # one copy
                    self._start, self._end = (0, 0) if start + need == end else (start + need, end)
                    return frame
            if start + need > len(buffer):  # make room: move the partial frame to the front, grow if needed
                moved = bytearray(max(len(buffer), need))
                moved[:end - start] = buffer[start:end]
                self._buffer, self._view, self._start, self._end = moved, memoryview(moved), 0, end - start
                start, end = 0, end - start
            view = (self._view[end:],)
            got = self._read(view) if self._poll is not None else os.readv(self.fd, view)
            if not got:
                return None
            self._end = end + got

    def _read(self, view: tuple[memoryview]) -> int:
        """One ``readv`` on the non-blocking descriptor: at once, else polling (see :meth:`spin`), else asleep."""
        try:
            return os.readv(self.fd, view)
        except BlockingIOError:
            pass
        start = time.perf_counter()
        budget = self._spin_s
        if self._typical_wait_s < budget:
            limit = start + budget
            while True:
                os.sched_yield()
                try:
                    got = os.readv(self.fd, view)
                except BlockingIOError:
                    if time.perf_counter() < limit:
                        continue
                    break
                self._learn(time.perf_counter() - start)
                return got
        while True:
            self._poll.poll()
            try:
                got = os.readv(self.fd, view)
            except BlockingIOError:  # (woken with nothing to read)
                continue
            self._learn(time.perf_counter() - start)
            return got

    def _learn(self, waited_s: float) -> None:
        # a running mean of the last few waits, each counted at most as 4 budgets: one long pause (a controller
        # that computes once, a supervisor's reload) stops the polling for a handful of steps only
        waited_s = min(waited_s, 4 * self._spin_s)
        self._typical_wait_s += (waited_s - self._typical_wait_s) * 0.125

    def close(self) -> None:
        for fd in {self.fd, self.out_fd}:
            with contextlib.suppress(OSError):
                os.close(fd)


# ------------------------------------------------------------------------------------------ child side


class _ChannelOutput(io.RawIOBase):
    """The bytes under a controller's ``sys.stdout``/``sys.stderr``, decoded: text for the parent's own stream."""

    mode = "wb"

    def __init__(self, channel: _Channel, fd: int, encoding: str, errors: str) -> None:
        self._channel = channel
        self._fd = fd
        self._decoder = codecs.getincrementaldecoder(encoding)(errors)
        self.name = "<stdout>" if fd == 1 else "<stderr>"

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:  # the descriptor this process inherited, as the script's own stream has
        return self._fd

    def write(self, data: Any) -> int:
        text = self._decoder.decode(bytes(data))
        if text:
            self._channel.output(self._fd, text)
        return len(data)

    def flush(self) -> None:
        self._channel.flush_output()


def _stream(channel: _Channel, fd: int, original: Any) -> io.TextIOWrapper:
    """A text stream like the one this interpreter made (encoding, errors, line buffering) whose output goes to
    the parent, in order with the controller's calls: ``sys.stdout.buffer``, ``fileno()``, ``name`` as usual."""
    encoding = getattr(original, "encoding", None) or "utf-8"
    errors = getattr(original, "errors", None) or "strict"
    raw = _ChannelOutput(channel, fd, encoding, errors)
    stream = io.TextIOWrapper(raw, encoding=encoding, errors=errors,
                              line_buffering=bool(getattr(original, "line_buffering", False)), write_through=True)
    stream.mode = "w"  # type: ignore[misc]  # (as the interpreter's own streams say)
    return stream


class _RemoteError(Exception):
    """Base of exception classes the parent raised that do not exist here (same class name)."""


class _Channel:
    """The child's end: requests, buffered commands, the step's values and the output buffer."""

    def __init__(self, wire: Wire) -> None:
        self.wire = wire
        self.proxies: dict[int, Any] = {}
        self.classes: dict[str, type] = {}
        self.descriptions: dict[str, dict[str, Any]] = {}
        #: what goes with the next message, in the script's order: output ``(fd, text)`` and buffered
        #: commands ``(handle, name, args)``
        self.pending: list[tuple[Any, ...]] = []
        self.out_size = 0
        #: marked getters' values valid now, by (handle, name); ``echoes``: those a command drops
        self.values: dict[tuple[int, str], Any] = {}
        self.echoes: list[tuple[int, str]] = []
        #: every marked getter read so far (the parent sends their values with each step), and its kind
        self.subscribed: dict[tuple[int, str], bool] = {}  # key -> whether a command drops it
        self.subscribed_echoes: list[tuple[int, str]] | None = None  # (computed when needed)
        self.subscribed_keys: list[tuple[int, str]] | None = None  # the keys in order (likewise)
        self.new_subscriptions: list[tuple[int, str]] = []
        self.dropped: list[tuple[int, str]] = []
        self.used: set[tuple[int, str]] = set()  # read since the last sweep
        self.steps = 0
        self.errors: dict[str, type[BaseException]] = {}
        self.closed = False

    # -- output

    def output(self, fd: int, text: str) -> None:
        self.pending.append((fd, text))
        self.out_size += len(text)
        if "\n" in text or self.out_size >= OUTPUT_CHUNK:  # line-buffered, so nothing waits for a call
            self.flush_output()

    def flush_output(self) -> None:
        if self.out_size and not self.closed:
            self._send(("out",))

    # -- wire

    def _send(self, message: tuple[Any, ...]) -> None:
        """Send ``message`` with what is pending and the subscription changes: one pickle, one write."""
        message = (*message, self.pending, self.new_subscriptions, self.dropped)
        self.pending, self.out_size = [], 0
        if self.new_subscriptions:  # (most messages change no subscription: no new lists for them)
            self.new_subscriptions = []
        if self.dropped:
            self.dropped = []
        global _SENDING
        _SENDING = True
        try:  # plain data (the usual case) pickles in C; an API object in it needs its handle
            data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        except _HandleNeeded:
            buf = io.BytesIO()
            pickler = pickle.Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL)
            pickler.persistent_id = self._persistent_id  # type: ignore[method-assign]
            pickler.dump(message)
            data = pickle.dumps(("H", buf.getvalue()), protocol=pickle.HIGHEST_PROTOCOL)
        finally:
            _SENDING = False
        self.wire.send(data)

    def _persistent_id(self, obj: Any) -> Any:
        if isinstance(obj, _Foreign):
            return ("f", *obj.described)
        if isinstance(obj, _Proxy) and type(obj)._dualtwin_role == "value":  # its data: the parent rebuilds it
            return ("v", type(obj)._dualtwin_real, dict(vars(obj)))
        handle = getattr(obj, "_dualtwin_handle", None) if isinstance(obj, _Proxy) else None
        return ("h", handle) if handle is not None else None

    def request(self, message: tuple[Any, ...]) -> Any:
        """Send ``message`` (with what is pending) and return the parent's answer. Any request but a read
        may change what the marked getters return: their values are dropped (a read keeps them)."""
        if message[0] != "read":
            self.values = {}
            self.echoes = []
            if message[0] != "call":  # (a call's arguments are made crossable by ``call``)
                message = _crossing(message)
        return self._exchange(message)[0]

    def _exchange(self, message: tuple[Any, ...]) -> tuple[Any, Any]:
        """(answer, fresh values of the subscribed getters or None)."""
        if self.closed:
            raise SystemExit(0)
        self._send(message)
        frame = self.wire.receive()
        if frame is None:  # the parent is gone or stopped this controller
            self.closed = True
            os._exit(0)
        reply = pickle.loads(frame)
        status, value, fresh = reply[0], reply[1], reply[2]
        if len(reply) > 3:  # the answer names API objects: pickled with handles, after new descriptions
            for description in reply[3]:
                self.descriptions[description["key"]] = description
            unpickler = pickle.Unpickler(io.BytesIO(value))
            unpickler.persistent_load = self._persistent_load  # type: ignore[assignment]
            value = unpickler.load()
        if status == "ok":
            return value, fresh
        raise self._error(*value)

    def _error(self, kind: str, name: str, message: str, code: Any = None, builtin: str | None = None,
               args: tuple[Any, ...] | None = None) -> BaseException:
        if kind == "exit":  # ControllerStopped: the parent's own class, caught by ``except ControllerStopped`` too
            return (self.error_class(name) if name in self.descriptions else SystemExit)(code)
        cls = getattr(builtins, name, None)
        if not (isinstance(cls, type) and issubclass(cls, BaseException)):
            cls = self.error_class(name, builtin)
        return cls(*args) if args is not None else cls(message)  # (the same ``args`` where they could cross)

    def error_class(self, name: str, builtin: str | None = None) -> type[BaseException]:
        """The one class here for the parent's exception class ``name``: the one a raised error has and, for an
        exported one (``SimulationUnstable``), the one ``from controller import`` gives, so that the script can
        catch it (a proxy class there made ``except SimulationUnstable`` itself raise TypeError). It derives from
        the parent's class's built-in base (``except TypeError`` catches NumPy's UFuncTypeError here too)."""
        cls = self.errors.get(name)
        if cls is None:
            base = getattr(builtins, self.descriptions.get(name, {}).get("builtin_base") or builtin or "", None)
            bases: tuple[type, ...] = (_RemoteError,)
            if isinstance(base, type) and issubclass(base, Exception) and base is not Exception:
                bases = (_RemoteError, base)
            elif isinstance(base, type) and issubclass(base, BaseException) and base is not BaseException:
                bases = (base,)  # ControllerStopped, a SystemExit: ``except Exception`` must not catch it
            cls = self.errors[name] = type(name, bases, {"__module__": "controller"})
        return cls

    def _persistent_load(self, pid: Any) -> Any:
        kind = pid[0]
        if kind == "h":
            _, handle, class_name, attrs, equal = pid
            proxy = self.proxies.get(handle)
            if proxy is None:
                cls = self.proxy_class(class_name)
                proxy = object.__new__(cls)
                object.__setattr__(proxy, "_dualtwin_handle", handle)
                if equal is not None:  # the handle of the first object equal to it (see _build_class)
                    object.__setattr__(proxy, "_dualtwin_equal", equal)
                self.proxies[handle] = proxy
            if attrs:
                for key, value in attrs.items():
                    object.__setattr__(proxy, key, value)
            return proxy
        _, class_name, attrs, results = pid  # a value object: its data and the results of its getters
        return _rebuild_value(class_name, attrs, results)

    # -- API calls

    def call(self, proxy: Any, name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        return self.request(("call", proxy._dualtwin_handle, name, *_arguments(args, kwargs)))

    def buffer(self, handle: int, name: str, args: tuple[Any, ...]) -> None:
        """Queue a command for the next message; the values that echo commands are no longer known."""
        self.pending.append((handle, name, args))
        if self.echoes:
            values = self.values
            for key in self.echoes:
                values.pop(key, None)
            self.echoes = []

    def read(self, handle: int, name: str, echo: bool) -> Any:
        """A marked getter's value: from this step's values, else read through the parent (and subscribed)."""
        key = (handle, name)
        self.used.add(key)
        value = self.values.get(key, _MISSING)
        if value is _MISSING:
            if key not in self.subscribed:
                self.subscribed[key] = echo
                self.subscribed_echoes = self.subscribed_keys = None
                self.new_subscriptions.append(key)
            value, printed = self._exchange(("read", handle, name))
            if printed is not False:  # False: the read printed (an error): each read asks again, as each prints
                self.values[key] = value
                if echo:
                    self.echoes.append(key)
        return value.copy() if type(value) is list else value  # a fresh list per call, as the parent gives

    def advance(self, proxy: Any, name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        """``step``: the answer brings the fresh values of every subscribed getter (``(values, missing)``:
        values in subscription order; ``missing``: indexes the parent could not read quietly, left to a read)."""
        self.values = {}
        self.echoes = []
        self.steps += 1
        if self.steps % SWEEP_STEPS == 0:
            self._sweep()
        result, fresh = self._exchange(("call", proxy._dualtwin_handle, name, *_arguments(args, kwargs)))
        if fresh is not None:
            values, missing = fresh
            keys = self.subscribed_keys
            if keys is None:
                keys = self.subscribed_keys = list(self.subscribed)
            self.values = dict(zip(keys, values, strict=True))
            for index in missing:
                del self.values[keys[index]]
            if self.subscribed_echoes is None:
                self.subscribed_echoes = [key for key, echo in self.subscribed.items() if echo]
            self.echoes = list(self.subscribed_echoes)
        return result

    def _sweep(self) -> None:
        """Drop the subscriptions not read since the last sweep (the parent drops them with the next message)."""
        stale = [key for key in self.subscribed if key not in self.used]
        for key in stale:
            del self.subscribed[key]
        if stale:
            self.subscribed_echoes = self.subscribed_keys = None
            self.dropped.extend(stale)
        self.used = set()

    def proxy_class(self, name: str) -> type[Any]:
        cls = self.classes.get(name)
        if cls is None:
            description = self.descriptions[name]
            if description["role"] == "exception":
                return self.error_class(name)
            bases = tuple(self.proxy_class(b) for b in description["bases"]) or (_Proxy,)
            cls = _build_class(self, description, bases)
            self.classes[name] = cls
        return cls


_PLAIN = frozenset({int, float, complex, str, bytes, bool, type(None)})
_PLAIN_BASES: tuple[Any, ...] = (bool, int, float, complex, str, bytes, tuple, list, dict)


class _Foreign:
    """An argument the parent could not rebuild (an object of the script's own class, a generator): it reaches the
    API as a stand-in of its class name and text, refused in the API's own words, as the object is in a thread."""

    def __init__(self, value: Any) -> None:
        self.described = (type(value).__module__, type(value).__qualname__, repr(value))

    def __reduce_ex__(self, protocol: Any) -> Any:
        raise _HandleNeeded


def _arguments(args: tuple[Any, ...], kwargs: dict[str, Any]) -> tuple[Any, ...]:  # (see _crossing)
    for arg in args:  # plain arguments (the usual case) as they are, at the cost of this check only
        if type(arg) not in _PLAIN:
            return _crossing(args), _crossing(kwargs)
    return args, _crossing(kwargs) if kwargs else kwargs


def _crossing(value: Any, depth: int = 0) -> Any:
    """``value`` as the parent can rebuild it: an instance of a subclass of a plain type (an IntEnum) as that type's
    value, anything but plain data, NumPy, API objects and standard objects that pickle as a :class:`_Foreign`."""
    cls = type(value)
    if cls in _PLAIN or isinstance(value, _Proxy) or depth > 32:
        return value
    if cls is tuple or cls is list:
        items = [_crossing(v, depth + 1) for v in value]
        return tuple(items) if cls is tuple else items
    if cls is dict:
        return {_crossing(k, depth + 1): _crossing(v, depth + 1) for k, v in value.items()}
    top = cls.__module__.partition(".")[0]
    if top == "numpy" and cls.__name__ == "ndarray":
        if not value.dtype.hasobject:
            return value
        if value.dtype.kind == "O":  # an array of objects: each as the parent can rebuild it, in an array still
            out = value.copy()
            flat = out.reshape(-1)  # (a view: the copy is contiguous)
            for i, item in enumerate(value.flat):
                flat[i] = _crossing(item, depth + 1)
            return out
    if top != "numpy":  # (a NumPy float64 is a float, and stays a float64)
        for base in _PLAIN_BASES:
            if isinstance(value, base):
                return _crossing(base(value), depth)
    if _rebuilt_by_parent(cls.__module__):
        try:  # every object the pickle holds, not only the value's class (a set holding one of the script's)
            _ParentPickler(io.BytesIO(), protocol=pickle.HIGHEST_PROTOCOL).dump(value)
        except Exception:
            return _Foreign(value)
        return value
    return _Foreign(value)


def _rebuilt_by_parent(module: str) -> bool:  # the parent has NumPy and the standard library, not the script
    top = module.partition(".")[0]
    return top == "numpy" or top in sys.stdlib_module_names and top != "__main__"


class _ParentPickler(pickle.Pickler):
    """Pickles only what the parent can rebuild: it raises on an object, class or function of another module."""

    def persistent_id(self, obj: Any) -> None:
        named = obj if isinstance(obj, type | types.FunctionType) else type(obj)
        if not _rebuilt_by_parent(getattr(named, "__module__", None) or ""):
            raise pickle.PicklingError(f"the parent cannot rebuild {named!r}")


class _HandleNeeded(Exception):
    """Raised when an API object is pickled without the channel's persistent ids (then they are used)."""


_SENDING = False  # a message to the parent is being pickled (see _Proxy.__reduce_ex__)
_CHANNEL: list[_Channel] = []  # this process's channel, for _rebuild_value (controller._dualtwin_value)


def _rebuild_value(key: str, attrs: dict[str, Any], results: dict[str, Any]) -> Any:
    value = object.__new__(_CHANNEL[0].proxy_class(key))
    value.__dict__.update(attrs)
    object.__setattr__(value, "_dualtwin_results", results)
    return value


_rebuild_value.__module__ = "controller"
_rebuild_value.__qualname__ = _rebuild_value.__name__ = "_dualtwin_value"


class _Proxy:
    """Base of every generated class: an object that lives in the parent, named by a handle (the channel's own
    fields are slots, out of its ``__dict__``: ``vars(obj)`` shows the real object's attributes)."""
    __slots__ = ("_dualtwin_handle", "_dualtwin_results", "_dualtwin_equal", "__weakref__")
    _dualtwin_role = "other"
    _dualtwin_real = ""

    def __reduce_ex__(self, protocol: Any) -> Any:
        if _SENDING:  # to the parent: as a handle, or a value object's data (``_Channel._persistent_id``)
            raise _HandleNeeded
        if type(self)._dualtwin_role == "value":  # the script's own pickle or copy of a LidarPoint, a RadarTarget:
            # rebuilt from its data by ``controller._dualtwin_value`` (any controller process has it)
            state = dict(vars(self)), getattr(self, "_dualtwin_results", {})
            return _rebuild_value, (type(self)._dualtwin_real, *state)
        raise TypeError(f"cannot pickle {type(self).__name__!r} object")  # an object of the simulation's process

    def __repr__(self) -> str:  # as ``object.__repr__`` writes an object of the real class
        return f"<{type(self).__module__}.{type(self).__qualname__} object at {id(self):#x}>"


def _build_class(channel: _Channel, description: dict[str, Any], bases: tuple[type, ...]) -> type:
    name = description["name"]
    qualified = description.get("qualified", f"controller.{name}")
    # the real class's module and, below, its methods' qualified names: what introspection of it reads
    ns: dict[str, Any] = {"__module__": qualified.rpartition(".")[0], "__doc__": description.get("doc")}
    ns["_dualtwin_role"] = description["role"]
    ns["_dualtwin_real"] = description["key"]
    value_class = description["role"] == "value"
    for attr, (kind, extra) in description["members"].items():
        if kind == "constant":
            ns[attr] = extra
        elif kind == "property":
            ns[attr] = _value_property(attr) if value_class else _remote_property(channel, attr, extra)
        elif kind == "method":
            ns[attr] = _value_method(name, attr, extra) if value_class else _remote_method(channel, attr, extra)
        elif kind == "static":
            ns[attr] = staticmethod(_static_method(channel, description["key"], attr, extra))
    if description.get("constructible"):
        ns["__init__"] = _remote_init(channel, description.get("init"))
    for member in ns.values():
        function = member.__func__ if isinstance(member, staticmethod) else member
        if inspect.isfunction(function):
            function.__qualname__ = f"{name}.{function.__name__}"
    dunders = description.get("dunders", ())
    if description.get("unhashable"):
        ns["__hash__"] = None
    if value_class:
        _value_dunders(ns, dunders)
    else:
        _remote_dunders(channel, ns, dunders)
    return type(name, bases, ns)


def _remote_dunders(channel: _Channel, ns: dict[str, Any], dunders: Any) -> None:
    """Own text from the object; own ``__eq__`` (a Node's: one scene node) by the first handle of equal objects."""
    for special in ("__repr__", "__str__"):
        if special in dunders:
            def text(self: Any, special: str = special) -> Any:
                return channel.request(("call", self._dualtwin_handle, special, (), {}))

            ns[special] = text
    if "__eq__" in dunders:
        def __eq__(self: Any, other: Any) -> Any:
            mine = getattr(self, "_dualtwin_equal", None)
            if mine is None or not isinstance(other, _Proxy):
                return NotImplemented if mine is None else False
            return mine == getattr(other, "_dualtwin_equal", None)

        def __hash__(self: Any) -> int:
            return hash(getattr(self, "_dualtwin_equal", id(self)))

        ns["__eq__"] = __eq__
        ns.setdefault("__hash__", __hash__)


def _value_dunders(ns: dict[str, Any], dunders: Any) -> None:
    """A value object's own text and hash are the parent's, taken with it; its own ``__eq__`` compares the data."""
    for special in ("__repr__", "__str__", "__hash__"):
        if special in dunders:
            ns[special] = lambda self, special=special: self._dualtwin_results[special]
    if "__eq__" in dunders:
        def __eq__(self: Any, other: Any) -> Any:
            if type(other) is not type(self):
                return NotImplemented
            return vars(self) == vars(other)

        ns["__eq__"] = __eq__


def _remote_method(channel: _Channel, name: str, extra: tuple[inspect.Signature | None, Any]) -> Any:
    signature, hint = extra
    kind = hint[0] if hint else None
    if kind == "buffered":
        arity, accepted = hint[1], frozenset(hint[2])

        def method(self: Any, *args: Any, **kwargs: Any) -> Any:
            if not kwargs and len(args) == arity:
                for arg in args:
                    if type(arg) not in accepted or type(arg) is int and not _C_INT_MIN <= arg <= _C_INT_MAX:
                        break
                else:
                    channel.buffer(self._dualtwin_handle, name, args)
                    return None
            return channel.call(self, name, args, kwargs)

    elif kind in ("step", "command"):
        echo = kind == "command"

        def method(self: Any, *args: Any, **kwargs: Any) -> Any:
            if args or kwargs:  # Webots' own TypeError, from the parent
                return channel.call(self, name, args, kwargs)
            return channel.read(self._dualtwin_handle, name, echo)

    elif kind == "advances":

        def method(self: Any, *args: Any, **kwargs: Any) -> Any:
            return channel.advance(self, name, args, kwargs)

    else:

        def method(self: Any, *args: Any, **kwargs: Any) -> Any:
            return channel.call(self, name, args, kwargs)

    method.__name__ = method.__qualname__ = name
    if signature is not None:
        method.__signature__ = signature  # type: ignore[attr-defined]
    return method


def _static_method(channel: _Channel, class_name: str, name: str, signature: inspect.Signature | None) -> Any:
    def function(*args: Any, **kwargs: Any) -> Any:
        return channel.request(("static", class_name, name, args, kwargs))

    function.__name__ = function.__qualname__ = name
    if signature is not None:
        function.__signature__ = signature  # type: ignore[attr-defined]
    return function


def _remote_property(channel: _Channel, name: str, extra: tuple[bool, Any, Any, bool]) -> property:
    settable, getter, setter, readable = extra

    def fget(self: Any) -> Any:
        return channel.request(("get", self._dualtwin_handle, name))

    def fset(self: Any, value: Any) -> None:
        channel.request(("set", self._dualtwin_handle, name, value))

    if getter is not None and getter[1][0] in ("step", "command"):  # ``value = property(getValue)``
        method, echo = getter[0], getter[1][0] == "command"

        def fget(self: Any) -> Any:  # noqa: F811 - the served variant
            return channel.read(self._dualtwin_handle, method, echo)

    if setter is not None and setter[1][0] == "buffered" and setter[1][1] == 1:  # ``= property(get, setVelocity)``
        command, accepted = setter[0], frozenset(setter[1][2])

        def fset(self: Any, value: Any) -> None:  # noqa: F811 - the buffered variant
            if type(value) in accepted and (type(value) is not int or _C_INT_MIN <= value <= _C_INT_MAX):
                channel.buffer(self._dualtwin_handle, command, (value,))
            else:
                channel.request(("set", self._dualtwin_handle, name, value))

    return property(fget if readable else None, fset if settable else None)


def _value_method(class_name: str, name: str, extra: tuple[inspect.Signature | None, Any]) -> Any:
    signature = extra[0]
    if signature is not None and len(signature.parameters) == 1:
        # a getter (its result came with the object): given arguments, Python's own TypeError for the real method

        def method(self: Any) -> Any:
            results = self._dualtwin_results
            if name not in results:
                raise NotImplementedError(f"{type(self).__name__}.{name}() is not available in a controller process")
            return results[name]

    else:

        def method(self: Any, *args: Any, **kwargs: Any) -> Any:  # type: ignore[misc]
            raise NotImplementedError(f"{type(self).__name__}.{name}() is not available in a controller process")

    method.__name__ = name
    method.__qualname__ = f"{class_name}.{name}"
    if signature is not None:
        method.__signature__ = signature  # type: ignore[attr-defined]
    return method


def _value_property(name: str) -> property:
    return property(lambda self: self._dualtwin_results[name])


def _remote_init(channel: _Channel, signature: inspect.Signature | None) -> Any:
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        handle, attrs = channel.request(("new", type(self)._dualtwin_real, args, kwargs))
        object.__setattr__(self, "_dualtwin_handle", handle)
        channel.proxies[handle] = self
        for key, value in attrs.items():
            setattr(self, key, value)
        # Webots' Robot.__init__ records the process's first Robot in the class attribute ``created`` (a Supervisor
        # or a user subclass included); the parent keeps it for its own class, this process needs its own copy.
        robot = next((c for c in type(self).__mro__ if c.__dict__.get("_dualtwin_real") == "Robot"), None)
        if robot is not None and robot.__dict__.get("created") is None:
            robot.created = self  # type: ignore[attr-defined]

    if signature is not None:
        __init__.__signature__ = signature  # type: ignore[attr-defined]
    return __init__


def _die_with_parent(parent: int) -> None:
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # not Linux: the closed channel still ends the child at its next call
        pass
    if os.getppid() != parent:
        os._exit(1)


def _main(argv: list[str]) -> None:
    fd, out_fd, parent = int(argv[1]), int(argv[2]), int(argv[3])
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)
    wire = Wire(fd, out_fd)
    frame = wire.receive()
    if frame is None:
        os._exit(1)
    start = pickle.loads(frame)
    wire.spin(start.get("spin_us", 0))
    channel = _Channel(wire)
    for description in start["classes"]:
        channel.descriptions[description["key"]] = description
    module = types.ModuleType("controller", start.get("doc"))
    exports = frozenset(start["exports"])

    def exported(name: str) -> type[Any]:  # classes are built when first imported (PEP 562)
        if name not in exports:
            raise AttributeError(f"module 'controller' has no attribute {name!r}")
        cls = channel.proxy_class(name)
        setattr(module, name, cls)
        return cls

    module.__getattr__ = exported  # type: ignore[method-assign]
    module.__all__ = list(start["exports"])  # type: ignore[attr-defined]
    module._dualtwin_value = _rebuild_value  # type: ignore[attr-defined]
    _CHANNEL.append(channel)
    sys.modules["controller"] = module
    script = start["script"]
    sys.argv = [script, *start["args"]]
    sys.path[0] = os.path.dirname(script)  # the controller's folder, as when Webots runs ``python NAME.py``
    sys.stdout = sys.__stdout__ = _stream(channel, 1, sys.stdout)  # type: ignore[misc]
    sys.stderr = sys.__stderr__ = _stream(channel, 2, sys.stderr)  # type: ignore[misc]
    status: list[Any] = [0]

    def finish() -> None:  # registered first, so it runs last of the exit handlers
        try:
            sys.stdout.flush()
            channel._send(("exit", status[0]))
        except OSError:
            pass
        channel.closed = True

    atexit.register(finish)
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as exc:
        code = exc.code
        if code is None:
            status[0] = 0
        elif isinstance(code, int):
            status[0] = code
        else:
            print(code, file=sys.stderr)
            status[0] = 1
    except BaseException as exc:
        if type(exc).__name__ == "SimulationUnstable" and type(exc).__module__ == "controller":
            # the physics blew up (a step raised it, and the script let it through): the run ends on one line,
            # not on a traceback of the script (a supervisor teleporting a slider to 1e308 m, found by fuzzing)
            print(f"Error: {exc}", file=sys.stderr)
            status[0] = 1
            sys.exit(status[0])
        import traceback

        tb = exc.__traceback__  # from the script's first frame on: how it was started is no business of it
        while tb is not None and (tb.tb_frame.f_code.co_filename == __file__
                                  or tb.tb_frame.f_code.co_filename.startswith("<frozen ")):
            tb = tb.tb_next
        traceback.print_exception(type(exc), exc, tb)
        status[0] = 1
    sys.exit(status[0])


if __name__ == "__main__":
    _main(sys.argv)
