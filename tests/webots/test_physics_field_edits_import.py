"""A Physics node a supervisor imports into a Solid that has none makes it a dynamic body as at load (its mass
from its boundingObject, §3.2; merged into its parent's body when that has one, §3.3); removing it makes the
Solid static again where it is.

Expectations by hand (no gravity, basicTimeStep h = 4 ms, reference density 1000 kg/m³): a 0.2 m cube weighs
8 kg with Izz = 8·(0.2² + 0.2²)/12; one step of a 1 N force along x adds h/m to the speed, one of a 0.01 N·m
torque about z adds 0.01·h/Izz to the spin. Before the import (and after the removal) the Solid has no body:
forces do nothing, it does not move."""

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
CUBE_IZZ = 8 * 0.08 / 12


def _supervisor(world_body: str) -> Supervisor:
    return supervisor_in(world_body, TS)


def _kick(sup: Supervisor, name: str) -> tuple[float, float]:
    return kick(sup, TS, name)


def test_a_physics_node_imported_into_a_static_solid_makes_it_a_body_and_removing_it_makes_it_static() -> None:
    sup = _supervisor("DEF CUBE Solid { translation 0 0 1 boundingObject Box { size 0.2 0.2 0.2 } }")
    cube = sup.getFromDef("CUBE")
    assert _kick(sup, "CUBE") == (0.0, 0.0)  # control: a static Solid takes no force
    cube.getField("physics").importSFNodeFromString("Physics { }")
    assert _kick(sup, "CUBE") == pytest.approx((H / 8, TAU * H / CUBE_IZZ), rel=1e-6)
    for _ in range(25):
        sup.step(TS)
    moved = cube.getPosition()
    assert moved[0] == pytest.approx(H / 8 * 26 * H, rel=1e-3)  # it drifts at the speed the kick gave it
    cube.getField("physics").removeSF()
    for _ in range(10):
        sup.step(TS)
    assert cube.getPosition() == pytest.approx(moved, abs=1e-12)  # static where it was
    assert cube.getVelocity() == [0.0] * 6


def test_a_physics_node_imported_into_a_child_solid_merges_its_mass_into_the_parents_body() -> None:
    # BASE (8 kg cube) holds a child Solid without Physics, a second 0.2 m cube 0.4 m out along x: its geom
    # rides on BASE's body but weighs nothing. Given Physics it adds 8 kg there: 16 kg, CoM 0.2 m out.
    sup = _supervisor("DEF BASE Solid { translation 0 0 1 boundingObject Box { size 0.2 0.2 0.2 } physics Physics { } "
                      "children [ DEF ARM Solid { translation 0.4 0 0 name \"arm\" "
                      "boundingObject Box { size 0.2 0.2 0.2 } } ] }")
    base = sup.getFromDef("BASE")
    assert _kick(sup, "BASE")[0] == pytest.approx(H / 8, rel=1e-6)  # control: the child weighs nothing
    sup.getFromDef("ARM").getField("physics").importSFNodeFromString("Physics { }")
    at, R = base.getPosition(), base.getOrientation()  # (the control's kick turned it a little)
    assert base.getCenterOfMass() == pytest.approx([at[k] + 0.2 * R[3 * k] for k in range(3)], abs=1e-9)
    assert _kick(sup, "BASE")[0] == pytest.approx(H / 16, rel=1e-6)
    sup.getFromDef("ARM").getField("physics").removeSF()
    assert _kick(sup, "BASE")[0] == pytest.approx(H / 8, rel=1e-6)


def test_simulation_reset_takes_an_imported_physics_away_and_puts_the_solid_back() -> None:
    sup = _supervisor("DEF CUBE Solid { translation 0 0 1 boundingObject Box { size 0.2 0.2 0.2 } }")
    cube = sup.getFromDef("CUBE")
    cube.getField("physics").importSFNodeFromString("Physics { }")
    _kick(sup, "CUBE")
    for _ in range(25):
        sup.step(TS)
    assert cube.getPosition()[0] > 1e-5  # control: it moved
    sup.simulationReset()
    sup.step(TS)
    assert cube.getField("physics").getSFNode() is None
    assert cube.getPosition() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    assert _kick(sup, "CUBE") == (0.0, 0.0)  # static again


HINGE_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BASE Solid {{
  translation 0 0 1
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 }}
      endPoint DEF ARM Solid {{ translation 0.5 0 0 boundingObject Sphere {{ radius 0.05 }} }}
    }}
  ]
}}
Robot {{ supervisor TRUE }}
"""


def test_a_physics_node_imported_into_a_static_joint_endpoint_makes_it_swing_about_the_joint() -> None:
    # A static arm 0.5 m out on a hinge about y: given Physics, its ball falls on a circle about the anchor
    # (distance kept 0.5 m), not straight down as a free body would.
    sup = Supervisor(simulation=Simulation(load_world_text(HINGE_WORLD)))
    sup.step(TS)
    arm = sup.getFromDef("ARM")
    for _ in range(10):
        sup.step(TS)
    assert arm.getPosition() == pytest.approx([0.5, 0.0, 1.0], abs=1e-12)  # control: static
    arm.getField("physics").importSFNodeFromString("Physics { }")
    for _ in range(100):
        sup.step(TS)
    x, _, z = arm.getPosition()
    assert z < 0.9  # it fell
    assert ((x * x + (z - 1.0) ** 2) ** 0.5) == pytest.approx(0.5, abs=1e-3)  # held by the hinge
    assert x < 0.45  # it swung in towards under the anchor


CHAIN_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BASE Solid {{
  translation 0 0 1
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 }}
      endPoint DEF ARM Solid {{
        translation 0.5 0 0
        boundingObject Sphere {{ radius 0.05 }}
        physics Physics {{ }}
        children [
          HingeJoint {{
            jointParameters HingeJointParameters {{ axis 0 1 0 }}
            endPoint DEF TIP Solid {{ name "tip" translation 0.2 0 0 boundingObject Sphere {{ radius 0.02 }}
                                     physics Physics {{ }} }}
          }}
        ]
      }}
    }}
  ]
}}
Robot {{ supervisor TRUE }}
"""


def test_removing_the_physics_of_a_swinging_arm_stops_it_where_it_is_its_own_jointed_child_swings_on() -> None:
    sup = Supervisor(simulation=Simulation(load_world_text(CHAIN_WORLD)))
    arm, tip = sup.getFromDef("ARM"), sup.getFromDef("TIP")
    for _ in range(50):
        sup.step(TS)
    stopped = arm.getPosition()
    assert stopped[2] < 0.95  # control: the arm swings down
    arm.getField("physics").removeSF()
    tip_before = tip.getPosition()
    for _ in range(50):
        sup.step(TS)
    assert arm.getPosition() == pytest.approx(stopped, abs=1e-12)  # static where it was
    assert tip.getPosition()[2] < tip_before[2] - 0.01  # the tip falls on...
    # ...held by its hinge. It keeps the velocity it had (the arm's swing in it: ~2.8 m/s round a 0.2 m circle), and
    # ODE's soft hinge lets the distance stretch by up to 1.4 mm at that speed (as in a world built with the arm
    # static and the tip given that velocity)
    assert math.dist(tip.getPosition(), stopped) == pytest.approx(0.2, abs=2e-3)
    sup.simulationReset()  # the removed Physics stays removed; the fields go back to the load's
    sup.step(TS)
    assert arm.getPosition() == pytest.approx([0.5, 0.0, 1.0], abs=1e-9)
    assert tip.getPosition() == pytest.approx([0.7, 0.0, 1.0], abs=1e-6)
