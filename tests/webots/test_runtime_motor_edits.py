"""A supervisor's edit of a motor's ``controlPID``, ``minPosition``/``maxPosition`` or ``multiplier`` acts from the
next step, as Webots' WbMotor update slots make it, the motor's getters follow, and ``simulationReset`` puts the
load configuration back.

S = shared/reference/webots-on-ode.md, D = shared/reference/webots-devices.md. The position loop is S §5.3 step 2:
e = Pt − pos, I += e·ts, u = Kp·e + Ki·I (+ Kd·D), clipped to ±maxVelocity; the arm's 1 kg bob (no gravity) is
light enough for a 1000 N·m motor to reach u within one 4 ms step, so one step moves the joint by u·ts (a step
needs at most u/ts·I = 5/0.004·0.251 ≈ 314 N·m, hand computation), within the softness of the motor row (world
CFM, S §5.3 step 4: the steps below come within 0.1 % of u·ts, hence the tolerances). Expected values are hand computations from
these rules, never runs of this code; each test has its control (the same run without the edit)."""

from __future__ import annotations

from typing import Any

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, DT, TS, load_arm
from tests.support.quiet_worlds import quiet_supervisor


def _arm(motor: str = "", extra_joint: str = "", name: str = "m") -> tuple[Supervisor, Any, Any]:
    """The arm with a RotationalMotor ``name`` (strong, fast; ``motor`` adds fields) and a PositionSensor 's'."""
    joint = ("HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 } "
             f'device [ RotationalMotor {{ name "{name}" maxTorque 1000 maxVelocity 100 {motor} }} '
             f'PositionSensor {{ name "s" }} ] endPoint {BOB.format(t="0.5 0 0")} }}')
    _, sup = load_arm(joint + extra_joint)
    sensor = sup.getDevice("s")
    sensor.enable(TS)
    return sup, sup.getDevice(name), sensor


def _motor_node(sup: Supervisor, index: int = 0) -> Any:
    joint = sup.getSelf().getField("children").getMFNode(index)
    return joint.getField("device").getMFNode(0)


def _step(sup: Supervisor, n: int = 1) -> None:
    for _ in range(n):
        assert sup.step(TS) != -1


def _moved(sup: Supervisor, sensor: Any) -> tuple[float, float]:
    """(position before, its change over) one step."""
    before = sensor.getValue()
    _step(sup)
    return before, sensor.getValue() - before


@pytest.mark.parametrize("edit", [True, False])
def test_control_pid_edit_sets_the_gains_from_the_next_step(edit: bool) -> None:
    sup, motor, sensor = _arm()
    motor.setPosition(0.5)
    _step(sup)  # Kp 10 (default): u = 10·0.5 = 5 rad/s, the joint at 0.02
    if edit:
        _motor_node(sup).getField("controlPID").setSFVec3f([1.0, 0.0, 0.0])
    before, moved = _moved(sup, sensor)
    assert before == pytest.approx(5.0 * DT, rel=2e-3)
    kp = 1.0 if edit else 10.0  # control: the load gain
    # (the motor row brakes from 5 rad/s here: within 1 % of u·ts, a tenth of the factor 10 the test tells apart)
    assert moved == pytest.approx(kp * (0.5 - before) * DT, rel=1e-2)


@pytest.mark.parametrize("edit", [True, False])
def test_control_pid_edit_starts_the_error_integral_again(edit: bool) -> None:
    # Kp 1, Ki 100: over 3 steps the integral gathers Σe·ts; an edit to Ki 50 starts it from 0 (S §5.2: the gains
    # replaced, the integral and previous error reset), so the next step's u = e + 50·(e·ts); the control keeps
    # the integral, u = e + 100·(I + e·ts)
    sup, motor, sensor = _arm("controlPID 1 100 0")
    motor.setPosition(0.5)
    integral, position = 0.0, 0.0
    for _ in range(3):
        e = 0.5 - position
        integral += e * DT
        _step(sup)
        position = sensor.getValue()
    if edit:
        _motor_node(sup).getField("controlPID").setSFVec3f([1.0, 50.0, 0.0])
    before, moved = _moved(sup, sensor)
    assert before == pytest.approx(position)
    e = 0.5 - before
    u = e + 50.0 * (e * DT) if edit else e + 100.0 * (integral + e * DT)
    assert moved == pytest.approx(u * DT, rel=2e-3)


