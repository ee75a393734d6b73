"""Numeric arguments of the controller API, accepted the way users pass them and checked at the call.

Webots' Python API wraps floats in ``ctypes.c_double``: Python and NumPy scalars pass, but a one-element array
(``model.predict()`` returns shape ``(1,)``) raises on recent NumPy, and integer arguments (sampling periods)
refuse floats and NumPy integers with a ``ctypes.ArgumentError``. Users pass all of these, so we accept every
real scalar, 0-d array and one-element array, and whole numbers where Webots wants an ``int``. Anything else is
a ``TypeError`` raised at the call and naming the method: storing a bad value would fail much later, inside
the physics step, far from its cause.

Text arguments (names, labels, messages) are encoded by Webots' wrapper before the C call (``str.encode``), so
anything but a ``str`` raises a ``TypeError`` there; :func:`as_text` raises it too, also where the text is not used
headless (a label, a robot-window message), so a script that fails in Webots fails here.
"""

from __future__ import annotations

import math
import numbers
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["as_float", "as_floats", "as_int", "as_text", "error", "finite", "warn"]


C_INT_MIN, C_INT_MAX = -(2**31), 2**31 - 1


def warn(message: str) -> None:
    """A warning for the controller's user, on stderr as Webots prints them in its console."""
    print(f"Warning: {message}", file=sys.stderr)


def error(message: str) -> None:
    """An error for the controller's user (a refused call), on stderr as libController prints them."""
    print(f"Error: {message}", file=sys.stderr)


def finite(*values: float) -> bool:
    """No NaN among ``values`` (±inf is allowed, e.g. ``setPosition(inf)``); NaN != NaN."""
    return all(v == v for v in values)


def _describe(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"a NumPy array of shape {value.shape} and dtype {value.dtype}"
    try:
        text = repr(value)
    except ValueError:  # an int of more digits than Python converts to text
        text = f"<{value.bit_length()} bits>"
    return f"{type(value).__name__} {text}"[:120]


def as_float(value: Any, method: str) -> float:
    """``value`` as a float: a real Python or NumPy scalar, a 0-d or one-element numeric array.

    Raises:
        TypeError: naming ``method`` (e.g. ``"Motor.setVelocity"``) and what was passed.
    """
    if isinstance(value, bool | np.bool_):
        return float(value)
    if isinstance(value, numbers.Real | np.integer | np.floating):
        return float(value)
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "biuf":
        return float(value.reshape(()))
    raise TypeError(
        f"{method}() expects a number (a Python or NumPy scalar or a one-element array), got {_describe(value)}"
    )


def as_int(value: Any, method: str) -> int:
    """``value`` as an int: a whole number given as any scalar or one-element array ``as_float`` accepts.

    The C functions take a C ``int``: a number outside its range is refused at the call too (Webots' ctypes
    passes a Python ``int`` raw: one beyond a C long raises, one within it is cut to its low 32 bits), instead of
    being stored (a sampling period of 10**400 broke the next step, found by fuzzing).

    Raises:
        TypeError: not a number, not a whole number, or not within a C int, naming ``method``.
    """
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        whole = int(value)
    else:
        try:
            number = as_float(value, method)
        except OverflowError:  # a Python int subclass too large for a float
            number = math.inf
        if not number.is_integer():
            raise TypeError(f"{method}() expects a whole number, got {number!r}")
        whole = int(number)
    if not C_INT_MIN <= whole <= C_INT_MAX:
        raise TypeError(f"{method}() expects a whole number within a C int [{C_INT_MIN}, {C_INT_MAX}], got {_describe(value)}")
    return whole


def as_floats(values: Any, method: str, count: int | None = None) -> list[float]:
    """A sequence (list, tuple or NumPy array) of numbers as floats, optionally of exactly ``count`` items.

    Raises:
        TypeError: not a sequence of numbers, naming ``method``.
        ValueError: the wrong number of items.
    """
    if isinstance(values, np.ndarray):
        if values.dtype.kind not in "biuf":
            raise TypeError(f"{method}() expects numbers, got {_describe(values)}")
        items: Sequence[Any] = values.reshape(-1).tolist()
    elif isinstance(values, list | tuple):
        items = values
    else:
        raise TypeError(f"{method}() expects a list of numbers, got {_describe(values)}")
    out = [as_float(v, method) for v in items]
    if count is not None and len(out) != count:
        raise ValueError(f"{method}() expects {count} values, got {len(out)}")
    return out


def as_text(value: Any, method: str) -> str:
    """``value`` if it is a ``str`` (a subclass too, as ``str.encode`` takes it), as a plain ``str``.

    Raises:
        TypeError: anything else (bytes, a number, None), naming ``method`` and what was passed.
    """
    if isinstance(value, str):
        return str(value)  # (a plain str: what the API stores and answers)
    raise TypeError(f"{method}() expects a str, got {_describe(value)}")
