"""Motors' ``multiplier`` and coupled motors (``prefix::suffix``) in the converted model, as Webots has them
(webots-devices §9): the numerics carry the multiplier and the limits Webots harmonises at load, the MuJoCo twin
scales each command by the multiplier and relays a coupled motor's commands to its siblings, and the
standalone plugin model (``native_law_xml``) scales ``ctrl`` by it.

Expected values are computed by hand from §9's rules, and the dual-twin test runs the Webots twin (our ODE
runtime, which implements §9) on the same world.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.twins import motor_plugin
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

PERIOD = 0.008


def _hinge(name: str, x: float, motor: str) -> str:
    return (f'DEF {name} HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 anchor {x} 0 0 }} '
            f'device [ {motor} PositionSensor {{ name "{name} sensor" }} ] '
            f'endPoint DEF {name}_END Solid {{ translation {x} 0 0 physics Physics {{ }} '
            'boundingObject Box { size 0.1 0.1 0.1 } } }')


# grip::a is the group's first motor (maxVelocity 4, limits [-1, 2]); grip::b's own limits are replaced by
# a's times the ratio -0.5: maxVelocity 2, limits sorted(0.5, -1) = [-1, 0.5]. solo is not coupled.
MOTORS = {
    "A": 'RotationalMotor { name "grip::a" maxVelocity 4 minPosition -1 maxPosition 2 }',
    "B": 'RotationalMotor { name "grip::b" multiplier -0.5 maxVelocity 9 }',
    "S": 'RotationalMotor { name "solo" multiplier 2 }',
    "P": 'RotationalMotor { name "plain" }',
}
WORLD = world_text(
    'DEF R Robot { controller "<extern>" children [\n'
    + "\n".join(_hinge(n, 0.5 * i, m) for i, (n, m) in enumerate(MOTORS.items())) + "\n] }",
    "basicTimeStep 2 gravity 0")


def _numeric(model: mujoco.MjModel, name: str) -> list[float]:
    n = model.numeric(f"webots_motor.{name}")
    return [float(v) for v in n.data]


def test_numerics_carry_the_multiplier_and_the_harmonised_limits() -> None:
    conv = convert_world_text(WORLD, "coupled.wbt")
    model = conv.compile()
    assert _numeric(model, "grip::a") == [4, 10, 0, 0, -1, -1, 2]
    assert _numeric(model, "grip::b") == [2, 10, 0, 0, -1, -1, 0.5, -0.5]
    assert _numeric(model, "solo") == [10, 10, 0, 0, -1, 0, 0, 2]
    assert _numeric(model, "plain") == [10, 10, 0, 0, -1]  # control: unchanged layout without a multiplier
    assert not [w for w in conv.warnings if "multiplier" in w and "not converted" in w]


@pytest.mark.parametrize("native", [False, True])
def test_the_mujoco_twin_scales_and_relays_commands(native: bool) -> None:
    if native and motor_plugin.available() is not None:
        pytest.skip(f"native motor law unavailable: {motor_plugin.available()}")
    twin = MuJoCoTwin(convert_world_text(WORLD, "coupled.wbt").spec, PERIOD, native_law=native)
    states = {name: twin._motor_by_name[name].state for name in ("grip::a", "grip::b", "solo", "plain")}
    twin.command("grip::a", "velocity", 10.0)  # clamped to a's 4, then x1 for a and x-0.5 for b
    assert (states["grip::a"].target_velocity, states["grip::b"].target_velocity) == (4.0, -2.0)
    twin.command("grip::b", "velocity", 3.0)  # clamped to b's 2 first (the command's motor), then relayed
    assert (states["grip::a"].target_velocity, states["grip::b"].target_velocity) == (2.0, -1.0)
    twin.command("grip::a", "position", 1.5)  # a: 1.5 in [-1, 2]; b: -0.75 in [-1, 0.5]
    assert (states["grip::a"].target_position, states["grip::b"].target_position) == (1.5, -0.75)
    # target velocity: a's maxVelocity 4 times each multiplier, within each one's maxVelocity
    assert (states["grip::a"].target_velocity, states["grip::b"].target_velocity) == (4.0, -2.0)
    twin.command("solo", "velocity", 1.0)
    assert states["solo"].target_velocity == 2.0
    twin.command("plain", "velocity", 1.0)  # control: no multiplier, no relay
    assert states["plain"].target_velocity == 1.0 and states["grip::a"].target_position == 1.5
    if not native:
        return  # the Python law's stepping is not what this test is about (it moves light joints erratically)
    for _ in range(200):  # 1.6 s: both reach their targets (a at 4 rad/s, b at 2 rad/s, then the PID)
        twin.step()
    assert twin.joint_position("A") == pytest.approx(1.5, abs=1e-3)
    assert twin.joint_position("B") == pytest.approx(-0.75, abs=1e-3)
    assert twin.joint_velocity("S") == pytest.approx(2.0, abs=1e-3)
    assert twin.joint_velocity("P") == pytest.approx(1.0, abs=1e-3)


def test_the_standalone_plugin_model_scales_ctrl_by_the_multiplier() -> None:
    if motor_plugin.available() is not None:
        pytest.skip(f"native motor law unavailable: {motor_plugin.available()}")
    conv = convert_world_text(WORLD, "coupled.wbt")
    model = mujoco.MjModel.from_xml_string(conv.native_law_xml("velocity"))
    data = mujoco.MjData(model)
    data.ctrl[:] = 1.0  # Webots' setVelocity(1) on every motor: x multiplier, within maxVelocity
    mujoco.mj_step(model, data, 200)
    velocities = [float(data.qvel[model.jnt_dofadr[model.joint(j).id]]) for j in ("A", "B", "S", "P")]
    assert velocities == pytest.approx([1.0, -0.5, 2.0, 1.0], abs=1e-3)


def test_the_webots_twin_moves_the_coupled_motors_the_same(tmp_path: Path) -> None:
    # The same commands in both twins; both run Webots' PID and velocity limits, MuJoCo through a stiff servo
    # that reaches the commanded velocity within a step where ODE's motor row reaches it in the step: 2e-3 rad
    # after 1.4 s of moves at up to 4 rad/s.
    with converted_twins(WORLD, tmp_path, PERIOD) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.command("grip::a", "velocity", 10.0)
            twin.command("solo", "velocity", 1.5)
            for _ in range(25):
                twin.step()
            twin.command("grip::b", "position", 0.4)
            for _ in range(150):
                twin.step()
        for joint in ("A", "B", "S", "P"):
            assert mujoco_twin.joint_position(joint) == pytest.approx(webots.joint_position(joint), abs=2e-3), joint
        # by hand: b's position command 0.4 relays 0.4 x 1 to a and 0.4 x -0.5 to b; solo ran 2 x 1.5 rad/s
        assert webots.joint_position("A") == pytest.approx(0.4, abs=1e-3)
        assert webots.joint_position("B") == pytest.approx(-0.2, abs=1e-3)
        assert webots.joint_velocity("S") == pytest.approx(3.0, abs=1e-3)
