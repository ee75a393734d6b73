"""The MuJoCo twin's Webots motor stays within ODE's bounded motor row (webots-on-ode §5: ``dParamVel = u``,
``dParamFMax`` = the available torque, solved with the other constraints): the torque it applies over a physics
step never exceeds the available torque, and the joint never passes ``u`` because of the motor. Both laws (the
Python reference and the native plugin), one physics step per control period so every step is seen.

The applied torque is measured from the motion, not read from the law: for one hinge, ``I (qdot' - qdot) / dt =
tau + G``, with ``I`` the joint's own inertia (the model without the servo) and ``G`` what else MuJoCo applied in
the step (``qfrc_passive - qfrc_bias + qfrc_applied + qfrc_constraint``, still in mjData after it)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.twins import motor_plugin
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

LAWS = [False, True] if motor_plugin.available() is None else [False]
DT = 0.002

# A 1.5 kg rod, 0.5 m long, on a hinge about y at one end, horizontal at q = 0: gravity pulls its end down with
# m g l/2 = 1.5 * 9.81 * 0.25 = 3.68 N m there, more than the motor's 2.8 N m (webots_motor data: maxVelocity 2,
# Kp 10, Ki 0, Kd 0, no acceleration limit).
PENDULUM = f"""<mujoco><option timestep="{DT}"/><worldbody><body name="rod">
  <joint name="hinge" axis="0 1 0"/><geom type="capsule" size="0.02" fromto="0 0 0 0.5 0 0" mass="1.5"/></body>
  </worldbody><actuator><general name="motor" joint="hinge" forcelimited="true" forcerange="-2.8 2.8"/></actuator>
  <custom><numeric name="webots_motor.motor" data="2 10 0 0 -1"/></custom></mujoco>"""


def _applied_torques(text: str, native: bool, periods: int, command: tuple[str, float],
                     load: tuple[int, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(torque the motor applied over each step, joint velocity after it): ``command`` from the start, and with
    ``load`` (period, torque) until that period an external torque on the joint (qfrc_applied) and the model's
    equality constraint (a coupled body), if it has one."""
    inertia = float(mujoco.MjModel.from_xml_string(text).dof_M0[0])  # the joint's own inertia, no servo
    twin = MuJoCoTwin(mujoco.MjSpec.from_string(text), DT, native_law=native)
    assert twin.native_law is native and twin._substeps == 1
    d = twin.data
    twin.reset(0)
    mode, value = command
    twin.command("motor", mode, value)  # type: ignore[arg-type]
    torques, speeds = [], []
    for k in range(periods):
        d.qfrc_applied[0] = load[1] if load is not None and k < load[0] else 0.0
        if load is not None and twin.model.neq:
            d.eq_active[0] = k < load[0]
        before = float(d.qvel[0])
        twin.step()
        smooth = float(d.qfrc_passive[0] - d.qfrc_bias[0] + d.qfrc_applied[0] + d.qfrc_constraint[0])
        torques.append(inertia * (float(d.qvel[0]) - before) / DT - smooth)
        speeds.append(float(d.qvel[0]))
    twin.close()
    return np.array(torques), np.array(speeds)


@pytest.mark.parametrize("native", LAWS, ids=lambda n: "native" if n else "python")
def test_a_pendulum_the_motor_cannot_hold_gets_at_most_the_max_torque(native: bool) -> None:
    """Held horizontal (setPosition(0)) it needs 3.68 N m: it sags and swings at the 2.8 N m limit, which ODE's
    row never exceeds; before, the servo steps at the edge of saturation applied up to ~4 % more."""
    torques, _ = _applied_torques(PENDULUM, native, 1500, ("position", 0.0))
    assert np.abs(torques).max() > 2.7  # it works at the limit (control: the test sees the bound)
    # Rounding only: the torque is a difference of velocities divided by dt (~1e-13 N m here).
    assert np.abs(torques).max() <= 2.8 + 1e-9


# A wheel (a 0.2 kg disc of radius 0.05 m on a vertical axis: I = m r^2 / 2 = 2.5e-4 kg m^2, gravity does not
# turn it) with a 2 N m motor (maxVelocity 10). At dt = 2 ms the full torque alone changes its speed by
# dt A / I = 16 rad/s in one step, more than the 5 rad/s command.
WHEEL = f"""<mujoco><option timestep="{DT}"/><worldbody><body name="wheel">
  <joint name="axle" axis="0 0 1"/><geom type="cylinder" size="0.05 0.01" mass="0.2"/></body></worldbody>
  <actuator><general name="motor" joint="axle" forcelimited="true" forcerange="-2 2"/></actuator>
  <custom><numeric name="webots_motor.motor" data="10 10 0 0 -1"/></custom></mujoco>"""


