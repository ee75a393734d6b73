"""Webots' own physics regression tests (the developers' half in ``../shared/conformance/webots-physics``), one
pytest item per Webots test, through the suite's own ``run.sh`` and the installed ``dualtwin`` command.

The suite's worlds, PROTOs and checks are data kept beside the project (never copied into it): each item runs
``run.sh <test>`` exactly as a user would and requires every check of that test to pass. Skipped when
``../shared`` is absent.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

#: Webots tests a check of which still fails, with the reason; strict, so one that starts passing must leave.
KNOWN_FAILING = {
    "connector_detach": "check 2: the locked pair separates at 0.448 s, not 0.736 s; the pulled robot tips at a "
                        "1.1 N pull once its floor contacts drop to one point (see the coverage page)",
}

SUITE = Path(__file__).resolve().parents[3] / "shared" / "conformance" / "webots-physics"  # ../shared


def _tests() -> list[str]:
    table = SUITE / "tests.tsv"
    if not table.is_file():
        return []
    names = []
    for line in table.read_text().splitlines():
        fields = line.split("\t")
        if line.strip() and not line.startswith("#") and not (len(fields) > 4 and fields[4].startswith("SKIP")):
            names.append(fields[0])
    return names


def _dualtwin() -> str:
    beside = Path(sys.executable).parent / "dualtwin"  # the venv's console script, as `make test` installs it
    found = str(beside) if beside.is_file() else shutil.which("dualtwin")
    if found is None:
        pytest.skip("no dualtwin command installed")
    return found


@pytest.mark.skipif(not SUITE.is_dir(), reason="../shared/conformance/webots-physics is not present")
@pytest.mark.parametrize("test", [
    pytest.param(name, marks=pytest.mark.xfail(strict=True, reason=KNOWN_FAILING[name]))
    if name in KNOWN_FAILING else name
    for name in _tests() or ["(none)"]])
def test_webots_physics_regression_test_passes(test: str, tmp_path: Path) -> None:
    env = {**os.environ, "DUALTWIN": _dualtwin(), "LOGS": str(tmp_path), "TIMEOUT_S": "240",
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[2] / "src"),
                                          os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(["bash", str(SUITE / "run.sh"), test], capture_output=True, text=True, env=env,
                          timeout=600)
    summary = re.search(r"(\d+)/(\d+) tests, (\d+)/(\d+) checks", done.stdout)
    assert summary is not None, done.stdout + done.stderr
    log = tmp_path / f"{test}.log"
    detail = log.read_text()[-3000:] if log.is_file() else ""
    passed, total = int(summary.group(3)), int(summary.group(4))
    assert total > 0 and passed == total, f"{done.stdout}\n--- log tail ---\n{detail}"


@pytest.mark.skipif(not SUITE.is_dir(), reason="../shared/conformance/webots-physics is not present")
def test_the_coverage_page_states_the_figures_these_items_give() -> None:
    """The coverage page restates the suite's figure (the product does not ship the suite): it must agree with
    the suite's own table (tests, checks) and with the failures this file knows of (one failing check each)."""
    from dualtwin.webots.coverage import CONFORMANCE

    table = [line.split("\t") for line in (SUITE / "tests.tsv").read_text().splitlines()
             if line.strip() and not line.startswith("#")]
    counted = [fields for fields in table if not (len(fields) > 4 and fields[4].startswith("SKIP"))]
    assert CONFORMANCE.tests == (len(counted) - len(KNOWN_FAILING), len(counted))
    total_checks = sum(int(fields[3]) for fields in counted)
    assert CONFORMANCE.checks == (total_checks - len(KNOWN_FAILING), total_checks)
    assert [what.split(",")[0] for what in CONFORMANCE.failing] == sorted(KNOWN_FAILING)
