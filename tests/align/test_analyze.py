"""Divergence analysis: each finding on constructed runs, bad input, determinism, simulated cases."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.align.analysis_report import write_analysis
from dualtwin.align.analyze import analyze_runs
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from tests.support.align_runs import record, write_suite
from tests.support.rundirs import fabricate_ensemble, fabricate_run

DT = 0.032
T = np.arange(1, 63) * DT  # ~2 s, logged after each control period like the runner
CHANNELS = {"pole_angle_rad": {"source": "ground_truth", "unit": "rad"},
            "cart_pos_m": {"source": "ground_truth", "unit": "m"}}
IDS = ["00_a", "01_b", "02_c"]

Signal = Callable[[np.ndarray], np.ndarray]


def cart(t: np.ndarray) -> np.ndarray:
    return 0.2 * np.sin(2 * np.pi * 0.7 * t) + 0.05 * t


def pole(t: np.ndarray, rate: float = 2.0) -> np.ndarray:
    return np.minimum(0.05 * np.exp(rate * t), 1.0)


def runs(tmp_path: Path, b_cart: dict[str, Signal] | Signal, b_pole: Signal = pole,
         statuses: dict[str, str] | None = None, ids: list[str] = IDS) -> tuple[Path, Path]:
    """Run A (the reference) and run B with the given B signals per scenario."""
    carts = b_cart if isinstance(b_cart, dict) else dict.fromkeys(ids, b_cart)
    a = {sid: {"pole_angle_rad": (T, pole(T)), "cart_pos_m": (T, cart(T))} for sid in ids}
    b = {sid: {"pole_angle_rad": (T, b_pole(T)), "cart_pos_m": (T, carts[sid](T))} for sid in ids}
    skip = tuple(sid for sid, s in (statuses or {}).items() if s == "unstable")
    return (fabricate_run(tmp_path / "a", a, twin="webots", channels=CHANNELS),
            fabricate_run(tmp_path / "b", b, channels=CHANNELS, statuses=statuses, skip_logs=skip))


def kinds(run_a: Path, run_b: Path) -> list[tuple[str, str | None]]:
    return [(f.kind, f.channel) for f in analyze_runs(run_a, run_b).findings]


def test_sign_inversion(tmp_path: Path) -> None:
    a, b = runs(tmp_path, {"00_a": lambda t: -cart(t), "01_b": lambda t: -cart(t), "02_c": cart})
    finding = analyze_runs(a, b).findings[0]
    assert (finding.kind, finding.channel) == ("sign_inversion", "cart_pos_m")
    assert finding.scenarios == ["00_a", "01_b"] and "2 of 3 scenarios" in finding.message
    assert "motor.*.gain" in finding.knobs and finding.evidence["00_a"]["correlation"] < -0.99


def test_lag(tmp_path: Path) -> None:
    a, b = runs(tmp_path, lambda t: cart(t - 3 * DT))
    found = [f for f in analyze_runs(a, b).findings if f.kind == "lag"]
    assert [f.channel for f in found] == ["cart_pos_m"]
    assert found[0].evidence["lag_periods"] == pytest.approx(3.0, abs=0.3)
    assert found[0].evidence["lagging"] == "B" and found[0].knobs[0] == "control.delay_periods"
    assert ("scale_mismatch", "cart_pos_m") not in kinds(a, b)


def test_scale_mismatch(tmp_path: Path) -> None:
    a, b = runs(tmp_path, lambda t: 1.5 * cart(t))
    found = [f for f in analyze_runs(a, b).findings if f.kind == "scale_mismatch"]
    assert [f.channel for f in found] == ["cart_pos_m"]
    assert found[0].evidence["slope"] == pytest.approx(1.5, rel=1e-6) and "1.5×" in found[0].message
    assert ("lag", "cart_pos_m") not in kinds(a, b)


def test_event_time(tmp_path: Path) -> None:
    a, b = runs(tmp_path, cart, b_pole=lambda t: pole(t, rate=2.5))
    found = [f for f in analyze_runs(a, b).findings if f.kind == "event_time"]
    assert [f.channel for f in found] == ["pole_angle_rad"]
    assert "earlier in B" in found[0].message and found[0].evidence["00_a"]["crossing_diff_s"] < -0.2


def test_endpoint(tmp_path: Path) -> None:
    a, b = runs(tmp_path, lambda t: cart(t) + 0.3 * (t / t[-1]) ** 4)
    found = [f for f in analyze_runs(a, b).findings if f.kind == "endpoint"]
    assert [f.channel for f in found] == ["cart_pos_m"]
    assert found[0].evidence["00_a"]["final_diff"] == pytest.approx(0.3)


def test_divergence_growing_with_an_input(tmp_path: Path) -> None:
    speeds = [1.0, 2.0, 4.0, 8.0]
    ids = [f"{i:02d}_v{int(v)}" for i, v in enumerate(speeds)]
    suite = {"suite_name": "growth", "scenarios": [{"name": f"v{int(v)}", "duration_s": 2.0, "initial_angle": 0.05,
                                                    "wheel_velocity": v} for v in speeds]}
    a_data = {sid: {"pole_angle_rad": (T, pole(T)), "cart_pos_m": (T, 0.04 * v * T)} for sid, v in zip(ids, speeds, strict=True)}
    b_data = {sid: {"pole_angle_rad": (T, pole(T)), "cart_pos_m": (T, 0.04 * v * T * (1 - 0.05 * v))}
              for sid, v in zip(ids, speeds, strict=True)}
    a = fabricate_run(tmp_path / "a", a_data, channels=CHANNELS)
    b = fabricate_run(tmp_path / "b", b_data, channels=CHANNELS)
    write_suite(a / "config" / "suite.json", suite)
    found = [f for f in analyze_runs(a, b).findings if f.kind == "input_growth"]
    assert len(found) == 1 and found[0].evidence["input"] == "wheel_velocity"
    assert found[0].evidence["spearman"] == pytest.approx(1.0) and found[0].scenarios == ["03_v8"]
    assert "grows with |wheel_velocity|" in found[0].message


def test_one_sided_instability_ranks_first(tmp_path: Path) -> None:
    a, b = runs(tmp_path, {"00_a": cart, "01_b": lambda t: -cart(t), "02_c": cart}, statuses={"02_c": "unstable"})
    findings = analyze_runs(a, b).findings
    assert findings[0].kind == "one_sided_instability" and findings[0].scenarios == ["02_c"]
    assert findings[1].kind == "sign_inversion"
    assert "twin B is numerically unstable in 1 of 3 scenarios" in findings[0].message


def test_mismatched_runs_work_on_what_both_have(tmp_path: Path) -> None:
    """Issue 15.2: fewer scenarios or channels on one side are left out with why; nothing shared is one line."""
    a, _ = runs(tmp_path / "x", lambda t: -cart(t))
    _, other = runs(tmp_path / "y", lambda t: -cart(t), ids=["00_a", "01_b", "03_d"])
    analysis = analyze_runs(a, other)
    assert [s.id for s in analysis.comparison.scenarios] == ["00_a", "01_b"]
    saved = analysis.to_dict()
    assert saved["left_out"]["scenarios"]["02_c"].startswith("only in A")
    assert saved["left_out"]["scenarios"]["03_d"].startswith("only in B")
    assert any(n.startswith("left out scenario 03_d: only in B") for n in analysis.notes)
    fewer = fabricate_run(tmp_path / "z", {sid: {"cart_pos_m": (T, -cart(T))} for sid in IDS},
                          channels={"cart_pos_m": CHANNELS["cart_pos_m"]})
    analysis = analyze_runs(a, fewer)
    assert analysis.comparison.channel_names == ["cart_pos_m"]
    assert list(analysis.to_dict()["left_out"]["channels"]) == ["pole_angle_rad"]
    pole_only = fabricate_run(tmp_path / "p", {sid: {"pole_angle_rad": (T, pole(T))} for sid in IDS},
                              channels={"pole_angle_rad": CHANNELS["pole_angle_rad"]})
    with pytest.raises(DualtwinError, match="no channel in common") as err:
        analyze_runs(fewer, pole_only)
    assert "\n" not in str(err.value)
    with pytest.raises(DualtwinError, match="both a robot and the twin"):
        analyze_runs(a, a, twin_b="mujoco")


def test_analysis_is_deterministic_and_written(tmp_path: Path) -> None:
    a, b = runs(tmp_path, lambda t: 1.3 * cart(t - 2 * DT), b_pole=lambda t: pole(t, 2.2))
    first, second = analyze_runs(a, b), analyze_runs(a, b)
    assert json.dumps(first.to_dict()) == json.dumps(second.to_dict())
    page = write_analysis(first, tmp_path / "out")
    assert page.name == "analysis.html" and "Findings" in page.read_text()
    saved = json.loads((tmp_path / "out" / "analysis.json").read_text())
    assert saved["config"]["run_a"] == str(a) and saved["findings"] == first.to_dict()["findings"]
    assert (tmp_path / "out" / "report.html").is_file()


def test_simulated_inverted_actuators_are_flagged(tmp_path: Path, robot: RobotBinding, suite3: Path,
                                                  nominal_run: Path) -> None:
    inverted = record(robot, suite3, tmp_path / "inverted", {f"motor.wheel{i}.gain": -1.0 for i in range(1, 5)})
    findings = analyze_runs(nominal_run, inverted).findings
    signs = {f.channel: f for f in findings if f.kind == "sign_inversion"}
    assert "cart_pos_m" in signs and findings[0].kind == "sign_inversion"
    assert signs["cart_pos_m"].scenarios == ["01_sine", "02_drive"]  # the free fall drives no motor


def test_sensitivities_of_another_twin_than_run_bs_are_refused(robot: RobotBinding, damped_ref: Path,
                                                                nominal_run: Path) -> None:
    """Run B was made by MuJoCo: asking the Webots twin's sensitivities is refused naming both (was a note)."""
    with pytest.raises(DualtwinError, match="run on the mujoco twin.*--target webots.*--target mujoco"):
        analyze_runs(damped_ref, nominal_run, robot=robot, twin_b="webots", knobs=["*"])


