"""The bundled Pioneer 3-AT-like robot: both twins agree on skid-steer turning and on the slope."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from dualtwin.align.patch import patch_mjcf
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.twins import Twin, make_twin
from dualtwin.twins.mujoco import MuJoCoTwin

WHEELS = ["front left wheel", "front right wheel", "back left wheel", "back right wheel"]
WHEEL_GEOMS = ["FRONT_LEFT_WHEEL_SOLID", "FRONT_RIGHT_WHEEL_SOLID", "BACK_LEFT_WHEEL_SOLID", "BACK_RIGHT_WHEEL_SOLID"]


@pytest.fixture(scope="module")
def pioneer() -> RobotBinding:
    return resolve_robot("pioneer3at")


def drive(twin: Twin, left: float, right: float, seconds: float, start_y: float = 0.0) -> tuple[np.ndarray, float]:
    """Hold wheel velocities (rad/s) for ``seconds``; the final position and heading."""
    twin.reset(0)
    if start_y:
        twin.set_body_position("pioneer", 1, start_y)
    for _ in range(round(seconds / twin.control_period)):
        for name, value in zip(WHEELS, (left, right, left, right), strict=True):
            twin.command(name, "velocity", value)
        twin.step()
    rotation = np.asarray(twin.body_orientation("pioneer"), dtype=float).reshape(3, 3)
    return np.asarray(twin.body_position("pioneer"), dtype=float), math.atan2(rotation[1, 0], rotation[0, 0])


def test_turning_in_place_agrees(pioneer: RobotBinding) -> None:
    # The MuJoCo wheel servo must resist contact friction inside the constraint solve, as ODE's motor row
    # does; when it did not, MuJoCo turned 0.90 rad against ODE's 2.25 rad.
    _, heading_webots = drive(make_twin("webots", pioneer), -2.0, 2.0, 3.0)
    _, heading_mujoco = drive(make_twin("mujoco", pioneer), -2.0, 2.0, 3.0)
    assert heading_webots > 1.5  # the wheels scrub: a no-slip turn would reach 3.4 rad
    assert heading_mujoco == pytest.approx(heading_webots, rel=0.08)


def test_both_twins_climb_the_ramp(pioneer: RobotBinding) -> None:
    ends = [drive(make_twin(name, pioneer), 2.5, 2.5, 6.0, start_y=3.0)[0] for name in ("webots", "mujoco")]
    for end in ends:
        assert end[2] > 0.15, "6 s at 2.5 rad/s end well up the 10 degree ramp"
        assert end[1] == pytest.approx(3.0, abs=0.01)
    assert ends[1][0] == pytest.approx(ends[0][0], rel=0.01)
    assert ends[1][2] == pytest.approx(ends[0][2], rel=0.03)


def test_wheel_radius_and_impratio_knobs(pioneer: RobotBinding) -> None:
    twin = MuJoCoTwin(pioneer.model_path("mujoco"), 0.032)
    knobs = twin.knobs()
    radius = knobs[f"geom.{WHEEL_GEOMS[0]}.radius"].nominal
    assert radius == pytest.approx(0.11)

    def second_second() -> float:
        """Distance covered between 1 s and 2 s at 2.5 rad/s (after the start-up transient)."""
        return float(drive(twin, 2.5, 2.5, 2.0)[0][0] - drive(twin, 2.5, 2.5, 1.0)[0][0])

    nominal = second_second()
    assert nominal == pytest.approx(2.5 * radius, rel=0.01)
    twin.set_knobs({f"geom.{g}.radius": 0.95 * radius for g in WHEEL_GEOMS} | {"option.impratio": 5.0})
    assert twin.model.opt.impratio == 5.0
    assert second_second() == pytest.approx(0.95 * nominal, rel=0.002)
    twin.set_knobs({})
    assert twin.model.opt.impratio == knobs["option.impratio"].nominal
    assert second_second() == nominal


def test_patched_mjcf_has_radius_and_impratio(pioneer: RobotBinding) -> None:
    result = patch_mjcf(pioneer.model_path("mujoco"), {f"geom.{WHEEL_GEOMS[0]}.radius": 0.1094,
                                                       "option.impratio": 3.0})
    assert result.text is not None and not result.not_applied
    model = mujoco.MjModel.from_xml_string(result.text)
    wheel = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, WHEEL_GEOMS[0])
    assert model.geom_size[wheel, 0] == pytest.approx(0.1094)
    assert model.opt.impratio == pytest.approx(3.0)
