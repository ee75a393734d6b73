"""Run one controller script on one world in both isolation modes (a thread of the runner, its own process) and
give what each printed and its exit code: the two must agree (tests/webots/test_controller_process_parity.py)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[2]


class Outcome(NamedTuple):
    out: str
    err: str
    code: int


def run_in_both_modes(folder: Path, world: str, script: str, duration_s: float | None = None) -> dict[str, Outcome]:
    """``world`` (its robot's controller is named ``probe``) run with ``script`` as ``probe.py``, once per isolation
    mode, each in a fresh interpreter with this checkout's ``src`` first on its path; object addresses (``0x...``)
    are the only thing made equal."""
    results: dict[str, Outcome] = {}
    for isolation in ("threads", "process"):
        project = folder / isolation
        (project / "worlds").mkdir(parents=True)
        (project / "controllers" / "probe").mkdir(parents=True)
        (project / "controllers" / "probe" / "probe.py").write_text(textwrap.dedent(script), encoding="utf-8")
        path = project / "worlds" / "w.wbt"
        path.write_text(world, encoding="utf-8")
        code = (f"from dualtwin.webots.runner import run_world; raise SystemExit(run_world({str(path)!r}, None, "
                f"{duration_s!r}, isolation={isolation!r}))")
        env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env,
                              cwd=project, check=False)
        results[isolation] = Outcome(_same_addresses(done.stdout, project), _same_addresses(done.stderr, project),
                                     done.returncode)
    return results


def _same_addresses(text: str, project: Path) -> str:
    return re.sub(r"0x[0-9a-fA-F]+", "0x?", text.replace(str(project), "<project>"))


def assert_threads_print(runs: dict[str, Outcome], expected: str) -> None:
    """The thread mode printed ``expected`` (nothing on stderr, exit 0), and a controller process did exactly the
    same."""
    assert runs["threads"] == (expected, "", 0)
    assert runs["process"] == runs["threads"]
