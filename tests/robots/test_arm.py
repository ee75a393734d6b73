"""The bundled six-joint arm (``arm`` and ``arm_payload``): both twins load it with the same mass properties,
the converter carries its motors faithfully, and a position step on every joint settles alike in both twins."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from dualtwin.convert import convert_world
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding, bundled_robots, load_binding, resolve_robot
from dualtwin.twins import Twin, make_twin
from dualtwin.twins.io import RobotIO
from dualtwin.twins.motors import servo_inertia
from dualtwin.twins.mujoco import SERVO_STIFFNESS, MuJoCoTwin
from dualtwin.webots import load_world
from dualtwin.webots.physics import Simulation

JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
LINKS = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"]
# UR's published link masses (kg), and the payload variant's 5 kg cube merged into the flange link.
UR_MASSES = [3.761, 8.058, 2.846, 1.37, 1.3, 0.365]
MAX_TORQUE = [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]


@pytest.fixture(scope="module", params=["arm", "arm_payload"])
def robot(request: pytest.FixtureRequest) -> RobotBinding:
    return resolve_robot(request.param)


def test_bundled() -> None:
    assert {"arm", "arm_payload"} <= set(bundled_robots())


def test_mass_properties_agree(robot: RobotBinding) -> None:
    """Mass, world CoM and inertia tensor of every link: Webots' ODE bodies against the converted MJCF."""
    sim = Simulation(load_world(robot.model_path("webots")))
    model = mujoco.MjModel.from_xml_path(str(robot.model_path("mujoco")))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ode_bodies = {b.root.node.def_name: b for b in sim.bodies}
    assert set(ode_bodies) == set(LINKS)
    payload = 5.0 if robot.name == "arm_payload" else 0.0
    for link, ur_mass in zip(LINKS, UR_MASSES, strict=True):
        body = ode_bodies[link]
        b = model.body(link).id
        expected = ur_mass + (payload if link == "wrist_3_link" else 0.0)
        assert body.mass == pytest.approx(expected, rel=1e-9)
        assert model.body_mass[b] == pytest.approx(expected, rel=1e-6)
        # World CoM at the file's pose; the ODE body's origin is its CoM.
        assert np.allclose(np.array(body.pos[:3]), data.xipos[b], atol=1e-5), link
        # Inertia about the CoM in world axes (both frames are world-aligned at q = 0).
        ode_inertia = np.array(body.inertia).reshape(3, 3)
        rot = data.ximat[b].reshape(3, 3)
        mj_inertia = rot @ np.diag(model.body_inertia[b]) @ rot.T
        assert np.allclose(ode_inertia, mj_inertia, atol=1e-6 * max(1.0, np.abs(ode_inertia).max())), link
    assert sum(b.mass for b in sim.bodies) == pytest.approx(sum(UR_MASSES) + payload)


def test_bundled_mjcf_is_the_conversion(robot: RobotBinding) -> None:
    """The bundled MJCF is exactly what ``dualtwin convert`` writes for the bundled world (no hand edits)."""
    conversion = convert_world(robot.model_path("webots"))
    assert conversion.xml == robot.model_path("mujoco").read_text()
    assert not [f for f in conversion.lint if f.level == "error"]


def test_motor_semantics_carried() -> None:
    """Webots' motor fields reach the MuJoCo twin: max velocity, PID gains, torque limit, position limits."""
    robot = resolve_robot("arm")
    model = mujoco.MjModel.from_xml_path(str(robot.model_path("mujoco")))
    for joint, torque in zip(JOINTS, MAX_TORQUE, strict=True):
        numeric = model.numeric(f"webots_motor.{joint}")
        max_velocity, kp, ki, kd, acceleration, lo, hi = numeric.data
        assert max_velocity == pytest.approx(math.pi, rel=1e-6)
        assert (kp, ki, kd, acceleration) == (10.0, 0.0, 0.0, -1.0)
        limit = math.pi if joint == "elbow" else 2 * math.pi
        assert (lo, hi) == (pytest.approx(-limit, rel=1e-6), pytest.approx(limit, rel=1e-6))
        assert tuple(model.actuator(joint).forcerange) == (-torque, torque)
        # Webots has no rotor inertia, joint damping or friction here: the conversion adds none.
        dof = model.jnt_dofadr[model.joint(joint).id]
        assert (model.dof_armature[dof], model.dof_damping[dof], model.dof_frictionloss[dof]) == (0, 0, 0)


