"""Joint and motor mechanisms as Webots builds them: Slot pairs as joint endPoints, device order, coupled-motor
limits at load. Own small worlds; expected values from Webots' documented rules, each with a control."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation


def _sup(body: str, step: int = 8, info: str = "") -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {step} {info} }}\n{body}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _pendulum(end_wrap: str) -> str:
    solid = """Solid { translation 0.5 0 0 boundingObject Sphere { radius 0.05 }
                      physics Physics { density -1 mass 1 } }"""
    end = end_wrap.replace("@", solid)
    return f"""Robot {{ supervisor TRUE children [ HingeJoint {{
  jointParameters HingeJointParameters {{ axis 0 1 0 }}
  device [ PositionSensor {{ name "s" }} ]
  endPoint {end} }} ] }}"""


def _swing(sup: Supervisor, steps: int = 25) -> float:
    s = sup.getDevice("s")
    s.enable(8)
    for _ in range(steps):
        sup.step(8)
    return s.getValue()


def test_a_slot_pair_as_endpoint_is_a_pass_through() -> None:
    slotted = _swing(_sup(_pendulum("Slot { type \"a\" endPoint Slot { type \"a\" endPoint @ } }")))
    plain = _swing(_sup(_pendulum("@")))  # control: the same arm without Slots
    assert plain > 0.1  # gravity swings the arm down about +y (positive angle)
    assert slotted == plain


def test_devices_are_numbered_in_scene_tree_order() -> None:
    sup = _sup("""Robot { supervisor TRUE children [
  HingeJoint { device [ PositionSensor { name "s1" } RotationalMotor { name "m1" } ]
               endPoint Solid { physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } }
  DistanceSensor { name "ds" }
  HingeJoint { jointParameters HingeJointParameters { anchor 0 1 0 }
               device [ RotationalMotor { name "m2" } PositionSensor { name "s2" } ]
               endPoint Solid { translation 0 1 0 name "b" children [ GPS { name "gps" } ]
                                physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } }
] }""")
    names = [sup.getDeviceByIndex(i).getName() for i in range(sup.getNumberOfDevices())]
    assert names == ["s1", "m1", "ds", "m2", "s2", "gps"]


def _motor(name: str, multiplier: float, extra: str = "", y: float = 0.0) -> str:
    return f"""HingeJoint {{ jointParameters HingeJointParameters {{ anchor 0 {y} 0 }}
  device [ RotationalMotor {{ name "{name}" multiplier {multiplier} {extra} }} ]
  endPoint Solid {{ translation 0 {y} 0 name "{name}" physics Physics {{ }} boundingObject Box {{ size 0.1 0.1 0.1 }} }} }}"""


def test_coupled_motor_limits_are_harmonised_to_the_first_motor_at_load() -> None:
    limits = "maxVelocity 8 minPosition -2 maxPosition 4"
    sup = _sup(
        "Robot { supervisor TRUE children [ "
        + _motor("arm::a", 2.0, limits)
        + _motor("arm::b", -1.0, "maxVelocity 3 minPosition -9 maxPosition 9", 1)
        + _motor("arm::c", 4.0, "", 2)
        + _motor("lone", 4.0, limits, 3)
        + " ] }",
        info="gravity 0",
    )
    a, b, c, lone = (sup.getDevice(n) for n in ("arm::a", "arm::b", "arm::c", "lone"))
    assert (a.getMinPosition(), a.getMaxPosition(), a.getMaxVelocity()) == (-2, 4, 8)  # the first is the reference
    # ratio -0.5: limits scaled and swapped, |ratio| on the velocity
    assert (b.getMinPosition(), b.getMaxPosition(), b.getMaxVelocity()) == (-2, 1, 4)
    assert (c.getMinPosition(), c.getMaxPosition(), c.getMaxVelocity()) == (-4, 8, 16)  # ratio 2
    assert b.getVelocity() == pytest.approx(4)  # the initial target velocity is the (new) maxVelocity
    # control: a motor outside any group keeps its own limits
    assert (lone.getMinPosition(), lone.getMaxPosition(), lone.getMaxVelocity()) == (-2, 4, 8)


HINGE2_WHEEL = """Robot { supervisor TRUE children [ Solid { children [ Solid {
  physics Physics { density -1 mass 50 } boundingObject Box { size 0.1 0.1 0.1 }
  children [ Hinge2Joint {
    jointParameters HingeJointParameters { axis 1 0 0 }
    jointParameters2 DEF P2 JointParameters { axis 0 0 1 }
    endPoint DEF WHEEL Solid { angularVelocity 0 0 10 boundingObject Sphere { radius 0.1 }
                               physics Physics { density -1 mass 1 } }
  } ] } ] } ] }"""


def test_hinge2_second_axis_damping_edited_at_run_time_reaches_ode() -> None:
    sup = _sup(HINGE2_WHEEL, info="gravity 0")
    wheel = sup.getFromDef("WHEEL")
    for _ in range(10):
        sup.step(8)
    assert wheel.getVelocity()[5] == pytest.approx(10.0, rel=1e-3)  # control: no damping yet, the spin is kept
    sup.getFromDef("P2").getField("dampingConstant").setSFFloat(0.04)
    sup.step(8)  # the edit is applied before this step's physics
    w0 = wheel.getVelocity()[5]
    for _ in range(10):
        sup.step(8)
    # implicit damper row: ω ← ω / (1 + h·B/I) per step, I = 2/5·m·r² = 0.004 kg·m², h = 0.008 s, B = 0.04
    assert wheel.getVelocity()[5] / w0 == pytest.approx(1.08**-10, rel=5e-3)


def _passive_arm_first_touch(rotation: float, damping: float) -> float | None:
    """A damped passive arm (reverse hinge on a static robot) falling onto the robot's own bumper."""
    world = f"""#VRML_SIM R2023b utf8
WorldInfo {{ }}
Robot {{ rotation 0 0 1 {rotation} selfCollision TRUE boundingObject Box {{ size 0.2 0.2 1 }} children [
  TouchSensor {{ name "touch" translation 0 -0.106 -0.45 boundingObject Box {{ size 0.1 0.01 0.1 }} physics Physics {{ }} }}
  HingeJoint {{ jointParameters HingeJointParameters {{ axis -1 0 0 anchor 0 -0.1 0.5 dampingConstant {damping} }}
    endPoint Solid {{ translation 0 -0.6 0.55 boundingObject Box {{ size 0.2 1 0.1 }}
                     physics Physics {{ density -1 mass 1 }} }} }} ] }}"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(world))
    robot = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    touch = robot.getDevice("touch")
    touch.enable(32)
    while robot.getTime() < 2.0:
        robot.step(32)
        if touch.getValue() == 1:
            return round(robot.getTime(), 3)
    return None


@pytest.mark.parametrize("rotation", [0.7, 1.5708, 3.14159])
def test_a_rotated_robot_touches_at_the_same_step(rotation: float) -> None:
    # Turning the whole robot about the vertical changes nothing physical. The bumper must see the pair as the
    # collision pass does (ODE's box-box collider can miss a deep overlap in one argument order only).
    assert _passive_arm_first_touch(rotation, 2.0) == _passive_arm_first_touch(0.0, 2.0) == 1.024
    assert _passive_arm_first_touch(rotation, 0.0) == 0.48  # control: without damping it falls faster


def test_a_physics_plugin_is_named_once_as_not_run() -> None:
    def build(info: str) -> list[str]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return Simulation(load_world_text(f"#VRML_SIM R2023b utf8\nWorldInfo {{ {info} }}\n")).build_warnings

    said = [w for w in build('physics "my_plugin"') if "physics plugin" in w]
    assert len(said) == 1 and "'my_plugin'" in said[0] and "not run" in said[0]
    assert not [w for w in build("") if "physics plugin" in w]  # control: the default '<none>' says nothing


def test_motor_limits_widen_to_a_joint_that_starts_outside_them() -> None:
    sup = _sup(
        """Robot { supervisor TRUE children [ HingeJoint {
  jointParameters HingeJointParameters { axis 0 0 1 position 1.0 }
  device [ RotationalMotor { name "m" minPosition -0.5 maxPosition 0.5 } PositionSensor { name "s" } ]
  endPoint Solid { rotation 0 0 1 1.0 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } } } ] }""",
        info="gravity 0",
    )
    motor, sensor = sup.getDevice("m"), sup.getDevice("s")
    assert (motor.getMinPosition(), motor.getMaxPosition()) == (-0.5, 1.0)
    sensor.enable(8)
    motor.setPosition(0.9)  # inside the widened range: not clamped to the file's 0.5
    for _ in range(100):
        sup.step(8)
    assert sensor.getValue() == pytest.approx(0.9, abs=1e-3)
    motor.setPosition(1.5)  # control: the widened limit still clamps
    assert motor.getTargetPosition() == 1.0


def _hinge2_sag(suspension: str) -> float:
    sup = _sup(
        f"""Robot {{ supervisor TRUE children [ Solid {{ children [ DEF BASE Solid {{
  physics Physics {{ density -1 mass 50 }} boundingObject Box {{ size 0.1 0.1 0.1 }}
  children [ Hinge2Joint {{
    jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 0 -0.3 {suspension} }}
    jointParameters2 JointParameters {{ axis 0 1 0 }}
    endPoint DEF WHEEL Solid {{ translation 0 0 -0.3 boundingObject Sphere {{ radius 0.1 }}
                               physics Physics {{ density -1 mass 1 }} }} }} ] }} ] }} ] }}""",
    )
    wheel, base = sup.getFromDef("WHEEL"), sup.getFromDef("BASE")
    for _ in range(400):
        sup.step(8)
    return base.getPosition()[2] - 0.3 - wheel.getPosition()[2]  # the wheel's drop relative to its parent


def test_hinge2_suspension_is_a_spring_along_the_first_axis() -> None:
    # K = 1000 N/m along the vertical first axis carries the 1 kg wheel: static sag m·g/K
    assert _hinge2_sag("suspensionSpringConstant 1000 suspensionDampingConstant 50") == pytest.approx(
        9.81 / 1000, rel=0.02
    )
    assert abs(_hinge2_sag("")) < 2e-4  # control: without suspension the anchor holds (world ERP/CFM)


def _fast_hinge2(motor: str) -> tuple[list[float], float]:
    """A Hinge2 wheel (fixed parent, no gravity) spinning one axis at 60 rad/s with basicTimeStep 32 ms: 1.92 rad
    of turn per step, more than π/2. Returns the axis' readings over 4 steps and its joint rate."""
    world = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 32 gravity 0 }
