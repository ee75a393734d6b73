"""A supervisor's edit of the ``translation``, ``rotation`` or ``scale`` of a Pose or Transform inside a Solid's
boundingObject moves its geoms at the next step, as in Webots (the geoms sit at their offset from the Solid):
ray sensors and contacts see the shape where the new frame puts it, a DEF frame used by several boundingObjects
moves all of them (each in its own Solid's frame), and on a body the mass follows (the centre of mass moves
with the shape, the Solid stays where it is, a hinge keeps working).

Expectations by hand; each test first checks the load's geometry (the control), so code that leaves the geoms
or the mass where they were fails the check after the edit."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 2
H = TS / 1000


def _supervisor(scene: str, robot_children: str = "", gravity: float = 0.0) -> Supervisor:
    world = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity {gravity} }}
{scene}
Robot {{ supervisor TRUE children [ {robot_children} ] }}
"""
    sup = Supervisor(simulation=Simulation(load_world_text(world)))
    sup.step(TS)
    return sup


# a single ray (generic DistanceSensor) whose value is the distance in metres, up to 2 m
_SENSOR = 'DistanceSensor {{ name "{name}" rotation 0 0 1 {angle} lookupTable [ 0 0 0, 2 2 0 ] }}'


def _sensors() -> str:
    return _SENSOR.format(name="east", angle=0) + " " + _SENSOR.format(name="north", angle=math.pi / 2)


def _read(sup: Supervisor) -> tuple[float, float]:
    sup.step(TS)
    return sup.getDevice("east").getValue(), sup.getDevice("north").getValue()


def test_a_ray_sensor_sees_a_bounding_box_where_its_moved_and_turned_pose_puts_it() -> None:
    # a 0.2 x 0.6 x 0.2 box 1 m east of the sensor: its near face at 0.9 m. The frame moved 0.3 m west: 0.6 m;
    # then turned 90° about z: the box is 0.6 m deep along x, its near face at 0.7 - 0.3 = 0.4 m.
    sup = _supervisor("Solid { translation 1 0 0 boundingObject DEF BP Pose { children [ Box { size 0.2 0.6 0.2 } ] } }",
                      _sensors())  # fmt: skip
    for name in ("east", "north"):
        sup.getDevice(name).enable(TS)
    assert _read(sup)[0] == pytest.approx(0.9, abs=1e-9)
    frame = sup.getFromDef("BP")
    frame.getField("translation").setSFVec3f([-0.3, 0.0, 0.0])
    assert _read(sup)[0] == pytest.approx(0.6, abs=1e-9)
    frame.getField("rotation").setSFRotation([0.0, 0.0, 1.0, math.pi / 2])
    assert _read(sup)[0] == pytest.approx(0.4, abs=1e-9)


def test_a_def_pose_moves_every_boundingObject_that_uses_it_each_in_its_own_solids_frame() -> None:
    # the east Solid as above; the north one turned 90° about z, so its x axis points north. Moving the shared
    # frame 0.3 m along x brings both boxes (0.2 m cubes) 0.3 m nearer: 0.9 -> 0.6 on both rays. Read in world
    # axes instead, the north box would leave the north ray (2 m: nothing seen).
    sup = _supervisor(
        "Solid { translation 1 0 0 boundingObject DEF BP Pose { children [ Box { size 0.2 0.2 0.2 } ] } } "
        'Solid { translation 0 1 0 rotation 0 0 1 1.5707963267948966 name "north" boundingObject USE BP }',
        _sensors(),
    )
    for name in ("east", "north"):
        sup.getDevice(name).enable(TS)
    assert _read(sup) == pytest.approx((0.9, 0.9), abs=1e-9)
    sup.getFromDef("BP").getField("translation").setSFVec3f([-0.3, 0.0, 0.0])
    assert _read(sup) == pytest.approx((0.6, 0.6), abs=1e-9)


