"""The scripts in examples/ run as a user runs them (a fresh Python process, the public API, the bundled
CartPole) and print what they promise. Each writes only into its own temporary folder."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def _run(script: str, *args: str, cwd: Path) -> str:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    result = subprocess.run([sys.executable, str(EXAMPLES / script), *args], cwd=cwd, env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "Traceback" not in result.stderr
    return result.stdout


def test_every_example_is_tested() -> None:
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py"))
    tested = sorted(re.findall(r'_run\("([a-z_]+\.py)"', Path(__file__).read_text(encoding="utf-8")))
    assert scripts == sorted(set(tested)), "every script in examples/ needs a test here"


def test_run_suite_both_twins(tmp_path: Path) -> None:
    out = _run("run_suite_both_twins.py", str(tmp_path / "runs"), cwd=tmp_path)
    for twin in ("mujoco", "webots"):
        assert f"{twin}: 6 scenarios of 'CartPole_Dual_Twin_V1'" in out
        assert (tmp_path / "runs" / twin / "manifest.json").is_file()
    rows = re.findall(r"^  (\d\d_\w+)\s+(\w+)\s+max \|pole angle\| ([0-9.]+) rad$", out, re.MULTILINE)
    assert len(rows) == 12
    # The pole falls onto its stops at 1 rad in every bundled scenario, in both twins.
    assert all(status == "completed" and 0.99 < float(angle) < 1.1 for _, status, angle in rows), out


def test_compare_and_analyze(tmp_path: Path) -> None:
    out = _run("compare_and_analyze.py", str(tmp_path / "work"), cwd=tmp_path)
    score = float(re.search(r"^summary score ([0-9.]+) over 6 scenarios$", out, re.MULTILINE).group(1))  # type: ignore[union-attr]
    assert 0 < score < 1, out
    pairs = re.findall(r"^  (\d\d_\w+)\s+(\w+)\s+([0-9.]+)% of the score$", out, re.MULTILINE)
    assert len(pairs) == 3
    shares = [float(s) for _, _, s in pairs]
    assert shares == sorted(shares, reverse=True)
    assert (tmp_path / "work" / "comparison.json").is_file()
    findings = int(re.search(r"^(\d+) findings$", out, re.MULTILINE).group(1))  # type: ignore[union-attr]
    # Without findings the analysis says why in a note; with findings each is printed in plain words.
    assert re.search(r"^  note: " if findings == 0 else r"^  \[\w+\] ", out, re.MULTILINE), out


def test_gym_make_and_check_env(tmp_path: Path) -> None:
    out = _run("gym_make_and_check_env.py", cwd=tmp_path)
    for twin in ("MuJoCo", "Webots"):
        line = re.search(rf"^dualtwin/CartPole-{twin}-Continuous-v0: check_env passed; (\d+) steps, reward (\d+), "
                         r"final pole angle ([-+0-9.]+) rad$", out, re.MULTILINE)
        assert line, out
        steps, reward, angle = int(line.group(1)), int(line.group(2)), float(line.group(3))
        # The example's controller balances the pole for the whole episode in both twins.
        assert steps == reward == 150 and abs(angle) < 0.3, out
