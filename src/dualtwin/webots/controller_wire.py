"""What crosses between the parent and a controller process: class descriptions, handles and values.

The parent describes the real API classes by reflection (:func:`describe_class`): for every public name of a
class, its kind (method with its signature, read-only or settable property, static method, constant) so the
child (:mod:`.controller_process`) can generate a proxy class of the same name and shape. Objects then cross a
:class:`HandleTable` pickle as persistent ids:

* API objects (robots, devices, nodes, fields, the keyboard, anything else of this package) are *handles*:
  the object stays here and the child gets a proxy (with the object's public plain attributes copied once);
* *value* classes (dataclasses, classes setting ``__webots_value__ = True``, and :data:`VALUE_CLASSES`) are
  plain data: their public attributes and the results of their argument-less getters travel by value;
* everything else (numbers, strings, bytes, lists, dicts, NumPy arrays) is pickled as is.

A method's description carries its mark from :mod:`.step_hints` (a getter served from the step's values, a
command buffered until the next message, the step itself), so the child knows which calls need no round trip.
"""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import io
import pickle
from typing import Any

from dualtwin.webots.step_hints import hint_of

__all__ = ["VALUE_CLASSES", "HandleTable", "class_key", "describe_class", "is_value_class", "plain"]

#: Special methods of an API class that its proxies in a child follow (:func:`describe_class`).
_DUNDERS = ("__repr__", "__str__", "__eq__", "__hash__")
#: API classes whose instances are plain data (Webots builds them from C structs on the controller side).
VALUE_CLASSES = frozenset({"ContactPoint", "LidarPoint"})
_PLAIN_SCALARS = (type(None), bool, int, float, complex, str, bytes)
_SCALARS = frozenset(_PLAIN_SCALARS)


