"""The bundled CartPole and the Webots fixture worlds convert and compile on the first try, and the converted
CartPole behaves like the hand-written cartpole.xml on the bundled suite."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from dualtwin.convert import convert_world
from dualtwin.convert.faithfulness import (
    converted_vs_mjcf,
    converted_vs_webots,
    prepare_fixture,
    run_pair,
    webots_twin_available,
)
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.twins import make_twin

CARTPOLE = BUNDLED / "cartpole"


def _check(conv, bodies: int) -> None:  # type: ignore[no-untyped-def]
    model = conv.compile()
    assert model.nbody == bodies
    assert not [f for f in conv.lint if f.level == "error"], conv.lint
    smoke = conv.smoke()
    assert smoke.ok, smoke.message


def test_bundled_cartpole_converts_with_the_same_names(tmp_path: Path) -> None:
    conv = convert_world(CARTPOLE / "cartpole.wbt")
    _check(conv, 7)
    model = conv.compile()
    for joint in ("pole_hinge", "wheel1_hinge", "wheel4_hinge", "cart_free"):
        assert model.joint(joint) is not None
    assert [model.actuator(i).name for i in range(model.nu)] == ["wheel1", "wheel2", "wheel3", "wheel4"]
    assert model.body("cart").mass[0] == pytest.approx(1.0)
    assert model.body("pole").mass[0] == pytest.approx(0.2)
    conv.write(tmp_path / "cartpole.xml", tmp_path / "binding.yaml")
    binding = load_binding(tmp_path / "binding.yaml")
    assert binding.spec.twins["webots"].robot == "cart"
    assert binding.spec.actions["wheel_velocity"].actuators == ["wheel1", "wheel2", "wheel3", "wheel4"]
    assert "pole_hinge_angle_rad" in binding.spec.ground_truth
    assert (tmp_path / binding.spec.twins["webots"].model).resolve() == (CARTPOLE / "cartpole.wbt").resolve()
    twin = make_twin("mujoco", binding, 0.032)
    for wheel in ("wheel1", "wheel2", "wheel3", "wheel4"):
        twin.command(wheel, "velocity", 1.0)
    for _ in range(5):
        twin.step()
    assert twin.joint_velocity("wheel1_hinge") == pytest.approx(1.0, abs=0.05)


@pytest.mark.parametrize(("robot", "motors"), [("FOUR_WHEELS", 4), ("ACKERMAN", 6), ("OMNI_WHEELS", 4)])
def test_four_wheels_robots_convert(webots_fixtures: Path, robot: str, motors: int) -> None:
    conv = convert_world(webots_fixtures / "four_wheels.wbt", robot)
    # Every conversion holds the three robots (dualtwin.convert.world_robots): the world body, FOUR_WHEELS' and
    # OMNI_WHEELS' chassis and four wheels, ACKERMAN's chassis, two steering knuckles and four wheels: 1 + 5 + 5 + 7.
    _check(conv, 18)
    assert len(conv.motors) == motors  # its own only (ACKERMAN's four wheels and two steering motors); 14 in the model
    assert conv.compile().nu == 14
    assert conv.compile().body(robot).mass[0] == pytest.approx({"FOUR_WHEELS": 8.0, "ACKERMAN": 8.0, "OMNI_WHEELS": 9.0}[robot])


def test_inverted_pendulum_converts(webots_fixtures: Path) -> None:
    conv = convert_world(webots_fixtures / "inverted_pendulum.wbt")
    _check(conv, 4)
    model = conv.compile()
    assert model.qpos0[model.jnt_qposadr[model.joint("HIP").id]] == pytest.approx(0.000161402)
    assert model.body("THIGH_BB").mass[0] == pytest.approx(0.05)
    assert model.body("THIGH_BB").ipos == pytest.approx([0, 0.061, -0.27])
    assert model.actuator("horizontal_motor").forcerange == pytest.approx([-40, 40])


def test_converted_cartpole_behaves_like_cartpole_xml(tmp_path: Path) -> None:
    report = converted_vs_mjcf(CARTPOLE / "cartpole.wbt", CARTPOLE / "binding.yaml", CARTPOLE / "suite.json",
                               tmp_path, report=False)
    crossings = {(c.scenario, c.channel): c for c in report.crossings}
    free_fall = crossings[("00_Step_Response", "pole_angle_rad")]
    assert free_fall.a_s is not None and free_fall.b_s is not None
    assert abs(free_fall.diff_s or 0.0) < 0.005  # pole-fall crossing within a few ms
    assert not report.one_sided_crossings()
    # Driven scenarios also depend on wheel contacts (Webots softERP/CFM vs the hand-tuned solref).
    worst = report.max_crossing_diff()
    assert worst is not None and worst < 0.05
    assert all(sc.status_a == sc.status_b for sc in report.comparison.scenarios)


@pytest.mark.parametrize("stem", ["four_wheels", "inverted_pendulum"])
def test_fixture_suites_run_on_the_converted_model(webots_fixtures: Path, tmp_path: Path, stem: str) -> None:
    binding, suite = prepare_fixture(webots_fixtures / f"{stem}.wbt", tmp_path / "model")
    data = yaml.safe_load(binding.path.read_text())
    assert data["onboard"]  # position sensors were added to the world copy
    report = run_pair(binding, "mujoco", binding, "mujoco", suite, tmp_path / "cmp", report=False)
    assert report.comparison.summary_score == pytest.approx(0.0, abs=1e-9)
    assert all(sc.status_a == "completed" for sc in report.comparison.scenarios)


def test_against_the_webots_twin(webots_fixtures: Path, tmp_path: Path) -> None:
    assert webots_twin_available()
    report = converted_vs_webots(CARTPOLE / "cartpole.wbt", tmp_path / "cartpole", suite=CARTPOLE / "suite.json",
                                 base_binding=CARTPOLE / "binding.yaml", report=False)
    free_fall = next(c for c in report.crossings if c.scenario == "00_Step_Response" and c.channel == "pole_angle_rad")
    assert free_fall.diff_s is not None and abs(free_fall.diff_s) < 0.1
    for stem in ("four_wheels", "inverted_pendulum"):
        rep = converted_vs_webots(webots_fixtures / f"{stem}.wbt", tmp_path / stem, report=False)
        assert rep.comparison.summary_score is not None
