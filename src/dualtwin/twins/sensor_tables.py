"""Webots' sensor lookup tables in the MuJoCo twin: ``<numeric name="webots_sensor_lut.<sensor>" data="in out noise ...">``.

A converted model carries the ``lookupTable`` of a DistanceSensor, Accelerometer, Gyro or Compass as this numeric
(rows ``input output noise``, flattened; :mod:`dualtwin.convert.sensor_models`). The MuJoCo reading is the physical
value Webots feeds to its table, and the twin returns the table's output as Webots does
(``docs/reference/webots-devices.md`` §0.3, through :func:`dualtwin.webots.lut.lookup`): clamped to the first and
last rows, output and noise interpolated between them, the noise multiplicative, ``v·(1 + n·N(0, 1))``, drawn
from the twin's seeded generator (the one its other sensor noise draws from) and only where ``n != 0``.

A rangefinder reads the distance to the first hit, or a negative number when its ray hits nothing (-1, or -cutoff
when the converter set the cutoff to the table's last input D). Webots' ray has length D and a miss counts as D
(§1.4), so the twin feeds ``min(d, D)`` to the table, and D where there was no hit: nothing in range reads the
table's last output. A vector sensor's components each go through the table (Webots applies it per axis).
"""

from __future__ import annotations

import mujoco
import numpy as np

from dualtwin.twins.mujoco_state import sensor_numerics
from dualtwin.webots.lut import Table, lookup

__all__ = ["LUT_NUMERIC", "NumpyGauss", "read_tables", "table_value"]

#: The numeric prefix of a sensor's lookup table in a converted model.
LUT_NUMERIC = "webots_sensor_lut."


class NumpyGauss:
    """``random.Random.gauss`` on a NumPy generator (the lookup table's noise draws from the twin's generator)."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def gauss(self, mu: float, sigma: float) -> float:
        return float(self.rng.normal(mu, sigma))


def read_tables(m: mujoco.MjModel) -> dict[int, tuple[Table, bool]]:
    """Sensor id -> (its table's rows, whether it is a rangefinder) for each sensor with a
    ``webots_sensor_lut.<name>`` numeric of whole rows (others have none: their reading is the MuJoCo value)."""
    out: dict[int, tuple[Table, bool]] = {}
    for s, data in sensor_numerics(m, LUT_NUMERIC).items():
        size = len(data)
        if size < 3 or size % 3:
            continue
        rows = [(data[i], data[i + 1], data[i + 2]) for i in range(0, size, 3)]
        out[s] = (rows, int(m.sensor_type[s]) == mujoco.mjtSensor.mjSENS_RANGEFINDER)
    return out


def table_value(table: Table, rangefinder: bool, value: float, rng: np.random.Generator) -> float:
    """Webots' output for the MuJoCo reading ``value`` (module docstring): a rangefinder's distance is capped
    at the table's last input D, a miss (negative) reads as D; then the table with its noise."""
    if rangefinder:
        full = table[-1][0]
        value = full if value < 0 else min(value, full)
    return lookup(table, value, NumpyGauss(rng))
