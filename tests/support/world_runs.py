"""Run a world through the command line in a child process: where a crash of the process (an abort inside ODE)
must fail a test, not end pytest."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def run_world_cli(folder: Path, name: str, world: str, controller: str) -> subprocess.CompletedProcess[str]:
    """``dualtwin webots run NAME.wbt --controller ...`` (both files written to ``folder``) in a child interpreter
    with this checkout's ``src`` first on its path; output captured."""
    path = folder / f"{name}.wbt"
    path.write_text(world, encoding="utf-8")
    script = folder / f"{name}_controller.py"
    script.write_text(controller, encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "dualtwin.cli", "webots", "run", str(path), "--controller",
                           str(script)], capture_output=True, text=True, timeout=120, env=env, cwd=ROOT, check=False)

