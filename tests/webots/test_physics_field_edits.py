"""A supervisor's edit of what a Solid's mass comes from (a bounding primitive's dimensions, ``Physics``
``density``, ``mass``, ``centerOfMass``, ``inertiaMatrix``) gives its body the mass properties the load would
give it (Webots §3.2, recomputed by ``WbSolid::updateMass`` whenever they change).

Expectations by hand (no gravity, basicTimeStep h = 4 ms, ODE's reference density 1000 kg/m³). One step of a
1 N force along x adds h/m to the speed; one of a 0.01 N·m torque about z adds 0.01·h/Izz to the spin. Before
each edit the same kick is measured against the old shape's values (the control), so code that leaves the
mass as it was fails the check after the edit."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.kicks import TORQUE, kick, supervisor_in

TS = 4
H = TS / 1000
TAU = TORQUE  # N·m about z, with a 1 N force along x: the kick of tests.support.kicks


def _supervisor(solid_body: str, gravity: float = 0.0) -> Supervisor:
    return supervisor_in(f'DEF BODY Solid {{ translation 0 0 1 name "body" {solid_body} }}', TS, gravity)


def _kick(sup: Supervisor) -> tuple[float, float]:
    return kick(sup, TS)


def _box(m: float, x: float, y: float) -> float:
    return m * (x * x + y * y) / 12  # Izz of a box


def _capsule(r: float, h: float) -> tuple[float, float]:
    """ODE's dMassSetCapsule at density 1000 (axis z): the mass and the inertia about the axis."""
    m1, m2 = 1000 * math.pi * r * r * h, 1000 * 4 / 3 * math.pi * r**3
    return m1 + m2, (0.5 * m1 + 0.4 * m2) * r * r


# (geometry, field, new value, setter, mass/Izz before, mass/Izz after), all at density 1000
SHAPES = [
    ("Box { size 0.2 0.2 0.2 }", "size", [0.4, 0.2, 0.2], "setSFVec3f",
     (8.0, _box(8.0, 0.2, 0.2)), (16.0, _box(16.0, 0.4, 0.2))),
    ("Sphere { radius 0.1 }", "radius", 0.2, "setSFFloat",
     (4000 / 3 * math.pi * 0.001, 0.4 * 4000 / 3 * math.pi * 0.001 * 0.01),
     (4000 / 3 * math.pi * 0.008, 0.4 * 4000 / 3 * math.pi * 0.008 * 0.04)),
    ("Cylinder { radius 0.1 height 0.2 }", "radius", 0.2, "setSFFloat",
     (1000 * math.pi * 0.01 * 0.2, 0.5 * 1000 * math.pi * 0.01 * 0.2 * 0.01),
     (1000 * math.pi * 0.04 * 0.2, 0.5 * 1000 * math.pi * 0.04 * 0.2 * 0.04)),
    ("Capsule { radius 0.1 height 0.2 }", "height", 0.6, "setSFFloat", _capsule(0.1, 0.2), _capsule(0.1, 0.6)),
]  # fmt: skip


@pytest.mark.parametrize(("geometry", "field", "value", "setter", "before", "after"), SHAPES,
                         ids=["box", "sphere", "cylinder", "capsule"])  # fmt: skip
def test_resizing_the_bounding_shape_of_a_density_body_gives_it_the_new_shapes_mass_and_inertia(
    geometry: str, field: str, value: object, setter: str, before: tuple[float, float], after: tuple[float, float]
) -> None:
    # the usual world: the boundingObject is a USE of the visual shape's geometry, the supervisor edits the DEF
    sup = _supervisor(f"children [ Shape {{ geometry DEF G {geometry} }} ] boundingObject USE G physics Physics {{ }}")
    assert _kick(sup) == pytest.approx((H / before[0], TAU * H / before[1]), rel=1e-6)  # control: the load's shape
    getattr(sup.getFromDef("G").getField(field), setter)(value)
    assert _kick(sup) == pytest.approx((H / after[0], TAU * H / after[1]), rel=1e-6)


