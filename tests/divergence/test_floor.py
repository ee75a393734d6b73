"""Reproducibility floor, floor ratio, resolution and ranking by physical significance (issue 15.4, 15.5)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from dualtwin.divergence import compare_runs, write_report
from dualtwin.divergence.floor import ensemble_floor, floor_verdict, judge_against_floor, simulate_floor
from dualtwin.divergence.metrics import compare_channel, default_resolution, predictability_horizon
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.ensemble import EnsembleRun, make_spec
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin
from tests.support.rundirs import fabricate_ensemble

DT = 0.032
T = np.arange(1, 95) * DT  # 3 s logged after each control period


def chaotic(t: np.ndarray, eps: float) -> np.ndarray:
    """A pole that falls identically, then bounces on its stop in a way a tiny ``eps`` changes."""
    fall = np.minimum(0.001 * np.exp(4.0 * t), 1.0)
    bounce = np.where(t > 1.75, 0.005 * eps * 1e6 * np.sin(40 * (t - 1.75)), 0.0)
    return fall - bounce


def test_default_resolution_by_unit() -> None:
    assert default_resolution("m") == 1e-3 and default_resolution("rad") == 1e-3
    assert default_resolution("m/s") == 1e-2 and default_resolution("furlong") == 1e-3


def test_floor_of_a_chaotic_ensemble() -> None:
    members = [(T, chaotic(T, e)) for e in (0.0, 1e-6, -1e-6, 3e-7)]  # member 0: no bounce
    floor = ensemble_floor(members, resolution=1e-3, threshold=0.99)
    assert floor.members == 4 and floor.rmse > 0 and floor.dtw > 0
    # The members agree until the first impact: that is where prediction stops.
    assert floor.horizon_s is not None and 1.75 < floor.horizon_s < 1.75 + 3 * DT
    assert floor.crossing_spread_s == pytest.approx(0.0)
    spread, horizon = predictability_horizon(T, np.vstack([y for _, y in members]), 1.0)
    assert horizon is None and spread == pytest.approx(floor.spread)
    with pytest.raises(ValueError, match="at least 2 members"):
        ensemble_floor(members[:1], resolution=1e-3)


def test_floor_ratio_in_words() -> None:
    members = [(T, chaotic(T, e)) for e in (0.0, 1e-6, -1e-6)]
    floor = ensemble_floor(members, resolution=1e-3)
    like_member = compare_channel(T, chaotic(T, 0.0), T, chaotic(T, 5e-7), resolution=1e-3)
    judged = judge_against_floor(like_member, floor, None)
    assert judged.ratio is not None and judged.ratio < 1.5
    assert judged.verdict.startswith("as close as the physics allows")
    assert "stop being predictable at t = 1.7" in judged.verdict
    late = compare_channel(T, chaotic(T, 0.0), T, chaotic(T - 0.3, 0.0), resolution=1e-3)
    far = judge_against_floor(late, floor, None)
    assert far.ratio is not None and far.ratio > 3 and "a modelling difference, not chaos" in far.verdict
    assert floor_verdict(2.0).startswith("near the reproducibility floor")


def test_differences_below_the_resolution_are_no_sign_inversion() -> None:
    """The bundled CartPole case: a 13 µm cart wobble that looks inverted is not a finding."""
    a = 13e-6 * np.sin(2 * T)
    plain = compare_channel(T, a, T, -a)
    assert plain.sign_inverted  # without a resolution the shape alone says "inverted"
    judged = compare_channel(T, a, T, -a, resolution=1e-3)
    assert not judged.sign_inverted and judged.significance is not None and judged.significance < 1
    big = compare_channel(T, 1000 * a, T, -1000 * a, resolution=1e-3)
    assert big.sign_inverted and (big.significance or 0) > 1
    with pytest.raises(ValueError, match="resolution must be positive"):
        compare_channel(T, a, T, a, resolution=0.0)


def test_compare_judges_against_the_floor_and_ranks_by_significance(tmp_path: Path) -> None:
    cart = 0.2 * np.sin(T)
    members_a = [{"pole_angle_rad": chaotic(T, e), "cart_pos_m": cart + 5e-6 * e * 1e6} for e in (0, 1e-6, -1e-6)]
    a = fabricate_ensemble(tmp_path / "a", members_a, "webots", T)
    same = fabricate_ensemble(tmp_path / "b", [{"pole_angle_rad": chaotic(T, 5e-7), "cart_pos_m": cart - 2e-5}],
                              "mujoco", T)
    comp = compare_runs(a, same)
    judged = comp.scenarios[0].floors["pole_angle_rad"]
    assert judged.floor_b is None and judged.floor_a is not None and judged.floor_a.members == 3
    assert judged.ratio is not None and judged.ratio < 1.5 and "as close as the physics allows" in judged.verdict
    # Within the floor and below 1 mm: nothing ranks.
    assert comp.contributions() == []
    saved = comp.to_dict()["scenarios"][0]["floors"]["pole_angle_rad"]
    assert saved["verdict"] == judged.verdict and saved["floor_a"]["members"] == 3
    assert type(comp).from_dict(comp.to_dict()).scenarios[0].floors["pole_angle_rad"] == judged
    both = compare_runs(a, a).scenarios[0].floors["pole_angle_rad"]  # two ensembles: both floors, no divergence
    assert both.floor_a == both.floor_b == judged.floor_a and both.ratio == 0.0
    page = write_report(comp, tmp_path / "report").read_text()
    assert "Against the reproducibility floor" in page and "as close as the physics allows" in page

    late = fabricate_ensemble(tmp_path / "late", [{"pole_angle_rad": chaotic(T - 0.3, 0.0), "cart_pos_m": cart}],
                              "mujoco", T)
    ranked = compare_runs(a, late).contributions()
    assert [(c.scenario_id, c.channel) for c in ranked] == [("00_fall", "pole_angle_rad")]
    assert ranked[0].share == pytest.approx(1.0)


def test_member_paths_stay_in_the_run(tmp_path: Path) -> None:
    a = fabricate_ensemble(tmp_path / "a", [{"pole_angle_rad": T, "cart_pos_m": T}] * 2, "webots", T)
    manifest = json.loads((a / "manifest.json").read_text())
    manifest["scenarios"][0]["members"][0]["ground_truth"] = "../../etc/passwd"
    (a / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DualtwinError, match=r"members\[0\]: ground_truth log '../../etc/passwd' is outside"):
        compare_runs(a, a)


SUITE = {"suite_name": "floor", "global_settings": {"TIME_STEP": 32},
         "scenarios": [{"name": "fall", "duration_s": 3.0, "initial_angle": 0.001}]}


def test_real_twin_floor_and_a_damped_pole(tmp_path: Path) -> None:
    """MuJoCo twin: another 1 µrad member is at the floor; a damped pole is far above it and ranks first."""
    robot = resolve_robot("cartpole")
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps(SUITE))
    spec = make_spec(4, {"initial_angle": 1e-6}, robot, seed=0)
    EnsembleRun(suite, "mujoco", robot, tmp_path / "ens", spec, executor="serial").run()
    shifted = json.loads(json.dumps(SUITE))
    shifted["scenarios"][0]["initial_angle"] = 0.001 + 5e-7
    (tmp_path / "shifted.json").write_text(json.dumps(shifted))
    SuiteRun(tmp_path / "shifted.json", "mujoco", robot, tmp_path / "member").run()
    twin = make_twin("mujoco", robot, 0.032)
    twin.set_knobs({"joint.pole_hinge.damping": 0.08})
    SuiteRun(suite, "mujoco", robot, tmp_path / "damped", twin=twin).run()

    near = compare_runs(tmp_path / "ens", tmp_path / "member").scenarios[0].floors["pole_angle_rad"]
    far = compare_runs(tmp_path / "ens", tmp_path / "damped")
    judged = far.scenarios[0].floors["pole_angle_rad"]
    assert near.ratio is not None and judged.ratio is not None
    assert near.ratio < 3 < judged.ratio
    assert near.horizon_s is not None and near.horizon_s > 1.0  # predictable until the pole lands
    assert (far.contributions()[0].channel or "").removeprefix("onboard/") == "pole_angle_rad"

    # The public floor function (for alignment goals) gives the stored ensemble's floor.
    floors = simulate_floor(robot, "mujoco", suite, {"initial_angle": 1e-6}, members=4, executor="serial",
                            channels=["pole_angle_rad"])
    assert floors["00_fall"]["pole_angle_rad"] == judged.floor_a


def test_declared_resolution_travels_with_the_run(tmp_path: Path, make_run: Callable[..., Path]) -> None:
    binding = resolve_robot("cartpole").path.read_text()
    custom = tmp_path / "robot"
    custom.mkdir()
    text = binding.replace("cart_pos_m: {body: cart, axis: x, quantity: position, unit: m}",
                           "cart_pos_m: {body: cart, axis: x, quantity: position, unit: m, resolution: 0.05}")
    for line in ("model: cartpole.xml", "model: cartpole.wbt"):
        text = text.replace(line, f"model: {resolve_robot('cartpole').root / line.split(': ')[1]}")
    (custom / "binding.yaml").write_text(text)
    robot = resolve_robot(str(custom / "binding.yaml"))
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps({"suite_name": "r", "scenarios": [
        {"name": "drive", "duration_s": 0.5, "wheel_velocity": 2.0}]}))
    SuiteRun(suite, "mujoco", robot, tmp_path / "a").run()
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["channels"]["cart_pos_m"]["resolution"] == 0.05
    assert "resolution" not in manifest["channels"]["pole_angle_rad"]
    comp = compare_runs(tmp_path / "a", tmp_path / "a")
    assert comp.settings["resolutions"]["cart_pos_m"] == 0.05
    assert comp.settings["resolutions"]["pole_angle_rad"] == 1e-3
    assert compare_runs(tmp_path / "a", tmp_path / "a", resolutions={"cart_pos_m": 0.2}).scenarios[0] \
        .channels["cart_pos_m"].resolution == 0.2


def test_predictable_scenarios_read_against_the_resolution() -> None:
    """Members that never spread beyond the resolution: the verdict reads the divergence against it."""
    smooth = [(T, 0.1 * T + e) for e in (0.0, 1e-9, -1e-9)]
    floor = ensemble_floor(smooth, resolution=1e-3)
    assert floor.horizon_s is None
    apart = judge_against_floor(compare_channel(T, 0.1 * T, T, 0.1 * T + 0.05, resolution=1e-3), floor, None)
    assert apart.ratio is not None and apart.ratio > 1e6  # a ratio to numerical noise says nothing ...
    assert "× the channel's resolution in a predictable scenario" in apart.verdict  # ... this does
    same = judge_against_floor(compare_channel(T, 0.1 * T, T, 0.1 * T + 1e-4, resolution=1e-3), floor, None)
    assert same.verdict.startswith("agree within the channel's resolution")
