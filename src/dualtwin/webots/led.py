"""LED: a light a controller switches; it has no physics and lights nothing headless.

``set(value)``: 0 is off; without ``gradual`` a value 1..n selects the n-th entry of ``color`` (other values are
refused with a message, as Webots does); with ``gradual`` TRUE (a single colour or RGB LED) the value is the
0xRRGGBB colour itself. ``get()`` returns the last value set (0 at start).
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.api_args import as_int, warn
from dualtwin.webots.device_base import Device
from dualtwin.webots.step_hints import buffered, command_value

__all__ = ["LED"]


class LED(Device):
    """Webots ``LED`` (module docstring)."""

    _state = 0  # off until set (per instance once set)

    @buffered(int)
    def set(self, v: Any) -> None:
        value = as_int(v, "LED.set")
        fields = self._record.node.fields
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
