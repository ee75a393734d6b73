"""The MuJoCo twin's alignment knobs: control delay, sensor models, contact, inertia, from nominal."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from dualtwin.align.patch import patch_mjcf
from dualtwin.align.simulate import simulate_twin
from dualtwin.robots.binding import RobotBinding
from dualtwin.twins.mujoco import MuJoCoTwin
from dualtwin.twins.mujoco_knobs import dampratio_to_restitution, restitution_to_dampratio


@pytest.fixture
def twin(robot: RobotBinding) -> MuJoCoTwin:
    return MuJoCoTwin(robot.model_path("mujoco"), 0.032)


def wheel_speeds(twin: MuJoCoTwin, delay: int, steps: int = 5) -> list[float]:
    twin.set_knobs({"control.delay_periods": delay})
    twin.reset(0)
    out = []
    for _ in range(steps):
        twin.command("wheel1", "velocity", 5.0)
        twin.step()
        out.append(twin.joint_velocity("wheel1_hinge"))
    return out


def test_control_delay_holds_commands_for_k_periods(twin: MuJoCoTwin) -> None:
    prompt, late = wheel_speeds(twin, 0), wheel_speeds(twin, 2)
    assert prompt[0] > 3.0
    assert late[:2] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert late[2] > 3.0


def test_sensor_bias_delay_quantization_and_noise(twin: MuJoCoTwin) -> None:
    twin.set_knobs({"sensor.pole sensor.delay": 2, "sensor.pole sensor.bias": 0.01,
                    "sensor.pole sensor.quantization": 0.005})
    twin.reset(0)
    twin.set_joint_state("pole_hinge", position=0.3)
    readings, truth = [], []
    for _ in range(4):
        twin.step()
        readings.append(twin.sensor("pole sensor"))
        truth.append(twin.joint_position("pole_hinge"))
    # Quantised to 5 mrad, 10 mrad of bias, two periods old (the initial reading until then).
    assert all(math.isclose(r / 0.005, round(r / 0.005), abs_tol=1e-9) for r in readings)
    assert readings[0] == pytest.approx(0.31, abs=0.003)
    assert readings[3] == pytest.approx(truth[1] + 0.01, abs=0.004)
    twin.set_knobs({"sensor.pole sensor.noise": 0.05})
    twin.reset(1)
    noisy = [twin.sensor("pole sensor") for _ in range(200)]
    assert float(np.std(noisy)) == pytest.approx(0.05, rel=0.2)


def test_knobs_apply_from_nominal_and_reset(twin: MuJoCoTwin) -> None:
    m = twin.model
    before = m.body_inertia.copy(), m.geom_solref.copy(), m.body_ipos.copy(), m.geom_solimp.copy(), m.jnt_solimp.copy()
    for _ in range(3):  # repeated settings must not compound
        twin.set_knobs({"body.pole.mass": 0.4, "body.pole.inertia_scale": 2.0, "body.pole.com_offset_z": 0.05,
                        "geom.floor.solref_timeconst": 0.04, "geom.floor.restitution": 0.3,
                        "geom.floor.impedance": 0.99, "joint.pole_hinge.limit_impedance": 0.95})
    pole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pole")
    assert m.body_inertia[pole] == pytest.approx(before[0][pole] * 2.0 * 2.0)
    assert m.body_ipos[pole, 2] == pytest.approx(before[2][pole, 2] + 0.05)
    floor, hinge = m.geom("floor").id, m.joint("pole_hinge").id
    # dmax moves to the knob's value; dmin keeps its ratio to dmax (0.9 / 0.95 for the floor).
    assert m.geom_solimp[floor, :2] == pytest.approx([0.99 * 0.9 / 0.95, 0.99])
    assert m.jnt_solimp[hinge, :2] == pytest.approx([0.95, 0.95])
    twin.set_knobs({})
    now = m.body_inertia, m.geom_solref, m.body_ipos, m.geom_solimp, m.jnt_solimp
    for current, then in zip(now, before, strict=True):
        assert np.array_equal(current, then)


def test_restitution_maps_to_a_damping_ratio() -> None:
    for e in (0.1, 0.5, 0.9):
        assert dampratio_to_restitution(restitution_to_dampratio(e, 1.0)) == pytest.approx(e)
    assert restitution_to_dampratio(0.0, 1.0) == 1.0


def test_patched_mjcf_reproduces_the_knobs(robot: RobotBinding, twin: MuJoCoTwin, suite3) -> None:  # noqa: ANN001
    knobs = {"joint.pole_hinge.damping": 0.05, "joint.pole_hinge.friction": 0.01, "geom.floor.friction": 0.7,
             "body.pole.mass": 0.25, "body.pole.inertia_scale": 1.2, "body.pole.com_offset_z": 0.03,
             "geom.wheel1_geom.solref_timeconst": 0.03, "geom.floor.impedance": 0.99,
             "joint.pole_hinge.limit_impedance": 0.97, "motor.wheel1.max_torque": 1.5,
             "motor.wheel2.max_velocity": 20.0, "motor.wheel3.gain": 1.1}
    result = patch_mjcf(robot.model_path("mujoco"), knobs)
    assert "motor.wheel3.gain" in result.not_applied and "body.pole.mass" in result.applied
    assert len(result.applied) == len(set(result.applied))
    assert result.text is not None and "dualtwin.knobs" in result.text
    patched = MuJoCoTwin(mujoco.MjSpec.from_string(result.text), 0.032)
    a = simulate_twin(robot, twin, suite3, knobs)
    b = simulate_twin(robot, patched, suite3, {"motor.wheel3.gain": 1.1})
    for sid in a:
        for name, series in a[sid].series.items():
            assert np.max(np.abs(series.y - b[sid].series[name].y)) < 1e-4, (sid, name)


def test_physics_substeps_change_the_fall_and_patch_into_the_timestep(robot: RobotBinding, twin: MuJoCoTwin,
                                                                       suite3) -> None:  # noqa: ANN001
    knob = twin.knobs()["physics.substeps"]
    assert (knob.nominal, knob.lower, knob.upper, knob.unit) == (16, 4, 32, "steps")  # 2 ms nominal, 8 ms lowest

    def fall(steps: int | None) -> list[float]:
        twin.set_knobs({} if steps is None else {"physics.substeps": steps})
        twin.reset(0)
        twin.set_joint_state("pole_hinge", position=0.2)
        angles = []
        for _ in range(15):
            twin.step()
            angles.append(twin.joint_position("pole_hinge"))
        return angles

    nominal, coarse = fall(None), fall(4)
    assert twin.model.opt.timestep == pytest.approx(0.008)
    # Semi-implicit Euler at 8 ms leads the 2 ms solution on the unstable fall (the Webots twin's bias).
    assert coarse[10] > nominal[10] + 1e-3
    assert fall(None) == nominal and twin.model.opt.timestep == 0.002  # back to nominal, bit for bit
    # The wheel servo keeps its stiffness per control period: a commanded speed is reached at either step.
    for steps in (4, 16):
        twin.set_knobs({"physics.substeps": steps})
        twin.reset(0)
        twin.command("wheel1", "velocity", 5.0)
        twin.step()
        assert twin.joint_velocity("wheel1_hinge") == pytest.approx(5.0, rel=0.05)
    result = patch_mjcf(robot.model_path("mujoco"), {"physics.substeps": 4}, control_period=0.032)
    assert result.applied == ["physics.substeps"] and result.text is not None
    patched = MuJoCoTwin(mujoco.MjSpec.from_string(result.text), 0.032)
    assert patched.model.opt.timestep == pytest.approx(0.008)
    a = simulate_twin(robot, twin, suite3, {"physics.substeps": 4})
    b = simulate_twin(robot, patched, suite3, {})
    for sid in a:
        for name, series in a[sid].series.items():
            assert np.max(np.abs(series.y - b[sid].series[name].y)) < 1e-9, (sid, name)
    assert "physics.substeps" in patch_mjcf(robot.model_path("mujoco"), {"physics.substeps": 4}).not_applied


def test_quantization_knob_follows_webots_resolution_rule(twin: MuJoCoTwin) -> None:
    # webots-devices.md §0.4: discretize(v, r) = (int)(v/r + 0.5)·r, truncation toward zero, so negatives are not
    # rounded to the nearest multiple. With r = 0.1 rad: -0.17 rad is -1.7 steps, int(-1.2) = -1 -> -0.1 rad
    # (rounding would give -0.2); +0.17 rad is int(2.2) = 2 -> 0.2 rad.
    twin.set_knobs({"sensor.pole sensor.quantization": 0.1})
    for angle, expected in ((-0.17, -0.1), (0.17, 0.2), (-0.04, 0.0)):
        twin.reset(0)
        twin.set_joint_state("pole_hinge", position=angle)
        assert twin.sensor("pole sensor") == pytest.approx(expected, abs=1e-12), angle
