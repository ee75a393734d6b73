"""The paper-faithful CartPole (cartpole_paper): the paper's chassis, stops and drive sign in both twins, and
both twins agree on its suite as closely as they do on the bundled CartPole."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from dualtwin.divergence.comparison import compare_runs
from dualtwin.divergence.runs import load_run
from dualtwin.robots.binding import BUNDLED, bundled_robots, resolve_robot
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin

WHEELS = ["wheel1", "wheel2", "wheel3", "wheel4"]


def test_it_is_bundled_with_the_papers_facts() -> None:
    assert {"cartpole", "cartpole_paper"} <= set(bundled_robots())
    binding = resolve_robot("cartpole_paper")
    mjcf = ET.parse(binding.model_path("mujoco")).getroot()
    chassis = mjcf.find(".//geom[@name='chassis']")
    assert chassis is not None and float(chassis.get("mass", "0")) == 2.0
    assert [2 * float(v) for v in chassis.get("size", "").split()] == pytest.approx([0.2, 0.05, 0.08])
    hinge = mjcf.find(".//joint[@name='pole_hinge']")
    assert hinge is not None and hinge.get("range") == "-1.3 1.3"
    text = binding.model_path("webots").read_text()
    assert "size 0.2 0.05 0.08" in text and "minStop -1.3" in text and "maxStop 1.3" in text
    # The robot's own Physics (its chassis) is the last in the file: after the wheels' and the pole's.
    assert text.rstrip().rsplit("physics Physics", 1)[1].split("}")[0].split() == ["{", "density", "-1", "mass", "2"]


@pytest.mark.parametrize("twin_name", ["webots", "mujoco"])
def test_the_drive_sign_is_the_papers(twin_name: str) -> None:
    # The same positive wheel command drives the bundled cart towards +x and the paper's towards -x.
    ends = {}
    for robot in ("cartpole", "cartpole_paper"):
        twin = make_twin(twin_name, resolve_robot(robot), 0.032)
        try:
            twin.reset(seed=0)
            start = float(twin.body_position("cart")[0])
            for _ in range(30):
                for w in WHEELS:
                    twin.command(w, "velocity", 5.0)
                twin.step()
            ends[robot] = float(twin.body_position("cart")[0]) - start
        finally:
            twin.close()
    assert ends["cartpole"] > 0.1
    assert ends["cartpole_paper"] < -0.1


def _suite_runs(robot: str, root: Path) -> dict[str, Path]:
    runs = {}
    for twin in ("webots", "mujoco"):
        runs[twin] = root / robot / twin
        SuiteRun(BUNDLED / robot / "suite.json", twin, resolve_robot(robot), runs[twin]).run()
    return runs


def _worst(comparison: object, channel: str) -> float:
    return max(sc.channels[channel].max_abs_error for sc in comparison.scenarios)  # type: ignore[attr-defined]


def test_both_twins_run_its_suite_and_agree_as_on_the_bundled_cartpole(tmp_path: Path) -> None:
    paper = _suite_runs("cartpole_paper", tmp_path)
    ours = _suite_runs("cartpole", tmp_path)
    c_paper = compare_runs(paper["webots"], paper["mujoco"])
    c_ours = compare_runs(ours["webots"], ours["mujoco"])
    assert all(sc.status_a == sc.status_b == "completed" for sc in c_paper.scenarios)
    assert c_paper.within_tolerance
    for channel in ("pole_angle_rad", "cart_pos_m", "onboard/cart_pos_m"):
        assert _worst(c_paper, channel) <= 2.0 * _worst(c_ours, channel), channel
    assert c_paper.summary_score is not None and c_ours.summary_score is not None
    assert c_paper.summary_score <= 1.5 * c_ours.summary_score
    # The pole falls from 1 rad onto the paper's 1.3 rad stop (ours rests at 1 rad) in both twins.
    for twin in ("webots", "mujoco"):
        run = load_run(paper[twin])
        angle = run.series("01_Step_Response_2")["pole_angle_rad"].y
        assert np.max(angle) == pytest.approx(1.3, abs=0.02)  # a small overshoot on impact
        assert angle[-1] == pytest.approx(1.3, abs=0.005)
    # On-board odometry follows the drive sign: it reads the cart's ground-truth position.
    run = load_run(paper["mujoco"])
    series = run.series("02_Step_Response_3")
    assert series["onboard/cart_pos_m"].y[-1] == pytest.approx(series["cart_pos_m"].y[-1], abs=0.05)