Robot { supervisor TRUE children [ Solid { children [ Solid {
  physics Physics { density -1 mass 50 } boundingObject Box { size 0.1 0.1 0.1 }
  children [ Hinge2Joint {
    jointParameters HingeJointParameters { axis 0 0 1 anchor 0 0 -0.3 }
    jointParameters2 JointParameters { axis 0 1 0 }
    device [ RotationalMotor { name "steer" maxVelocity 100 } PositionSensor { name "s1" } ]
    device2 [ RotationalMotor { name "drive" maxVelocity 100 } PositionSensor { name "s2" } ]
    endPoint Solid { translation 0 0 -0.3 boundingObject Sphere { radius 0.1 }
                     physics Physics { density -1 mass 1 } } } ] } ] } ] }"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(world))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    sensor = sup.getDevice("s1" if motor == "steer" else "s2")
    sensor.enable(32)
    m = sup.getDevice(motor)
    m.setPosition(float("inf"))
    m.setVelocity(60.0)
    out = []
    for _ in range(4):
        sup.step(32)
        out.append(sensor.getValue())
    joint = next(j for j in sim.joints if j.kind == "hinge2")
    return out, sim.joint_velocity(joint, 0 if motor == "steer" else 1)


@pytest.mark.parametrize("motor", ["drive", "steer"])
def test_hinge2_axes_read_a_fast_turn_forward(motor: str) -> None:
    # ODE turns a body by 2·atan(ω·h/2) per step (its infinitesimal quaternion update): 1.5348 rad at ω·h = 1.92.
    # Each position must advance by that much every step, and the joint rate read +60 rad/s. Axis 2's reading
    # used to be unwrapped about a prediction of the wrong sign (it went backwards by 2π − 1.53 per step) and
    # its rate had the wrong sign. The steering axis is the control.
    per_step = 2 * math.atan(60.0 * 0.032 / 2)
    readings, rate = _fast_hinge2(motor)
    assert readings == pytest.approx([per_step * k for k in (1, 2, 3, 4)], abs=1e-6)
    assert rate == pytest.approx(60.0, rel=1e-6)