def _settle(twin: Twin, targets: list[float], seconds: float) -> tuple[np.ndarray, np.ndarray]:
    twin.reset(0)
    trace = []
    for _ in range(round(seconds / twin.control_period)):
        for joint, target in zip(JOINTS, targets, strict=True):
            twin.command(joint, "position", target)
        twin.step()
        trace.append([twin.joint_position(j) for j in JOINTS])
    return np.array(trace), np.asarray(twin.body_position("wrist_3_link"), dtype=float)


def test_position_step_settles_alike(robot: RobotBinding) -> None:
    """A step on every joint at once (shoulder and elbow against gravity) settles to the target in both twins:
    Webots' P = 10 velocity servo capped at pi rad/s, reproduced by the MuJoCo twin's motor emulation."""
    targets = [0.6, -0.5, 0.9, -0.7, 0.5, 1.2]
    results = {name: _settle(make_twin(name, robot), targets, 1.6) for name in ("webots", "mujoco")}
    for trace, _ in results.values():
        assert np.allclose(trace[-1], targets, atol=2e-3)
        # The first period moves about the speed cap (pi rad/s): Webots' maxVelocity binds, not P = 10.
        assert np.all(np.abs(trace[0]) <= 1.1 * math.pi * 0.016)
    (webots, ee_webots), (mujoco_trace, ee_mujoco) = results["webots"], results["mujoco"]
    assert np.abs(webots - mujoco_trace).max() < 0.01
    assert np.linalg.norm(ee_webots - ee_mujoco) < 2e-3


def test_target_beyond_motor_limit_is_clamped_in_both_twins() -> None:
    """The elbow's motor limits (+-pi) clamp a position target in both twins, as Webots' setPosition does."""
    robot = resolve_robot("arm")
    ends = []
    for name in ("webots", "mujoco"):
        twin = make_twin(name, robot)
        twin.reset(0)
        twin.set_joint_state("elbow", position=3.0)
        for _ in range(40):
            twin.command("elbow", "position", 4.0)
            twin.step()
        ends.append(twin.joint_position("elbow"))
    assert ends[0] == pytest.approx(math.pi, abs=2e-3)
    assert ends[1] == pytest.approx(ends[0], abs=2e-3)


def test_flange_orientation_channels() -> None:
    """roll/pitch/yaw body channels are Z-Y-X Euler angles of the flange frame."""
    robot = resolve_robot("arm")
    twin = make_twin("mujoco", robot)
    io = RobotIO(robot, twin)
    names = io.ground_truth_names

    def pose(**q: float) -> dict[str, float]:
        twin.reset(0)
        for joint, value in q.items():
            twin.set_joint_state(joint, position=value)
        return dict(zip(names, io.sample_ground_truth(), strict=True))

    p = pose(shoulder_pan=0.4)
    assert (p["ee_roll_rad"], p["ee_pitch_rad"], p["ee_yaw_rad"]) == pytest.approx((0, 0, 0.4), abs=1e-9)
    p = pose(wrist_3=0.3)  # flange axis +y at q = 0: a pitch
    assert (p["ee_roll_rad"], p["ee_pitch_rad"], p["ee_yaw_rad"]) == pytest.approx((0, 0.3, 0), abs=1e-9)
    p = pose(shoulder_pan=math.pi / 2, wrist_3=0.25)  # intrinsic: yaw first, then the flange's pitch
    assert (p["ee_roll_rad"], p["ee_pitch_rad"], p["ee_yaw_rad"]) == pytest.approx((0, 0.25, math.pi / 2),
                                                                                   abs=1e-9)
    assert (p["ee_x_m"], p["ee_y_m"]) == pytest.approx((-0.2329, 0.8172), abs=1e-4)
    # A general pose: the three angles rebuild the flange's rotation matrix.
    p = pose(shoulder_pan=0.3, shoulder_lift=-0.8, elbow=1.1, wrist_1=0.7, wrist_2=-1.2, wrist_3=0.4)
    assert abs(p["ee_roll_rad"]) > 0.1
    rebuilt = (_rotation(2, p["ee_yaw_rad"]) @ _rotation(1, p["ee_pitch_rad"]) @ _rotation(0, p["ee_roll_rad"]))
    assert np.allclose(rebuilt, np.asarray(twin.body_orientation("wrist_3_link")).reshape(3, 3), atol=1e-9)


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def test_orientation_channel_has_no_velocity(tmp_path: Path) -> None:
    text = resolve_robot("arm").path.read_text().replace(
        "ee_roll_rad: {body: wrist_3_link, axis: roll, unit: rad}",
        "ee_roll_rad: {body: wrist_3_link, axis: roll, quantity: velocity, unit: rad}")
    path = tmp_path / "binding.yaml"
    path.write_text(text)
    with pytest.raises(DualtwinError, match="orientation angle"):
        load_binding(path)


