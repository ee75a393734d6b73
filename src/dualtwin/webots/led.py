"""LED: a light a controller switches; it has no physics.

``set(value)``: 0 is off; without ``gradual`` a value 1..n selects the n-th entry of ``color`` (other values are
refused with a message, as Webots does); with ``gradual`` TRUE (a single colour or RGB LED) the value is the
0xRRGGBB colour itself. ``get()`` returns the last value set (0 at start). The lights among the LED's children
follow the value sent with the controller's next step request (:mod:`.led_lights`): cameras and light sensors
see them switched from that step on. The LED's own Shapes keep their colour in camera images.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.api_args import as_int, warn
from dualtwin.webots.device_base import Device
from dualtwin.webots.led_lights import send_led_value
from dualtwin.webots.step_hints import buffered, command_value

__all__ = ["LED"]


class LED(Device):
    """Webots ``LED`` (module docstring)."""

    _state = 0  # off until set (per instance once set)
    _sent: int | None = None  # the value its last step request sent (None: none yet, its first step sends one)

    def _setup(self) -> None:
        self._robot.step_listeners.append(self._controller_step)

    def _controller_step(self, _ms: float) -> None:
        # libController sends the value with the step request (when it changed): the world's lights follow it from
        # the step the request makes
        if self._state != self._sent:
            self._sent = self._state
            send_led_value(self._robot._sim, self._record.node, self._state)

    @buffered(int)
    def set(self, v: Any) -> None:
        value = as_int(v, "LED.set")
        # the colours as the steps executed them: a supervisor's write of the list counts from the step that
        # executes it, whichever came first in real time (webots-on-ode.md §6)
        fields = self._fields()
        if not fields.get("gradual", False):
            colours = len(fields.get("color", []) or [])
            if value < 0 or value > colours:
                warn(f"LED.set(): value {value} out of range [0, {colours}] for '{self._name}'; ignored")
                return
        elif not 0 <= value <= 0xFFFFFF:
            warn(f"LED.set(): colour {value:#x} out of range [0, 0xffffff] for '{self._name}'; ignored")
            return
        self._state = value

    @command_value
    def get(self) -> int:
        return self._state

    value = property(get, set)
