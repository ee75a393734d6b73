"""The fixed cost of a small alignment (issue 25): CPU seconds of ``dualtwin align --budget 4`` on the CartPole,
and the size of its report, on the CartPole and (``--arm``) on the arm.

Run: ``python bench/bench_align_cost.py [--arm] [SRC ...]`` (default: this checkout's ``src``; name another
checkout's ``src`` too, e.g. the commit before a change, to compare both in one run on the same machine).
Goals: ``align --budget 4`` on the CartPole <= 3 CPU-seconds in total; the arm's report <= 1 MB.

CPU time, not wall time: the machine may be shared. The command runs with ``--executor serial``, so every
simulation is in the measured process (a process pool's workers are the fork server's children, and their
time is lost when it exits before reaping them); the default executor's figure is printed beside it. Each
figure is the best of ``--runs`` runs, with their median beside it. Several source folders are measured in
turns (one run of each, then the next round), so a change of the machine's load falls on all of them alike
rather than on whichever was measured last. The command, as a user types it::

    dualtwin align --reference webots --target mujoco --robot cartpole --scenarios cartpole \\
        --knobs 'joint.pole_hinge.*' --budget 4 --out OUT

Bytecode: an installed package runs from its compiled ``.pyc`` files, so the command runs with bytecode
written to a cache of this bench's own (``PYTHONPYCACHEPREFIX``, even where ``PYTHONDONTWRITEBYTECODE`` is
set, and never into the checkouts): the first run of each source folder compiles (a warm-up, not counted),
the runs that count read the cache.

The arm run fits one knob (``joint.elbow.damping``, budget 2): its report's size is set by the suite (13
scenarios, every channel), not by the fit.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CARTPOLE = ["--robot", "cartpole", "--scenarios", "cartpole", "--knobs", "joint.pole_hinge.*", "--budget", "4"]
ARM = ["--robot", "arm", "--scenarios", "arm", "--knobs", "joint.elbow.damping", "--budget", "2"]
CPU_GOAL_S = 3.0
ARM_REPORT_GOAL_B = 1_000_000


def align_cpu(src: Path, args: list[str], executor: str, pycache: Path) -> tuple[float, int]:
    """CPU seconds (user + system, the command and the children it reaped) and report.html bytes of one run."""
    env = {**os.environ, "PYTHONPATH": str(src) + os.pathsep + os.environ.get("PYTHONPATH", ""), "MUJOCO_GL": "egl",
           "PYTHONPYCACHEPREFIX": str(pycache)}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run([sys.executable, "-c", "from dualtwin.cli import main; main()", "align", "--reference",
                               "webots", "--target", "mujoco", *args, "--executor", executor, "--out", str(out)],
                              env=env, capture_output=True, text=True, check=False)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            raise SystemExit(f"align failed ({src}):\n{done.stderr[-2000:]}")
        size = (out / "report.html").stat().st_size
        shutil.rmtree(out)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), size


def main() -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sources", nargs="*", type=Path, help="src folders to compare (default: this checkout's)")
    parser.add_argument("--arm", action="store_true", help="also the arm's report size (minutes)")
    parser.add_argument("--runs", type=int, default=2, help="runs per figure (the best counts)")
    ns = parser.parse_args()
    sources = [src.resolve() for src in ns.sources or [ROOT / "src"]]
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as caches:
        pycache = {src: Path(caches) / str(i) for i, src in enumerate(sources)}
        for src in sources:
            align_cpu(src, CARTPOLE, "serial", pycache[src])  # warm-up: compiles the bytecode
        serial = in_turns(sources, pycache, "serial", ns.runs)
        pooled = in_turns(sources, pycache, "process", ns.runs)
        for src in sources:
            out.update(report(src, pycache[src], serial[src], pooled[src], ns.arm))
    return out


def in_turns(sources: list[Path], pycache: dict[Path, Path], executor: str,
             runs: int) -> dict[Path, list[tuple[float, int]]]:
    """``runs`` runs of each source folder, one of each per round."""
    out: dict[Path, list[tuple[float, int]]] = {src: [] for src in sources}
    for _ in range(runs):
        for src in sources:
            out[src].append(align_cpu(src, CARTPOLE, executor, pycache[src]))
    return out


def report(src: Path, pycache: Path, serial_runs: list[tuple[float, int]], pooled_runs: list[tuple[float, int]],
           arm: bool) -> dict[str, float]:
    """Print and return one source folder's figures (the best run's, and the median CPU beside it)."""
    out: dict[str, float] = {}
    serial, pooled = min(serial_runs), min(pooled_runs)
    load = os.getloadavg()[0]
    print(f"{src} (load {load:.1f} on {os.cpu_count()} cores):")
    print(f"  align --budget 4, CartPole, serial executor   {serial[0]:6.2f} CPU-s (goal <= {CPU_GOAL_S:g})  "
          f"report {serial[1] / 1000:7.1f} kB  (median {statistics.median(c for c, _ in serial_runs):.2f})")
    print(f"  align --budget 4, CartPole, process pool      {pooled[0]:6.2f} CPU-s (workers' time may be missing)")
    out.update({f"{src}:cartpole_cpu_s": serial[0], f"{src}:cartpole_pool_cpu_s": pooled[0],
                f"{src}:cartpole_report_bytes": serial[1]})
    if arm:
        cpu, size = align_cpu(src, ARM, "serial", pycache)
        print(f"  align --budget 2, arm (1 knob), serial         {cpu:6.2f} CPU-s  report {size / 1000:7.1f} kB "
              f"(goal <= {ARM_REPORT_GOAL_B / 1e6:g} MB)")
        out.update({f"{src}:arm_cpu_s": cpu, f"{src}:arm_report_bytes": size})
    return out


if __name__ == "__main__":
    main()
