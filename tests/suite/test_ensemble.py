"""Suite ensembles on the real MuJoCo twin: layout, shifts applied, determinism, resume, bad input."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.suite.ensemble import EnsembleRun, EnsembleSpec, make_spec, parse_perturb, simulate_members
from dualtwin.suite.runner import SuiteRun

SUITE = {
    "suite_name": "ens",
    "global_settings": {"TIME_STEP": 32},
    "scenarios": [
        {"name": "fall", "duration_s": 2.5, "initial_angle": 0.001},
        {"name": "drive", "duration_s": 0.5, "wheel_velocity": 4.0},
        {"name": "more", "duration_s": 0.5, "reset": "continue", "wheel_velocity": -4.0},
    ],
}


@pytest.fixture(scope="module")
def robot() -> RobotBinding:
    return resolve_robot("cartpole")


@pytest.fixture(scope="module")
def suite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("ens") / "suite.json"
    path.write_text(json.dumps(SUITE), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory: pytest.TempPathFactory, robot: RobotBinding, suite: Path) -> Path:
    out = tmp_path_factory.mktemp("run") / "run"
    spec = make_spec(4, {"initial_angle": 1e-6}, robot, seed=3)
    EnsembleRun(suite, "mujoco", robot, out, spec, executor="process", workers=2).run()
    return out


def test_spec_shifts_are_seeded_and_include_the_extremes() -> None:
    spec = EnsembleSpec(members=5, perturb={"initial_angle": 1e-5}, seed=1)
    shifts = [o["initial_angle"] for o in spec.offsets()]
    assert shifts[:3] == [0.0, 1e-5, -1e-5]
    assert all(abs(s) <= 1e-5 for s in shifts) and len(set(shifts)) == 5
    assert spec.offsets() == EnsembleSpec(members=5, perturb={"initial_angle": 1e-5}, seed=1).offsets()
    assert spec.offsets() != EnsembleSpec(members=5, perturb={"initial_angle": 1e-5}, seed=2).offsets()


def test_layout_and_manifest(ensemble: Path) -> None:
    manifest = json.loads((ensemble / "manifest.json").read_text())
    assert manifest["ensemble"]["members"] == 4
    assert [o["shift"]["initial_angle"] for o in manifest["ensemble"]["offsets"]][:3] == [0.0, 1e-6, -1e-6]
    for record in manifest["scenarios"]:
        assert [m["member"] for m in record["members"]] == [1, 2, 3]
        for member in record["members"]:
            for source in ("onboard", "ground_truth"):
                rel = member[source]
                assert rel == f"scenarios/{record['id']}/members/{member['member']}/{source}.tsv"
                assert (ensemble / rel).is_file() and rel in manifest["logs"]


def test_member_is_the_suite_run_with_the_shift_applied(ensemble: Path, robot: RobotBinding,
                                                        tmp_path: Path) -> None:
    """Member 1 (+1 µrad, through the process pool) is byte-identical to a plain run of the shifted suite."""
    shifted = json.loads(json.dumps(SUITE))
    shifted["scenarios"][0]["initial_angle"] = 0.001 + 1e-6
    path = tmp_path / "shifted.json"
    path.write_text(json.dumps(shifted))
    SuiteRun(path, "mujoco", robot, tmp_path / "plain").run()
    member = (ensemble / "scenarios/00_fall/members/1/ground_truth.tsv").read_bytes()
    assert member == (tmp_path / "plain/scenarios/00_fall/ground_truth.tsv").read_bytes()
    # ... and a 1 µrad shift is visible: the member differs from the unperturbed run.
    assert member != (ensemble / "scenarios/00_fall/ground_truth.tsv").read_bytes()
    # The scenario that sets no initial angle is shifted from the reset value (0), so it moves too.
    assert (ensemble / "scenarios/01_drive/members/1/ground_truth.tsv").read_bytes() != \
        (ensemble / "scenarios/01_drive/ground_truth.tsv").read_bytes()


def test_in_memory_members_match_the_stored_ones(ensemble: Path, robot: RobotBinding, suite: Path) -> None:
    spec = make_spec(4, {"initial_angle": 1e-6}, robot, seed=3)
    members = simulate_members(spec, robot, "mujoco", suite, scenarios=["02_more"], executor="serial")
    assert [list(m) for m in members] == [["02_more"]] * 4
    stored = (ensemble / "scenarios/02_more/members/3/ground_truth.tsv").read_text().splitlines()[1:]
    assert [[float(c) for c in line.split("\t")] for line in stored] == members[3]["02_more"].ground_truth


def test_same_inputs_same_bytes_and_resume(ensemble: Path, robot: RobotBinding, suite: Path, tmp_path: Path) -> None:
    out = tmp_path / "again"
    spec = make_spec(4, {"initial_angle": 1e-6}, robot, seed=3)
    EnsembleRun(suite, "mujoco", robot, out, spec, executor="serial").run()
    files = sorted(p.relative_to(ensemble) for p in ensemble.rglob("*.tsv"))
    assert files == sorted(p.relative_to(out) for p in out.rglob("*.tsv")) and len(files) == 3 * 2 * 4
    assert all((ensemble / f).read_bytes() == (out / f).read_bytes() for f in files)
    # Resume after losing one member's log: only that member is simulated again, the rest is kept.
    lost = out / "scenarios/00_fall/members/2/onboard.tsv"
    lost.unlink()
    kept = (out / "scenarios/00_fall/members/3/onboard.tsv").stat().st_mtime_ns
    seen: list[int] = []
    EnsembleRun(suite, "mujoco", robot, out, spec, executor="serial").run(
        resume=True, on_member=lambda k, n: seen.append(k))
    assert seen == [2] and lost.is_file()
    assert (out / "scenarios/00_fall/members/3/onboard.tsv").stat().st_mtime_ns == kept
    other = make_spec(4, {"initial_angle": 1e-5}, robot, seed=3)
    with pytest.raises(DualtwinError, match="ensemble .* differs"):
        EnsembleRun(suite, "mujoco", robot, out, other, executor="serial").run(resume=True)


def test_bad_input_is_one_line(robot: RobotBinding, suite: Path, tmp_path: Path) -> None:
    with pytest.raises(DualtwinError, match="expected KEY=EPS"):
        parse_perturb(["initial_angle"])
    with pytest.raises(DualtwinError, match="positive"):
        parse_perturb(["initial_angle=-1"])
    with pytest.raises(DualtwinError, match="not an initial condition of robot 'cartpole'"):
        make_spec(3, {"wheel_velocity": 1e-6}, robot)
    with pytest.raises(DualtwinError, match="at least 2"):
        make_spec(1, {"initial_angle": 1e-6}, robot)
    out = tmp_path / "never"
    proc = subprocess.run([sys.executable, "-m", "dualtwin.cli", "suite", "run", "--twin", "mujoco", "--robot",
                           "cartpole", "--scenarios", str(suite), "--out", str(out), "--ensemble", "3",
                           "--perturb", "initial_speed=1e-6"], capture_output=True, text=True, timeout=120)
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert len(errors) == 1 and "--perturb 'initial_speed'" in errors[0]
    assert not out.exists()


@pytest.mark.parametrize(("manifest", "expected"), [
    ([1], "$: Input should be a valid dictionary"),
    ({"robot": "cartpole", "twin": "mujoco", "channels": {}, "scenarios": [{"id": "00_a", "status": "completed",
                                                                           "members": 5}]},
     "$.scenarios[0].members"),
])
def test_resume_refuses_a_manifest_of_the_wrong_shape(robot: RobotBinding, suite: Path, tmp_path: Path,
                                                      manifest: object, expected: str) -> None:
    # Found by fuzzing suite run --resume --ensemble: the ensemble read the folder's manifest unchecked (a list
    # was a traceback) before the base run got to check it.
    out = tmp_path / "run"
    spec = make_spec(2, {"initial_angle": 1e-6}, robot, seed=3)
    SuiteRun(suite, "mujoco", robot, out)  # the suite is valid: what is refused below is the manifest
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps({"kind": "suite-run"} | manifest if isinstance(manifest, dict)
                                                  else manifest))
    with pytest.raises(DualtwinError, match=r"cannot resume: .*manifest\.json: " + expected.replace("$", r"\$")
                       .replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        EnsembleRun(suite, "mujoco", robot, out, spec, executor="serial").run(resume=True)


@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="Ray is not installed (pip install 'dualtwin[ray]')")
def test_members_on_ray_match_the_process_pool(robot: RobotBinding, suite: Path) -> None:
    """One option moves the members to a Ray cluster (here a real local one): same members, same values."""
    import ray

    spec = make_spec(3, {"initial_angle": 1e-6}, robot, seed=3)
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        on_ray = simulate_members(spec, robot, "mujoco", suite, scenarios=["00_fall"], executor="ray")
    finally:
        ray.shutdown()
    in_pool = simulate_members(spec, robot, "mujoco", suite, scenarios=["00_fall"], executor="process")
    assert [m["00_fall"].ground_truth for m in on_ray] == [m["00_fall"].ground_truth for m in in_pool]
    assert on_ray[1]["00_fall"].ground_truth != on_ray[0]["00_fall"].ground_truth
