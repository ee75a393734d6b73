"""Lidar, RangeFinder and infra-red DistanceSensor rays hit visual Shapes (issue 26 item 6), as Webots' depth
rendering and infra-red shape intersection do; generic/sonar/laser rays keep hitting bounding objects.

Worlds: a Shape-only wall (no boundingObject) 1 m ahead and a boundingObject-only wall 0.5 m ahead in
another direction. Expected distances follow from the layout. Control: every lidar range was +inf before (the
rays only knew bounding objects), and the infra-red sensor read its table's far end.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Solid { translation 1.05 0 0 children [ Shape { geometry DEF SEEN Box { size 0.1 0.4 1 } } ] }
Solid { translation 0 0.55 0 boundingObject Box { size 4 0.1 1 } }
Solid { translation 0 -1.05 0 children [ Pose { translation 0 -0.1 0 children [ Shape { geometry USE SEEN } ] } ] }
Robot {
  supervisor TRUE
  children [
    Lidar { name "lidar" horizontalResolution 3 fieldOfView 0.3 numberOfLayers 1 maxRange 3
            children [ Shape { geometry Box { size 0.05 0.05 0.05 } } ] }
    Lidar { name "left" rotation 0 0 1 1.5707963267948966 horizontalResolution 1 fieldOfView 0.1
            numberOfLayers 1 maxRange 3 }
    DistanceSensor { name "ir" type "infra-red" lookupTable [ 0 0 0, 2 2 0 ] }
    DistanceSensor { name "generic" lookupTable [ 0 0 0, 2 2 0 ] }
    DistanceSensor { name "ir right" rotation 0 0 1 -1.5707963267948966 type "infra-red"
                     lookupTable [ 0 0 0, 2 2 0 ] }
  ]
}
"""


def _supervisor() -> Supervisor:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(WORLD))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def test_lidar_and_infra_red_see_shapes_without_bounding_objects() -> None:
    sup = _supervisor()
    names = ("lidar", "left", "ir", "generic", "ir right")
    devices = {n: sup.getDevice(n) for n in names}
    for d in devices.values():
        d.enable(8)
    sup.step(8)
    # columns at +0.1, 0, −0.1 rad; the lidar's own box around it is not seen
    assert devices["lidar"].getRangeImage() == pytest.approx([1.0 / math.cos(a) for a in (0.1, 0.0, -0.1)])
    assert devices["left"].getRangeImage() == [math.inf]  # a boundingObject nothing draws is invisible
    assert devices["ir"].getValue() == pytest.approx(1.0)
    assert devices["generic"].getValue() == pytest.approx(2.0)  # generic rays: no boundingObject, no hit
    assert devices["ir right"].getValue() == pytest.approx(0.95)  # the USE of the Shape, inside a Pose


def test_an_edited_shape_is_what_the_rays_see_next() -> None:
    sup = _supervisor()
    lidar, ir_right = sup.getDevice("lidar"), sup.getDevice("ir right")
    lidar.enable(8)
    ir_right.enable(8)
    sup.step(8)
    sup.getFromDef("SEEN").getField("size").setSFVec3f([0.5, 0.8, 1.0])  # the DEF and its USE grow
    sup.step(8)
    assert lidar.getRangeImage()[1] == pytest.approx(0.8)
    assert ir_right.getValue() == pytest.approx(0.75)


@pytest.mark.parametrize(
    "appearance, sensitivity, expected",
    [
        ("Appearance { material Material { diffuseColor 1 0 0 } }", 1, 1.0),  # red reflects fully: f = 1
        ("Appearance { material Material { diffuseColor 0 0 1 } }", 1, 5.0),  # no red: f = 0.2, d/f
        ("PBRAppearance { baseColor 0.5 0 0 roughness 1 }", 1, 2.5),  # f = 0.2 + 0.8·0.5·0.5 = 0.4
        ("PBRAppearance { baseColor 0.5 0 0 roughness 1 }", 0.5, 1.75),  # d + (d/f − d)·0.5
        ("Appearance { material Material { diffuseColor 0 0 1 } }", 0, 1.0),  # colour-blind sensor
    ],
)
def test_infra_red_distance_is_weighted_by_the_red_of_what_it_sees(
    appearance: str, sensitivity: float, expected: float
) -> None:
    # control: a generic sensor reads 1.0 on every colour (and the infra-red one did too before)
    text = (
        "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n"
        f"Solid {{ translation 1.05 0 0 children [ Shape {{ appearance {appearance} geometry Box {{ size 0.1 1 1 }} }} ] "
        "boundingObject Box { size 0.1 1 1 } }\n"
        f'Robot {{ supervisor TRUE children [ DistanceSensor {{ name "ir" type "infra-red" '
        f"redColorSensitivity {sensitivity} lookupTable [ 0 0 0, 10 10 0 ] }} "
        'DistanceSensor { name "generic" lookupTable [ 0 0 0, 10 10 0 ] } ] }'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    ir, generic = sup.getDevice("ir"), sup.getDevice("generic")
    ir.enable(8)
    generic.enable(8)
    sup.step(8)
    assert ir.getValue() == pytest.approx(expected)
    assert generic.getValue() == pytest.approx(1.0)
