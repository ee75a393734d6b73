"""`dualtwin compare` on runs with different channel sets: shared ones compared, the rest listed, JSON out."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests.support.rundirs import CHANNELS, cartpole_like

T = np.arange(1, 63) * 0.032


def dualtwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "dualtwin.cli", *args], capture_output=True, text=True,
                          timeout=120)


def test_compare_fewer_channels_json_and_nothing_shared(tmp_path: Path, make_run: Callable[..., Path]) -> None:
    a = make_run("a", {"00_Step": cartpole_like(T), "01_Push": cartpole_like(T)})
    pole = {"pole_angle_rad": CHANNELS["pole_angle_rad"]}
    b = make_run("b", {"00_Step": {"pole_angle_rad": cartpole_like(T, delay=0.1)["pole_angle_rad"]}}, channels=pole)
    proc = dualtwin("compare", "--reference-run", str(a), "--target-run", str(b),
                    "--out", str(tmp_path / "out"), "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert [s["id"] for s in result["scenarios"]] == ["00_Step"]
    assert set(result["left_out"]["channels"]) == {"cart_pos_m", "wheel_vel_rad_s"}
    assert result["left_out"]["scenarios"]["01_Push"].startswith("only in A")
    saved = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert saved["comparison"]["left_out"] == result["left_out"]
    page = (tmp_path / "out" / "report.html").read_text()
    assert "Left out" in page and "only in A" in page
    table = dualtwin("compare", "--reference-run", str(a), "--target-run", str(b),
                     "--out", str(tmp_path / "out2"))
    assert "left out channel cart_pos_m: only in A" in table.stdout

    cart = make_run("c", {"00_Step": {"cart_pos_m": cartpole_like(T)["cart_pos_m"]}},
                    channels={"cart_pos_m": CHANNELS["cart_pos_m"]})
    bad = dualtwin("compare", "--reference-run", str(b), "--target-run", str(cart),
                   "--out", str(tmp_path / "never"))
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    errors = [line for line in bad.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and errors[0].startswith("error: runs are not comparable: no channel in common")
    assert not (tmp_path / "never").exists()

    manifest = json.loads((cart / "manifest.json").read_text())
    manifest["suite_name"] = "another"
    (cart / "manifest.json").write_text(json.dumps(manifest))
    other = dualtwin("compare", "--reference-run", str(a), "--target-run", str(cart),
                     "--out", str(tmp_path / "never"))
    errors = [line for line in other.stderr.splitlines() if line.startswith("error:")]
    assert other.returncode == 2 and len(errors) == 1 and "suites differ" in errors[0]
    assert "Traceback" not in other.stderr