def test_a_transform_scaled_inside_a_boundingObject_scales_and_moves_its_box() -> None:
    # Transform { translation 0.1 0 0 scale 1 1 1 } around a 0.2 m cube at x = 1: near face at 1.1 - 0.1 = 1.0.
    # Scaled by 2: the cube is 0.4 m and the frame's translation is not scaled by its own scale: 1.1 - 0.2 = 0.9.
    sup = _supervisor("Solid { translation 1 0 0 boundingObject DEF BT Transform { translation 0.1 0 0 "
                      "children [ Box { size 0.2 0.2 0.2 } ] } }", _sensors())  # fmt: skip
    sup.getDevice("east").enable(TS)
    assert _read(sup)[0] == pytest.approx(1.0, abs=1e-9)
    sup.getFromDef("BT").getField("scale").setSFVec3f([2.0, 2.0, 2.0])
    assert _read(sup)[0] == pytest.approx(0.9, abs=1e-9)


def test_a_ball_dropped_on_a_static_solid_whose_bounding_pose_went_down_lands_on_it_there() -> None:
    # a 1 m x 1 m x 0.1 m slab at the origin, its bounding frame moved 0.3 m down before the 0.05 m ball (0.5 m
    # up) reaches it: the ball rests at -0.3 + 0.05 + 0.05 = -0.2 (at 0.1 on the old slab).
    sup = _supervisor(
        "Solid { boundingObject DEF BP Pose { children [ Box { size 1 1 0.1 } ] } } "
        "DEF BALL Solid { translation 0 0 0.5 name \"ball\" boundingObject Sphere { radius 0.05 } physics Physics { } }",
        gravity=9.81,
    )
    sup.getFromDef("BP").getField("translation").setSFVec3f([0.0, 0.0, -0.3])
    for _ in range(int(1.5 / H)):
        sup.step(TS)
    z = sup.getFromDef("BALL").getPosition()[2]
    assert z == pytest.approx(-0.2, abs=2e-3)
    assert abs(sup.getFromDef("BALL").getVelocity()[2]) < 1e-2  # resting on it, not falling through


def test_moving_the_bounding_pose_of_a_body_moves_its_centre_of_mass_and_the_solid_stays() -> None:
    sup = _supervisor("DEF BODY Solid { translation 0 0 1 boundingObject DEF BP Pose { children [ "
                      "Box { size 0.2 0.2 0.2 } ] } physics Physics { } }")  # fmt: skip
    body = sup.getFromDef("BODY")
    assert body.getCenterOfMass() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    sup.getFromDef("BP").getField("translation").setSFVec3f([0.3, 0.0, 0.0])
    sup.step(TS)
    assert body.getPosition() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    assert body.getCenterOfMass() == pytest.approx([0.3, 0.0, 1.0], abs=1e-12)


def _period(sup: Supervisor) -> float:
    """The time between the first and the third sign change of the bob's swing rate (one full period)."""
    bob = sup.getFromDef("BOB")
    changes: list[float] = []
    last = bob.getVelocity()[3]
    t = 0.0
    while len(changes) < 3 and t < 5.0:
        sup.step(TS)
        t += H
        w = bob.getVelocity()[3]
        if w * last < 0:
            changes.append(t - H * abs(w) / (abs(w) + abs(last)))  # the crossing, linearly interpolated
        last = w
    assert len(changes) == 3
    return changes[2] - changes[0]


def _pendulum(d: float, r: float = 0.05, m: float = 1.0, g: float = 9.81) -> float:
    """Small-swing period of a solid sphere of mass m and radius r whose centre is d below the hinge."""
    return 2 * math.pi * math.sqrt((0.4 * m * r * r + m * d * d) / (m * g * d))


