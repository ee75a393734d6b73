"""The Webots reference worlds (``shared/fixtures/webots``) run on the ODE twin with Webots-style controllers."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from dualtwin.webots import load_world
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import find_controllers, run_controllers, run_world

CONTROLLERS = Path(__file__).resolve().parent / "controllers"


def _project(tmp_path: Path, world: Path, controller: str) -> Path:
    """Lay out ``worlds/X.wbt`` beside ``controllers/NAME/NAME.py`` as in a Webots project."""
    (tmp_path / "worlds").mkdir()
    shutil.copy(world, tmp_path / "worlds" / world.name)
    shutil.copytree(CONTROLLERS / controller, tmp_path / "controllers" / controller)
    return tmp_path / "worlds" / world.name


def test_inverted_pendulum_stays_up_for_30_s(
    webots_fixtures: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    world = _project(tmp_path, webots_fixtures / "inverted_pendulum.wbt", "inverted_pendulum")
    code = run_world(world, None, 30.0)  # controller found through the robot's controller field
    out = capsys.readouterr().out
    assert code == 0, out
    match = re.search(r"time=([\d.]+) max_abs_theta=([\d.]+) max_abs_x=([\d.]+)", out)
    assert match is not None, out
    time, theta, x = (float(v) for v in match.groups())
    assert time == pytest.approx(30.0, abs=0.04)
    assert theta < 0.3  # the pole never falls (a fallen pole lies beyond ±1.2 rad)
    assert x > 0.1  # the force actually moved the cart


def test_inverted_pendulum_world_model(webots_fixtures: Path) -> None:
    sim = Simulation(load_world(webots_fixtures / "inverted_pendulum.wbt"))
    assert [round(b.mass, 6) for b in sim.bodies] == [30.0, 1.0, 0.05]
    slider, hip = sim.joints
    assert (slider.kind, hip.kind) == ("slider", "hinge")
    assert hip.positions[0] == pytest.approx(0.000161402)
    # the floor PROTO's material is "default": the robot_basis/floor ContactProperties never applies
    cart = sim.bodies[1].root
    assert cart.material == "robot_basis"
    assert sim.contact_properties_for("robot_basis", "default") is None


def test_four_wheels_robots_drive_forward(webots_fixtures: Path) -> None:
    path = webots_fixtures / "four_wheels.wbt"
    sim = Simulation(load_world(path))
    assert sorted(r.name for r in sim.robots) == ["ackerman", "four_wheels", "omni_wheels"]
    start = {r.name: sim.solid_world_pose(r.solid).t for r in sim.robots}
    script = CONTROLLERS / "four_wheels" / "four_wheels.py"
    specs = find_controllers(sim, path, script)
    assert len(specs) == 3  # the override replaces the "four_wheels" controller of all three robots
    assert run_controllers(sim, specs, 3.0) == 0
    assert sim.time == pytest.approx(3.0, abs=0.016)
    for robot in sim.robots:
        end = sim.solid_world_pose(robot.solid).t
        dx, dy = end[0] - start[robot.name][0], end[1] - start[robot.name][1]
        # hinge axes are -x, so positive wheel speeds roll the robots toward +y
        assert dy > (0.8 if robot.name != "omni_wheels" else 0.3), robot.name
        assert abs(dx) < 0.1, robot.name
        assert abs(end[2] - 0.08) < 0.01  # resting on the arena floor on r = 0.08 wheels
    sim.close()