@pytest.mark.parametrize("edit", [True, False])
def test_max_position_edit_clips_the_target_and_the_getters_follow(edit: bool, capsys: Any) -> None:
    sup, motor, sensor = _arm("minPosition -1 maxPosition 1")
    motor.setPosition(0.8)
    _step(sup)
    if edit:
        _motor_node(sup).getField("maxPosition").setSFFloat(0.3)
    _step(sup, 400)
    # the target 0.8 left outside [−1, 0.3] is clipped to 0.3, where the joint settles; the control reaches 0.8
    assert sensor.getValue() == pytest.approx(0.3 if edit else 0.8, abs=1e-4)
    assert motor.getMaxPosition() == (0.3 if edit else 1.0)
    assert motor.getTargetPosition() == pytest.approx(0.3 if edit else 0.8)
    capsys.readouterr()
    motor.setPosition(0.9)  # S §5.2: setPosition clips into the limits of now, with a warning
    assert motor.getTargetPosition() == (0.3 if edit else 0.9)
    assert ("outside [minPosition, maxPosition]" in capsys.readouterr().err) == edit


def test_min_position_edit_clips_a_target_below_it() -> None:
    sup, motor, sensor = _arm("minPosition -1 maxPosition 1")
    motor.setPosition(-0.6)
    _step(sup)
    _motor_node(sup).getField("minPosition").setSFFloat(-0.2)
    _step(sup, 400)
    assert motor.getMinPosition() == -0.2
    assert sensor.getValue() == pytest.approx(-0.2, abs=1e-4)


def test_limits_set_at_run_time_on_an_unlimited_motor_clip_its_target() -> None:
    # min = max = 0 means no limits (S §5.1); writing maxPosition 0.4 makes [0, 0.4] the limits
    sup, motor, sensor = _arm()
    motor.setPosition(0.7)
    _step(sup)
    _motor_node(sup).getField("maxPosition").setSFFloat(0.4)
    _step(sup, 400)
    assert sensor.getValue() == pytest.approx(0.4, abs=1e-4)


def test_limits_do_not_touch_velocity_control() -> None:
    # a velocity-controlled motor (target +inf, S §5.2: ±inf kept, never clipped) keeps turning
    sup, motor, sensor = _arm("minPosition -1 maxPosition 1")
    motor.setPosition(float("inf"))
    motor.setVelocity(2.0)
    _step(sup)
    _motor_node(sup).getField("maxPosition").setSFFloat(0.5)
    _, moved = _moved(sup, sensor)
    assert moved == pytest.approx(2.0 * DT, rel=2e-3)
    assert motor.getTargetPosition() == float("inf")


@pytest.mark.parametrize("edit", [True, False])
def test_multiplier_edit_scales_the_next_commands(edit: bool) -> None:
    sup, motor, sensor = _arm()
    _step(sup)
    if edit:
        _motor_node(sup).getField("multiplier").setSFFloat(2.0)
    _step(sup)
    assert motor.getMultiplier() == (2.0 if edit else 1.0)
    motor.setPosition(0.2)  # D §9: target = 0.2·multiplier
    _step(sup, 400)
    assert sensor.getValue() == pytest.approx(0.4 if edit else 0.2, abs=1e-4)


def test_multiplier_edited_to_zero_warns_and_keeps_one() -> None:
    sup, motor, sensor = _arm("multiplier 3")
    _step(sup)
    # D §9: 0 → 1 with a warning, as at load; the motor takes the field at the step that executes the write (S §6)
    with pytest.warns(UserWarning, match="multiplier 0"):
        _motor_node(sup).getField("multiplier").setSFFloat(0.0)
        _step(sup)
    assert motor.getMultiplier() == 1.0


