"""Alignment on ensembles (issue 15.4): fit the members' mean instead of one chaotic trajectory."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from dualtwin.align import AlignConfig, run_align
from dualtwin.align.ensemble import EnsembleProblem
from dualtwin.align.knobs import select_knobs
from dualtwin.align.objective import build_spec, mean_trace, residual_layout
from dualtwin.align.simulate import (
    Evaluator,
    ScenarioTrace,
    SimJob,
    ensemble_offsets,
    load_member_traces,
    load_traces,
)
from dualtwin.divergence.runs import Series
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import BUNDLED, RobotBinding, load_binding
from dualtwin.suite.ensemble import EnsembleRun, make_spec
from dualtwin.suite.loader import load_suite
from dualtwin.twins import make_twin
from tests.support.align_runs import TRUE_DAMPING

DAMPING = "joint.pole_hinge.damping"
MEMBERS = 3


def damped_binding(folder: Path) -> RobotBinding:
    """The CartPole binding with the true damping written into its MJCF (an ensemble run takes no knobs)."""
    spec = mujoco.MjSpec.from_file(str(BUNDLED / "cartpole" / "cartpole.xml"))
    spec.joint("pole_hinge").damping[0] = TRUE_DAMPING
    (folder / "cartpole_damped.xml").write_text(spec.to_xml())
    binding = yaml.safe_load((BUNDLED / "cartpole" / "binding.yaml").read_text())
    binding["twins"]["mujoco"]["model"] = "cartpole_damped.xml"
    binding["twins"]["webots"]["model"] = str(BUNDLED / "cartpole" / "cartpole.wbt")
    (folder / "binding.yaml").write_text(yaml.safe_dump(binding, sort_keys=False))
    return load_binding(folder / "binding.yaml")


@pytest.fixture(scope="module")
def ensemble_ref(tmp_path_factory: pytest.TempPathFactory, suite3: Path) -> Path:
    folder = tmp_path_factory.mktemp("ensemble")
    robot = damped_binding(folder)
    out = folder / "reference"
    EnsembleRun(suite3, "mujoco", robot, out, make_spec(MEMBERS, {"initial_angle": 0.02}, robot),
                executor="serial").run()
    return out


def test_mean_trace_is_the_pointwise_mean_of_the_members_that_reach_each_time() -> None:
    t = (np.arange(1, 6) * 0.5).astype(np.float64)
    members = [ScenarioTrace("s", "completed", 2.5, {"x": Series(t, np.ones(5))}),
               ScenarioTrace("s", "failed", 2.5, {"x": Series(t[:3], np.full(3, 3.0))}),
               ScenarioTrace("s", "completed", 2.5, {"x": Series(t, np.full(5, 5.0))})]
    mean = mean_trace(members)
    assert mean.status == "completed" and np.array_equal(mean.series["x"].t, t)
    # The member that stopped at 1.5 s counts until then, and is not extrapolated after.
    assert mean.series["x"].y.tolist() == [3.0, 3.0, 3.0, 3.0, 3.0]
    members[1] = ScenarioTrace("s", "failed", 2.5, {"x": Series(t[:3], np.full(3, 6.0))})
    assert mean_trace(members).series["x"].y.tolist() == [4.0, 4.0, 4.0, 3.0, 3.0]
    assert mean_trace(members[:1]) is members[0]
    with pytest.raises(DualtwinError):
        mean_trace([])


def test_align_fits_the_ensemble_mean(tmp_path: Path, robot: RobotBinding, suite3: Path, ensemble_ref: Path) -> None:
    offsets = ensemble_offsets(ensemble_ref)
    assert len(offsets) == MEMBERS and offsets[1] == {"initial_angle": 0.02}
    members = load_member_traces(ensemble_ref)
    fall = members["00_fall"]
    # The members differ, so their mean is not member 0's trajectory.
    gap = np.abs(mean_trace(fall).series["pole_angle_rad"].y - fall[0].series["pole_angle_rad"].y).max()
    assert gap > 0.01
    # The mean is smooth: the fit stops close to the truth.
    assert fit_to_ensemble(ensemble_ref, robot, suite3, "mean", tmp_path / "out") == pytest.approx(TRUE_DAMPING,
                                                                                                     rel=2e-2)


def test_ensemble_mean_needs_members(tmp_path: Path, robot: RobotBinding, suite3: Path, damped_ref: Path) -> None:
    with pytest.raises(DualtwinError, match="needs a run with ensemble members; this one has none"):
        run_align(AlignConfig(reference=str(damped_ref), target="mujoco", robot=str(robot.path),
                              suite=str(suite3), knobs=[DAMPING], executor="serial", ensemble="mean"),
                  tmp_path / "a")
    with pytest.raises(DualtwinError, match="not a twin"):
        run_align(AlignConfig(reference="webots", target="mujoco", robot=str(robot.path),
                              suite=str(suite3), knobs=[DAMPING], executor="serial", ensemble="mean"),
                  tmp_path / "b")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def members_problem(ref_dir: Path, robot: RobotBinding, suite: Path, mode: str,
                    reference_members: dict[str, list[ScenarioTrace]]) -> EnsembleProblem:
    """An ensemble problem on the pole angle with the pole damping as its only knob (serial, no held-out)."""
    reference = load_traces(ref_dir)
    reference.update({sid: mean_trace(m) for sid, m in reference_members.items()})
    ids = list(reference)
    twin = make_twin("mujoco", robot, load_suite(suite).global_settings.control_period_s)
    specs = select_knobs(twin.knobs(), [DAMPING], {}, where="mujoco")
    twin.close()
    job = SimJob(str(robot.path), "mujoco", str(suite), tuple(ids), (), 0)
    return EnsembleProblem(specs, job, build_spec(reference, ids, ["pole_angle_rad"]), None, Evaluator("serial"), 20,
                           0.0, ensemble_offsets(ref_dir), mode, reference_members)  # type: ignore[arg-type]


def test_members_mode_scores_each_member_against_the_reference_member_of_its_shift(
        robot: RobotBinding, suite3: Path, ensemble_ref: Path) -> None:
    members = load_member_traces(ensemble_ref)
    # Members 1 and 2 of every scenario swapped: the same trajectories, each filed under the other's shift.
    swapped = {sid: [m[0], m[2], m[1]] for sid, m in members.items()}
    truth = [{DAMPING: TRUE_DAMPING}]
    norms = {}
    for mode in ("mean", "members"):
        for label, reference_members in (("own", members), ("swapped", swapped)):
            problem = members_problem(ensemble_ref, robot, suite3, mode, reference_members)
            point = problem.evaluate_knobs(truth)[0]
            problem.evaluator.close()
            norms[mode, label] = float(point.residual @ point.residual)
            if mode == "members":
                # One block layout per member, back to back, covering the stacked residuals.
                layout = problem.residual_blocks()
                assert len(layout) == MEMBERS * len(residual_layout(problem.train))
                assert layout[-1].stop == point.residual.size
    # At the truth every member reproduces its own reference member (the same engine and shifts).
    assert norms["mean", "own"] < 1e-20 and norms["members", "own"] < 1e-20
    # The mean cannot tell which trajectory came from which shift; member by member, the swap shows.
    assert norms["mean", "swapped"] < 1e-20
    assert norms["members", "swapped"] > 1e-6


def fit_to_ensemble(reference: Path, robot: RobotBinding, suite: Path, ensemble: str, out: Path) -> float:
    """The damping fitted to an ensemble reference run (``ensemble``: how its members are compared); the fit
    must have explained most of the gap, and its record must say how the members were used."""
    result = run_align(AlignConfig(reference=str(reference), target="mujoco", robot=str(robot.path),
                                   suite=str(suite), knobs=[DAMPING], optimizer="lsq", budget=30,
                                   executor="serial", ensemble=ensemble), out)
    assert result.objective_after < 0.05 * result.objective_before
    assert json.loads((out / "align_record.json").read_text())["config"]["ensemble"] == ensemble
    return result.fitted[DAMPING]


def test_align_fits_member_by_member(tmp_path: Path, robot: RobotBinding, suite3: Path, ensemble_ref: Path) -> None:
    # Each member's impacts keep their own roughness (the mean smooths them): the stop is a little wider.
    assert fit_to_ensemble(ensemble_ref, robot, suite3, "members", tmp_path / "out") == pytest.approx(
        TRUE_DAMPING, rel=5e-2)


SMALL_SUITE = '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.1, "initial_angle": 0.1}]}'


@pytest.mark.parametrize(("offsets", "expected"), [
    (5, "$.ensemble.offsets"),
    ([{"member": 0, "shift": {"initial_angle": "x"}}], "$.ensemble.offsets[0].shift.initial_angle"),
    ([{"member": "0", "shift": {}}], "$.ensemble.offsets[0].member"),
])
def test_hostile_ensemble_offsets_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                               offsets: object, expected: str) -> None:
    # Found by fuzzing align --ensemble mean with mutated run manifests: a number for the offsets was a traceback.
    from dualtwin.cli import main

    suite = tmp_path / "suite.json"
    suite.write_text(SMALL_SUITE)
    ref = tmp_path / "ref"
    assert main(["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", str(suite), "-o", str(ref),
                 "--ensemble", "2", "--perturb", "initial_angle=0.01", "--executor", "serial"]) == 0
    manifest = json.loads((ref / "manifest.json").read_text())
    manifest["ensemble"]["offsets"] = offsets
    (ref / "manifest.json").write_text(json.dumps(manifest))
    capsys.readouterr()
    out = tmp_path / "fit"
    assert main(["align", "--reference-run", str(ref), "--scenarios", str(suite), "--target", "mujoco", "--robot",
                 "cartpole", "--knobs", "joint.*.damping", "--budget", "2", "--ensemble", "mean", "-o", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert len(err) == 1 and str(ref / "manifest.json") in err[0] and expected in err[0], err
    assert not out.exists()
