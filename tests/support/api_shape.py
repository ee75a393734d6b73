"""The shape of a controller API class as a controller sees it: every public name with its kind (method or static
method with its parameters and defaults, a property readable and/or settable, a class constant), annotations left
out (a controller process's generated classes carry none)."""

from __future__ import annotations

import inspect
from typing import Any

__all__ = ["class_shape"]


def _parameters(function: Any) -> str:
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return "(?)"
    plain = [p.replace(annotation=inspect.Parameter.empty) for p in signature.parameters.values()]
    return str(signature.replace(parameters=plain, return_annotation=inspect.Signature.empty))


def class_shape(cls: type) -> dict[str, str]:
    """{public name: kind} of ``cls``, inherited names included."""
    shape = {}
    for name in dir(cls):
        if name.startswith("_"):
            continue
        raw = inspect.getattr_static(cls, name)
        if isinstance(raw, property):
            kind = "property " + ("r" if raw.fget else "-") + ("w" if raw.fset else "-")
        elif isinstance(raw, staticmethod):
            kind = "static " + _parameters(raw.__func__)
        elif inspect.isfunction(raw):
            kind = "method " + _parameters(raw)
        else:
            kind = "constant " + repr(raw)
        shape[name] = kind
    return shape