@pytest.mark.parametrize("control", [True, False], ids=["load", "moved"])
def test_a_pendulums_period_follows_its_bounding_pose_moved_down_the_arm(control: bool) -> None:
    # a 1 kg ball (mass given, its distribution from the boundingObject) swinging 0.1 rad about a hinge 0.2 m
    # above its centre: 0.908 s; its bounding frame moved to 0.5 m below the hinge: 1.421 s
    sup = _supervisor(
        "Solid { translation 0 0 1 children [ HingeJoint { jointParameters HingeJointParameters { axis 1 0 0 } "
        "endPoint DEF BOB Solid { rotation 1 0 0 0.1 boundingObject DEF BP Pose { translation 0 0 -0.2 "
        "children [ Sphere { radius 0.05 } ] } physics Physics { density -1 mass 1 } } } ] }",
        gravity=9.81,
    )
    d = 0.2
    if not control:
        d = 0.5
        sup.getFromDef("BP").getField("translation").setSFVec3f([0.0, 0.0, -d])
    assert _period(sup) == pytest.approx(_pendulum(d), rel=5e-3)
    assert sup.getFromDef("BOB").getPosition() == pytest.approx([0.0, 0.0, 1.0], abs=1e-5)  # still on its hinge


def test_a_reset_puts_the_geoms_and_the_mass_back_where_the_load_put_them() -> None:
    sup = _supervisor("DEF BODY Solid { translation 0 0 1 boundingObject DEF BP Pose { children [ "
                      "Box { size 0.2 0.2 0.2 } ] } physics Physics { } }", _sensors())  # fmt: skip
    sup.getFromDef("BP").getField("translation").setSFVec3f([0.3, 0.0, 0.0])
    sup.step(TS)
    assert sup.getFromDef("BODY").getCenterOfMass() == pytest.approx([0.3, 0.0, 1.0], abs=1e-12)
    sup.simulationReset()
    sup.step(TS)
    assert sup.getFromDef("BODY").getCenterOfMass() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)


def test_a_visual_pose_edited_moves_the_boundingObject_that_uses_it() -> None:
    # the usual world: the boundingObject is USE of a Pose among the Solid's children; the supervisor moves the
    # DEF (visual) one 0.5 m nearer: the ray meets the 0.2 m cube at 0.4 m instead of 0.9 m
    sup = _supervisor("Solid { translation 1 0 0 children [ DEF BP Pose { children [ Shape { geometry "
                      "Box { size 0.2 0.2 0.2 } } ] } ] boundingObject USE BP }", _sensors())  # fmt: skip
    sup.getDevice("east").enable(TS)
    assert _read(sup)[0] == pytest.approx(0.9, abs=1e-9)
    sup.getFromDef("BP").getField("translation").setSFVec3f([-0.5, 0.0, 0.0])
    assert _read(sup)[0] == pytest.approx(0.4, abs=1e-9)


def test_a_resting_body_whose_bounding_pose_is_raised_wakes_and_settles_that_much_lower() -> None:
    # a 0.2 m cube resting on the floor (asleep after 4 s); its bounding frame raised 0.1 m above the Solid: the
    # Solid stays where it is at the edit, then falls 0.1 m until the box is on the floor again
    sup = _supervisor(
        'Solid { boundingObject Plane { size 10 10 } } DEF BODY Solid { translation 0 0 0.1 name "body" '
        "boundingObject DEF BP Pose { children [ Box { size 0.2 0.2 0.2 } ] } physics Physics { } }",
        gravity=9.81,
    )
    body = sup.getFromDef("BODY")
    for _ in range(int(4.0 / H)):
        sup.step(TS)
    rest = body.getPosition()[2]
    assert rest == pytest.approx(0.1, abs=1e-3)
    sup.getFromDef("BP").getField("translation").setSFVec3f([0.0, 0.0, 0.1])
    sup.step(TS)
    assert body.getPosition()[2] == pytest.approx(rest, abs=1e-4)
    for _ in range(int(1.0 / H)):
        sup.step(TS)
    assert body.getPosition()[2] == pytest.approx(rest - 0.1, abs=1e-4)
    assert body.getCenterOfMass()[2] == pytest.approx(rest, abs=1e-4)
