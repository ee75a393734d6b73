"""The lights an LED switches: what a light inside an LED shines with, for the LightSensor and the Camera.

Webots' LED page: the LED drives the lights among its children (through Group/Pose/Transform); when the LED is
off (``set(0)``, its state at start) they are off, when it is on they are on, in the LED's colour: for a
non-``gradual`` LED the ``color`` entry its value selects (1 the first), for a ``gradual`` one the value read as
0xRRGGBB. The light's own ``on`` and ``color`` fields are not what it shines with while an LED drives it.

A controller's ``LED.set`` reaches the world with its next step request (libController sends the actuator
commands buffered since the last step with it: :func:`send_led_value`), and it acts on the physics step that
request makes (webots-on-ode.md §6: "commands issued before call k act on the physics of call k"): the lights
follow it from that physics step on. Not from the request itself: a camera draws its image when its controller
reads it, after its step, and another controller's request sent meanwhile must not show in the image of the step
before (it did, depending on which controller ran first).
"""

from __future__ import annotations

import threading
from typing import Any

from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import Simulation

__all__ = ["Colour", "led_colour", "led_value", "light_state", "send_led_value"]

Colour = tuple[float, float, float]
_KEY = "led_values"
_MADE = threading.Lock()  # the first controllers of a run may send their values at the same time


class _LedValues:
    """The values the LEDs show, and those their controllers sent that the next physics step executes."""

    def __init__(self) -> None:
        self.shown: dict[Node, int] = {}
        self.sent: dict[Node, int] = {}
        # (a controller whose synchronization is FALSE may send while the physics steps)
        self.lock = threading.Lock()

    def execute(self, _dt: float) -> None:
        with self.lock:
            self.shown.update(self.sent)
            self.sent.clear()


def _values(sim: Simulation) -> _LedValues:
    values: _LedValues | None = sim.extensions.get(_KEY)
    if values is None:
        with _MADE:
            values = sim.extensions.get(_KEY)
            if values is None:
                values = _LedValues()
                sim.pre_step_hooks.append(values.execute)
                sim.extensions[_KEY] = values
    return values


def send_led_value(sim: Simulation, led: Node, value: int) -> None:
    """``led``'s value sent with a step request (its controller's last ``LED.set`` before it): shown from the
    physics step that executes the request on."""
    values = _values(sim)
    with values.lock:
        values.sent[led] = value


def led_value(sim: Simulation, led: Node) -> int:
    """The value ``led`` shows now: 0 (off) until a physics step executed another."""
    return _values(sim).shown.get(led, 0)


def led_colour(sim: Simulation, led: Node, value: int) -> Colour | None:
    """The colour of ``led`` showing ``value``, or None when that value is off; its ``gradual`` and ``color`` fields
    as the steps executed them (see :func:`light_state`)."""
    if value <= 0:
        return None
    if sim.executed_value(led, "gradual", False):
        return ((value >> 16 & 0xFF) / 255.0, (value >> 8 & 0xFF) / 255.0, (value & 0xFF) / 255.0)
    colours = sim.executed_value(led, "color") or []
    if value > len(colours):  # LED.set refuses such a value; a colour removed since leaves the LED dark
        return None
    red, green, blue = (float(c) for c in colours[value - 1])
    return red, green, blue


def light_state(sim: Simulation, light: Node, led: Node | None) -> tuple[bool, Colour]:
    """Whether ``light`` shines now and in which colour: its own ``on``/``color``, or those ``led`` gives it. The
    fields are read as the steps executed them: a supervisor's write acts from the step that executes it (a camera
    draws the image of the step just done when its controller first reads it, maybe after the write)."""
    if led is None:
        colour: Any = sim.executed_value(light, "color", (1.0, 1.0, 1.0))
        red, green, blue = (float(c) for c in colour)
        return bool(sim.executed_value(light, "on", True)), (red, green, blue)
    shown = led_colour(sim, led, led_value(sim, led))
    if shown is None:
        return False, (0.0, 0.0, 0.0)
    return True, shown
