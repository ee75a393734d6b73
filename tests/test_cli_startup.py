"""The command line's fixed cost: it imports what a command needs only when that command runs.

``dualtwin --help`` and a bad-input error must not pay for NumPy, SciPy, matplotlib, CMA-ES, MuJoCo, Gymnasium
or torch (issue 25: the CLI used to import scipy.stats, matplotlib.pyplot and cma before parsing anything).
Each check runs in a fresh interpreter, because this test process has long imported all of them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ["numpy", "scipy", "scipy.stats", "matplotlib", "matplotlib.pyplot", "cma", "mujoco", "gymnasium", "torch"]


def loaded_after(code: str) -> list[str]:
    """The heavy modules a fresh interpreter has imported after running ``code``."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, env=env,
                          cwd=ROOT, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return list(json.loads(done.stdout.strip().splitlines()[-1]))


def test_the_control_sees_heavy_modules() -> None:
    """The probe is able to see them: running an alignment's module imports the optimiser stack, and an interval's
    t quantile SciPy."""
    seen = loaded_after("import dualtwin.align.run\nfrom dualtwin.align.core import t_quantile\nt_quantile(3)")
    assert {"numpy", "scipy", "cma"} <= set(seen), seen


def test_an_alignment_imports_scipy_only_for_its_intervals() -> None:
    """A small fit computes no interval (a budget below 6 simulations per knob), so it does not pay for SciPy's
    import (about half a CPU-second): the module imports it where a t quantile is asked for."""
    seen = loaded_after("import dualtwin.align.run, dualtwin.align.report, dualtwin.cli.align")
    assert {"numpy", "cma"} <= set(seen) and "scipy" not in seen, seen


def test_importing_the_cli_imports_nothing_heavy() -> None:
    assert loaded_after("import dualtwin.cli") == []


def test_help_and_a_bad_input_error_import_nothing_heavy(tmp_path: Path) -> None:
    code = f"""
import contextlib, io
from dualtwin.cli import main
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    assert main(["--help"]) == 0
    assert main(["align", "--help"]) == 0
    assert main(["suite", "validate", "--scenarios", {str(tmp_path / 'missing.json')!r}]) == 2
    assert main(["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", "cartpole",
                 "--out", "x", "--seed", "nan"]) == 2
"""
    assert loaded_after(code) == []