def test_reset_restores_the_load_gains_limits_and_multiplier() -> None:
    sup, motor, sensor = _arm("minPosition -1 maxPosition 1")
    _step(sup)
    node = _motor_node(sup)
    node.getField("controlPID").setSFVec3f([1.0, 0.0, 0.0])
    node.getField("maxPosition").setSFFloat(0.3)
    node.getField("multiplier").setSFFloat(2.0)
    _step(sup)
    sup.simulationReset()
    _step(sup)
    assert (motor.getMaxPosition(), motor.getMultiplier()) == (1.0, 1.0)
    # the load gain Kp 10 again: one step toward 0.5 from the load position 0 moves 10·0.5·ts
    motor.setPosition(0.5)
    before, moved = _moved(sup, sensor)
    assert before == pytest.approx(0.0, abs=1e-6)
    assert moved == pytest.approx(10.0 * 0.5 * DT, rel=2e-3)


def test_reset_restores_a_coupled_motors_harmonised_limits() -> None:
    # D §9: at load the sibling 'g::b' (multiplier 2) takes maxVelocity and limits from 'g::a' scaled by 2:
    # [−2, 2], maxVelocity 200, whatever its own fields say ([0, 0]); after an edit of its maxPosition, a reset
    # gives back those load values, not its fields
    second = ('HingeJoint { jointParameters HingeJointParameters { axis 0 1 0 } '
              'device [ RotationalMotor { name "g::b" multiplier 2 } ] '
              'endPoint Solid { translation 0 0.5 0 name "bob2" boundingObject Sphere { radius 0.05 } '
              'physics Physics { density -1 mass 1 } } }')
    sup, _, _ = _arm("minPosition -1 maxPosition 1", extra_joint=" " + second, name="g::a")
    sibling = sup.getDevice("g::b")
    assert (sibling.getMinPosition(), sibling.getMaxPosition(), sibling.getMaxVelocity()) == (-2.0, 2.0, 200.0)
    _motor_node(sup, 1).getField("maxPosition").setSFFloat(0.5)
    _step(sup)
    assert (sibling.getMinPosition(), sibling.getMaxPosition()) == (0.0, 0.5)  # its fields now: [0, 0.5]
    sup.simulationReset()
    _step(sup)
    assert (sibling.getMinPosition(), sibling.getMaxPosition(), sibling.getMaxVelocity()) == (-2.0, 2.0, 200.0)


# ------------------------------------------------------------------------------------------ a Track's motor

TRACK = ('Robot { supervisor TRUE children [ Track { translation 0 0 0.2 boundingObject Box { size 2 0.4 0.1 } '
         'physics Physics { mass 5 } device [ DEF TM LinearMotor { %s } PositionSensor { name "s" } ] } ] }')