@pytest.mark.parametrize("native", LAWS, ids=lambda n: "native" if n else "python")
def test_a_wheel_whose_load_vanishes_does_not_overshoot_its_command(native: bool) -> None:
    """setVelocity(5) against a 3 N m load (more than the motor's 2 N m: the wheel turns backwards at the limit),
    which then vanishes. ODE's row then needs I (5 - qdot) / dt, within 2 N m once the wheel is near 5 rad/s,
    and stops the wheel at 5: it never runs faster than its command (nor than maxVelocity, 10). Before, the
    saturated motor applied its full 2 N m over the step the load vanished: 16 rad/s in one step."""
    torques, speeds = _applied_torques(WHEEL, native, 200, ("velocity", 5.0), load=(50, -3.0))
    assert speeds[49] < 0.0  # the load won while it was there (control: the motor was saturated)
    assert speeds.max() <= 5.0 + 1e-9
    assert np.abs(torques).max() <= 2.0 + 1e-9
    assert speeds[-1] == pytest.approx(5.0, abs=0.05)  # and it does reach the command (the servo's 1 % lag)


# The wheel coupled (a joint equality) to a flywheel 100 times its inertia (2 kg, radius 0.5 m: 0.25 kg m^2
# against 2.5e-4): the motor's 2 N m spins both up at 2 / 0.25 = 8 rad/s^2, saturated, until the coupling is
# switched off. That load was a constraint force: not a smooth force the law could read before the step.
COUPLED = WHEEL.replace("</body></worldbody>", """</body><body name="flywheel" pos="1 0 0">
  <joint name="flyaxle" axis="0 0 1"/><geom type="cylinder" size="0.5 0.01" mass="2" contype="0" conaffinity="0"/>
  </body></worldbody><equality><joint joint1="axle" joint2="flyaxle"/></equality>""")


@pytest.mark.parametrize("native", LAWS, ids=lambda n: "native" if n else "python")
def test_a_wheel_whose_coupled_body_lets_go_does_not_overshoot_its_command(native: bool) -> None:
    """After 100 periods (0.2 s: ~1.6 rad/s) the coupling goes: ODE's row then needs I (5 - qdot) / dt, about
    2.5e-4 x 3.4 / 0.002 = 0.43 N m, and stops the wheel at 5 rad/s. Before, the full 2 N m over that step took
    it to ~1.6 + 0.002 x 2 / 2.5e-4 = 17.6 rad/s, above maxVelocity (10)."""
    torques, speeds = _applied_torques(COUPLED, native, 200, ("velocity", 5.0), load=(100, 0.0))
    assert speeds[99] == pytest.approx(8.0 * 0.2, rel=0.05)  # 2 N m on both: 8 rad/s^2 for 0.2 s
    assert speeds.max() <= 5.0 + 1e-9
    assert np.abs(torques[100]) == pytest.approx(2.5e-4 * (5.0 - speeds[99]) / 0.002, rel=0.01)  # ODE's 0.43
    # The first step's servo did not know the flywheel yet (a constraint's load shows only after a step, see
    # twins.motors.servo_steps): from then on the motor applies at most its 2 N m, up to rounding.
    assert np.abs(torques[1:]).max() <= 2.0 + 1e-9


def _wheel(name: str, y: float) -> str:
    """A 0.02 kg wheel (radius 0.05 m: I = 2.5e-5 kg m^2) with a 0.1 N m motor and its position sensor."""
    return (f'DEF {name.upper()} HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 {y} 0 }} '
            f'device [ RotationalMotor {{ name "{name}" maxVelocity 10 maxTorque 0.1 }} '
            f'PositionSensor {{ name "{name} sensor" }} ] endPoint Solid {{ translation 0 {y} 0 rotation 1 0 0 1.5708 '
            f'children [ Shape {{ geometry DEF W{name} Cylinder {{ height 0.02 radius 0.05 }} }} ] '
            f'boundingObject USE W{name} physics Physics {{ density -1 mass 0.02 }} }} }}')


# A 1 kg two-wheel robot with a caster ball, dropped from 0.15 m with its wheels commanded at 5 rad/s: the
# wheels spin up in the air, the landing loads them beyond the 0.1 N m, and the bounces unload them again.
TWO_WHEELS = world_text(
    'DEF FLOOR Solid { children [ Shape { geometry DEF G Plane { size 10 10 } } ] boundingObject USE G }\n'
    'DEF R Robot { translation 0 0 0.15 controller "<extern>" children [\n'
    + _wheel("left", 0.08) + "\n" + _wheel("right", -0.08) + "\n"
    'Solid { translation -0.1 0 -0.025 children [ Shape { geometry DEF C Sphere { radius 0.025 } } ] '
    'boundingObject USE C physics Physics { density -1 mass 0.05 } }\n'
    '] boundingObject Box { size 0.2 0.1 0.02 } physics Physics { density -1 mass 1 } }',
    "basicTimeStep 2")