# ---------------------------------------------------------------- the suite


def _suite_path(robot: RobotBinding) -> Path:
    return robot.root / "suite.json"


def test_suites_resolve_against_their_bindings(robot: RobotBinding) -> None:
    from dualtwin.suite.loader import load_suite
    from dualtwin.suite.runner import check_against_binding

    suite = load_suite(_suite_path(robot))
    check_against_binding(suite, _suite_path(robot), robot)
    kinds = {s.type for s in suite.scenarios}
    assert {"step_response", "sine_sweep", "trajectory", "gravity_hold", "torque_saturation"} <= kinds


def _run(robot: RobotBinding, twin_name: str, scenario: str) -> tuple[list[str], np.ndarray]:
    from dualtwin.suite.loader import load_suite
    from dualtwin.suite.runner import run_scenario

    suite = load_suite(_suite_path(robot))
    chosen = next(s for s in suite.scenarios if s.name == scenario)
    io = RobotIO(robot, make_twin(twin_name, robot, suite.global_settings.control_period_s))
    result, _, truth = run_scenario(io, chosen, 0, {}, fresh=True)
    assert result.status == "completed"
    return io.ground_truth_names, np.array(truth)


def _ee_rmse(a: np.ndarray, b: np.ndarray, names: list[str]) -> float:
    cols = [names.index(c) + 1 for c in ("ee_x_m", "ee_y_m", "ee_z_m")]
    return float(np.sqrt(((a[:, cols] - b[:, cols]) ** 2).sum(axis=1).mean()))


def test_fast_move_saturates_the_motor_in_both_twins() -> None:
    """fast_pan: pi rad/s in one 2 ms step would take thousands of N*m; at 150 N*m the stretched arm (about
    3.5 kg*m^2 about the base axis) needs tens of ms to reach the speed cap, in both twins alike."""
    robot = resolve_robot("arm")
    runs = {name: _run(robot, name, "fast_pan") for name in ("webots", "mujoco")}
    names = runs["webots"][0]
    dq1 = names.index("dq1_rad_s") + 1
    for _, truth in runs.values():
        first = truth[7]  # the first period after the 0.1 s step
        assert 0.3 < first[dq1] < 0.9 * math.pi, "the torque limit, not the speed cap, sets the first period"
        assert truth[:, dq1].max() == pytest.approx(math.pi, abs=0.02)
        assert truth[-1][names.index("q1_rad") + 1] == pytest.approx(2.0, abs=2e-3)
    assert np.abs(runs["webots"][1][:, dq1] - runs["mujoco"][1][:, dq1]).max() < 0.05
    assert _ee_rmse(runs["webots"][1], runs["mujoco"][1], names) < 1e-3


def test_gravity_hold_with_payload() -> None:
    """The stretched arm holds its pose with and without the 5 kg payload (about 95 N*m on the shoulder with
    it), and both twins agree on the flange position to well under a millimetre."""
    for name in ("arm", "arm_payload"):
        robot = resolve_robot(name)
        runs = {twin: _run(robot, twin, "gravity_hold_stretched") for twin in ("webots", "mujoco")}
        names = runs["webots"][0]
        for _, truth in runs.values():
            assert np.abs(truth[:, [names.index(f"q{k}_rad") + 1 for k in range(1, 7)]]).max() < 1e-3
        assert _ee_rmse(runs["webots"][1], runs["mujoco"][1], names) < 5e-4


