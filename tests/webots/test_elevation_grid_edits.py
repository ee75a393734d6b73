"""A supervisor's edit of an ElevationGrid reaches ODE (issue 23 §2: "every field write reaches ODE at the next
step"; Webots rebuilds the field's ODE heightfield from the grid's fields when one changes, as it re-applies a Box's
size): rays and contacts see the new heights and spacings from the next step.

The grid is a 3×3 field with 1 m spacing, its corner at the origin, flat at height 0; a DistanceSensor 1 m above
(1, 0.75) looks straight down with an identity table over 2 m, so it reads the distance to the surface.
"""

from __future__ import annotations

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor


def _world() -> Supervisor:
    return quiet_supervisor("""#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { supervisor TRUE translation 1 0.75 1 rotation 0 1 0 1.5707963267948966
  children [ DistanceSensor { name "down" lookupTable [ 0 0 0, 2 2 0 ] } ] }
Solid { name "ground" children [ Shape { geometry DEF GRID ElevationGrid { xDimension 3 yDimension 3
  xSpacing 1 ySpacing 1 height [ 0 0 0, 0 0 0, 0 0 0 ] } } ] boundingObject USE GRID }
DEF BALL Solid { translation 0.5 1.5 0.3 children [ Shape { geometry Sphere { radius 0.1 } } ]
  boundingObject Sphere { radius 0.1 } physics Physics { } }
""")


def _reading(sup: Supervisor, steps: int = 1) -> float:
    sensor = sup.getDevice("down")
    sensor.enable(8)
    for _ in range(steps):
        sup.step(8)
    return float(sensor.getValue())


def test_new_heights_are_seen_by_rays_and_contacts() -> None:
    sup = _world()
    assert _reading(sup) == pytest.approx(1.0, abs=1e-9)  # the flat field, 1 m below the sensor
    field = sup.getFromDef("GRID").getField("height")
    for i in range(9):
        field.setMFFloat(i, 0.3)
    # the whole field raised by 0.3 m: the sensor reads 0.7 from the next sample on
    assert _reading(sup) == pytest.approx(0.7, abs=1e-9)
    # the ball, resting on the flat field (its centre 0.1 m above it), is lifted onto the new surface
    for _ in range(200):
        sup.step(8)
    z = sup.getFromDef("BALL").getPosition()[2]
    assert z == pytest.approx(0.3 + 0.1, abs=5e-3)  # ODE's soft contact sinks it by a fraction of a mm


def test_new_spacings_move_the_grid_under_the_sensor() -> None:
    # heights 0 except the far row (y = 2 m) at 0.6 m: under the sensor (y = 0.75, between the rows at 0 and 1 m)
    # the field is flat. With ySpacing 0.5 the rows stand at y = 0, 0.5 and 1 m, and at y = 0.75 the surface is
    # half way up to the 0.6 m row (x = 1 m is a grid column, so linear whatever ODE's triangle split): 0.3 m,
    # read as 1 - 0.3 = 0.7
    sup = _world()
    grid = sup.getFromDef("GRID")
    heights = grid.getField("height")
    for i in (6, 7, 8):
        heights.setMFFloat(i, 0.6)
    assert _reading(sup) == pytest.approx(1.0, abs=1e-9)
    grid.getField("ySpacing").setSFFloat(0.5)
    assert _reading(sup) == pytest.approx(0.7, abs=1e-9)
