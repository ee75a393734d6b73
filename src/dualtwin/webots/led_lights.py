"""The lights an LED switches: what a light inside an LED shines with, for the LightSensor and the Camera.

Webots' LED page: the LED drives the lights among its children (through Group/Pose/Transform); when the LED is
off (``set(0)``, its state at start) they are off, when it is on they are on, in the LED's colour: for a
non-``gradual`` LED the ``color`` entry its value selects (1 the first), for a ``gradual`` one the value read as
0xRRGGBB. The light's own ``on`` and ``color`` fields are not what it shines with while an LED drives it.

A controller's ``LED.set`` reaches the world with its next step request (libController sends the actuator
commands buffered since the last step with it), so the value the lights follow is the one committed then
(:func:`commit_led_value`), not a value set after the step that a camera image of that step must not show.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import Simulation

__all__ = ["Colour", "commit_led_value", "led_colour", "led_value", "light_state"]

Colour = tuple[float, float, float]
_KEY = "led_values"


def _values(sim: Simulation) -> dict[Node, int]:
    values: dict[Node, int] | None = sim.extensions.get(_KEY)
    if values is None:
        values = sim.extensions[_KEY] = {}
    return values


def commit_led_value(sim: Simulation, led: Node, value: int) -> None:
    """The value ``led`` shows from this step on (a controller's last ``LED.set`` before its step request)."""
    _values(sim)[led] = value


def led_value(sim: Simulation, led: Node) -> int:
    """The value ``led`` shows now: 0 (off) until a controller's step sent another."""
    return _values(sim).get(led, 0)


def led_colour(led: Node, value: int) -> Colour | None:
    """The colour of ``led`` showing ``value``, or None when that value is off."""
    if value <= 0:
        return None
    if led.fields.get("gradual", False):
        return ((value >> 16 & 0xFF) / 255.0, (value >> 8 & 0xFF) / 255.0, (value & 0xFF) / 255.0)
    colours = led.fields.get("color") or []
    if value > len(colours):  # LED.set refuses such a value; a colour removed since leaves the LED dark
        return None
    red, green, blue = (float(c) for c in colours[value - 1])
    return red, green, blue


def light_state(sim: Simulation, light: Node, led: Node | None) -> tuple[bool, Colour]:
    """Whether ``light`` shines now and in which colour: its own ``on``/``color``, or those ``led`` gives it."""
    if led is None:
        colour: Any = light.fields.get("color", (1.0, 1.0, 1.0))
        red, green, blue = (float(c) for c in colour)
        return bool(light.fields.get("on", True)), (red, green, blue)
    shown = led_colour(led, led_value(sim, led))
    if shown is None:
        return False, (0.0, 0.0, 0.0)
    return True, shown