def _hinge2_spring_swing(axis: int) -> list[float]:
    """A sphere (I = 2/5·m·r² = 0.004 kg·m² about any axis) on a Hinge2 whose ``axis`` (1 or 2) has a spring
    K = 1 N·m/rad, started at 0.05 rad/s about that axis: readings of that axis over 200 steps of 8 ms."""
    spring = ("springConstant 1", "") if axis == 1 else ("", "springConstant 1")
    spin = "0 0 0.05" if axis == 1 else "0 0.05 0"
    sup = _sup(
        f"""Robot {{ supervisor TRUE children [ Solid {{ children [ Solid {{
  physics Physics {{ density -1 mass 50 }} boundingObject Box {{ size 0.1 0.1 0.1 }}
  children [ Hinge2Joint {{
    jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 0 -0.3 {spring[0]} }}
    jointParameters2 JointParameters {{ axis 0 1 0 {spring[1]} }}
    device [ PositionSensor {{ name "s1" }} ]
    device2 [ PositionSensor {{ name "s2" }} ]
    endPoint Solid {{ translation 0 0 -0.3 angularVelocity {spin} boundingObject Sphere {{ radius 0.1 }}
                     physics Physics {{ density -1 mass 1 }} }} }} ] }} ] }} ] }}""",
        info="gravity 0",
    )
    sensor = sup.getDevice(f"s{axis}")
    sensor.enable(8)
    out = []
    for _ in range(200):
        sup.step(8)
        out.append(sensor.getValue())
    return out