def test_a_landing_two_wheel_robot_never_spins_its_wheels_past_the_command_in_either_twin(tmp_path: Path) -> None:
    """The dual-twin fuzz's finding: each time a landing or bounce unloaded a saturated wheel, the MuJoCo twin's
    full explicit torque threw it past its command (12.7 rad/s on 5 here, above maxVelocity) while ODE's row
    (the Webots twin) stops it at 5. Every physics step is a control period here (2 ms), so none is missed.
    Tolerances: 2 % of the command for the wheel speed (the stiff servo reaches u within 1 % per step,
    SERVO_STIFFNESS 100, and a contact separating within a saturated step may still carry a wheel past u by
    what it held, see twins.motors.servo_steps; 5.03 rad/s measured); 5 % for the distance travelled in 2 s
    (the twins' contacts differ: the bundled Pioneer's scenarios differ by up to ~2 % before alignment, and
    the landing's bounces add to it; +3.7 % measured)."""
    travelled = []
    with converted_twins(TWO_WHEELS, tmp_path, DT) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.reset(0)
            start = twin.body_position("R")
            twin.command("left", "velocity", 5.0)
            twin.command("right", "velocity", 5.0)
            fastest = 0.0
            for _ in range(1000):  # 2 s: the fall, the landing, the bounces, then rolling
                twin.step()
                fastest = max(fastest, abs(twin.joint_velocity("LEFT")), abs(twin.joint_velocity("RIGHT")))
            assert 4.9 < fastest <= 5.0 * 1.02, type(twin).__name__
            travelled.append(float(twin.body_position("R")[0] - start[0]))
    assert travelled[0] > 0.3  # it rolled (control)
    assert travelled[1] == pytest.approx(travelled[0], rel=0.05)



# A 0.584 kg carriage on a vertical slider with stops at ±0.1 m, and a LinearMotor (maxForce 2.864 N, maxVelocity
# 0.2 m/s) told to hold it 6.85 mm above its start. Its weight, 0.584 x 9.81 = 5.73 N, is twice the motor's force:
# it sinks at (5.73 - 2.864) / 0.584 = 4.9 m/s^2 (the motor saturated, its u the 0.2 m/s up), reaches the lower stop
# after sqrt(2 x 0.1 / 4.9) = 0.2 s at about 1 m/s, and stays there: ODE solves the stop row with the motor row
# (webots-on-ode §4.3, §5.3), the motor pushes up with its 2.864 N and the stop holds the other 2.86 N; nothing
# lifts the carriage off it. basicTimeStep 1 ms, one physics step per control period.
ON_STOP = world_text(
    'DEF R Robot { translation 0 0 1 controller "<extern>" children [ DEF J SliderJoint { jointParameters '
    'JointParameters { axis 0 0 1 minStop -0.1 maxStop 0.1 } device [ LinearMotor { name "m" maxVelocity 0.2 '
    'maxForce 2.86394 } PositionSensor { name "s" } ] endPoint DEF E Solid { children [ Shape { geometry DEF B '
    'Box { size 0.1 0.1 0.1 } } ] boundingObject USE B physics Physics { density -1 mass 0.583882 } } } ] }',
    "basicTimeStep 1")


@pytest.mark.parametrize("native", LAWS, ids=lambda n: "native" if n else "python")
def test_a_joint_a_load_drives_onto_its_stop_rests_there_like_in_the_webots_twin(tmp_path: Path, native: bool) -> None:
    """The impact on the stop is, for one step, a large reaction in the direction the saturated motor pushes.
    Counted as a load doing the motor's work, it took the motor out of saturation: the stiff servo then lifted
    the carriage with far more than its 2.864 N, it fell back, and it kept hopping up to 4 mm off the stop,
    where the Webots twin rests on it. Tolerance: 0.05 mm (the stops' softness: both twins rest 0.14 µm in)."""
    heights = []
    with converted_twins(ON_STOP, tmp_path, 0.001) as (_, webots, _):
        mujoco_twin = MuJoCoTwin(tmp_path / "model.xml", 0.001, native_law=native)
        for twin in (webots, mujoco_twin):
            twin.reset(0)
            twin.command("m", "position", 0.00685)
            heights.append([])
            for _ in range(1200):  # 1.2 s: sinking (0.2 s), the impact, then on the stop
                twin.step()
                heights[-1].append(twin.joint_position("J"))
        mujoco_twin.close()
    for name, z in zip(("webots", "mujoco"), np.array(heights), strict=True):
        landed = int(np.argmax(z < -0.099))
        assert landed * 0.001 == pytest.approx(0.2, abs=0.01), name  # it sank as computed (control)
        assert np.abs(z[-500:] + 0.1).max() < 5e-5, name  # the last 0.5 s: on the stop


