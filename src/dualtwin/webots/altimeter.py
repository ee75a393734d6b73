"""Altimeter: the device's altitude, its coordinate along the world's up axis (z in ENU, y in NUE/EUN).

Webots adds Gaussian noise of standard deviation ``accuracy`` (m) and then applies ``resolution``.
"""

from __future__ import annotations

import math

from dualtwin.webots.compass import coordinate_system
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.lut import discretize
from dualtwin.webots.step_hints import step_value

__all__ = ["Altimeter"]


class Altimeter(SolidSensor):
    """Webots ``Altimeter`` (module docstring)."""

    def _invalidate(self) -> None:
        self._value = math.nan

    def _read(self) -> None:
        sim = self._robot._sim
        f = self._record.node.fields
        up = 2 if coordinate_system(sim) == "ENU" else 1  # z up in ENU, y up in NUE and EUN
        value = self._pose().t[up]
        accuracy = float(f.get("accuracy", 0.0))
        if accuracy > 0.0:
            value += sim.rng.gauss(0.0, accuracy)
        self._value = discretize(value, float(f.get("resolution", -1.0)))

    @step_value
    def getValue(self) -> float:
        self._check_enabled("wb_altimeter_get_value")
        return self._value

    value = property(getValue)
