"""The fitted point's suite run (``runs/after``) is written from the traces the fit already simulated there, not
simulated again (issue 25), and its files are those a simulation writes, byte for byte.

* `scenario_logs` + ``SuiteRun.run(replay=...)``: a suite with a failing scenario, a scenario continuing from it
  and a sine drive, simulated in memory (one job alone, and two as a MuJoCo batch) or read back from a run
  folder, written as a run folder: every file equals the simulated run's.
* ``align --budget 4`` (real MuJoCo, a recorded reference): the only suite runs simulated outside the evaluator
  are ``runs/before``'s; ``runs/after`` equals a fresh simulation at the fitted values; the fake twin (no
  MuJoCo batch, least squares and CMA-ES) likewise.

Simulations are counted where they happen (``run_scenario`` and ``Evaluator.map`` are wrapped, not replaced).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dualtwin.align import AlignConfig, run_align
from dualtwin.align.run import run_suite
from dualtwin.align.simulate import Evaluator, SimJob, Traces, load_traces
from dualtwin.robots.binding import RobotBinding, load_binding
from dualtwin.suite import runner
from dualtwin.suite.loader import load_suite
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin
from tests.support.align_runs import count_batches, write_suite
from tests.support.fake_twin import NAME, fit_fake, registered

# A fall that crosses the failure threshold, a scenario continuing from where it stopped, and a sine drive.
FAILING = {
    "suite_name": "replay_test",
    "global_settings": {"TIME_STEP": 32, "failure_pole_angle_rad": 0.5},
    "scenarios": [
        {"name": "fall", "duration_s": 1.5, "initial_angle": 0.2},
        {"name": "after_fall", "duration_s": 0.5, "reset": "continue", "wheel_velocity": 2.0},
        {"name": "sine", "duration_s": 1.0, "initial_angle": -0.05,
         "wheel_velocity": {"kind": "sine", "amplitude": 6.0, "frequency_hz": 0.7}},
    ],
}
KNOBS = {"joint.pole_hinge.damping": 0.03}


def files(run: Path) -> dict[str, bytes]:
    return {str(p.relative_to(run)): p.read_bytes() for p in sorted(run.rglob("*")) if p.is_file()}


@pytest.fixture()
def scenario_runs(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The twin of every scenario a suite run simulates (``run_scenario``, the suite runner's only way)."""
    seen: list[str] = []
    original = runner.run_scenario

    def counting(io: Any, *args: Any, **kwargs: Any) -> Any:
        seen.append(type(io.twin).__name__)
        return original(io, *args, **kwargs)

    monkeypatch.setattr(runner, "run_scenario", counting)
    return seen