# A 0.4 kg disc (radius 0.026 m: I = 0.4 x 0.026^2 / 2 = 1.35e-4 kg m^2) on a hinge along its axis, vertical (gravity
# does not turn it), with dampingConstant 2 N m s/rad and a 0.3 N m motor told to go to 1.5 rad: its PID asks for
# maxVelocity (Kp 10 x 1.5 = 15, clamped to 2 rad/s) while the disc is far from 1.5 rad, and the motor saturates.
# The disc speeds up until the damping takes all of the motor's torque: b v = 0.3 N m at v = 0.3 / 2 = 0.15 rad/s
# (webots-on-ode §4.5, §5.3), within a few I / b = 7e-5 s (far less than a step: the damping is stiff); at
# 0.15 rad/s it takes 10 s to get near 1.5 rad. basicTimeStep 2 ms.
DAMPED = world_text(
    'DEF R Robot { controller "<extern>" children [ DEF H HingeJoint { jointParameters HingeJointParameters { '
    'axis 0 0 1 dampingConstant 2 } device [ RotationalMotor { name "m" maxVelocity 2 maxTorque 0.3 } '
    'PositionSensor { name "s" } ] endPoint DEF E Solid { children [ Shape { geometry DEF D Cylinder { '
    'radius 0.026 height 0.05 } } ] boundingObject USE D physics Physics { density -1 mass 0.4 } } } ] }',
    "basicTimeStep 2 gravity 0")


@pytest.mark.parametrize("native", LAWS, ids=lambda n: "native" if n else "python")
def test_a_damped_joint_its_motor_cannot_speed_up_turns_steadily_at_the_damping_limit(tmp_path: Path,
                                                                                          native: bool) -> None:
    """MuJoCo integrates the joint's damping at the step's end velocity (implicitfast) while the smooth force the
    law reads has it at the start velocity. The law took that difference for a load that helps the motor: it left
    saturation, its stiff servo drove the joint far past 0.15 rad/s with more than 0.3 N m, the damping then braked
    it, and the motor chattered between the two every step (1.53 and 0.19 rad/s here) where the Webots twin
    turns steadily at 0.15 rad/s. Tolerance: 2 % of 0.15 rad/s, far below the chatter (both twins measured
    within 1e-15 of it)."""
    speeds = []
    with converted_twins(DAMPED, tmp_path, 0.002) as (_, webots, _):
        mujoco_twin = MuJoCoTwin(tmp_path / "model.xml", 0.002, native_law=native)
        for twin in (webots, mujoco_twin):
            twin.reset(0)
            twin.command("m", "position", 1.5)
            speeds.append([])
            for _ in range(500):  # 1 s
                twin.step()
                speeds[-1].append(twin.joint_velocity("H"))
        mujoco_twin.close()
    for name, v in zip(("webots", "mujoco"), np.array(speeds), strict=True):
        assert np.abs(v[-400:] - 0.15).max() < 0.003, name  # the last 0.8 s, every step