def test_resizing_the_bounding_box_of_a_body_with_a_given_mass_keeps_the_mass_and_rescales_the_inertia() -> None:
    sup = _supervisor("boundingObject DEF G Box { size 0.2 0.2 0.2 } physics Physics { density -1 mass 2 }")
    assert _kick(sup) == pytest.approx((H / 2, TAU * H / _box(2, 0.2, 0.2)), rel=1e-6)
    sup.getFromDef("G").getField("size").setSFVec3f([0.6, 0.2, 0.2])
    assert _kick(sup) == pytest.approx((H / 2, TAU * H / _box(2, 0.6, 0.2)), rel=1e-6)


def test_resizing_one_part_of_the_bounding_object_moves_the_centre_of_mass_and_the_solid_stays() -> None:
    # two 0.2 m cubes, at x = 0 and x = 0.4: CoM at 0.2. Doubling the second's size (8 kg -> 64 kg) moves it to
    # 64·0.4 / 72 = 0.35556 m, where the body's origin must go while the Solid itself does not move.
    sup = _supervisor("boundingObject Group { children [ Box { size 0.2 0.2 0.2 } Pose { translation 0.4 0 0 "
                      "children [ DEF FAR Box { size 0.2 0.2 0.2 } ] } ] } physics Physics { }")
    body = sup.getFromDef("BODY")
    at = body.getPosition()
    assert body.getCenterOfMass() == pytest.approx([at[0] + 0.2, at[1], at[2]], abs=1e-9)
    sup.getFromDef("FAR").getField("size").setSFVec3f([0.4, 0.4, 0.4])
    assert body.getCenterOfMass() == pytest.approx([at[0] + 64 * 0.4 / 72, at[1], at[2]], abs=1e-9)
    sup.step(TS)
    assert body.getPosition() == pytest.approx(at, abs=1e-9)
    assert _kick(sup)[0] == pytest.approx(H / 72, rel=1e-6)


def test_a_density_edit_scales_mass_and_inertia_and_a_shared_physics_node_edits_every_solid_using_it() -> None:
    world = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF BODY Solid {{ translation 0 0 1 boundingObject Box {{ size 0.2 0.2 0.2 }} physics DEF P Physics {{ }} }}
DEF OTHER Solid {{ translation 2 0 1 name "other" boundingObject Sphere {{ radius 0.1 }} physics USE P }}
Robot {{ supervisor TRUE }}
"""
    sup = Supervisor(simulation=Simulation(load_world_text(world)))
    sup.step(TS)
    assert _kick(sup) == pytest.approx((H / 8, TAU * H / _box(8, 0.2, 0.2)), rel=1e-6)
    other = sup.getFromDef("OTHER")
    ball = 4000 / 3 * math.pi * 0.001
    other.addForce([1.0, 0.0, 0.0], False)
    v0 = other.getVelocity()[0]
    sup.step(TS)
    assert other.getVelocity()[0] - v0 == pytest.approx(H / ball, rel=1e-6)
    sup.getFromDef("P").getField("density").setSFFloat(2000)  # twice the mass: half the velocity change
    assert _kick(sup) == pytest.approx((H / 16, TAU * H / _box(16, 0.2, 0.2)), rel=1e-6)
    other.addForce([1.0, 0.0, 0.0], False)
    v0 = other.getVelocity()[0]
    sup.step(TS)
    assert other.getVelocity()[0] - v0 == pytest.approx(H / (2 * ball), rel=1e-6)


def test_mass_edits_follow_the_load_rules_a_given_mass_then_back_to_the_density() -> None:
    sup = _supervisor("boundingObject Box { size 0.2 0.2 0.2 } physics Physics { }")
    mass = sup.getFromDef("BODY").getField("physics").getSFNode().getField("mass")
    mass.setSFFloat(2)
    assert _kick(sup) == pytest.approx((H / 2, TAU * H / _box(2, 0.2, 0.2)), rel=1e-6)
    mass.setSFFloat(-1)  # unset again: the density's 8 kg
    assert _kick(sup) == pytest.approx((H / 8, TAU * H / _box(8, 0.2, 0.2)), rel=1e-6)


def test_an_inertia_matrix_edit_replaces_the_inertia_once_it_is_complete() -> None:
    sup = _supervisor("boundingObject Box { size 0.2 0.2 0.2 } "
                      "physics Physics { density -1 mass 2 centerOfMass [ 0 0 0 ] }")
    assert _kick(sup) == pytest.approx((H / 2, TAU * H / _box(2, 0.2, 0.2)), rel=1e-6)
    inertia = sup.getFromDef("BODY").getField("physics").getSFNode().getField("inertiaMatrix")
    with pytest.warns(UserWarning, match="invalid inertiaMatrix"):  # one vector: ignored, as at load
        inertia.insertMFVec3f(0, [0.5, 0.25, 0.125])
    assert _kick(sup) == pytest.approx((H / 2, TAU * H / _box(2, 0.2, 0.2)), rel=1e-6)
    inertia.insertMFVec3f(1, [0.0, 0.0, 0.0])
    assert _kick(sup) == pytest.approx((H / 2, TAU * H / 0.125), rel=1e-6)


PENDULUM_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{
  translation 0 0 1
  supervisor TRUE
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 }}
      device [ PositionSensor {{ name "sensor" }} ]
      endPoint DEF ARM Solid {{ name "arm" boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }}
    }}
  ]
}}
"""


