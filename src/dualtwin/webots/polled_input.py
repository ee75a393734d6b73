"""The sampling period Webots' user-input devices share (Joystick and Mouse): enabled with a period in ms,
``Cls(None)`` enabled at the basic time step, ``Cls(0)`` created disabled (as the Robot's own are)."""

from __future__ import annotations

from typing import Any

from dualtwin.webots.api_args import as_int
from dualtwin.webots.device_base import current_host

__all__ = ["PolledInput"]


class PolledInput:
    """enable/disable/getSamplingPeriod and the ``sampling_period`` property, with Webots' constructor rule."""

    def __init__(self, sampling_period: Any = None) -> None:
        host = current_host()
        self._period = 0
        if sampling_period is None:
            self.enable(int(host.getBasicTimeStep()))
        elif sampling_period:
            self.enable(sampling_period)

    def enable(self, p: Any) -> None:
        self._period = max(0, as_int(p, f"{type(self).__name__}.enable"))

    def disable(self) -> None:
        self._period = 0

    def getSamplingPeriod(self) -> int:
        return self._period

    @property
    def sampling_period(self) -> int:
        return self._period

    @sampling_period.setter
    def sampling_period(self, p: Any) -> None:
        self.enable(0 if p is None else p)