# A four-link arm (the dual-twin fuzz's world 43): its first hinge has staticFriction 0.5 (a MuJoCo friction-loss
# row on the joint every step) and a 5.28 N m motor; the smooth force on it, 6.24 N m of gravity, exceeds that, but
# the chain below it (its other motors holding or moving their links) carries part of the load, and the motor holds
# the joint nearly still in the Webots twin (|velocity| under 1e-4 rad/s; the MuJoCo twin's first step 8e-3).
FRICTION_ARM = world_text(
    'DEF R Robot { translation 0 0 1 controller "<extern>" children [ DEF J0 HingeJoint { jointParameters '
    'HingeJointParameters { axis -0.143243 -0.426571 -1.11469 anchor 0 0 0 minStop -1.31239 maxStop 0.95969 '
    'staticFriction 0.5 } device [ RotationalMotor { name "m0" maxVelocity 2 maxTorque 5.27834 acceleration 0.5'
    ' } PositionSensor { name "s0" } ] endPoint DEF E0 Solid { name "e0" children [ Pose { translation 0.077276'
    ' 0 0 rotation 0 1 0 1.5708 children [ Shape { geometry Capsule { radius 0.0357377 height 0.154552 } } ] } '
    'Pose { translation 0.154552 0 0 children [ DEF J1 HingeJoint { jointParameters HingeJointParameters { axis'
    ' -0.797183 -1.35993 1.40555 anchor 0 0 0  } device [ RotationalMotor { name "m1" maxVelocity 5 maxTorque '
    '31.801 acceleration 20 controlPID 5 1 0 } PositionSensor { name "s1" } ] endPoint DEF E1 Solid { name "e1"'
    ' children [ Pose { translation 0.0595297 0 0 rotation 0 1 0 1.5708 children [ Shape { geometry Capsule { '
    'radius 0.021407 height 0.119059 } } ] } Pose { translation 0.119059 0 0 children [ DEF J2 HingeJoint { '
    'jointParameters HingeJointParameters { axis 0 1 0 anchor 0 0 0 minStop -1.45652 maxStop 0.98242 '
    'springConstant 1 } device [ RotationalMotor { name "m2" maxVelocity 1 maxTorque 9.20768 acceleration 5 } '
    'PositionSensor { name "s2" } ] endPoint DEF E2 Solid { name "e2" children [ Pose { translation 0.13689 0 0'
    ' rotation 0 1 0 1.5708 children [ Shape { geometry Capsule { radius 0.0346224 height 0.27378 } } ] } Pose '
    '{ translation 0.27378 0 0 children [ DEF J3 HingeJoint { jointParameters HingeJointParameters { axis 1 0 0'
    ' anchor 0 0 0 minStop -0.203275 maxStop 1.37459 dampingConstant 2 staticFriction 0.5 } device [ '
    'RotationalMotor { name "m3" maxVelocity 5 maxTorque 0.947344 acceleration 100 controlPID 30 0 0 } '
    'PositionSensor { name "s3" } ] endPoint DEF E3 Solid { name "e3" children [ Pose { translation 0.0779929 0'
    ' 0 rotation 0 1 0 1.5708 children [ Shape { geometry Capsule { radius 0.0223708 height 0.155986 } } ] }  ]'
    ' boundingObject Pose { translation 0.0779929 0 0 rotation 0 1 0 1.5708 children [ Capsule { radius '
    '0.0223708 height 0.155986 } ] } physics Physics { density -1 mass 0.825453 } } } ] } ] boundingObject Pose'
    ' { translation 0.13689 0 0 rotation 0 1 0 1.5708 children [ Capsule { radius 0.0346224 height 0.27378 } ] '
    '} physics Physics { density -1 mass 2.44986 } } } ] } ] boundingObject Pose { translation 0.0595297 0 0 '
    'rotation 0 1 0 1.5708 children [ Capsule { radius 0.021407 height 0.119059 } ] } physics Physics { density'
    ' -1 mass 1.08976 } } } ] } ] boundingObject Pose { translation 0.077276 0 0 rotation 0 1 0 1.5708 children'
    ' [ Capsule { radius 0.0357377 height 0.154552 } ] } physics Physics { density -1 mass 0.49602 } } } ] }',
    "basicTimeStep 2")


@pytest.mark.parametrize("native", LAWS, ids=lambda n: "native" if n else "python")
def test_a_held_joint_with_static_friction_does_not_chatter_in_a_chain(tmp_path: Path, native: bool) -> None:
    """Dropping every residual that pushed the joint the motor's way whenever a constraint row acted on it (the
    friction loss does, every step) also dropped the links' real help: the motor left saturation and re-entered it
    every step, the joint's velocity alternating 0.008 and 0 rad/s. Only the constraint force itself (qfrc_constraint)
    is a reaction. Tolerance: no step-to-step reversal of the joint velocity change above 1e-3 rad/s
    (the chatter's 8e-3; the Webots twin has none)."""
    with converted_twins(FRICTION_ARM, tmp_path, 0.002) as (_, webots, _):
        mujoco_twin = MuJoCoTwin(tmp_path / "model.xml", 0.002, native_law=native)
        for twin in (webots, mujoco_twin):
            twin.reset(0)
            for motor, target in (("m1", 2.6194296630756844), ("m2", 2.4747225702017106), ("m3", 1.9642035300025258)):
                twin.command(motor, "position", target)
            speeds = []
            for _ in range(100):  # 0.2 s
                twin.step()
                speeds.append(twin.joint_velocity("J0"))
            change = np.diff(speeds)
            reversals = (change[1:] * change[:-1] < 0) & (np.abs(change[1:]) > 1e-3)
            assert not reversals.any(), type(twin).__name__
        mujoco_twin.close()
