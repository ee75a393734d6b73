"""Webots' ``Mouse`` and ``MouseState`` headless: there is no 3D view to click in, so the state never changes.

What Webots answers when no mouse event ever reaches the controller: the state it starts with, ``u``/``v`` and
the 3D point ``x``/``y``/``z`` NaN, no button pressed. ``enable``/``disable``/``enable3dPosition`` keep their
settings, as they do in Webots; reading a disabled mouse prints Webots' error on stderr.
"""

from __future__ import annotations

import math
import sys
from typing import Any

from dualtwin.webots.device_base import current_host
from dualtwin.webots.polled_input import PolledInput

__all__ = ["Mouse", "MouseState"]


class MouseState:
    """One reading of the mouse: position in the 3D view (``u``, ``v`` in 0..1), 3D point, buttons."""

    u: float
    v: float
    x: float
    y: float
    z: float
    left: bool
    middle: bool
    right: bool

    def __init__(self, u: float, v: float, x: float, y: float, z: float, left: bool, middle: bool,
                 right: bool) -> None:
        self.u, self.v, self.x, self.y, self.z = u, v, x, y, z
        self.left, self.middle, self.right = left, middle, right

    def __repr__(self) -> str:
        return (f"MouseState(u={self.u}, v={self.v}, x={self.x}, y={self.y}, z={self.z}, left={self.left}, "
                f"middle={self.middle}, right={self.right})")


class Mouse(PolledInput):
    """Webots ``Mouse`` (``robot.mouse``): the robot's own is created disabled (``Mouse(0)``)."""

    def __init__(self, sampling_period: Any = None) -> None:
        self._robot = current_host()
        self._3d = False
        super().__init__(sampling_period)

    def enable3dPosition(self) -> None:
        self._3d = True

    def disable3dPosition(self) -> None:
        self._3d = False

    def is3dPositionEnabled(self) -> bool:
        return self._3d

    def getState(self) -> MouseState:
        if self._period == 0:
            print("Error: wb_mouse_get_state() called for a disabled device! Please use: wb_mouse_enable().",
                  file=sys.stderr)
        return MouseState(math.nan, math.nan, math.nan, math.nan, math.nan, False, False, False)
