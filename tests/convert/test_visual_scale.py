"""A non-uniform Transform scale above Shapes alone is drawn per axis; above a Solid or a joint it acts as its largest
factor.

A Robot's drawing often stretches a Shape with ``Transform { scale ... }``. The converter refused any non-uniform
scale outside a boundingObject, so one stretched visual stopped the conversion of the whole world, although it
only changes what is drawn. It now scales each visual geom under it per axis, as a boundingObject's (a Box's
extents per axis, a Sphere's radius by the largest factor, as the Webots twin's and dualtwin.webots.mass_rules'
round primitives). Above a Solid, whose mass (s^3) and inertia (s^5, on-ODE §3.2) need one factor, the scale acts
as its largest factor with a warning, as in the Webots twin (it was refused).

Hand computation: a 0.1 m cube in ``scale 1 2 0.5`` has half extents 0.05 x (1, 2, 0.5) = (0.05, 0.1, 0.025); a
0.02 m sphere there has radius 0.02 x 2 = 0.04.
"""

from __future__ import annotations

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import world_text


def robot(inside: str) -> str:
    return world_text(
        'DEF R Robot { controller "<extern>" physics Physics { density -1 mass 1 } boundingObject Box { size 0.1 0.1 0.1 } '
        f'children [ GPS {{ name "gps" }} Transform {{ translation 0 0 0.05 scale 1 2 0.5 children [ {inside} ] }} ] }}',
        "basicTimeStep 4")


def test_stretched_shapes_are_drawn_per_axis() -> None:
    model = convert_world_text(robot("Shape { geometry Box { size 0.1 0.1 0.1 } } "
                                     "Shape { geometry Sphere { radius 0.02 } }"), "drawn.wbt").compile()
    np.testing.assert_allclose(model.geom("R_visual").size, [0.05, 0.1, 0.025], rtol=1e-12)
    np.testing.assert_allclose(model.geom("R_visual").pos, [0.0, 0.0, 0.05], atol=1e-12)
    assert model.geom("R_visual_1").size[0] == pytest.approx(0.04)


def test_a_solid_under_a_stretch_is_scaled_by_the_largest_factor_with_one_warning() -> None:
    # as the Webots twin does (webots.solid_scale.body_factor): everything below it, the Shapes too, by 2
    conv = convert_world_text(robot('Solid { name "s" } Shape { geometry Box { size 0.1 0.1 0.1 } }'), "solid.wbt")
    np.testing.assert_allclose(conv.compile().geom("R_visual").size, [0.1, 0.1, 0.1], rtol=1e-12)
    assert sum("is not uniform above a Solid or joint: scaled by its largest factor 2" in w for w in conv.warnings) == 1
