"""The CLI end to end: bad input gets one clear line, exit code 2, no traceback and no partial output."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from dualtwin.robots.binding import BUNDLED

CARTPOLE = BUNDLED / "cartpole"


def dualtwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "dualtwin.cli", *args], capture_output=True, text=True, timeout=300)


def user_binding(tmp_path: Path, model: str) -> Path:
    text = (CARTPOLE / "binding.yaml").read_text().replace("model: cartpole.xml", f"model: {model}")
    path = tmp_path / "binding.yaml"
    path.write_text(text)
    return path


def suite(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "suite.json"
    path.write_text(text)
    return path


GOOD = '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.1, "initial_angle": 0.1}]}'


@pytest.mark.parametrize(("suite_text", "model", "message"), [
    ('{"suite_name": "s", "scenarios": [', None, "invalid JSON"),
    ('{"suite_name": "s", "scenarios": [{"name": "a"}]}', None, "$.scenarios[0].duration_s: Field required"),
    ('{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": -2}]}', None,
     "$.scenarios[0].duration_s: Input should be greater than 0"),
    ('{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": NaN}]}', None, "NaN"),
    ('{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 1, "initial_angle": Infinity}]}', None,
     "Infinity"),
    ('{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 1, "gravity_gun": 3}]}', None,
     "unknown robot-specific key 'gravity_gun'"),
    (GOOD, "missing.xml", "model file for twin 'mujoco' not found"),
    (GOOD, "broken.xml", "broken.xml: MJCF does not compile"),
])
def test_bad_input(tmp_path: Path, suite_text: str, model: str | None, message: str) -> None:
    robot = "cartpole"
    if model is not None:
        robot = str(user_binding(tmp_path, model))
        (tmp_path / "broken.xml").write_text(
            '<mujoco><worldbody><body><joint type="hinge"/><geom type="box" size="0 0 0"/></body></worldbody></mujoco>')
    out = tmp_path / "run"
    result = dualtwin("suite", "run", "--twin", "mujoco", "--robot", robot,
                      "--scenarios", str(suite(tmp_path, suite_text)), "--out", str(out))
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert message in lines[0]
    assert not out.exists(), "no partial output"


def test_run_validate_and_compare(tmp_path: Path) -> None:
    path = suite(tmp_path, GOOD)
    assert dualtwin("suite", "validate", "--scenarios", str(path), "--robot", "cartpole").returncode == 0
    for name in ("a", "b"):
        result = dualtwin("suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", str(path),
                          "--out", str(tmp_path / name))
        assert result.returncode == 0, result.stderr
    result = dualtwin("compare", "--reference-run", str(tmp_path / "a"),
                      "--target-run", str(tmp_path / "b"), "--out", str(tmp_path / "report"))
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "report" / "metrics.json").read_text())
    assert metrics["comparison"]["summary_score"] == 0.0
    assert (tmp_path / "report" / "report.html").is_file()


def test_convert_writes_a_model_the_suite_runs_on(tmp_path: Path) -> None:
    result = dualtwin("convert", str(CARTPOLE / "cartpole.wbt"), "--out", str(tmp_path / "cp.xml"),
                      "--binding", str(tmp_path / "binding.yaml"))
    assert result.returncode == 0, result.stderr
    path = suite(tmp_path, '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.2, "wheel_velocity": 2}]}')
    result = dualtwin("suite", "run", "--twin", "mujoco", "--robot", str(tmp_path / "binding.yaml"),
                      "--scenarios", str(path), "--out", str(tmp_path / "run"))
    assert result.returncode == 0, result.stderr


def test_convert_and_generate_bad_input(tmp_path: Path) -> None:
    world = tmp_path / "empty.wbt"
    world.write_text("#VRML_SIM R2023b utf8\nWorldInfo {\n}\n")
    result = dualtwin("convert", str(world), "--out", str(tmp_path / "x.xml"))
    assert result.returncode == 2 and "no robot" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "x.xml").exists()
    result = dualtwin("generate", "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "exactly one of" in result.stderr


def test_lockstep_and_predict_error(tmp_path: Path) -> None:
    path = suite(tmp_path, '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.5, "initial_angle": 0.2}]}')
    result = dualtwin("lockstep", "--robot", "cartpole", "--scenarios", str(path), "--resync", "every:2",
                      "--out", str(tmp_path / "ls"))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "ls" / "report" / "report.html").is_file()
    result = dualtwin("predict-error", "--robot", "cartpole", "--scenarios", str(path), "--horizons", "1", "--horizons", "5",
                      "--out", str(tmp_path / "pe"))
    assert result.returncode == 0, result.stderr
    result = dualtwin("lockstep", "--robot", "cartpole", "--scenarios", str(path), "--resync", "sometimes",
                      "--out", str(tmp_path / "bad"))
    assert result.returncode == 2 and "Traceback" not in result.stderr


def test_train_export_transfer(tmp_path: Path) -> None:
    run = tmp_path / "run"
    result = dualtwin("train", "--env", "dualtwin/CartPole-MuJoCo-Continuous-v0", "--out", str(run), "--steps", "4096")
    assert result.returncode == 0, result.stderr
    assert (run / "model.zip").is_file() and (run / "vecnormalize.json").is_file()
    result = dualtwin("export", "--policy", str(run), "--out", str(tmp_path / "export"))
    assert result.returncode == 0, result.stderr
    contract = json.loads((tmp_path / "export" / "policy_contract.json").read_text())
    assert [o["name"] for o in contract["observation"]][:2] == ["cart_position", "cart_velocity"]
    result = dualtwin("transfer", "--policy", str(run), "--target-env", "dualtwin/CartPole-Webots-Continuous-v0",
                      "--episodes", "1", "--out", str(tmp_path / "transfer"))
    assert result.returncode == 0, result.stderr
    assert "target (before alignment)" in result.stdout
    # 4096 steps do not converge: the terminal says so, not only transfer.md; the start line has no stray "0".
    assert "warning: the source is not converged" in result.stdout
    assert "transfer: 1 episodes per row" in result.stderr and "transfer: 0 " not in result.stderr
    result = dualtwin("train", "--env", "dualtwin/Nope-v0", "--out", str(tmp_path / "bad"))
    assert result.returncode == 2 and "registered dualtwin ids" in result.stderr
