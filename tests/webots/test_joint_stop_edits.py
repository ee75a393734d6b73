"""A supervisor's edit of a joint's ``minStop``/``maxStop``, ``staticFriction`` or (Hinge2) suspension constants
acts on ODE from the next step, as in Webots, on every joint type and axis that has the field.

S = /work/shared/reference/webots-on-ode.md. Webots applies edited stops to ODE again (WbJointParameters'
minStopChanged/maxStopChanged, the joint's updateMinAndMaxStop) with the mapping of the load: S §4.2 (hinge and
Hinge2 axes: LoStop = −maxStop + offset, HiStop = −minStop + offset, clamped into [−π, π]), S §4.3 (slider:
minStop − offset, maxStop − offset), stops only when minStop ≠ maxStop. Expected values are hand computations
(each test says which), never runs of this code; each test checks the behaviour before the edit (the control)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, TS, G, load_arm
from tests.support.quiet_worlds import quiet_supervisor
from tests.support.world_runs import run_world_cli

HEAVY_BASE = 'Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _swing(sup: Supervisor, sensor: Any, n: int) -> float:
    """The largest position the sensor reads over ``n`` steps."""
    top = -math.inf
    for _ in range(n):
        assert sup.step(TS) != -1
        top = max(top, sensor.getValue())
    return top


def _joint_world(joint: str, static_parent: bool) -> str:
    return joint if static_parent else f"{HEAVY_BASE} children [ {joint} ] }}"


def _params(sup: Supervisor, static_parent: bool, field: str = "jointParameters") -> Any:
    children = sup.getSelf().getField("children")
    joint = children.getMFNode(0)
    if not static_parent:
        joint = joint.getField("children").getMFNode(0)
    return joint.getField(field).getSFNode()


def _hinge(params: str, bob_at: str = "0.5 0 0") -> str:
    return (f"HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 {params} }} "
            f"device [ PositionSensor {{ name \"s\" }} ] endPoint {BOB.format(t=bob_at)} }}")


def _arm(params: str, static_parent: bool = True, bob_at: str = "0.5 0 0") -> tuple[Supervisor, Any]:
    _, sup = load_arm(_joint_world(_hinge(params, bob_at), static_parent), gravity=G)
    s = sup.getDevice("s")
    s.enable(TS)
    return sup, s


# ------------------------------------------------------------------------------------------ HingeJoint stops


@pytest.mark.parametrize("static_parent", [True, False])
def test_hinge_stops_set_at_run_time_hold_the_arm_about_the_offset(static_parent: bool) -> None:
    # S §4.2: the stops are Webots positions (−maxStop + offset in ODE): an arm loaded at position 0.2 without
    # stops, given minStop −0.3 / maxStop 0.3 after its first step, rests on 0.3 (gravity turns it toward +)
    bob_at = f"{0.5 * math.cos(0.2)} 0 {-0.5 * math.sin(0.2)}"
    sup, s = _arm("position 0.2", static_parent, bob_at)
    _steps(sup, 1)
    params = _params(sup, static_parent)
    params.getField("minStop").setSFFloat(-0.3)
    params.getField("maxStop").setSFFloat(0.3)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3, abs=1e-3)
    # control: the same arm left without stops swings far past 0.3 (toward π − 0.2, energy kept)
    free, s_free = _arm("position 0.2", static_parent, bob_at)
    assert _swing(free, s_free, 250) > 2.5


def test_hinge_stop_moved_then_taken_away_at_run_time() -> None:
    sup, s = _arm("minStop -0.3 maxStop 0.3")
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3, abs=1e-3)  # control: the load stop holds
    params = _params(sup, True)
    params.getField("maxStop").setSFFloat(0.6)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.6, abs=1e-3)
    # S §4.2: stops only when minStop ≠ maxStop; equal, the arm swings free from rest at 0.6 toward π − 0.6
    # (energy kept, no damping: hand computation), half a period of about 0.7 s later
    params.getField("minStop").setSFFloat(0.6)
    assert _swing(sup, s, 250) > 2.4


def test_hinge_stops_edited_in_reverse_order_are_swapped() -> None:
    # S §4.2: LoStop/HiStop are swapped if needed: minStop 0.3 / maxStop −0.3 hold the arm as −0.3 / 0.3 do
    sup, s = _arm("")
    params = _params(sup, True)
    params.getField("minStop").setSFFloat(0.3)
    params.getField("maxStop").setSFFloat(-0.3)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3, abs=1e-3)


def test_a_reset_gives_the_hinge_its_load_stops_again() -> None:
    # a reset restores the fields (S §6): the arm, loaded without stops, swings past a stop set at run time
    sup, s = _arm("")
    params = _params(sup, True)
    params.getField("maxStop").setSFFloat(0.3)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3, abs=1e-3)
    sup.simulationReset()
    _steps(sup, 1)
    assert params.getField("maxStop").getSFFloat() == 0.0
    assert _swing(sup, s, 250) > 2.5


def test_parameters_removed_from_a_hinge_resting_on_its_stop_take_the_stop_away() -> None:
    # removed, the joint goes back to the defaults where it is (physics/joint_changes.py): axis x, no stop. ODE
    # must take the stop away from a hinge resting on it (it stopped inside the next step); about x gravity has
    # no torque on the arm (its bob lies in the xz plane through the anchor), which stays where it is
    sup, s = _arm("minStop -0.3 maxStop 0.3")
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(0.3, abs=1e-3)  # control: resting on the stop
    joint = sup.getSelf().getField("children").getMFNode(0)
    bob = joint.getField("endPoint").getSFNode()
    before = bob.getPosition()
    joint.getField("jointParameters").removeSF()
    _steps(sup, 100)
    assert bob.getPosition() == pytest.approx(before, abs=1e-5)  # (the rows sag by m·g·h·CFM/ERP = 2e-6 m)


# ------------------------------------------------------------------------------------------ SliderJoint stops


@pytest.mark.parametrize("static_parent", [True, False])
def test_slider_stops_set_at_run_time_hold_it_about_the_offset(static_parent: bool) -> None:
    # S §4.3: LoStop = minStop − offset: a slider loaded at position 0.1 (axis +z) without stops, given
    # minStop −0.2 / maxStop 0.3, falls onto −0.2 (0.3 m in 0.25 s, hand computation)
    slider = ("SliderJoint { jointParameters JointParameters { axis 0 0 1 position 0.1 } "
              f"device [ PositionSensor {{ name \"s\" }} ] endPoint {BOB.format(t='0 0 0.1')} }}")
    _, sup = load_arm(_joint_world(slider, static_parent), gravity=G)
    s = sup.getDevice("s")
    s.enable(TS)
    _steps(sup, 1)
    params = _params(sup, static_parent)
    params.getField("minStop").setSFFloat(-0.2)
    params.getField("maxStop").setSFFloat(0.3)
    _steps(sup, 500)
    assert s.getValue() == pytest.approx(-0.2, abs=1e-3)
    params.getField("minStop").setSFFloat(0.3)  # equal stops: none (S §4.3 "if min ≠ max"): it falls on
    _steps(sup, 50)
    assert s.getValue() < -0.3


# ------------------------------------------------------------------------------------------ Hinge2Joint stops

HINGE2 = """Robot {{ supervisor TRUE children [ Solid {{ children [ DEF BASE Solid {{
  physics Physics {{ density -1 mass 50 }} boundingObject Box {{ size 0.1 0.1 0.1 }}
  children [ Hinge2Joint {{
    jointParameters DEF P1 HingeJointParameters {{ axis {axis1} }}
    jointParameters2 DEF P2 JointParameters {{ axis {axis2} }}
    device [ RotationalMotor {{ name "m1" maxTorque 1 }} PositionSensor {{ name "s1" }} ]
    device2 [ RotationalMotor {{ name "m2" maxTorque 1 }} PositionSensor {{ name "s2" }} ]
    endPoint DEF WHEEL Solid {{ boundingObject Sphere {{ radius 0.1 }} physics Physics {{ density -1 mass 1 }} }}
  }} ] }} ] }} ] }}"""


def _world(scene: str, gravity: float = 0.0) -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity {gravity} physicsDisableTime 0 }}\n{scene}\n"
    return quiet_supervisor(text)


def _driven(sup: Supervisor, axis: int, velocity: float) -> Any:
    motor = sup.getDevice(f"m{axis}")
    motor.setPosition(math.inf)
    motor.setVelocity(velocity)
    s = sup.getDevice(f"s{axis}")
    s.enable(TS)
    return s


def _rests_on_new_stops(sup: Supervisor, axis: int, velocity: float) -> tuple[Any, Any]:
    """Drive ``axis`` at ``velocity`` for 0.1 s (no stop yet: the control), give it minStop −0.2 / maxStop 0.5,
    and check it rests on the stop it runs into 1 s later; (its sensor, its parameters node)."""
    s = _driven(sup, axis, velocity)
    _steps(sup, 25)
    assert s.getValue() == pytest.approx(0.1 * velocity, abs=0.005)  # control: no stop yet
    params = sup.getFromDef(f"P{axis}")
    params.getField("minStop").setSFFloat(-0.2)
    params.getField("maxStop").setSFFloat(0.5)
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(0.5 if velocity > 0 else -0.2, abs=3e-3)
    return s, params


@pytest.mark.parametrize("velocity", [1.0, -1.0])
@pytest.mark.parametrize("axis", [1, 2])
def test_hinge2_stops_set_at_run_time_hold_each_axis(axis: int, velocity: float) -> None:
    # S §4.4: stops on both axes like the hinge. Driven at ±1 rad/s (1 N·m) for 0.1 s, then given minStop −0.2 /
    # maxStop 0.5: 1 s later it rests on the stop (it would be at ±1.1 rad without it, hand computation)
    sup = _world(HINGE2.format(axis1="1 0 0", axis2="0 0 1"))
    s, params = _rests_on_new_stops(sup, axis, velocity)
    # equal stops take them away: the motor turns the axis on at 1 rad/s
    params.getField("minStop").setSFFloat(0.5)
    _steps(sup, 250)
    assert s.getValue() * velocity > 1.0


def test_hinge2_first_axis_stop_cfm_edited_at_run_time_reaches_ode() -> None:
    # S §4.2/§4.4: a Hinge2's HingeJointParameters stopCFM reaches its first axis' stop row when edited. Driven
    # onto maxStop 0.5 by 1 N·m, the row's force ERP·err/(h·CFM) balances it: err = 1·h·CFM/ERP = 0.002 rad with
    # CFM 0.1 and the world's ERP 0.2 (hand computation; 2e-7 rad with the world's CFM 1e-5)
    sup = _world(HINGE2.format(axis1="1 0 0", axis2="0 0 1"))
    s = _driven(sup, 1, 1.0)
    params = sup.getFromDef("P1")
    params.getField("maxStop").setSFFloat(0.5)
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(0.5, abs=1e-5)  # control
    params.getField("stopCFM").setSFFloat(0.1)
    _steps(sup, 250)
    assert s.getValue() == pytest.approx(0.5 + 1.0 * TS / 1000 * 0.1 / 0.2, abs=1e-4)

# ------------------------------------------------------------------------------------------ BallJoint stops

BALL = """Robot {{ supervisor TRUE {parent} children [ BallJoint {{
  jointParameters DEF P1 BallJointParameters {{ }}
  jointParameters2 DEF P2 JointParameters {{ axis 1 0 0 }}
  jointParameters3 DEF P3 JointParameters {{ axis 0 0 1 }}
  device [ RotationalMotor {{ name "m1" maxTorque 1 }} PositionSensor {{ name "s1" }} ]
  device2 [ RotationalMotor {{ name "m2" maxTorque 1 }} PositionSensor {{ name "s2" }} ]
  device3 [ RotationalMotor {{ name "m3" maxTorque 1 }} PositionSensor {{ name "s3" }} ]
  endPoint DEF BALL Solid {{ boundingObject Sphere {{ radius 0.1 }} physics Physics {{ density -1 mass 2 }} }}
}} ] }}"""
HEAVY_ROBOT = "boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1e6 }"


@pytest.mark.parametrize("velocity", [1.0, -1.0])
@pytest.mark.parametrize("axis", [1, 2, 3])
@pytest.mark.parametrize("parent", ["static", "body"])
def test_ball_stops_set_at_run_time_hold_each_axis(parent: str, axis: int, velocity: float) -> None:
    # the BallJoint's stops, on its Euler AMotor, act as at load: a sphere centred on the anchor driven at ±1 rad/s
    # for 0.1 s, then given minStop −0.2 / maxStop 0.5, rests on the stop 1 s later (hand computation)
    sup = _world(BALL.format(parent=HEAVY_ROBOT if parent == "body" else ""))
    _rests_on_new_stops(sup, axis, velocity)


# ------------------------------------------------------------------------------------------ static friction


def test_static_friction_edited_to_zero_lets_the_arm_fall() -> None:
    # S §4.5: without a motor, static friction is a velocity-0 motor limited to staticFriction. 6 N·m holds the
    # arm (gravity's torque m·g·r = 4.9 N·m); edited to 0 the arm falls: from rest at horizontal it passes
    # 1 rad within 0.4 s (α = 4.9/0.251 = 19.5 rad/s² at first, hand computation)
    sup, s = _arm("staticFriction 6")
    _steps(sup, 100)
    assert abs(s.getValue()) < 1e-3  # control: held
    _params(sup, True).getField("staticFriction").setSFFloat(0.0)
    _steps(sup, 100)
    assert s.getValue() > 1.0


def test_static_friction_edited_up_at_run_time_brakes_the_arm() -> None:
    # 6 N·m set on a free arm at rest: it is held as if loaded with it (gravity's 4.9 N·m is less); this worked
    # before, kept beside the edit to 0 as the way up
    sup, s = _arm("")
    _params(sup, True).getField("staticFriction").setSFFloat(6.0)
    _steps(sup, 100)
    assert abs(s.getValue()) < 1e-3


KINEMATIC = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { controller "<extern>" supervisor TRUE children [ HingeJoint {
  jointParameters DEF P HingeJointParameters { axis 0 1 0 staticFriction 1 minStop -1 maxStop 1 }
  endPoint DEF TIP Solid { translation 0.5 0 0 } } ] }
"""
KINEMATIC_EDITS = """from controller import Supervisor
s = Supervisor()
s.step(8)
params = s.getFromDef("P")
for name, value in (("staticFriction", 0.0), ("staticFriction", 2.0), ("minStop", -0.5), ("maxStop", 0.5),
                    ("springConstant", 3.0), ("stopERP", 0.5)):
    params.getField(name).setSFFloat(value)
    s.step(8)
print("TIP", " ".join(repr(v) for v in s.getFromDef("TIP").getPosition()))
"""