def test_sensitivity_names_the_damping(tmp_path: Path, robot: RobotBinding, damped_ref: Path,
                                       nominal_run: Path) -> None:
    analysis = analyze_runs(damped_ref, nominal_run, robot=robot, twin_b="mujoco",
                            knobs=["joint.pole_hinge.damping", "geom.floor.friction", "body.cart.mass"],
                            executor="process", workers=2)
    by_knob = {s.knob: s for s in analysis.sensitivity}
    assert set(by_knob) == {"joint.pole_hinge.damping", "geom.floor.friction", "body.cart.mass"}
    damping = by_knob["joint.pole_hinge.damping"]
    assert damping.best_direction == "increase" and damping.change["up"] < 0
    assert analysis.sensitivity[0].knob == "joint.pole_hinge.damping"
    events = [f for f in analysis.findings if f.kind == "event_time"]
    assert events and events[0].knobs[0] == "joint.pole_hinge.damping"
    assert "increase it" in events[0].message
    assert not analysis.notes  # the nominal twin reproduces run B exactly
    assert analysis.objective is not None and analysis.objective.total > 0


# ------------------------------------------------------------------ analyze on a recording (issue 15.3)
def recording(run: Path, out: Path, seed: int = 0) -> Path:
    """A hand-built recorded run of a twin run, as real logs come: only the paper's two channels, values
    rounded to 3 decimals, time stamps with up to 2 ms of jitter, ``kind: recorded`` and no twin name."""
    manifest = json.loads((run / "manifest.json").read_text())
    rng = np.random.default_rng(seed)
    scenarios = []
    for sc in manifest["scenarios"]:
        table = np.genfromtxt(run / sc["ground_truth"], names=True, delimiter="\t")
        t = table["time_s"] + rng.uniform(-0.002, 0.002, table.size)
        rel = f"scenarios/{sc['id']}/ground_truth.tsv"
        (out / rel).parent.mkdir(parents=True)
        rows = [f"{ti:.4f}\t{p:.3f}\t{c:.3f}" for ti, p, c in zip(t, table["pole_angle_rad"], table["cart_pos_m"],
                                                                   strict=True)]
        (out / rel).write_text("time_s\tpole_angle_rad\tcart_pos_m\n" + "\n".join(rows) + "\n")
        scenarios.append({"id": sc["id"], "index": sc["index"], "name": sc["name"], "status": sc["status"],
                          "ground_truth": rel})
    (out / "manifest.json").write_text(json.dumps({
        "kind": "recorded", "robot": manifest["robot"], "suite_name": manifest["suite_name"],
        "channels": {"pole_angle_rad": {"source": "ground_truth", "unit": "rad"},
                     "cart_pos_m": {"source": "ground_truth", "unit": "m"}},
        "scenarios": scenarios}))
    return out


