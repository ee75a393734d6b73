"""Radar: which Solids with a radarCrossSection it sees (range, field of view by the target's extent,
occlusion) and what it reports (distance, azimuth, radial speed, received power by the radar equation)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world


def _robot(targets: str, radar: str = "") -> Robot:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 }}
{targets}
Robot {{ children [ Radar {{ name "radar" minRange 0.5 maxRange 10 {radar} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Robot(simulation=sim, robot_node=sim.robots[0].node)


def _targets(robot: Robot) -> list:
    radar = robot.getDevice("radar")
    radar.enable(16)
    robot.step(16)
    assert radar.getNumberOfTargets() == len(radar.getTargets())
    return radar.getTargets()


def _box(x: float, y: float, z: float = 0.0, rcs: float = 1.0, size: str = "0.1 0.1 0.1", extra: str = "") -> str:
    return f"Solid {{ translation {x} {y} {z} radarCrossSection {rcs} boundingObject Box {{ size {size} }} {extra} }}"


def test_target_ahead_distance_azimuth_and_power() -> None:
    y = 2 * math.tan(0.3)  # 0.3 rad to the left, inside the default ±0.39 rad
    (t,) = _targets(_robot(_box(2, y)))
    r = math.hypot(2, y)
    assert t.distance == pytest.approx(r, abs=1e-9)
    assert t.azimuth == pytest.approx(0.3, abs=1e-9)
    assert t.speed == pytest.approx(0.0, abs=1e-9)
    wavelength = 299792458.0 / 24e9
    # Pt 1 dBm + 2 × 20 dBi + radar equation with σ = 1 m²
    expected = 1 + 40 + 10 * math.log10(wavelength**2 / ((4 * math.pi) ** 3 * r**4))
    assert t.receiver_power == pytest.approx(expected, abs=1e-9)


def test_outside_field_of_view_range_or_without_cross_section() -> None:
    assert _targets(_robot(_box(2, 2 * math.tan(0.5)))) == []  # 0.5 rad > 0.39 rad
    assert _targets(_robot(_box(11, 0))) == []  # beyond maxRange
    assert _targets(_robot(_box(0.3, 0))) == []  # closer than minRange
    assert _targets(_robot(_box(2, 0, rcs=0))) == []  # no radarCrossSection: not a target
    assert len(_targets(_robot(_box(2, 0)))) == 1  # control


def test_a_tall_target_centred_above_the_beam_is_seen_by_its_extent() -> None:
    # centre 0.5 m above the beam (14° > 0.05 rad half vertical fov) but the box reaches down through it
    assert len(_targets(_robot(_box(2, 0, 0.5, size="0.1 0.1 1.2")))) == 1
    assert _targets(_robot(_box(2, 0, 0.5, size="0.1 0.1 0.2"))) == []


def test_occlusion_hides_a_target_behind_a_wall() -> None:
    scene = _box(3, 0) + "\nSolid { translation 1.5 0 0 boundingObject Box { size 0.05 1 1 } }"
    assert len(_targets(_robot(scene))) == 1
    assert _targets(_robot(scene, "occlusion TRUE")) == []


def test_radial_speed_of_a_receding_target() -> None:
    moving = _box(2, 0, extra="physics Physics { mass 1 } linearVelocity 1.5 0 0")
    (t,) = _targets(_robot(moving))
    assert t.speed == pytest.approx(1.5, abs=1e-6)
    assert t.distance == pytest.approx(2 + 1.5 * 0.016, abs=1e-6)
    # minAbsoluteRadialSpeed drops slower targets
    assert _targets(_robot(moving, "minAbsoluteRadialSpeed 2")) == []


def test_api_values() -> None:
    radar = _robot("", "horizontalFieldOfView 1.2 verticalFieldOfView 0.3").getDevice("radar")
    assert (radar.getMinRange(), radar.getMaxRange()) == (0.5, 10.0)
    assert (radar.getHorizontalFov(), radar.getVerticalFov()) == (1.2, 0.3)
    assert (radar.min_range, radar.max_range, radar.horizontal_fov, radar.vertical_fov) == (0.5, 10.0, 1.2, 0.3)


def test_targets_reach_a_controller_process_by_value(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``getTargets()`` in a real controller process returns RadarTarget records with their fields."""
    world = tmp_path / "worlds" / "radar.wbt"
    script = tmp_path / "controllers" / "probe" / "probe.py"
    world.parent.mkdir(parents=True)
    script.parent.mkdir(parents=True)
    world.write_text(
        "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 16 gravity 0 }\n"
        + _box(2, 0)
        + '\nRobot { children [ Radar { name "radar" minRange 0.5 maxRange 10 } ] controller "probe" }\n'
    )
    script.write_text(
        "from controller import Robot\nr = Robot()\nradar = r.getDevice('radar')\nradar.enable(16)\nr.step(16)\n"
        "t = radar.getTargets()[0]\nprint('TARGET', type(t).__name__, t.distance, t.azimuth)\n"
    )
    assert run_world(world, None, 0.048) == 0
    out = capsys.readouterr()
    assert "TARGET RadarTarget 2.0 0.0" in out.out, out.err[-2000:]