def test_a_spring_on_the_second_hinge2_axis_pulls_back() -> None:
    # ω_n = √(K/I) = 15.8 rad/s: amplitude ω0/ω_n = 3.16 mrad (a little less: ODE's implicit spring row damps),
    # swinging back through zero every 25 steps. The second axis' spring row measured its angle with the wrong
    # sign and pushed away (the wheel spun off to radians). Control: the first axis' spring, the same swing.
    second, first = _hinge2_spring_swing(2), _hinge2_spring_swing(1)
    assert max(second) == pytest.approx(0.05 / math.sqrt(1 / 0.004), rel=0.12)
    assert min(second) < -0.002 and abs(second[-1]) < 1e-3
    assert second == pytest.approx(first, abs=1e-9)


def _hinge2_drive_against_stops(stops: str, velocity: float, position: float = 0.0) -> float:
    """A Hinge2 wheel (fixed parent, no gravity) steered to 0.4 rad while its second axis is driven at
    ``velocity`` for 0.8 s; the second axis' position at the end."""
    sup = _sup(
        f"""Robot {{ supervisor TRUE children [ Solid {{ children [ Solid {{
  physics Physics {{ density -1 mass 50 }} boundingObject Box {{ size 0.1 0.1 0.1 }}
  children [ Hinge2Joint {{
    jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 0 -0.3 }}
    jointParameters2 JointParameters {{ axis 0 1 0 position {position} {stops} }}
    device [ RotationalMotor {{ name "steer" }} ]
    device2 [ RotationalMotor {{ name "drive" }} PositionSensor {{ name "s2" }} ]
    endPoint Solid {{ translation 0 0 -0.3 rotation 0 1 0 {position} boundingObject Sphere {{ radius 0.1 }}
                     physics Physics {{ density -1 mass 1 }} }} }} ] }} ] }} ] }}""",
        info="gravity 0",
    )
    sensor = sup.getDevice("s2")
    sensor.enable(8)
    drive = sup.getDevice("drive")
    drive.setPosition(float("inf"))
    drive.setVelocity(velocity)
    sup.getDevice("steer").setPosition(0.4)
    for _ in range(100):
        sup.step(8)
    return sensor.getValue()


