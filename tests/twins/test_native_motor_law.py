"""Webots' motor law compiled into MuJoCo's step (twins/native/webots_motor.c) against the Python reference
(twins/motors.py), bit for bit on every bundled robot, and the plugin on its own in plain MuJoCo."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from dualtwin.robots.binding import bundled_robots, resolve_robot
from dualtwin.twins import motor_plugin
from dualtwin.twins.mujoco import MuJoCoTwin

pytestmark = pytest.mark.skipif(motor_plugin.available() is not None,
                                reason=f"motor plugin unavailable: {motor_plugin.available()}")

PERIOD = 0.016


def _trajectory(robot: str, native: bool, kp_scale: float = 1.0) -> tuple[np.ndarray, int]:
    """80 control periods of position, velocity and torque commands (random, seeded; large enough to
    saturate), with a rotor-inertia and a gain knob, a PID with I and D terms and an acceleration limit on
    the first motors; rows of qpos, qvel and actuator forces, and how many periods ended with a servo at its
    torque bound.
    ``robot`` is a bundled robot's name or an MJCF text."""
    model = mujoco.MjSpec.from_string(robot) if robot.startswith("<") else resolve_robot(robot).model_path("mujoco")
    twin = MuJoCoTwin(model, PERIOD, native_law=native)
    assert twin.native_law is native
    motors = twin._motors
    registry = twin.knobs()
    joint = mujoco.mj_id2name(twin.model, mujoco.mjtObj.mjOBJ_JOINT, int(twin.model.dof_jntid[motors[0].dof]))
    knobs = {f"joint.{joint}.armature": 0.01, f"motor.{motors[-1].name}.kp": 7.0 * kp_scale}
    twin.set_knobs({k: v for k, v in knobs.items() if k in registry})
    motors[0].state.params.ki, motors[0].state.params.kd = 0.5, 0.02
    motors[-1].state.params.acceleration = 20.0
    twin.reset(0)
    rng = np.random.default_rng(0)
    rows, saturated = [], 0
    for k in range(80):
        if k % 10 == 0:
            mode = ("position", "velocity", "torque", "position")[(k // 10) % 4]
            scale = {"position": 1.5, "velocity": 6.0, "torque": 0.5}[mode]
            for mo in motors:
                twin.command(mo.name, mode, scale * float(rng.normal()))  # type: ignore[arg-type]
        twin.step()
        d = twin.data
        rows.append(np.concatenate([d.qpos, d.qvel, d.actuator_force]))
        # A servo at its torque bound: actuator_force is the torque it applied over the last step.
        saturated += any(not mo.state.torque_mode and abs(d.actuator_force[mo.index]) > 0.99 * mo.state.available_torque
                         for mo in motors)
    twin.close()
    return np.array(rows), saturated


@pytest.mark.parametrize("robot", bundled_robots())
def test_native_law_is_bit_identical_to_the_python_law(robot: str) -> None:
    native, saturated = _trajectory(robot, True)
    python, python_saturated = _trajectory(robot, False)
    assert saturated > 0 and saturated == python_saturated, "the commands must drive motors into saturation"
    assert np.isfinite(native).all()
    assert native.tobytes() == python.tobytes()
    # control: the comparison sees a gain change
    assert _trajectory(robot, True, kp_scale=1.1)[0].tobytes() != native.tobytes()


# One joint on the world: MuJoCo calls these dofs "simple" and reads their mass-matrix diagonal from dof_M0, not from
# dof_armature, so the Python law's servo armature (and the rotor knob) must reach dof_M0 too. Before, the Python
# law's stiff servo diverged here (a 1 rad/s command ran the hinge at hundreds of rad/s) while the plugin's held.
SIMPLE_DOFS = {
    joint: f"""<mujoco><option timestep="0.002" gravity="0 0 -9.81"/><worldbody><body name="b" pos="0 0 1">
      <joint name="j" type="{joint}" axis="0 1 0"/><geom type="box" size="0.05 0.05 0.05" mass="{mass}"/>
      </body></worldbody><actuator><general name="m" joint="j" forcelimited="true" forcerange="-{limit} {limit}"/>
      </actuator><custom><numeric name="webots_motor.m" data="10 10 0 0 -1"/></custom></mujoco>"""
    for joint, mass, limit in (("hinge", 1.0, 1), ("slide", 0.05, 2))
}


@pytest.mark.parametrize("joint", sorted(SIMPLE_DOFS))
def test_native_law_is_bit_identical_to_the_python_law_on_a_simple_dof(joint: str) -> None:
    probe = mujoco.MjModel.from_xml_string(SIMPLE_DOFS[joint])
    assert probe.dof_simplenum[0] > 0  # the case this test is about
    native, saturated = _trajectory(SIMPLE_DOFS[joint], True)
    python, python_saturated = _trajectory(SIMPLE_DOFS[joint], False)
    assert saturated > 0 and saturated == python_saturated
    assert np.isfinite(native).all() and np.abs(native[:, 1]).max() < 100.0  # qvel: the servo held
    assert native.tobytes() == python.tobytes()


def test_native_law_is_bit_identical_to_the_python_law_with_a_sparse_jacobian() -> None:
    """A saturated motor's load counts last step's residual only while a constraint row acts on its joint; the
    native law finds those rows in the sparse Jacobian (efc_J_colind) when the model is sparse, the Python law too
    (MuJoCoTwin._constrained_dofs). The bundled robots are all dense (under 60 dofs), so this is the Pioneer, whose
    wheels' contacts come and go, made sparse."""
    text = resolve_robot("pioneer3at").model_path("mujoco").read_text(encoding="utf-8")
    text = text.replace('<option integrator="implicitfast"/>', '<option integrator="implicitfast" jacobian="sparse"/>')
    assert mujoco.mj_isSparse(mujoco.MjModel.from_xml_string(text))  # the case this test is about
    native, saturated = _trajectory(text, True)
    python, python_saturated = _trajectory(text, False)
    assert saturated > 0 and saturated == python_saturated
    assert np.isfinite(native).all()
    assert native.tobytes() == python.tobytes()


def test_the_twin_drives_all_its_motors_from_one_plugin_instance() -> None:
    """MuJoCo dispatches plugins per instance and stage, which costs more than the law: the twin's motors share
    one instance, each with its block of plugin_state in actuator order (the bit-identity test above steps
    it; the converted model's one instance per motor steps the same, see the last test)."""
    twin = MuJoCoTwin(resolve_robot("arm").model_path("mujoco"), PERIOD)
    model = twin.model
    assert model.nu == 6 and model.nplugin == 1
    assert model.plugin_statenum[0] == motor_plugin.NSTATE * model.nu
    assert [mo.plugin for mo in twin._motors] == [motor_plugin.NSTATE * k for k in range(model.nu)]
    blocks = twin.data.plugin_state.reshape(model.nu, motor_plugin.NSTATE)
    assert blocks[:, motor_plugin.SLOT["actuator"]].tolist() == list(range(model.nu))
    # control: only the last block factorises the inertia matrix
    assert blocks[:, motor_plugin.SLOT["last"]].tolist() == [0.0] * (model.nu - 1) + [1.0]


PENDULUM = """<mujoco>
  <extension><plugin plugin="dualtwin-webots-motor"/></extension>
  <option timestep="0.002"/>
  <worldbody><body><joint name="hinge" axis="0 1 0"/>
    <geom type="capsule" size="0.05" fromto="0 0 0 0.5 0 0" mass="1"/></body></worldbody>
  <actuator><plugin name="motor" joint="hinge" plugin="dualtwin-webots-motor">
    <config key="maxVelocity" value="2"/><config key="maxTorque" value="{torque}"/>
    <config key="Kp" value="10"/><config key="ctrl" value="position"/></plugin></actuator>
</mujoco>"""


def test_the_plugin_runs_webots_position_control_in_plain_mujoco() -> None:
    """No twin: ctrl is Webots' setPosition, the speed is capped at maxVelocity, the torque at maxTorque."""
    model = mujoco.MjModel.from_xml_string(PENDULUM.format(torque=20))
    data = mujoco.MjData(model)
    data.ctrl[0] = -1.0  # up, against gravity
    speeds = []
    for _ in range(1000):
        mujoco.mj_step(model, data)
        speeds.append(abs(data.qvel[0]))
    assert data.qpos[0] == pytest.approx(-1.0, abs=2e-3)  # P control holds against gravity with a small offset
    # Webots' velocity cap while it travels (leaving saturation overshoots it for one step)
    assert np.median(speeds[20:200]) == pytest.approx(2.0, abs=0.01)
    weak = mujoco.MjModel.from_xml_string(PENDULUM.format(torque=1))
    held = mujoco.MjData(weak)
    held.ctrl[0] = -1.0
    for _ in range(1000):
        mujoco.mj_step(weak, held)
    # 1 N m cannot lift 1 kg at 0.25 m (2.45 N m): saturated at the limit, the arm hangs below the horizontal
    assert abs(held.actuator_force[0]) == pytest.approx(1.0) and held.qpos[0] > 0.0
    # mujoco.rollout runs it too, and the same as mj_step
    fresh = mujoco.MjData(model)
    state0 = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, fresh, state0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    from mujoco import rollout

    states, _ = rollout.rollout(model, fresh, state0[None], -np.ones((1, 1000, 1)))
    qpos_adr = 1  # the full-physics state starts with time
    assert states[0, -1, qpos_adr] == data.qpos[0]
    assert not math.isnan(states[0, -1, qpos_adr])


def test_a_converted_model_carries_the_law_into_plain_mujoco() -> None:
    """Conversion.native_law_xml: plain MuJoCo holds Webots' position targets through ctrl, and the MuJoCo
    twin steps that file bit for bit as it steps the plain conversion (the plugin's config is the motors')."""
    from dualtwin.convert import convert_world
    from dualtwin.errors import DualtwinError
    from dualtwin.robots.binding import BUNDLED

    conversion = convert_world(BUNDLED / "arm" / "arm.wbt")
    xml = conversion.native_law_xml()
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.8
    mujoco.mj_step(model, data, nstep=400)
    assert np.abs(data.qpos - 0.8).max() < 2e-3
    runs = []
    for text in (conversion.xml, xml):
        twin = MuJoCoTwin(mujoco.MjSpec.from_string(text), PERIOD)
        twin.reset(0)
        for k in range(40):
            for mo in twin._motors:
                twin.command(mo.name, "position", 0.8 if k < 20 else -0.4)
            twin.step()
        runs.append(np.concatenate([twin.data.qpos, twin.data.qvel]))
    assert runs[0].tobytes() == runs[1].tobytes()
    with pytest.raises(DualtwinError, match="plugin actuators"):
        MuJoCoTwin(mujoco.MjSpec.from_string(xml), PERIOD, native_law=False)
