"""A HingeJointParameters a supervisor imports into a joint's empty ``jointParameters`` field gives the joint its
axis, position, damping... from the next step, the joint set again where its Solids are (nothing moves; the
current configuration is the node's ``position``); removed, the joint goes back to the default axis (x) where it
is, its position read on without a jump. A reset puts the joint back as at load.

Expectations by hand (g = 9.81, basicTimeStep h = 4 ms). The bob is a sphere (r = 0.05 m) 0.5 m out along x from
the joint's anchor. On the default axis x its centre is on the axis: gravity cannot turn it, it stays. About y
it is a physical pendulum released level: its first step adds α·h = g·L/(2/5·r² + L²)·h = 0.0781673 rad/s to
its swing about y (positive: the weight at +x pulls it round +y towards -z). Hanging below the x axis after that
swing, it can only turn about x: it keeps its x. A damper of constant c on an axis about which the spinning
sphere (I = 2/5·m·r², m = 1000·4/3·π·r³) is centred takes one step's spin ω to ω·I/(I + c·h)."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 4
H = TS / 1000
G = 9.81
L = 0.5
R = 0.05
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity {{g}} }}
DEF BOT Robot {{ supervisor TRUE children [
  DEF HINGE HingeJoint {{
    device [ PositionSensor {{ name "s" }} ]
    endPoint DEF BOB Solid {{ translation {{x}} 0 0 boundingObject Sphere {{ radius {R} }} physics Physics {{ }} }}
  }}
] }}
"""


def _supervisor(gravity: float = G, x: float = L) -> Supervisor:
    sup = Supervisor(simulation=Simulation(load_world_text(WORLD.replace("{g}", str(gravity)).replace("{x}", str(x)))))
    sup.getDevice("s").enable(TS)
    for _ in range(20):
        sup.step(TS)
    return sup


def _parameters(sup: Supervisor) -> object:
    return sup.getFromDef("HINGE").getField("jointParameters")


def test_imported_parameters_turn_the_joint_about_their_axis_from_their_position() -> None:
    sup = _supervisor()
    bob = sup.getFromDef("BOB")
    assert bob.getPosition() == pytest.approx([L, 0.0, 0.0], abs=1e-5)  # control: on the x axis it stays
    _parameters(sup).importSFNodeFromString("HingeJointParameters { axis 0 1 0 position 0.3 }")
    sup.step(TS)
    swing = G * L / (0.4 * R * R + L * L) * H
    assert bob.getVelocity()[4] == pytest.approx(swing, rel=1e-3)
    assert sup.getDevice("s").getValue() == pytest.approx(0.3 + swing * H, abs=1e-5)  # read from 0.3 on
    for _ in range(30):
        sup.step(TS)
    assert bob.getPosition()[2] < -0.05  # it swings down...
    assert math.dist(bob.getPosition(), (0.0, 0.0, 0.0)) == pytest.approx(L, abs=1e-4)  # ...about the anchor


def test_removed_parameters_leave_the_joint_on_the_default_axis_where_it_is() -> None:
    sup, control = _supervisor(), _supervisor()
    for s in (sup, control):
        _parameters(s).importSFNodeFromString("HingeJointParameters { axis 0 1 0 }")
        for _ in range(30):
            s.step(TS)
    _parameters(sup).removeSF()
    at, read = sup.getFromDef("BOB").getPosition(), sup.getDevice("s").getValue()
    for s in (sup, control):
        for _ in range(50):
            s.step(TS)
    assert control.getFromDef("BOB").getPosition()[0] < at[0] - 0.01  # control: about y it swings on
    assert sup.getFromDef("BOB").getPosition()[0] == pytest.approx(at[0], abs=1e-5)  # about x it keeps its x
    assert sup.getDevice("s").getValue() == pytest.approx(read, abs=1e-3)  # no jump in the reading


def test_a_reset_puts_the_joint_back_as_at_load() -> None:
    sup = _supervisor()
    _parameters(sup).importSFNodeFromString("HingeJointParameters { axis 0 1 0 position 0.3 }")
    for _ in range(30):
        sup.step(TS)
    sup.simulationReset()
    sup.step(TS)
    assert _parameters(sup).getSFNode() is None
    assert sup.getDevice("s").getValue() == pytest.approx(0.0, abs=1e-6)
    for _ in range(20):
        sup.step(TS)
    assert sup.getFromDef("BOB").getPosition() == pytest.approx([L, 0.0, 0.0], abs=1e-5)  # on the x axis again


def test_imported_damping_acts_on_the_axis() -> None:
    sup = _supervisor(gravity=0.0, x=0.0)  # the sphere centred on the anchor, spinning about x
    bob = sup.getFromDef("BOB")
    bob.setVelocity([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    sup.step(TS)
    assert bob.getVelocity()[3] == pytest.approx(1.0, rel=1e-12)  # control: no damper
    _parameters(sup).importSFNodeFromString("HingeJointParameters { dampingConstant 0.5 }")
    sup.step(TS)
    inertia = 0.4 * (1000 * 4 / 3 * math.pi * R**3) * R * R
    assert bob.getVelocity()[3] == pytest.approx(inertia / (inertia + 0.5 * H), rel=1e-9)
