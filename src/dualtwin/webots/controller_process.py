"""The child side of a controller process: one Webots Python controller in its own interpreter.

``dualtwin webots run`` starts one process per controller, as Webots does, with this file as its main script
(by path, so the child imports only the standard library: a child starts in a few tens of milliseconds). The
parent (:mod:`dualtwin.webots.controller_host`) keeps the real API objects over the simulation; this side
builds a ``controller`` module whose classes are proxies generated from the parent's description of the real
classes (same names, methods with the same signatures, read-only or settable properties, class constants,
plain instance attributes), then runs the controller script with its own ``sys.argv``, working directory,
module state and output.

Wire protocol (both directions): frames of a 4-byte big-endian length and a pickle. API objects cross as
handles (pickle persistent ids), plain data by value. Like Webots' libController, the child batches commands
and caches sensor readings, so a steady control loop costs one round trip per ``step``:

* a device's ``set*``/``enable``/``disable`` call whose arguments are plain numbers is queued and sent, in
  order, with the next message, once a call of the same method with the same argument types was accepted
  (the first one, and any other argument, is sent at once, so a ``TypeError`` is raised at the call); an
  error a queued command raises (a value refused) is raised at the next synchronous call;
* argument-less sensor reads (:data:`CACHED_READS`) are kept until the next ``step``, and the reads made
  during one step are computed by the parent right after the next one and returned with its reply.

The controller's ``sys.stdout``/``sys.stderr`` travel on the same channel, so the parent can print every
controller's output in robot order at each synchronisation point (deterministic output). SIGINT is ignored
here (the parent stops its children) and the child dies with its parent (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import atexit
import builtins
import contextlib
import inspect
import io
import os
import pickle
import runpy
import signal
import struct
import sys
import types
from typing import Any

_LENGTH = struct.Struct("!I")
#: Output kept in the child before it is sent although no line ended (characters).
OUTPUT_CHUNK = 1 << 16
#: Argument-less reads whose value changes only at ``step`` (cached per step and prefetched).
CACHED_READS = frozenset(
    {"getValue", "getValues", "getRollPitchYaw", "getQuaternion", "getSpeed", "getSpeedVector",
     "getTargetPosition", "getVelocity", "getTorqueFeedback", "getForceFeedback", "getSamplingPeriod"}
)
#: Device methods queued when their arguments are plain numbers (commands Webots sends with the next step).
QUEUED_PREFIXES = ("set",)
QUEUED_NAMES = frozenset({"enable", "disable"})
_PLAIN_NUMBERS = (int, float)


class Wire:
    """Frames over a connected stream file descriptor (a socketpair end), read in large chunks."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self._buffer = bytearray()

    def send(self, data: bytes) -> None:
        view = memoryview(_LENGTH.pack(len(data)) + data)
        while view:
            view = view[os.write(self.fd, view):]

    def receive(self) -> bytes | None:
        """One frame's payload, or None when the other side closed the channel."""
        buffer = self._buffer
        while True:
            if len(buffer) >= _LENGTH.size:
                end = _LENGTH.size + _LENGTH.unpack_from(buffer)[0]
                if len(buffer) >= end:
                    frame = bytes(buffer[_LENGTH.size:end])
                    del buffer[:end]
                    return frame
            chunk = os.read(self.fd, 1 << 18)
            if not chunk:
                return None
            buffer += chunk

    def close(self) -> None:
        with contextlib.suppress(OSError):
            os.close(self.fd)


# ------------------------------------------------------------------------------------------ child side


class _Stream(io.TextIOBase):
    """``sys.stdout``/``sys.stderr`` of a controller: text sent to the parent with the next message."""

    def __init__(self, channel: _Channel, fd: int) -> None:
        self._channel = channel
        self._fd = fd

    def writable(self) -> bool:
        return True

    @property
    def encoding(self) -> str:  # type: ignore[override]
        return "utf-8"

    def write(self, text: str) -> int:
        if not isinstance(text, str):
            raise TypeError(f"write() argument must be str, not {type(text).__name__}")
        if text:
            self._channel.output(self._fd, text)
        return len(text)

    def flush(self) -> None:
        self._channel.flush_output()

    def isatty(self) -> bool:
        return False


class _RemoteError(Exception):
    """Base of exception classes the parent raised that do not exist here (same class name)."""


