"""Transform ``scale`` × boundingObject geometries (webots-on-ode.md §3.4: "Geometries inside a scaled Transform use
scaled dimensions"), for an ElevationGrid: its grid spacing scales with the scale's x and y and its heights with
its z, as a Box's sizes scale per axis.

Hand computation: a 2 × 2 grid of spacing 1 m and heights 0.1 m covers x, y ∈ [0, 1] at z = 0.1; scaled by 2 it
covers x, y ∈ [0, 2] at z = 0.2. A sphere of radius 0.1 m dropped at (1.5, 1.5, 0.5) lands on the scaled grid and
rests with its centre at 0.2 + 0.1 = 0.3 m (soft contact: within 1 cm); without the grid under it, it would fall
0.5·9.81·1² ≈ 4.9 m in the second simulated."""

from __future__ import annotations

import pytest

from tests.support.quiet_worlds import quiet_supervisor

TS = 8


def test_an_elevation_grid_in_a_scaled_transform_collides_with_its_scaled_spacing_and_heights() -> None:
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} contactProperties [ ContactProperties {{ bounce 0 }} ] }}
Robot {{ supervisor TRUE }}
Solid {{ name "ground" boundingObject Transform {{ scale 2 2 2 children [
  ElevationGrid {{ xDimension 2 yDimension 2 xSpacing 1 ySpacing 1 height [ 0.1 0.1 0.1 0.1 ] }} ] }} }}
DEF BALL Solid {{ translation 1.5 1.5 0.5 boundingObject Sphere {{ radius 0.1 }} physics Physics {{ }} }}
""")
    for _ in range(125):  # 1 s
        sup.step(TS)
    assert sup.getFromDef("BALL").getPosition() == pytest.approx([1.5, 1.5, 0.3], abs=0.01)
