"""Which API methods a controller process may serve without a round trip to the simulation, as Webots does.

Webots' libController exchanges one message per ``wb_robot_step`` each way: the actuator commands buffered
since the last step go out with the step request, and the step's answer brings every enabled sensor's value,
which the controller then reads locally. The controller processes (:mod:`.controller_process`) do the same
for the methods marked here; the marks travel with the class descriptions (:mod:`.controller_wire`).

* :func:`step_value`: an argument-less getter whose value changes only when the simulation steps (a sensor
  reading, the clock, a node's pose). The child keeps the value it last got until the next ``step`` (whose
  answer brings the fresh value of every such getter it has used) or until any call that is not a read
  goes to the simulation (a supervisor edit, ``enable``, ``simulationReset``...).
* :func:`command_value`: the same, for a getter that also echoes a command (a motor's target position): a
  buffered command of the same controller drops it too (a coupled motor's target moves with its sibling's).
* :func:`buffered`: a command that never raises for ``arity`` arguments of the given exact types (it warns
  on a bad value instead, as Webots does): such a call is queued and sent, in order, with the next message.
  Any other call of it (other types, an int beyond a C int, keyword arguments, another arity) goes at once,
  so errors surface at the call.
* :func:`advances`: a method that runs the simulation (``step``): its answer carries the fresh values.

A marked getter must be a pure read of what the last step sampled (no random draw, no change of state): the
simulation's process calls it after every step for a controller that has read it, whether it reads it again
or not. A mark is an attribute of the function object, so aliases (``getAvailableTorque = getAvailableForce``) share
it; a subclass that overrides a marked method without marking it loses the shortcut (never correctness).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["ADVANCES", "BUFFERED", "COMMAND_VALUE", "STEP_VALUE", "advances", "buffered", "command_value",
           "hint_of", "step_value"]

STEP_VALUE = "step"
COMMAND_VALUE = "command"
BUFFERED = "buffered"
ADVANCES = "advances"
_ATTRIBUTE = "__webots_wire__"

F = TypeVar("F", bound=Callable[..., Any])


def step_value(function: F) -> F:
    _argument_less(function)
    setattr(function, _ATTRIBUTE, (STEP_VALUE,))
    return function


def command_value(function: F) -> F:
    _argument_less(function)
    setattr(function, _ATTRIBUTE, (COMMAND_VALUE,))
    return function


def advances(function: F) -> F:
    setattr(function, _ATTRIBUTE, (ADVANCES,))
    return function


def buffered(*types: type) -> Callable[[F], F]:
    """Mark a command safe to queue when called with exactly its positional parameters, each of an exact
    type in ``types`` (default: ``int`` and ``float``; ``bool`` is never one of them)."""
    accepted = tuple(types) or (int, float)

    def mark(function: F) -> F:
        parameters = list(inspect.signature(function).parameters.values())[1:]
        if any(p.kind not in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) or p.default is not p.empty
               for p in parameters):
            raise TypeError(f"{function.__qualname__}: only fixed positional parameters can be buffered")
        setattr(function, _ATTRIBUTE, (BUFFERED, len(parameters), accepted))
        return function

    return mark


def hint_of(member: Any) -> tuple[Any, ...] | None:
    """The mark of a class member (a plain function), or None."""
    hint = getattr(member, _ATTRIBUTE, None)
    return hint if isinstance(hint, tuple) else None


def _argument_less(function: Callable[..., Any]) -> None:
    if len(inspect.signature(function).parameters) != 1:
        raise TypeError(f"{function.__qualname__}: only argument-less getters can be served from a step's values")
