"""Track, Propeller, coupled motors and SolidReference: one test per fact of webots-devices.md §7-§10 that no
other test pinned.

Line numbers (D:n) cite /work/shared/reference/webots-devices.md; expected values come from it or from hand
computation, never from running this code.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.quiet_worlds import quiet_supervisor

TS = 4


def _sup(body: str, info: str = "gravity 0") -> Supervisor:
    return quiet_supervisor(f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} {info} }}\n{body}\n")


def _steps(sup: Supervisor, n: int) -> None:
    for _ in range(n):
        sup.step(TS)


# ------------------------------------------------------------------------------------------ §7 Track


TRACK = ('Robot {{ supervisor TRUE children [ Track {{ translation 0 0 0.2 boundingObject Box {{ size 2 0.4 0.1 }} '
         'physics Physics {{ mass 5 }} device [ {devices} ] }} ] }}')


def test_track_motor_is_found_by_its_own_name_linear_motor_by_default() -> None:
    # D:290-291: the motor's device name is its own name field (LinearMotor default "linear motor", maxForce 10)
    sup = _sup(TRACK.format(devices="LinearMotor { }"))
    motor = sup.getDevice("linear motor")
    assert motor is not None and motor.getMaxForce() == 10


def test_track_position_sensor_is_linear() -> None:
    # D:311: "Position sensor in device: type LINEAR"
    sup = _sup(TRACK.format(devices='LinearMotor { } PositionSensor { name "s" }'))
    sensor = sup.getDevice("s")
    assert sensor.getType() == sensor.LINEAR == 1


def test_track_belt_travel_integrates_the_velocity() -> None:
    # D:307: trackPos += v·dt; velocity control at 0.25 m/s (within maxVelocity 10, acceleration -1) for 0.2 s
    sup = _sup(TRACK.format(devices='LinearMotor { } PositionSensor { name "s" }'))
    sensor = sup.getDevice("s")
    sensor.enable(TS)
    motor = sup.getDevice("linear motor")
    motor.setPosition(math.inf)
    motor.setVelocity(0.25)
    _steps(sup, 50)
    assert sensor.getValue() == pytest.approx(0.05, rel=1e-6)


# ------------------------------------------------------------------------------------------ §8 Propeller


def _drone(propeller: str, motor: str = "maxVelocity 200 maxTorque 1000", body: str = "size 0.1 0.1 0.1",
           mass: float = 1.0) -> Supervisor:
    return _sup(
        f"DEF DRONE Robot {{ supervisor TRUE boundingObject Box {{ {body} }} physics Physics {{ mass {mass} }} "
        f'children [ Propeller {{ {propeller} device RotationalMotor {{ name "prop" {motor} }} }} ] }}'
    )


def _spin(sup: Supervisor, speed: float, ramp_steps: int, measure_steps: int) -> tuple[list[float], list[float]]:
    prop = sup.getDevice("prop")
    prop.setPosition(math.inf)
    prop.setVelocity(speed)
    _steps(sup, ramp_steps)
    drone = sup.getFromDef("DRONE")
    v0 = drone.getVelocity()
    _steps(sup, measure_steps)
    return v0, drone.getVelocity()


def test_propeller_zero_shaft_axis_becomes_y() -> None:
    # D:320: "shaftAxis 1 0 0 (zero -> (0,1,0) with warning)"; T = t1·w² = 1e-4·100² = 1 N on 1 kg for 0.5 s
    v0, v1 = _spin(_drone("shaftAxis 0 0 0 thrustConstants 1e-4 0 torqueConstants 0 0"), 100.0, 50, 125)
    assert (v1[1] - v0[1]) == pytest.approx(0.5, rel=1e-3)
    assert abs(v1[0] - v0[0]) < 1e-9 and abs(v1[2] - v0[2]) < 1e-9


def test_propeller_shaft_axis_is_normalised() -> None:
    # D:320: shaftAxis "normalised": (0 0 2) pushes as (0 0 1), 1 N on 1 kg for 0.5 s
    v0, v1 = _spin(_drone("shaftAxis 0 0 2 thrustConstants 1e-4 0 torqueConstants 0 0"), 100.0, 50, 125)
    assert (v1[2] - v0[2]) == pytest.approx(0.5, rel=1e-3)


def test_propeller_defaults_thrust_and_torque_constants_1_0_along_x() -> None:
    # D:320-322: shaftAxis 1 0 0, thrustConstants 1 0, torqueConstants 1 0, RotationalMotor maxTorque 10 (spin-up
    # at 10 rad/s²: w = 1 rad/s after 0.1 s). T = 1·1² = 1 N along x on 1 kg; Q = 1 N·m applied as -Q about x on
    # a 1 m cube of 1 kg (I = 1/6): -6 rad/s². Measured over 0.2 s after 30 steps.
    v0, v1 = _spin(_drone("", motor="", body="size 1 1 1"), 1.0, 30, 50)
    assert (v1[0] - v0[0]) == pytest.approx(0.2, rel=1e-3)
    assert (v1[3] - v0[3]) == pytest.approx(-6 * 0.2, rel=1e-3)


def test_propeller_torque_is_clamped_to_max_torque_but_thrust_is_not() -> None:
    # D:333-334: T = t1·w|w|, Q = q1·w|w| clamped to ±maxTorque (T not clamped). w = 20 rad/s (spin-up at
    # 50 rad/s²: 0.4 s), t1 = q1 = 1: T = 400 N (> 50) on 100 kg -> 4 m/s²; Q = 400 -> 50 N·m on a 1 m cube of
    # 100 kg (I = 100/6) -> -3 rad/s². Measured over 0.2 s.
    v0, v1 = _spin(_drone("shaftAxis 0 0 1 thrustConstants 1 0 torqueConstants 1 0", motor="maxTorque 50 "
                          "maxVelocity 30", body="size 1 1 1", mass=100.0), 20.0, 110, 50)
    assert (v1[2] - v0[2]) == pytest.approx(0.8, rel=1e-3)
    assert (v1[5] - v0[5]) == pytest.approx(-0.6, rel=1e-3)


def test_propeller_negative_speed_gives_negative_thrust() -> None:
    # D:331-333: w signed in velocity mode; T = t1·w·|w| = -1 N for w = -100
    v0, v1 = _spin(_drone("shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0"), -100.0, 50, 125)
    assert (v1[2] - v0[2]) == pytest.approx(-0.5, rel=1e-3)


@pytest.mark.parametrize("mount", ["Solid {{ children [ {} ] }}", "Pose {{ children [ Solid {{ children [ {} ] }} ] }}"])
def test_a_propeller_in_a_solid_without_physics_pushes_the_body_that_carries_it(mount: str) -> None:
    # D:334-337: applied to "the body of the closest upper Solid (its merged body)"; "No Physics upstream =>
    # warning, no effect". Here the closest upper Solid has no Physics but the Robot above it has: no warning, and
    # the Robot's body is pushed (it had no effect, and no warning either). As in the shaftAxis tests: T = 1e-4·100²
    # = 1 N along z on the 1 kg Robot (the Solid without Physics adds no mass) for 0.5 s: 0.5 m/s.
    propeller = ('Propeller { shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0 '
                 'device RotationalMotor { name "prop" maxVelocity 200 maxTorque 1000 } }')
    sup = _sup("DEF DRONE Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } "
               f"children [ {mount.format(propeller)} ] }}")
    v0, v1 = _spin(sup, 100.0, 50, 125)
    assert (v1[2] - v0[2]) == pytest.approx(0.5, rel=1e-3)
    assert not [w for w in sup.simulation.build_warnings if "Propeller" in w]


def test_propeller_thrust_at_the_centre_of_thrust_also_turns_the_body() -> None:
    # D:335-336: F = T·a applied at the centre of thrust (0.1, 0, 0): torque r × F = (0, -0.1·T, 0) with T = 1 N;
    # a 0.1 m cube of 1 kg has I = 1/600: -60 rad/s² about y. Measured over 4 ms right after spin-up
    sup = _drone("shaftAxis 0 0 1 centerOfThrust 0.1 0 0 thrustConstants 1e-4 0 torqueConstants 0 0")
    v0, v1 = _spin(sup, 100.0, 50, 1)
    assert (v1[4] - v0[4]) == pytest.approx(-60 * 0.004, rel=2e-2)


# ------------------------------------------------------------------------------------------ §9 coupled motors


def _joint(name: str, multiplier: float = 1.0, extra: str = "", y: float = 0.0, sensor: bool = False) -> str:
    s = f'PositionSensor {{ name "{name} sensor" }}' if sensor else ""
    return f"""HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 {y} 0 }}
  device [ RotationalMotor {{ name "{name}" multiplier {multiplier} maxTorque 50 {extra} }} {s} ]
  endPoint Solid {{ translation 0.1 {y} 0 boundingObject Box {{ size 0.2 0.02 0.02 }} physics Physics {{ }} }} }}"""


def _robot(*joints: str) -> Supervisor:
    return _sup("Robot { supervisor TRUE children [ " + " ".join(joints) + " ] }")


def test_multiplier_zero_is_reset_to_one() -> None:
    # D:344: "multiplier (default 1; 0 -> reset to 1 with warning)"
    sup = _robot(_joint("m", 0.0))
    assert sup.getDevice("m").getMultiplier() == 1.0


def test_a_name_of_three_parts_is_not_coupled() -> None:
    # D:341: the name must split into exactly two parts on "::"
    sup = _robot(_joint("g::a::x", y=0.0), _joint("g::b", y=0.3))
    sup.getDevice("g::a::x").setPosition(0.4)
    assert sup.getDevice("g::b").getTargetPosition() == 0.0


def test_motors_of_another_robot_are_not_coupled() -> None:
    # D:342: "motors of the same Robot sharing the first part are coupled"
    sup = _sup("Robot { supervisor TRUE children [ " + _joint("g::a") + " ] }\n"
               'Robot { name "other" children [ ' + _joint("g::b") + " ] }")
    sup.getDevice("g::a").setPosition(0.4)
    other = sup.simulation.robots[1]
    assert other.devices["g::b"].target_position == 0.0


def test_the_commanded_motor_keeps_the_raw_value_and_siblings_their_multiplied_one() -> None:
    # D:350-352: libController caches: sibling target = value × sibling multiplier; "the commanded motor's
    # cache holds the raw, unmultiplied value". Webots moves the commanded joint to p·m = 0.6
    sup = _robot(_joint("g::a", 2.0, sensor=True), _joint("g::b", -1.0, y=0.3))
    a, b = sup.getDevice("g::a"), sup.getDevice("g::b")
    a.setPosition(0.3)
    assert a.getTargetPosition() == pytest.approx(0.3) and b.getTargetPosition() == pytest.approx(-0.3)
    a.setVelocity(2.0)
    assert a.getVelocity() == pytest.approx(2.0) and b.getVelocity() == pytest.approx(-2.0)
    sensor = sup.getDevice("g::a sensor")
    sensor.enable(TS)
    _steps(sup, 300)
    assert sensor.getValue() == pytest.approx(0.6, abs=1e-3)


def test_a_lone_motor_with_a_multiplier_keeps_the_raw_target_too() -> None:
    # D:344-345 and D:352: target p·m goes to Webots; the cache holds p
    sup = _robot(_joint("m", 2.0, sensor=True))
    motor = sup.getDevice("m")
    motor.setPosition(0.25)
    assert motor.getTargetPosition() == pytest.approx(0.25)
    sensor = sup.getDevice("m sensor")
    sensor.enable(TS)
    _steps(sup, 300)
    assert sensor.getValue() == pytest.approx(0.5, abs=1e-3)


def test_acceleration_available_torque_and_pid_are_not_relayed() -> None:
    # D:349-350: "Not relayed: setAcceleration, setAvailableForce/Torque, setControlPID"
    sup = _robot(_joint("g::a"), _joint("g::b", y=0.3))
    a, b = sup.getDevice("g::a"), sup.getDevice("g::b")
    a.setAcceleration(3.0)
    a.setAvailableTorque(7.0)
    a.setControlPID(20.0, 0.0, 0.0)
    assert b.getAcceleration() == -1 and b.getAvailableTorque() == 50
    assert b._record.kp == 10.0


def test_sibling_velocity_is_clipped_to_its_own_max_velocity() -> None:
    # D:345-347: v·m clipped to ±maxVelocity per motor. Both maxVelocity 10 (harmonised: 10·|2|/|1| = 20 for b)
    sup = _robot(_joint("g::a", 1.0, "maxVelocity 10"), _joint("g::b", 2.0, "maxVelocity 20", y=0.3))
    a, b = sup.getDevice("g::a"), sup.getDevice("g::b")
    a.setPosition(math.inf)
    a.setVelocity(15.0)  # a: clipped to 10; b: 30 clipped to 20
    assert a._record.target_velocity == 10.0 and b._record.target_velocity == 20.0


def test_an_unlimited_first_motor_makes_the_whole_group_unlimited() -> None:
    # D:357-358: "if one motor is unlimited (0/0) all become 0/0". Webots' own regression test (coupled_motor,
    # groups D and E) shows it for the FIRST motor only: an unlimited later motor takes the first's limits
    # (test_joint_mechanisms pins that), so only the first-motor case is pinned here
    sup = _robot(_joint("g::a", 1.0), _joint("g::b", 2.0, "minPosition -1 maxPosition 1", y=0.3))
    a, b = sup.getDevice("g::a"), sup.getDevice("g::b")
    assert (a.getMinPosition(), a.getMaxPosition(), b.getMinPosition(), b.getMaxPosition()) == (0, 0, 0, 0)


def test_max_torque_is_not_harmonised() -> None:
    # D:359: "maxForce/maxTorque are not harmonised"
    sup = _robot(_joint("g::a", 1.0), _joint("g::b", 2.0, "maxTorque 7", y=0.3).replace("maxTorque 50 ", ""))
    assert sup.getDevice("g::a").getMaxTorque() == 50 and sup.getDevice("g::b").getMaxTorque() == 7


# ------------------------------------------------------------------------------------------ §10 SolidReference


def _loop_world(reference: str) -> Simulation:
    # a base (robot body) with three hinged arms: arm "p" carries a nested "x" at z = 0.5; arm "x" is a sibling
    # at y = 1; the third joint's endPoint refers to "x"
    def arm(name: str, y: float, children: str = "") -> str:
        return (f'HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 {y} 0 }} endPoint Solid {{ '
                f'name "{name}" translation 0 {y} 0.2 boundingObject Box {{ size 0.05 0.05 0.05 }} '
                f'physics Physics {{ }} children [ {children} ] }} }}')
    nested = arm("x", 0.0).replace("translation 0 0.0 0.2", "translation 0 0 0.3")
    text = (
        "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 gravity 0 }\n"
        'Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } children [ '
        + arm("p", 0.0, nested) + arm("x", 1.0) + arm("q", 2.0,
            f"HingeJoint {{ jointParameters HingeJointParameters {{ position 0.7 }} "
            f'endPoint SolidReference {{ solidName "{reference}" }} }}')
        + " ] }"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world_text(text))


def _referenced(sim: Simulation) -> str:
    (joint,) = [j for j in sim.joints if j.reference is not None]
    (solid,) = [s for s in sim.solids if s.body is not None and s.body is joint.child_body]
    return f"{solid.name} z={solid.node.fields['translation'][2]:g}"


def test_solid_reference_lookup_is_depth_first_first_match_wins() -> None:
    # D:368-369: depth-first from the topmost Solid ancestor; the "x" nested in the first arm comes first
    assert _referenced(_loop_world("x")) == "x z=0.3"


def test_solid_reference_skips_the_joints_own_upper_solid() -> None:
    # D:369: the joint sits in arm "q"; referring to "q" must find no other Solid -> no loop, q is skipped
    sim = _loop_world("q")
    assert [j for j in sim.joints if j.reference is not None and j.child_body is not None] == []


def test_solid_reference_joint_position_does_not_move_the_referenced_solid() -> None:
    # D:374: "The joint position (0.7 here) never moves the referenced Solid": the nested "x" stays at its
    # world place, arm p's (0, 0, 0.2) plus its own (0, 0, 0.3)
    sim = _loop_world("x")
    (solid,) = [s for s in sim.solids if s.name == "x" and s.node.fields["translation"][2] == 0.3]
    assert sim.solid_world_pose(solid).t == pytest.approx((0.0, 0.0, 0.5), abs=1e-12)
