"""A run folder is untrusted data: a manifest with valid JSON but hostile content is one error line (exit 2).

Found by fuzzing ``dualtwin compare`` with structurally mutated manifests: each field below reached the
comparison unchecked and ended in a traceback (or, for a log path, a read outside the run folder).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.cli import main

T = np.arange(1, 11) * 0.032
DATA = {"00_a": {"pole_angle_rad": (T, np.sin(T)), "onboard/pole_angle_rad": (T, np.sin(T))}}


def _set(doc: Any, path: tuple[Any, ...], value: Any) -> None:
    for key in path[:-1]:
        doc = doc[key]
    doc[path[-1]] = value


@pytest.mark.parametrize(("path", "value", "expected"), [
    (("scenarios", 0, "failure"), "boom", "$.scenarios[0].failure"),
    (("seed",), [1], "$.seed"),
    (("seed",), -1, "$.seed"),
    (("control_period_s",), "x", "$.control_period_s"),
    (("tolerances",), 3, "$.tolerances"),
    (("channels", "pole_angle_rad"), None, "$.channels.pole_angle_rad"),
    (("channels",), [], "$.channels"),
    (("scenarios", 0), "00_a", "$.scenarios[0]"),
    (("scenarios", 0, "index"), "first", "$.scenarios[0].index"),
    (("scenarios", 0, "onboard"), {}, "$.scenarios[0].onboard"),
    (("scenarios", 0, "state_continuity"), [1], "$.scenarios[0].state_continuity"),
    # a log path must stay inside the run folder, like an ensemble member's
    (("scenarios", 0, "onboard"), "../../../../../../etc/passwd", "outside the run folder"),
    (("scenarios", 0, "ground_truth"), "/etc/passwd", "outside the run folder"),
])
def test_hostile_manifest_field_is_one_line_naming_it(
    make_run: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
    path: tuple[Any, ...], value: Any, expected: str,
) -> None:
    good = make_run("good", DATA)
    bad = make_run("bad", DATA)
    manifest = json.loads((bad / "manifest.json").read_text())
    manifest.pop("logs", None)  # an unverified (older) run: the fields themselves must be checked
    _set(manifest, path, value)
    (bad / "manifest.json").write_text(json.dumps(manifest))
    capsys.readouterr()
    code = main(["compare", "--reference-run", str(bad), "--target-run", str(good), "-o", str(tmp_path / "out")])
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert code == 2
    assert len(err) == 1 and str(bad / "manifest.json") in err[0] and expected in err[0], err
    assert "root:" not in err[0]  # nothing of a file outside the run folder is shown
    assert not (tmp_path / "out").exists()