def _track(motor: str = "") -> tuple[Supervisor, Any, Any]:
    """A Track whose belt travel the sensor reads: the belt follows the motor law exactly (D §7.2: v = u, the
    position integrates v·dt), so the values below are the law's, without ODE's softness."""
    sup = quiet_supervisor(f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n" + TRACK % motor)
    sensor = sup.getDevice("s")
    sensor.enable(TS)
    return sup, sup.getDevice("linear motor"), sensor


@pytest.mark.parametrize("edit", [True, False])
def test_track_motor_max_velocity_and_multiplier_edits(edit: bool) -> None:
    # velocity control at 5 m/s (maxVelocity 10); maxVelocity edited to 2 clips the target: 2·ts per step; with
    # multiplier 2 a setVelocity(0.5) made after the step that executes the write (S §6) commands 1 m/s (D §9)
    sup, motor, sensor = _track()
    motor.setPosition(float("inf"))
    motor.setVelocity(5.0)
    _step(sup)
    if edit:
        sup.getFromDef("TM").getField("maxVelocity").setSFFloat(2.0)
    _, moved = _moved(sup, sensor)
    assert moved == pytest.approx((2.0 if edit else 5.0) * DT)
    assert motor.getMaxVelocity() == (2.0 if edit else 10.0)
    if edit:
        sup.getFromDef("TM").getField("multiplier").setSFFloat(2.0)
    _step(sup)
    motor.setVelocity(0.5)
    _, moved = _moved(sup, sensor)
    assert moved == pytest.approx((1.0 if edit else 0.5) * DT)


@pytest.mark.parametrize("edit", [True, False])
def test_track_motor_control_pid_and_limits_edits(edit: bool) -> None:
    # position control toward 0.8 within [−1, 1]: Kp 10 moves 10·0.8 = 8 m/s (< maxVelocity 10) the first step;
    # Kp edited to 1 moves 1·(0.8 − p)·ts the next one; maxPosition edited to 0.3 then leaves the belt at 0.3
    sup, motor, sensor = _track("minPosition -1 maxPosition 1")
    motor.setPosition(0.8)
    _step(sup)
    if edit:
        sup.getFromDef("TM").getField("controlPID").setSFVec3f([1.0, 0.0, 0.0])
    before, moved = _moved(sup, sensor)
    assert before == pytest.approx(8.0 * DT)
    assert moved == pytest.approx((1.0 if edit else 10.0) * (0.8 - before) * DT)
    if edit:
        sup.getFromDef("TM").getField("maxPosition").setSFFloat(0.3)
    _step(sup, 3000)
    # (Kp 1 closes the last gap by a factor 1 − ts per step: 0.27·0.996^3000 ≈ 2e-6 left)
    assert sensor.getValue() == pytest.approx(0.3 if edit else 0.8, abs=1e-5)
    sup.simulationReset()  # the load gains and limits again: Kp 10 from the belt's 0
    _step(sup)
    motor.setPosition(0.8)
    _, moved = _moved(sup, sensor)
    assert moved == pytest.approx(8.0 * DT)
    assert motor.getMaxPosition() == 1.0


# ------------------------------------------------------------------------------------------ a Propeller


def _drone() -> Supervisor:
    """A 1 kg drone, no gravity, whose propeller pushes along z: T = t1·ω·|ω| = 1e-4·ω² (D §8), no torque."""
    return quiet_supervisor(
        f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n"
        "DEF DRONE Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } "
        "children [ DEF P Propeller { shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0 "
        'device DEF PM RotationalMotor { name "prop" maxVelocity 200 maxTorque 1000 } } ] }')


def _gain(sup: Supervisor, steps: int) -> float:
    """The drone's gain of vertical speed over ``steps`` steps."""
    before = sup.getFromDef("DRONE").getVelocity()[2]
    _step(sup, steps)
    return float(sup.getFromDef("DRONE").getVelocity()[2] - before)


@pytest.mark.parametrize("edit", ["", "thrustConstants", "maxVelocity"])
def test_propeller_and_its_motor_edits_act_from_the_next_step(edit: str) -> None:
    # ω = 100 rad/s (reached after 0.1 s at the maxTorque ramp of 1000 rad/s²): T = 1 N, 0.5 m/s gained in 0.5 s on
    # 1 kg. thrustConstants edited to 2e-4 0: T = 2 N, 1 m/s. maxVelocity edited to 50: the target clipped to 50 rad/s
    # (reached within 0.05 s), T = 1e-4·2500 = 0.25 N, 0.125 m/s
    sup = _drone()
    prop = sup.getDevice("prop")
    prop.setPosition(float("inf"))
    prop.setVelocity(100.0)
    _step(sup, 50)
    if edit == "thrustConstants":
        sup.getFromDef("P").getField("thrustConstants").setSFVec2f([2e-4, 0.0])
    elif edit == "maxVelocity":
        sup.getFromDef("PM").getField("maxVelocity").setSFFloat(50.0)
    _step(sup, 25)
    gained = _gain(sup, 125)
    assert gained == pytest.approx({"": 0.5, "thrustConstants": 1.0, "maxVelocity": 0.125}[edit], rel=1e-3)
    assert prop.getMaxVelocity() == (50.0 if edit == "maxVelocity" else 200.0)
    sup.simulationReset()  # the load fields again: T = 1e-4·100² = 1 N once ω is back at 100 rad/s
    _step(sup)
    prop.setPosition(float("inf"))
    prop.setVelocity(100.0)
    _step(sup, 50)
    assert prop.getMaxVelocity() == 200.0
    assert _gain(sup, 125) == pytest.approx(0.5, rel=1e-3)