def test_a_centre_of_mass_moved_off_the_hinge_axis_makes_the_arm_a_pendulum_about_the_same_anchor() -> None:
    # The ball's centre of mass is on the hinge axis: the arm hangs at any angle. centerOfMass set 0.5 m away,
    # 0.1 rad out, carries the ball's distribution there rigidly: a physical pendulum about the same anchor,
    # T = 2π·sqrt((2/5·r² + L²) / (g·L)) = 1.4213 s. Left anchored at the old centre of mass, the joint would
    # hold the new one still (and the arm's origin would leave the axis).
    sup = Supervisor(simulation=Simulation(load_world_text(PENDULUM_WORLD)))
    sensor = sup.getDevice("sensor")
    sensor.enable(TS)
    sup.step(TS)
    sup.step(TS)
    assert sensor.getValue() == pytest.approx(0.0, abs=1e-9)  # control: it does not swing
    arm = sup.getFromDef("ARM")
    arm.getField("physics").getSFNode().getField("centerOfMass").insertMFVec3f(
        0, [-0.5 * math.sin(0.1), 0.0, -0.5 * math.cos(0.1)])
    crossings, previous = [], sensor.getValue() + 0.1
    for _ in range(round(4.5 / H)):
        sup.step(TS)
        value = sensor.getValue() + 0.1  # straight down is 0.1 rad from where the centre of mass was put
        if previous < 0.0 <= value:
            crossings.append(sup.getTime() - H * value / (value - previous))
        previous = value
        assert math.dist(arm.getPosition(), (0.0, 0.0, 1.0)) < 1e-3  # the origin stays on the axis
    assert len(crossings) >= 3
    expected = 2 * math.pi * math.sqrt((0.4 * 0.05**2 + 0.25) / (9.81 * 0.5))
    assert (crossings[-1] - crossings[0]) / (len(crossings) - 1) == pytest.approx(expected, rel=0.01)


def test_simulation_reset_gives_back_the_loaded_shapes_mass_and_centre_of_mass() -> None:
    sup = _supervisor("boundingObject Group { children [ Box { size 0.2 0.2 0.2 } Pose { translation 0.4 0 0 "
                      "children [ DEF FAR Box { size 0.2 0.2 0.2 } ] } ] } physics DEF P Physics { }")
    body = sup.getFromDef("BODY")
    at = body.getPosition()
    sup.getFromDef("FAR").getField("size").setSFVec3f([0.4, 0.4, 0.4])
    sup.getFromDef("P").getField("density").setSFFloat(500)
    assert _kick(sup)[0] == pytest.approx(H / 36, rel=1e-6)  # control: (8 + 64) kg at half the density
    sup.simulationReset()
    sup.step(TS)
    assert body.getPosition() == pytest.approx(at, abs=1e-9)
    assert body.getCenterOfMass() == pytest.approx([at[0] + 0.2, at[1], at[2]], abs=1e-9)
    assert _kick(sup)[0] == pytest.approx(H / 16, rel=1e-6)