def test_the_second_hinge2_axis_stops_at_its_limits() -> None:
    # Webots limits both Hinge2 axes (§4.4); upstream ODE's hinge2 never limits the second, so the twin holds it
    # with a stop AMotor. Driven at ±2 rad/s for 0.8 s (1.6 rad of travel), the axis rests on maxStop 0.5 or
    # minStop −0.3, also when it starts at position 0.2, while the first axis steers. Control: without stops it
    # turns the full 1.6 rad (and the old twin ignored the stops).
    stops = "minStop -0.3 maxStop 0.5"
    assert _hinge2_drive_against_stops(stops, 2.0) == pytest.approx(0.5, abs=2e-3)
    assert _hinge2_drive_against_stops(stops, -2.0) == pytest.approx(-0.3, abs=2e-3)
    assert _hinge2_drive_against_stops(stops, 2.0, position=0.2) == pytest.approx(0.5, abs=2e-3)
    assert _hinge2_drive_against_stops("", 2.0) == pytest.approx(1.6, abs=2e-3)


def test_hinge2_motors_feed_back_the_torque_they_hold() -> None:
    # The wheel's centre of mass sits 0.2 m along x from the anchor; axis 2 is horizontal (+y), axis 1 vertical.
    # Gravity pulls with r × F = (0.2, 0, 0) × (0, 0, −9.81) = +1.962 N·m about +y, so the drive motor holding the
    # wheel still feeds back −1.962 N·m, the torque setTorque would need (the hinge's convention), and the
    # steering motor, whose axis gravity does not load, about 0. The old twin fed back nothing (NaN) for Hinge2.
    sup = _sup(
        """Robot { supervisor TRUE children [ Solid { children [ Solid {
  physics Physics { density -1 mass 50 } boundingObject Box { size 0.1 0.1 0.1 }
  children [ Hinge2Joint {
    jointParameters HingeJointParameters { axis 0 0 1 anchor 0 0 -0.3 }
    jointParameters2 JointParameters { axis 0 1 0 }
    device [ RotationalMotor { name "steer" } ]
    device2 [ RotationalMotor { name "drive" } PositionSensor { name "s2" } ]
    endPoint Solid { translation 0 0 -0.3 physics Physics { density -1 mass 1 }
                     boundingObject Pose { translation 0.2 0 0 children [ Sphere { radius 0.05 } ] } } } ] } ] } ] }"""
    )
    steer, drive = sup.getDevice("steer"), sup.getDevice("drive")
    for motor in (steer, drive):
        motor.enableTorqueFeedback(8)
    for _ in range(50):
        sup.step(8)
    assert drive.getTorqueFeedback() == pytest.approx(-0.2 * 9.81, rel=2e-3)
    assert abs(steer.getTorqueFeedback()) < 1e-3
    sensor = sup.getDevice("s2")
    sensor.enable(8)
    sup.step(8)
    held = sensor.getValue()
    drive.setTorque(-0.2 * 9.81)  # control: commanding the fed-back torque holds the wheel as well
    for _ in range(25):
        sup.step(8)
    assert drive.getTorqueFeedback() == pytest.approx(-0.2 * 9.81)
    assert sensor.getValue() == pytest.approx(held, abs=2e-3)
