"""Webots' ``Joystick`` headless: no game controller is ever connected.

What Webots answers without a connected joystick: ``isConnected()`` False, no axes and no POVs (0), axis and POV
values 0, ``getPressedButton()`` -1, ``model`` None; the force-feedback setters have nothing to act on. The
sampling period is kept as in Webots.
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.api_args import as_float, as_int
from dualtwin.webots.polled_input import PolledInput

__all__ = ["Joystick"]


class Joystick(PolledInput):
    """Webots ``Joystick`` (``robot.joystick``): the robot's own is created disabled (``Joystick(0)``)."""

    def isConnected(self) -> bool:
        return False

    def getNumberOfAxes(self) -> int:
        return 0

    def getAxisValue(self, axis: Any) -> int:
        as_int(axis, "Joystick.getAxisValue")
        return 0

    def getNumberOfPovs(self) -> int:
        return 0

    def getPovValue(self, pov: Any) -> int:
        as_int(pov, "Joystick.getPovValue")
        return 0

    def getPressedButton(self) -> int:
        return -1

    def setConstantForce(self, level: Any) -> None:
        as_int(level, "Joystick.setConstantForce")

    def setConstantForceDuration(self, duration: Any) -> None:
        as_float(duration, "Joystick.setConstantForceDuration")

    def setAutoCenteringGain(self, gain: Any) -> None:
        as_float(gain, "Joystick.setAutoCenteringGain")

    def setResistanceGain(self, gain: Any) -> None:
        as_float(gain, "Joystick.setResistanceGain")

    def setForceAxis(self, axis: Any) -> None:
        as_int(axis, "Joystick.setForceAxis")

    is_connected = property(lambda self: self.isConnected())
    number_of_axes = property(lambda self: self.getNumberOfAxes())
    number_of_povs = property(lambda self: self.getNumberOfPovs())
    pressed_button = property(lambda self: self.getPressedButton())
    model = property(lambda self: None)
