"""CLI fixed cost: wall time of ``dualtwin --help`` and of a bad-input error, against a bare interpreter.

Run: ``python bench/bench_cli_startup.py [SRC ...]`` (default: this checkout's ``src``; give another checkout's
``src`` too to compare, e.g. the commit before the change, in the same run). Goal (issue 25): ``dualtwin --help`` <= 0.5 s wall. The ratio is
the command's wall time over ``python -c pass`` (the interpreter's own start-up, which no command can avoid).
Each figure is the best of several runs, so a busy machine's hiccups do not count; the machine's load is shown.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNS = 7


def best_wall(argv: list[str], src: Path = ROOT / "src") -> float:
    env = {**os.environ, "PYTHONPATH": str(src) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    best = float("inf")
    for _ in range(RUNS):
        start = time.perf_counter()
        subprocess.run(argv, env=env, capture_output=True, check=False)
        best = min(best, time.perf_counter() - start)
    return best


def main(sources: list[Path] | None = None) -> dict[str, float]:
    cli = [sys.executable, "-c", "from dualtwin.cli import main; main()"]
    bare = best_wall([sys.executable, "-c", "pass"])
    out = {"bare_s": bare}
    for src in sources or [ROOT / "src"]:
        helped = best_wall([*cli, "--help"], src)
        error = best_wall([*cli, "suite", "validate", "--scenarios", "missing.json"], src)
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        print(f"CLI start-up of {src} (best of {RUNS}, load {load:.1f} on {os.cpu_count()} cores): python -c pass "
              f"{bare:.3f} s; dualtwin --help {helped:.3f} s ({helped / bare:.1f}x bare; goal <= 0.5 s); "
              f"bad-input error {error:.3f} s ({error / bare:.1f}x bare)")
        out.update({f"{src}:help_s": helped, f"{src}:error_s": error})
    return out


if __name__ == "__main__":
    main([Path(a) for a in sys.argv[1:]] or None)