def on_recording(tmp_path: Path, robot: RobotBinding, suite3: Path, nominal_run: Path,
                 knobs: dict[str, float]) -> list[Any]:
    twin_run = record(robot, suite3, tmp_path / "twin", knobs)
    analysis = analyze_runs(nominal_run, recording(twin_run, tmp_path / "rec"))
    assert analysis.comparison.channel_names == ["pole_angle_rad", "cart_pos_m"]
    assert "cart_vel_m_s" in analysis.comparison.left_out["channels"]  # the recording logs two channels
    assert analysis.comparison.twin_b == "recorded"
    return analysis.findings


def test_recording_with_an_inverted_cart(tmp_path: Path, robot: RobotBinding, suite3: Path,
                                         nominal_run: Path) -> None:
    """A cart that moves the other way for the same wheel command: sign inversion, explained by motor gain."""
    findings = on_recording(tmp_path, robot, suite3, nominal_run, {f"motor.wheel{i}.gain": -1.0 for i in range(1, 5)})
    signs = [f for f in findings if f.kind == "sign_inversion" and f.channel == "cart_pos_m"]
    assert signs and signs[0].scenarios == ["01_sine", "02_drive"] and signs[0].knobs[0] == "motor.*.gain"
    assert findings[0].kind == "sign_inversion"