# ---------------------------------------------------------------- arm knobs (MuJoCo twin)


def test_armature_and_pid_gain_knobs_and_their_patched_mjcf() -> None:
    """joint.<j>.armature (rotor inertia, which Webots does not model) and motor.<m>.kp (the emulated Webots
    P gain) change the response; the patched MJCF reproduces the knob values exactly; {} restores nominal."""
    from dualtwin.align.patch import patch_mjcf
    from dualtwin.twins.mujoco import MuJoCoTwin

    path = resolve_robot("arm").model_path("mujoco")

    def response(twin: MuJoCoTwin) -> np.ndarray:
        twin.reset(0)
        rows = []
        for _ in range(20):
            twin.command("wrist_3", "position", 1.0)
            twin.command("elbow", "position", 0.5)
            twin.step()
            rows.append([twin.joint_velocity("wrist_3"), twin.joint_position("elbow")])
        return np.array(rows)

    twin = MuJoCoTwin(path, 0.016)
    registry = twin.knobs()
    assert {f"joint.{j}.armature" for j in JOINTS} | {f"motor.{j}.kp" for j in JOINTS} <= set(registry)
    assert registry["motor.elbow.kp"].nominal == 10.0
    nominal = response(twin)
    knobs = {"joint.wrist_3.armature": 0.2, "motor.elbow.kp": 5.0}
    twin.set_knobs(knobs)
    changed = response(twin)
    # 28 N*m against 0.2 kg*m^2 of rotor: 0.016 s reach 2.24 rad/s, not the pi rad/s cap.
    assert changed[0, 0] == pytest.approx(28.0 / 0.2 * 0.016, rel=0.01)
    assert nominal[0, 0] == pytest.approx(math.pi, rel=1e-3)
    # Half the gain: the elbow's ~0.45 rad error in the second period asks 5 x 0.45 = 2.25 rad/s instead of the
    # pi rad/s cap (0.72 of it). The second period: in the first both spin up at the motor's torque limit.
    assert changed[1, 1] - changed[0, 1] < 0.8 * (nominal[1, 1] - nominal[0, 1])
    patched = patch_mjcf(path, knobs)
    assert patched.text is not None and not patched.not_applied
    assert np.array_equal(response(MuJoCoTwin(mujoco.MjSpec.from_string(patched.text), 0.016)), changed)
    twin.set_knobs({})
    assert np.array_equal(response(twin), nominal)