class _Channel:
    """The child's end: RPCs, queued commands, the per-step read cache and the output buffer."""

    def __init__(self, wire: Wire) -> None:
        self.wire = wire
        self.proxies: dict[int, Any] = {}
        self.classes: dict[str, type] = {}
        self.descriptions: dict[str, dict[str, Any]] = {}
        self.queued: list[tuple[int, str, tuple[Any, ...]]] = []
        self.cache: dict[tuple[int, str], Any] = {}
        self.reads: set[tuple[int, str]] = set()
        self.out: list[tuple[int, str]] = []
        self.out_size = 0
        self.errors: dict[str, type[BaseException]] = {}
        self.accepted: set[tuple[str, str, tuple[type, ...]]] = set()  # command shapes known to be accepted
        self.closed = False

    # -- output

    def output(self, fd: int, text: str) -> None:
        self.out.append((fd, text))
        self.out_size += len(text)
        if "\n" in text or self.out_size >= OUTPUT_CHUNK:  # line-buffered, so nothing waits for a call
            self.flush_output()

    def flush_output(self) -> None:
        if self.out and not self.closed:
            self._send(("out",))

    def _take(self) -> tuple[list[tuple[int, str]], list[tuple[int, str, tuple[Any, ...]]]]:
        out, queued = self.out, self.queued
        self.out, self.out_size, self.queued = [], 0, []
        return out, queued

    # -- wire

    def _send(self, message: tuple[Any, ...]) -> None:
        out, queued = self._take()
        try:  # plain data (the usual case) pickles in C; an API object in it needs its handle
            data = pickle.dumps((*message, out, queued), protocol=pickle.HIGHEST_PROTOCOL)
        except _HandleNeeded:
            buf = io.BytesIO()
            pickler = pickle.Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL)
            pickler.persistent_id = self._persistent_id  # type: ignore[method-assign]
            pickler.dump((*message, out, queued))
            data = buf.getvalue()
        self.wire.send(data)

    def _persistent_id(self, obj: Any) -> Any:
        handle = getattr(obj, "_dualtwin_handle", None) if isinstance(obj, _Proxy) else None
        return ("h", handle) if handle is not None else None

    def request(self, message: tuple[Any, ...]) -> Any:
        """Send ``message`` (with pending output and commands) and return the parent's answer."""
        if self.closed:
            raise SystemExit(0)
        self._send(message)
        frame = self.wire.receive()
        if frame is None:  # the parent is gone or stopped this controller
            self.closed = True
            os._exit(0)
        status, descriptions, payload = pickle.loads(frame)
        for description in descriptions:
            self.descriptions[description["key"]] = description
        unpickler = pickle.Unpickler(io.BytesIO(payload))
        unpickler.persistent_load = self._persistent_load  # type: ignore[assignment]
        value = unpickler.load()
        if status == "ok":
            return value
        raise self._error(*value)

    def _error(self, kind: str, name: str, message: str, code: Any = None) -> BaseException:
        if kind == "exit":
            return SystemExit(code)
        cls = getattr(builtins, name, None)
        if not (isinstance(cls, type) and issubclass(cls, BaseException)):
            cls = self.errors.get(name)
            if cls is None:
                cls = self.errors[name] = type(name, (_RemoteError,), {"__module__": "controller"})
        return cls(message)

    def _persistent_load(self, pid: Any) -> Any:
        kind = pid[0]
        if kind == "h":
            _, handle, class_name, attrs = pid
            proxy = self.proxies.get(handle)
            if proxy is None:
                cls = self.proxy_class(class_name)
                proxy = object.__new__(cls)
                object.__setattr__(proxy, "_dualtwin_handle", handle)
                self.proxies[handle] = proxy
            if attrs:
                for key, value in attrs.items():
                    object.__setattr__(proxy, key, value)
            return proxy
        _, class_name, attrs, results = pid  # a value object: its data and the results of its getters
        cls = self.proxy_class(class_name)
        value = object.__new__(cls)
        value.__dict__.update(attrs)
        object.__setattr__(value, "_dualtwin_results", results)
        return value

    # -- API calls

    def call(self, proxy: Any, name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        handle = proxy._dualtwin_handle
        role = type(proxy)._dualtwin_role
        if role == "device" and not kwargs and (name in QUEUED_NAMES or name.startswith(QUEUED_PREFIXES)):
            kinds = tuple(type(a) for a in args)
            if all(k in _PLAIN_NUMBERS for k in kinds):
                shape = (type(proxy)._dualtwin_real, name, kinds)
                for key in [k for k in self.cache if k[0] == handle]:
                    del self.cache[key]
                if shape in self.accepted:
                    self.queued.append((handle, name, args))
                    return None
                # the first call of this shape goes at once, so a type the method refuses raises here
                value = self.request(("call", handle, name, args, kwargs, ()))
                self.accepted.add(shape)
                return value
        if role == "device" and name in CACHED_READS and not args and not kwargs:
            key = (handle, name)
            self.reads.add(key)
            if key in self.cache:
                return self.cache[key]
            value = self.request(("call", handle, name, args, kwargs, ()))
            self.cache[key] = value
            return value
        if role == "robot" and name == "step":
            reads = tuple(self.reads)
            self.reads = set()
            self.cache = {}
            result, prefetched = self.request(("call", handle, name, args, kwargs, reads))
            self.cache = dict(prefetched)
            return result
        self.cache = {}
        return self.request(("call", handle, name, args, kwargs, ()))

    def proxy_class(self, name: str) -> type[Any]:
        cls = self.classes.get(name)
        if cls is None:
            description = self.descriptions[name]
            bases = tuple(self.proxy_class(b) for b in description["bases"]) or (_Proxy,)
            cls = _build_class(self, description, bases)
            self.classes[name] = cls
        return cls


class _HandleNeeded(Exception):
    """Raised when an API object is pickled without the channel's persistent ids (then they are used)."""


class _Proxy:
    """Base of every generated class: an object that lives in the parent, named by a handle."""

    _dualtwin_role = "other"
    _dualtwin_real = ""

    def __reduce_ex__(self, protocol: Any) -> Any:
        raise _HandleNeeded

    def __repr__(self) -> str:
        return f"<{type(self).__name__} (controller proxy)>"


def _build_class(channel: _Channel, description: dict[str, Any], bases: tuple[type, ...]) -> type:
    name = description["name"]
    ns: dict[str, Any] = {"__module__": "controller", "__doc__": description.get("doc")}
    ns["_dualtwin_role"] = description["role"]
    ns["_dualtwin_real"] = description["key"]
    value_class = description["role"] == "value"
    for attr, (kind, extra) in description["members"].items():
        if kind == "constant":
            ns[attr] = extra
        elif kind == "property":
            ns[attr] = _value_property(attr) if value_class else _remote_property(channel, attr, extra)
        elif kind == "method":
            ns[attr] = _value_method(attr, extra) if value_class else _remote_method(channel, attr, extra)
        elif kind == "static":
            ns[attr] = staticmethod(_static_method(channel, description["key"], attr, extra))
    if description.get("constructible"):
        ns["__init__"] = _remote_init(channel, description.get("init"))
    return type(name, bases, ns)


def _remote_method(channel: _Channel, name: str, signature: inspect.Signature | None) -> Any:
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


def _remote_property(channel: _Channel, name: str, settable: bool) -> property:
    def fget(self: Any) -> Any:
        channel.cache = {}
        return channel.request(("get", self._dualtwin_handle, name))

    def fset(self: Any, value: Any) -> None:
        channel.cache = {}
        channel.request(("set", self._dualtwin_handle, name, value))

    return property(fget, fset if settable else None)


def _value_method(name: str, signature: inspect.Signature | None) -> Any:
    def method(self: Any, *args: Any, **kwargs: Any) -> Any:
        results = self._dualtwin_results
        if args or kwargs or name not in results:
            raise NotImplementedError(f"{type(self).__name__}.{name}() is not available in a controller process")
        return results[name]

    method.__name__ = method.__qualname__ = name
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
    fd, parent = int(argv[1]), int(argv[2])
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)
    wire = Wire(fd)
    frame = wire.receive()
    if frame is None:
        os._exit(1)
    start = pickle.loads(frame)
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
    sys.modules["controller"] = module
    script = start["script"]
    sys.argv = [script, *start["args"]]
    sys.path[0] = os.path.dirname(script)  # the controller's folder, as when Webots runs ``python NAME.py``
    sys.stdout = _Stream(channel, 1)
    sys.stderr = _Stream(channel, 2)
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