def test_parameter_edits_on_a_kinematic_joint_leave_it_as_it_is(tmp_path: Path) -> None:
    # S §4.1: an endPoint without Physics makes a kinematic joint, with no ODE joint: its parameters' friction,
    # stops, spring and stop softness have nothing in ODE to act on (edited, friction was passed to ODE on a null
    # joint, which aborted the process: the run goes through a child process). The endPoint stays where it is.
    run = run_world_cli(tmp_path, "kinematic", KINEMATIC, KINEMATIC_EDITS)
    assert run.returncode == 0, run.stderr
    tip = next(line for line in run.stdout.splitlines() if line.startswith("TIP "))
    assert [float(v) for v in tip.split()[1:]] == pytest.approx([0.5, 0.0, 0.0], abs=1e-12)


# ------------------------------------------------------------------------------------------ Hinge2 suspension


def _sag(sup: Supervisor, n: int = 500) -> float:
    """How far the wheel hangs below its anchor (the base's origin; the base, fixed to the world, sags too)."""
    _steps(sup, n)
    return sup.getFromDef("BASE").getPosition()[2] - sup.getFromDef("WHEEL").getPosition()[2]


def test_hinge2_suspension_edited_at_run_time_reaches_ode() -> None:
    # S §4.4/§4.5: suspension ERP = hK/(hK + B), CFM = 1/(hK + B); at rest the row's force ERP·err/(h·CFM) is then
    # K·err, so a 1 kg wheel hanging on a vertical first axis sags m·g/K (hand computation). With both constants 0
    # ODE keeps the world's ERP 0.2 / CFM 1e-5: a sag of m·g·h·CFM/ERP = 2e-6 m
    sup = _world(HINGE2.format(axis1="0 0 1", axis2="1 0 0"), gravity=G)
    world_sag = G * TS / 1000 * 1e-5 / 0.2
    assert _sag(sup) == pytest.approx(world_sag, abs=1e-6)  # control
    params = sup.getFromDef("P1")
    params.getField("suspensionSpringConstant").setSFFloat(1000.0)
    params.getField("suspensionDampingConstant").setSFFloat(60.0)
    assert _sag(sup) == pytest.approx(G / 1000.0, rel=1e-3)
    params.getField("suspensionSpringConstant").setSFFloat(2000.0)
    assert _sag(sup) == pytest.approx(G / 2000.0, rel=1e-3)
    params.getField("suspensionSpringConstant").setSFFloat(0.0)
    params.getField("suspensionDampingConstant").setSFFloat(0.0)
    assert _sag(sup) == pytest.approx(world_sag, abs=1e-6)