def _per_motor_law_steps(twin: MuJoCoTwin, servos: list[Any], steps: int) -> None:
    """The control: the MuJoCo twin's servo loop written plainly, one call of Webots' motor law
    (MotorState.velocity_command -> motor_law.motor_velocity) per motor and physics step, then the bounded row
    of twins.motors.servo_steps (its docstring) in plain terms."""
    m, d = twin.model, twin.data
    dt = m.opt.timestep
    for _ in range(steps):
        mujoco.mj_step1(m, d)
        taken, switched = {}, False
        for mo in servos:
            st = mo.state
            qdot = float(d.qvel[mo.dof])
            smooth = float(d.qfrc_passive[mo.dof] - d.qfrc_bias[mo.dof] + d.qfrc_applied[mo.dof])
            taken[mo.index] = (qdot, smooth, 0.0, 0.0)
            if st.torque_mode:
                continue
            u = st.velocity_command(float(d.qpos[mo.qpos]), dt)
            limit, inertia = st.available_torque, servo_inertia(mo.kv, dt, SERVO_STIFFNESS)
            reach, margin = dt / inertia, limit / mo.kv

            def beyond(sign: float, load: float, u: float = u, qdot: float = qdot, limit: float = limit,
                       reach: float = reach, margin: float = margin) -> bool:  # u past what sign x limit reaches
                edge = qdot + ((load + sign * limit) * reach + sign * margin)
                return u > edge if sign > 0 else u < edge

            sign = mo.saturated
            if not sign:
                sign = 1.0 if beyond(1.0, smooth) else -1.0 if beyond(-1.0, smooth) else 0.0
            # A constraint's reaction pushing the way the saturated motor pushes does none of its work.
            load = smooth + (mo.residual - mo.reaction if sign * mo.reaction > 0.0 else mo.residual)
            if sign and not beyond(sign, load):
                sign = 0.0
            mo.saturated = sign
            stiffness, torque = mo.kv, 0.0
            if sign:  # saturated: no servo, the torque to u under the smooth force alone, within the limit
                stiffness, torque = 0.0, inertia * (u - qdot) / dt - (load if mo.dof in twin._constrained_dofs() else smooth)
                torque = torque if torque < limit else limit  # min(torque, limit), as servo_steps picks it
                torque = torque if torque > -limit else -limit
            if stiffness != mo.stiffness:
                switched = True
                twin._set_stiffness(mo, stiffness)
            taken[mo.index] = (qdot, smooth, stiffness, torque)
            d.ctrl[mo.index] = stiffness * (u - qdot) + torque
        if switched:
            mujoco.mj_step1(m, d)
        mujoco.mj_step2(m, d)
        for mo in servos:
            qdot, smooth, stiffness, explicit = taken[mo.index]
            limit = mo.state.available_torque
            after = float(d.qvel[mo.dof])
            torque = mo.state.torque if mo.state.torque_mode else stiffness * (mo.state.current_velocity - after) + explicit
            d.actuator_force[mo.index] = torque
            change = after - qdot
            mo.residual = (servo_inertia(mo.kv, dt, SERVO_STIFFNESS) * change / dt + float(m.dof_damping[mo.dof]) * change
                           - torque - smooth)
            mo.reaction = float(d.qfrc_constraint[mo.dof])
            if not mo.state.torque_mode and not mo.saturated and abs(torque) > limit:
                mo.saturated = math.copysign(1.0, torque)


def test_inlined_motor_law_is_bit_identical_to_the_per_motor_law() -> None:
    """The MuJoCo twin's inlined servo loop (twins.motors.servo_steps) against the law called per motor and
    step, bit for bit: saturating position steps, a PID with I and D terms, an acceleration limit in velocity
    control and a motor without available torque, with a control that a changed gain does show."""
    robot = resolve_robot("arm_payload")

    def trajectory(per_motor: bool, kd: float = 0.02) -> np.ndarray:
        # The Python law (twins.motors), which the native law is checked against in test_native_motor_law.
        twin = MuJoCoTwin(robot.model_path("mujoco"), 0.016, native_law=False)
        if per_motor:
            twin._servo_steps = lambda servos, steps: _per_motor_law_steps(twin, servos, steps)  # type: ignore[method-assign]
        motors = twin._motor_by_name
        motors["elbow"].state.params.ki, motors["elbow"].state.params.kd = 0.5, kd
        motors["wrist_2"].state.params.acceleration = 4.0
        twin.reset(0)
        motors["wrist_3"].state.available_torque = 0.0
        rows = []
        for k in range(60):
            twin.command("shoulder_pan", "position", 2.5 if k < 30 else -1.0)
            twin.command("shoulder_lift", "position", -1.2)
            twin.command("elbow", "position", 0.8 * math.sin(0.2 * k))
            twin.command("wrist_1", "position", 1.5)
            twin.command("wrist_2", "velocity", 3.0 if k < 40 else -3.0)
            twin.step()
            rows.append(np.concatenate([twin.data.qpos, twin.data.qvel, twin.data.ctrl,
                                        [mo.saturated for mo in twin._motors]]))
        twin.close()
        return np.array(rows)

    inlined, per_motor = trajectory(False), trajectory(True)
    assert np.abs(inlined[:, -6:]).sum() > 0, "no motor saturated: the test would not cover saturation"
    assert inlined.tobytes() == per_motor.tobytes()
    assert trajectory(False, kd=0.03).tobytes() != inlined.tobytes()  # control: the comparison can see a change