def plain(value: Any, depth: int = 0) -> bool:
    """Whether ``value`` is data the child can rebuild without this package (numbers, strings, containers)."""
    if isinstance(value, _PLAIN_SCALARS):
        return True
    if depth > 8:
        return False
    if isinstance(value, (list, tuple, frozenset, set)):
        return all(plain(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(plain(k, depth + 1) and plain(v, depth + 1) for k, v in value.items())
    return False


def _crosses(value: Any, depth: int = 0) -> bool:
    """Whether an instance attribute can be copied to the child: plain data, an API object (a handle), or a
    container of those (``Robot.devices``, name -> device: the child's dict then holds the proxies
    ``getDevice`` returns, as Webots' dict holds the objects it returns)."""
    if plain(value) or type(value).__module__.startswith("dualtwin."):
        return True
    if depth > 2:
        return False
    if isinstance(value, (list, tuple)):
        return all(_crosses(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(plain(k) and _crosses(v, depth + 1) for k, v in value.items())
    return False


def is_value_class(cls: type) -> bool:
    return (
        cls.__name__ in VALUE_CLASSES
        or dataclasses.is_dataclass(cls)
        or bool(getattr(cls, "__webots_value__", False))
    )


def class_key(cls: type, exported: dict[str, type]) -> str:
    """The name the child knows a class by: its API name when exported, else module-qualified."""
    name = cls.__name__
    return name if exported.get(name) is cls else f"{cls.__module__}:{cls.__qualname__}"


def _signature(function: Any) -> inspect.Signature | None:
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return None
    # annotations cross as the text they are (this package postpones them): one that is an object stays here
    parameters = [
        p.replace(annotation=p.annotation if isinstance(p.annotation, str) else inspect.Parameter.empty,
                  default=p.default if p.default is inspect.Parameter.empty or plain(p.default) else None)
        for p in signature.parameters.values()
    ]
    returns = signature.return_annotation
    return signature.replace(parameters=parameters,
                             return_annotation=returns if isinstance(returns, str) else inspect.Signature.empty)


def describe_class(cls: type, exported: dict[str, type], role: str) -> dict[str, Any]:
    """The shape of ``cls`` for the child: its own public members (its bases are described apart)."""
    members: dict[str, tuple[str, Any]] = {}
    per_process = vars(cls).get("_per_process_attributes", ())
    for name, member in vars(cls).items():
        if name.startswith("_"):
            continue
        if name in per_process:  # the child's own, starting empty: not what this process's class holds now
            members[name] = ("constant", None)
            continue
        if isinstance(member, property):
            # (settable, getter's mark, setter's mark, readable): a write-only property (Motor.torque) stays one
            members[name] = ("property", (member.fset is not None, _marked(cls, member.fget), _marked(cls, member.fset),
                                          member.fget is not None))
        elif isinstance(member, (staticmethod, classmethod)):
            members[name] = ("static", _signature(getattr(cls, name)))
        elif inspect.isfunction(member):
            members[name] = ("method", (_signature(member), hint_of(member)))
        elif plain(member):
            members[name] = ("constant", member)
    if role == "value":  # dataclass fields and annotated attributes come with each instance
        members = {k: v for k, v in members.items() if v[0] != "constant" or k not in _annotations(cls)}
    init = vars(cls).get("__init__")
    bases = [b for b in cls.__bases__ if b is not object and b.__module__.startswith("dualtwin.")]
    return {
        "name": cls.__name__,
        "key": class_key(cls, exported),
        "bases": [class_key(b, exported) for b in bases],
        "role": role,
        "doc": cls.__doc__,
        "members": members,
        "constructible": role != "value" and exported.get(cls.__name__) is cls,
        "init": _signature(init) if inspect.isfunction(init) else None,
        # the real class's own comparison and text: a proxy compares as it does (two handles of one scene node are
        # equal Nodes), prints what it prints, and else looks like a plain object of the real class
        # (``__hash__`` None: Python's mark of a class that defines ``__eq__`` alone, unhashable)
        "dunders": sorted(name for name in _DUNDERS if vars(cls).get(name) is not None),
        "unhashable": "__hash__" in vars(cls) and vars(cls)["__hash__"] is None,
        "qualified": f"{cls.__module__}.{cls.__qualname__}",
        # an exception class becomes a real exception class in the child: the name of the built-in class it
        # derives from (RuntimeError for SimulationUnstable), so ``except RuntimeError`` catches it there too
        "builtin_base": next((b.__name__ for b in cls.__mro__ if b.__module__ == "builtins"), None),
    }


def _marked(cls: type, accessor: Any) -> tuple[str, tuple[Any, ...]] | None:
    """(method name, mark) of a property's getter or setter that is a marked method of ``cls`` (``value =
    property(getValue)``, or ``api_property("getValue")``: the method of that name on ``cls``), so the child serves
    the property as it serves the method."""
    by_name = getattr(accessor, "__api_method__", None)
    if by_name is not None:
        accessor = getattr(cls, by_name, None)
    hint = hint_of(accessor)
    name = getattr(accessor, "__name__", "")
    if hint is None or name.startswith("_") or getattr(cls, name, None) is not accessor:
        return None
    return name, hint


def _annotations(cls: type) -> dict[str, Any]:
    return dict(getattr(cls, "__annotations__", {}))


def _value_state(obj: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """Public attributes and the results of the argument-less public getters of a value object."""
    attrs = {k: v for k, v in vars(obj).items() if not k.startswith("_")} if hasattr(obj, "__dict__") else {}
    results: dict[str, Any] = {}
    for klass in type(obj).__mro__:
        if klass is object:
            continue
        for name, member in vars(klass).items():
            if name.startswith("_") or name in results:
                continue
            try:
                if isinstance(member, property):
                    results[name] = getattr(obj, name)
                elif inspect.isfunction(member) and len(inspect.signature(member).parameters) == 1:
                    results[name] = getattr(obj, name)()
            except Exception:  # a getter that fails here fails in the child when called
                continue
    for name in _DUNDERS:  # what the object's own special methods give (the child serves them from here)
        if name != "__eq__" and any(name in vars(klass) for klass in type(obj).__mro__[:-1]):
            with contextlib.suppress(Exception):
                results[name] = getattr(obj, name)()
    return attrs, results


class HandleTable:
    """The parent's side of one child: handles of the objects it was given and the classes it knows."""

    def __init__(self, exported: dict[str, type], roles: dict[type, str]) -> None:
        self.exported = exported
        self.roles = roles  # base class -> role ("robot", "device"), most specific first
        self.objects: dict[int, Any] = {}
        self._handles: dict[int, int] = {}
        self.described: set[type] = set()
        #: the first handle of each object of a class with its own ``__eq__``, by the object itself (so by that
        #: ``__eq__`` and ``__hash__``): a proxy compares and hashes by it, as the real objects do
        self._equal: dict[Any, int] = {}
        self._new: list[dict[str, Any]] = []

    def role(self, cls: type) -> str:
        if issubclass(cls, BaseException):
            return "exception"
        if is_value_class(cls):
            return "value"
        for base, role in self.roles.items():
            if issubclass(cls, base):
                return role
        return "other"

    def describe(self, cls: type) -> None:
        """Queue the description of ``cls`` and its package bases for the next message (once per class)."""
        if cls in self.described:
            return
        for base in cls.__bases__:
            if base is not object and base.__module__.startswith("dualtwin."):
                self.describe(base)
        self.described.add(cls)
        self._new.append(describe_class(cls, self.exported, self.role(cls)))

    def take_descriptions(self) -> list[dict[str, Any]]:
        new, self._new = self._new, []
        return new

    def handle(self, obj: Any) -> tuple[int, bool]:
        """(handle, first time) of an API object, keeping it alive for the child."""
        key = id(obj)
        handle = self._handles.get(key)
        if handle is not None:
            return handle, False
        handle = len(self.objects) + 1
        self.objects[handle] = obj
        self._handles[key] = handle
        return handle, True

    def public_attrs(self, obj: Any) -> dict[str, Any]:
        """Plain instance attributes the child copies (data, or other API objects as handles)."""
        if not hasattr(obj, "__dict__") or self.exported.get(type(obj).__name__) is None and not any(
            isinstance(obj, c) for c in self.exported.values()
        ):
            return {}
        return {k: v for k, v in vars(obj).items() if not k.startswith("_") and _crosses(v)}

    def persistent_id(self, obj: Any) -> Any:
        cls = type(obj)
        if cls in _PLAIN_SCALARS or not cls.__module__.startswith("dualtwin.") or isinstance(obj, BaseException):
            return None
        if isinstance(obj, type):
            return None
        self.describe(cls)
        key = class_key(cls, self.exported)
        if is_value_class(cls):
            attrs, results = _value_state(obj)
            return ("v", key, attrs, results)
        handle, first = self.handle(obj)
        if not first:
            return ("h", handle, key, None, None)
        equal = None
        if cls.__eq__ is not object.__eq__ and cls.__hash__ is not None:
            equal = self._equal.setdefault(obj, handle)
        return ("h", handle, key, self.public_attrs(obj), equal)

    def persistent_load(self, pid: Any) -> Any:
        if pid[0] == "h":
            return self.objects[pid[1]]
        if pid[0] == "v":  # a value object the child was given (a ContactPoint): one of the real class, its data
            cls = self._class(pid[1])
            value: Any = object.__new__(cls)
            vars(value).update(pid[2])
            return value
        if pid[0] == "f":  # an object of the child this process cannot rebuild: a stand-in of its class and text
            module, qualname, text = pid[1:]
            return type(qualname.rpartition(".")[2], (), {"__module__": module, "__qualname__": qualname,
                                                          "__repr__": lambda self: text})()
        raise pickle.UnpicklingError(f"unknown object reference {pid!r}")

    def _class(self, key: str) -> type:
        """The class the child knows by ``key`` (:func:`class_key`): one described to it."""
        return next(cls for cls in self.described if class_key(cls, self.exported) == key)

    def dumps(self, status: str, value: Any, fresh: Any = None) -> bytes:
        """A reply frame: ``(status, value, fresh)``, one pickle made in C, when the value is plain data (most
        replies); else ``(status, pickled value, fresh, new class descriptions)``, the value pickled with
        handles (the child reads the descriptions first, it needs them to unpickle the value). ``fresh``:
        a step's values of the getters the child subscribed to (plain data, see the host)."""
        if not self._new and (type(value) in _SCALARS or plain(value)):
            return pickle.dumps((status, value, fresh), protocol=pickle.HIGHEST_PROTOCOL)
        buf = io.BytesIO()
        pickler = pickle.Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL)
        pickler.persistent_id = self.persistent_id  # type: ignore[method-assign]
        pickler.dump(value)
        return pickle.dumps((status, buf.getvalue(), fresh, self.take_descriptions()),
                            protocol=pickle.HIGHEST_PROTOCOL)

    def loads(self, frame: bytes) -> Any:
        """A message of the child: plain data, or ``("H", pickle with handles)`` when it names API objects."""
        message = pickle.loads(frame)
        if message[0] != "H":
            return message
        unpickler = pickle.Unpickler(io.BytesIO(message[1]))
        unpickler.persistent_load = self.persistent_load  # type: ignore[assignment]
        return unpickler.load()
