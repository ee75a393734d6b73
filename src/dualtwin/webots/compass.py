"""Compass: the direction of the world's north in the device frame.

Webots R2022a+ has no ``northDirection``: the north is the axis that ``WorldInfo.coordinateSystem`` names ``N``
(+y in ENU, +x in NUE, +z in EUN). ``getValues()`` is that unit vector expressed in the compass frame (a 3D
vector, not projected on the horizontal plane); each enabled component goes through the ``lookupTable`` (an
empty table is the identity) and ``resolution``; a component whose ``xAxis``/``yAxis``/``zAxis`` is FALSE reads
NaN.
"""

from __future__ import annotations

import math

from dualtwin.webots import _math3 as m3
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.lut import discretize, lookup, table_from_field
from dualtwin.webots.physics import Simulation
from dualtwin.webots.step_hints import step_value
from dualtwin.webots.world_frame import axes

__all__ = ["Compass", "coordinate_system", "north"]

def coordinate_system(sim: Simulation) -> str:
    """``WorldInfo.coordinateSystem`` (``ENU``, ``NUE`` or ``EUN``; ENU when absent or unknown) as the load read it,
    the one reading the gravity and every device go by (a supervisor's later write of the field is not applied)."""
    return sim.coordinate_system


def north(sim: Simulation) -> m3.Vec3:
    """The world's north direction for its ``coordinateSystem`` (the one the GPS's WGS84 latitude grows along)."""
    return axes(coordinate_system(sim)).north


class Compass(SolidSensor):
    """Webots ``Compass`` (module docstring)."""

    def _read(self) -> None:
        sim = self._robot._sim
        f = self._record.node.fields
        local = m3.mat_t_vec(self._pose().R, north(sim))
        table = table_from_field(f.get("lookupTable", []))
        resolution = float(f.get("resolution", -1.0))
        self._values = [
            discretize(lookup(table, v, sim.rng), resolution) if f.get(axis + "Axis", True) else math.nan
            for v, axis in zip(local, "xyz", strict=True)
        ]

    @step_value
    def getValues(self) -> list[float]:
        self._check_enabled("wb_compass_get_values")
        return list(self._values)

    def getLookupTable(self) -> list[float]:
        # (as the steps executed it, as every device getter: webots-on-ode.md §6)
        return [v for row in table_from_field(self._fields().get("lookupTable", [])) for v in row]

    value = property(getValues)
    lookup_table = property(getLookupTable)
