"""A boundingObject geometry in a non-uniformly scaled Transform collides at its scaled size per axis in the converted
model, as in the Webots twin and as its converted mass already had it (on-ODE §3.4: geometries inside a scaled
Transform use scaled dimensions; a Box's size is its full extents along x, y and z). The converter read only the
scale's x factor, so a 0.1 m cube in ``Transform { scale 1 2 3 }`` collided in MuJoCo as a 0.1 m cube instead of a
0.1 x 0.2 x 0.3 m box: its mass was that of the tall box, its contacts those of the cube.

Hand computation: half extents 0.1/2 x (1, 2, 3) = (0.05, 0.1, 0.15) m; offset by the Transform's translation
(0, 0, 0.02), unscaled (a Transform's scale acts below it). Resting on the floor, the robot's origin is 0.15 - 0.02 =
0.13 m above it (ODE and MuJoCo contacts sink a few millimetres at most: 5 mm allowed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text

BOX = world_text(
    'DEF R Robot { controller "<extern>" translation 0 0 0.2 physics Physics { density -1 mass 1 } '
    "boundingObject Transform { translation 0 0 0.02 scale 1 2 3 children [ Box { size 0.1 0.1 0.1 } ] } "
    'children [ GPS { name "gps" } ] }\n'
    "DEF FLOOR Solid { boundingObject Plane { size 10 10 } }", "basicTimeStep 4")


def test_the_box_is_scaled_per_axis() -> None:
    model = convert_world_text(BOX, "scaled.wbt").compile()
    box = model.geom("R")
    np.testing.assert_allclose(box.size, [0.05, 0.1, 0.15], rtol=1e-12)
    np.testing.assert_allclose(box.pos, [0.0, 0.0, 0.02], atol=1e-12)


def test_both_twins_rest_the_box_on_its_scaled_height(tmp_path: Path) -> None:
    with converted_twins(BOX, tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(100):  # 0.8 s: dropped from 7 cm above its rest height, it has landed and settled
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("R")[2] == pytest.approx(0.13, abs=5e-3)
        assert mujoco_twin.body_position("R")[2] == pytest.approx(0.13, abs=5e-3)