@pytest.fixture()
def evaluated(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The size of every batch the evaluators simulate."""
    return count_batches(monkeypatch)


def replayed(robot: RobotBinding, suite: Path, out: Path, traces: Traces) -> Path:
    # Imported here, so the alignment tests below also run (and fail) on the code before the replay.
    from dualtwin.align.simulate import scenario_logs

    spec = robot.spec
    logs = {sid: scenario_logs(t, list(spec.ground_truth), list(spec.onboard)) for sid, t in traces.items()}
    assert all(log is not None for log in logs.values())
    twin = make_twin("mujoco", robot, 0.032)
    try:
        SuiteRun(suite, "mujoco", robot, out, twin=twin).run(replay={k: v for k, v in logs.items() if v is not None})
    finally:
        twin.close()
    return out


def test_replayed_logs_are_the_simulated_files(tmp_path: Path, robot: RobotBinding,
                                               scenario_runs: list[str]) -> None:
    suite = write_suite(tmp_path / "failing.json", FAILING)
    twin = make_twin("mujoco", robot, 0.032)
    twin.set_knobs(dict(KNOBS))
    simulated = tmp_path / "simulated"
    SuiteRun(suite, "mujoco", robot, simulated, twin=twin).run()
    twin.close()
    manifest = json.loads((simulated / "manifest.json").read_text())
    statuses = [s["status"] for s in manifest["scenarios"]]
    assert statuses[0] == "failed" and manifest["scenarios"][0]["failure"]["key"] == "failure_pole_angle_rad"
    assert manifest["scenarios"][1]["reset"] == "continue"
    assert len(scenario_runs) == 3
    job = SimJob(str(robot.path), "mujoco", str(suite), None, (), 0).with_knobs(KNOBS)
    with Evaluator("serial") as evaluator:
        alone = evaluator.map([job])[0]
        pair = evaluator.map([job, job.with_knobs({"joint.pole_hinge.damping": 0.0})])
        assert evaluator.batched
    expected = files(simulated)
    for name, traces in (("alone", alone), ("batched", pair[0]), ("read back", load_traces(simulated))):
        out = replayed(robot, suite, tmp_path / name.replace(" ", "_"), traces)
        assert files(out) == expected, name
    assert len(scenario_runs) == 3  # writing replayed logs simulated nothing
    # The control: other knobs' traces write other files.
    assert files(replayed(robot, suite, tmp_path / "other", pair[1])) != expected


def test_a_replay_must_cover_the_suite(tmp_path: Path, robot: RobotBinding) -> None:
    suite = write_suite(tmp_path / "failing.json", FAILING)
    job = SimJob(str(robot.path), "mujoco", str(suite), ("02_sine",), (), 0)
    with Evaluator("serial") as evaluator:
        traces = evaluator.map([job])[0]
    with pytest.raises(ValueError, match="replay lacks scenarios"):
        replayed(robot, suite, tmp_path / "partial", traces)


def fitted_values(out: Path) -> dict[str, float]:
    return dict(json.loads((out / "knobs.json").read_text())["values"])


def fresh_after(out: Path, robot: RobotBinding, twin_name: str, tmp: Path) -> dict[str, bytes]:
    """The after run simulated anew at the fitted values, as the alignment wrote it before (same paths)."""
    record = json.loads((out / "align_record.json").read_text())
    suite = Path(record["config"]["suite"])
    twin = make_twin(twin_name, robot, load_suite(suite).global_settings.control_period_s)
    try:
        fresh = run_suite(suite, twin_name, robot, tmp, record["simulation_seed"], twin, fitted_values(out), False)
    finally:
        twin.close()
    return files(fresh)


def test_align_writes_the_after_run_from_the_fit(tmp_path: Path, robot: RobotBinding, suite3: Path,
                                                damped_ref: Path, scenario_runs: list[str],
                                                evaluated: list[int]) -> None:
    config = AlignConfig(reference=str(damped_ref), target="mujoco", robot="cartpole", suite=str(suite3),
                         knobs=["joint.pole_hinge.damping"], budget=4, optimizer="cma", executor="serial")
    out = tmp_path / "fit"
    result = run_align(config, out)
    scenarios = len(load_traces(damped_ref))
    assert fitted_values(out) != {"joint.pole_hinge.damping": 0.0}, "the fit should move for this test"
    # Simulated outside the evaluator: runs/before only (the reference is a recorded run).
    assert len(scenario_runs) == scenarios, scenario_runs
    # In the evaluator: the fit's new points (the nominal one is runs/before) and the floor's two members.
    assert sum(evaluated) == result.evaluations - 1 + 2, evaluated
    del scenario_runs[:]
    assert files(out / "runs" / "after") == fresh_after(out, robot, "mujoco", tmp_path / "fresh")
    assert len(scenario_runs) == scenarios  # the control simulated


@pytest.fixture()
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


@pytest.mark.parametrize("optimizer", ["lsq", "cma"])
def test_the_fake_twins_after_run_is_the_fits(tmp_path: Path, fake: str, optimizer: str,
                                              scenario_runs: list[str]) -> None:
    truth = {"joint.j1.damping": 0.9, "joint.j2.stiffness": 6.5}
    out = tmp_path / optimizer
    fit_fake(out, sorted(truth), truth, budget=4, optimizer=optimizer)
    record = json.loads((out / "align_record.json").read_text())
    binding = load_binding(Path(record["config"]["robot"]))
    scenarios = len(load_traces(out / "reference"))
    # The reference twin's run and runs/before; not runs/after.
    assert len(scenario_runs) == 2 * scenarios, scenario_runs
    assert files(out / "runs" / "after") == fresh_after(out, binding, NAME, tmp_path / "fresh")