def test_recording_with_a_control_delay(tmp_path: Path, robot: RobotBinding, suite3: Path,
                                        nominal_run: Path) -> None:
    findings = on_recording(tmp_path, robot, suite3, nominal_run, {"control.delay_periods": 3})
    lags = [f for f in findings if f.kind == "lag" and f.channel == "cart_pos_m"]
    assert lags and lags[0].evidence["lag_periods"] == pytest.approx(3.0, abs=0.5)
    assert lags[0].evidence["lagging"] == "B" and lags[0].knobs[0] == "control.delay_periods"
    # (The late drive lets the pole fall the other way in 02_drive: a real sign flip of the pole, not the cart.)
    assert not [f for f in findings if f.kind in ("sign_inversion", "scale_mismatch") and f.channel == "cart_pos_m"]


def test_recording_with_a_wheel_gain(tmp_path: Path, robot: RobotBinding, suite3: Path, nominal_run: Path) -> None:
    findings = on_recording(tmp_path, robot, suite3, nominal_run, {f"motor.wheel{i}.gain": 1.4 for i in range(1, 5)})
    scales = [f for f in findings if f.kind == "scale_mismatch" and f.channel == "cart_pos_m"]
    assert scales and scales[0].evidence["slope"] == pytest.approx(1.4, rel=0.1)
    assert scales[0].knobs[0] == "motor.*.gain"
    assert not [f for f in findings if f.kind == "sign_inversion"]


def test_recording_of_the_same_twin_raises_no_structural_finding(tmp_path: Path, robot: RobotBinding,
                                                                 suite3: Path, nominal_run: Path) -> None:
    """The control: rounding to 1 mm and 2 ms jitter alone raise no sign, lag or scale finding."""
    findings = on_recording(tmp_path, robot, suite3, nominal_run, {})
    assert not [f for f in findings if f.kind in ("sign_inversion", "lag", "scale_mismatch")]


def test_event_time_within_the_members_spread_is_no_finding(tmp_path: Path) -> None:
    """A pole that falls 0.06 s late is no finding when the reference's own members spread by 0.2 s."""
    members = [{"pole_angle_rad": pole(T - shift), "cart_pos_m": cart(T)} for shift in (0.0, 0.1, -0.1)]
    a = fabricate_ensemble(tmp_path / "a", members, "webots", T)
    near = fabricate_ensemble(tmp_path / "near", [{"pole_angle_rad": pole(T - 0.06), "cart_pos_m": cart(T)}],
                              "mujoco", T)
    far = fabricate_ensemble(tmp_path / "far", [{"pole_angle_rad": pole(T - 0.4), "cart_pos_m": cart(T)}],
                             "mujoco", T)
    assert not [f for f in analyze_runs(a, near).findings if f.kind == "event_time"]
    found = [f for f in analyze_runs(a, far).findings if f.kind == "event_time"]
    assert found and found[0].evidence["00_fall"]["crossing_diff_s"] == pytest.approx(0.4, abs=0.02)
    floors = analyze_runs(a, far).to_dict()["floors"]
    assert floors[0]["channel"] == "pole_angle_rad" and floors[0]["ratio"] > 1
