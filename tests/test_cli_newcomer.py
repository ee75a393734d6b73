"""What a newcomer reads: help that says what options take, --version, remedies in CLI words, exit codes."""

from __future__ import annotations

import ast
import re
import socket
from pathlib import Path

import pytest
import typer

from dualtwin.cli import main
from dualtwin.cli.common import app
from dualtwin.cli.policy import harden
from dualtwin.reporting.progress import ProgressEvent

SRC = Path(__file__).resolve().parents[1] / "src" / "dualtwin"


def commands() -> list[list[str]]:
    """Every command's path (``["suite", "run"]``), walked from the CLI itself."""
    out: list[list[str]] = []

    def walk(command: object, path: list[str]) -> None:
        subs = getattr(command, "commands", None)
        if subs:
            for name, sub in subs.items():
                walk(sub, [*path, name])
        else:
            out.append(path)

    walk(harden(typer.main.get_command(app)), [])
    return out


@pytest.mark.parametrize("path", commands(), ids=" ".join)
def test_help_shows_flags_as_flags_and_scenarios_as_file_or_name(path: list[str], capsys: pytest.CaptureFixture[str],
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "250")
    assert main([*path, "--help"]) == 0
    out = capsys.readouterr().out
    assert "<bool>" not in out
    for line in out.splitlines():
        if "--scenarios" in line:
            assert "bundled robot's name" in line


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    from dualtwin import __version__

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"dualtwin {__version__}"


def test_ensemble_default_agrees_with_its_text(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["suite", "run", "--help"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "--ensemble" in x)
    assert "[default: 0]" not in line and "N >= 2" in line
    # Asked for, an ensemble below 2 is refused (it used to mean "no ensemble" in silence).
    assert main(["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", "cartpole",
                 "--out", str(tmp_path / "run"), "--ensemble", "1", "--perturb", "initial_angle=1e-6"]) == 2
    assert "--ensemble must be at least 2" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


PYTHON_REMEDY = re.compile(r"\bprepare_world_for_twins\b|\bproto_paths\b|\bdualtwin(\.\w+){2,}\(")


def _message_strings(tree: ast.AST) -> list[tuple[int, str]]:
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant)}
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings]


def test_messages_name_what_a_cli_user_types_not_python_functions() -> None:
    found = [f"{path.relative_to(SRC)}:{line}: {text[:90]}"
             for path in sorted(SRC.rglob("*.py"))
             for line, text in _message_strings(ast.parse(path.read_text(encoding="utf-8")))
             if PYTHON_REMEDY.search(text)]
    assert found == []


def test_a_stage_start_without_a_count_prints_no_zero() -> None:
    assert ProgressEvent("transfer", 0, None, "3 episodes per row").line() == "transfer: 3 episodes per row"
    assert ProgressEvent("fit", 4, None, "objective 0.1").line() == "fit: 4 objective 0.1"  # a count stays


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_analyze_llm_unreachable_exits_2_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from tests.support.paper_logs import SUITE, write_logs

    runs = []
    for name in ("a", "b"):
        logs = write_logs(tmp_path / f"logs_{name}", [0.0] * 6, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
        assert main(["import", "paper", str(logs), "--scenarios", str(SUITE), "--robot", "cartpole",
                     "--out", str(tmp_path / name)]) == 0
        runs.append(tmp_path / name)
    capsys.readouterr()
    url = f"http://127.0.0.1:{_closed_port()}/v1"
    monkeypatch.setenv("DUALTWIN_LLM_PROVIDER", "openai")
    monkeypatch.setenv("DUALTWIN_LLM_BASE_URL", url)
    monkeypatch.setenv("DUALTWIN_LLM_MODEL", "any")
    monkeypatch.setenv("DUALTWIN_LLM_API_KEY", "sk-test")
    out = tmp_path / "an"
    assert main(["analyze", "--reference-run", str(runs[0]), "--target-run", str(runs[1]), "--out", str(out),
                 "--llm"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --llm:") and "127.0.0.1" in err[0]
    assert not out.exists()
    # Control: without --llm the same analysis succeeds.
    assert main(["analyze", "--reference-run", str(runs[0]), "--target-run", str(runs[1]), "--out", str(out)]) == 0


def test_deploy_summary_is_readable() -> None:
    from dualtwin.cli.serve import deploy_summary

    result = {"server": "http://127.0.0.1:8000", "env_id": "dualtwin/CartPole-MuJoCo-v0", "episodes": 2, "seed": 0,
              "loop": "perception_pole_angle_only", "inputs_from_perception": ["pole_angle"],
              "inputs_from_onboard_sensors": ["cart_position"], "mean_perception_reward": 480.0,
              "mean_privileged_reward": 500.0, "ratio": 0.96, "episode_cap": 500, "perception_success": 0.5,
              "privileged_success": 1.0, "estimate_mae": {"pole_angle": 0.0123},
              "latency_ms": {"p50": 1.2, "p99": 3.4, "requests": 900}}
    text = "\n".join(deploy_summary(result))
    assert "reward: served 480.0, privileged 500.0 (ratio 0.960)" in text
    assert "served 50 %, privileged 100 %" in text and "p99 3.4 ms over 900 requests" in text
    assert "{" not in text


def test_deploy_has_a_json_flag(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["deploy", "--help"]) == 0
    assert "--json" in capsys.readouterr().out


@pytest.fixture(scope="module")
def paired_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same logs imported as a cartpole run and as a cartpole_paper run (seconds, no simulation)."""
    from tests.support.paper_logs import SUITE, write_logs

    root = tmp_path_factory.mktemp("pairs")
    logs = write_logs(root / "logs", [0.0] * 6, [0.0] * 6)
    runs = {}
    for robot in ("cartpole", "cartpole_paper"):
        runs[robot] = root / robot
        assert main(["import", "paper", str(logs), "--scenarios", str(SUITE), "--robot", robot,
                     "--out", str(runs[robot])]) == 0
    runs["logs"] = logs
    return runs


WRONG_PAIRINGS = {
    "suite run: another robot's suite": (["suite", "run", "--twin", "mujoco", "--robot", "cartpole",
                                          "--scenarios", "arm"], "arm"),
    "lockstep: another robot's suite": (["lockstep", "--reference", "webots", "--target", "mujoco", "--robot",
                                         "cartpole", "--scenarios", "arm"], "arm"),
    "import paper: a robot without the paper's channels": (["import", "paper", "{logs}", "--scenarios", "cartpole",
                                                            "--robot", "arm"], "arm"),
    "compare: runs of two robots": (["compare", "--reference-run", "{cartpole}", "--target-run",
                                     "{cartpole_paper}"], "cartpole_paper"),
    "analyze: runs of two robots": (["analyze", "--reference-run", "{cartpole}", "--target-run",
                                     "{cartpole_paper}"], "cartpole_paper"),
}


@pytest.mark.parametrize("name", list(WRONG_PAIRINGS))
def test_a_wrong_pairing_is_one_line_and_leaves_nothing(name: str, paired_runs: dict[str, Path], tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    argv, named = WRONG_PAIRINGS[name]
    out = tmp_path / "out"
    argv = [a.format(**{k: str(v) for k, v in paired_runs.items()}) for a in argv] + ["--out", str(out)]
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and named in err[0], err
    assert not out.exists()
