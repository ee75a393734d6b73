"""The fixed cost of a small alignment (issue 25): CPU seconds of ``dualtwin align --budget 4`` on the CartPole,
and the size of its report, on the CartPole and (``--arm``) on the arm.

Run: ``python bench/bench_align_cost.py [--arm] [SRC ...]`` (default: this checkout's ``src``; name another
checkout's ``src`` too, e.g. the commit before a change, to compare both in one run on the same machine).
Goals: ``align --budget 4`` on the CartPole <= 3 CPU-seconds in total; the arm's report <= 1 MB.

CPU time, not wall time: the machine may be shared. The command runs with ``--executor serial``, so every
simulation is in the measured process (a process pool's workers are the fork server's children, and their
time is lost when it exits before reaping them); the default executor's figure is printed beside it. Each
figure is the best of ``--runs`` runs. The command, as a user types it::

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
    out: dict[str, float] = {}
    for src in ns.sources or [ROOT / "src"]:
        with tempfile.TemporaryDirectory() as pycache:
            out.update(measure(src.resolve(), Path(pycache), ns.runs, ns.arm))
    return out


def measure(src: Path, pycache: Path, runs: int, arm: bool) -> dict[str, float]:
    """One source folder's figures (bytecode compiled into ``pycache`` by a warm-up run first)."""
    out: dict[str, float] = {}
    align_cpu(src, CARTPOLE, "serial", pycache)  # warm-up: compiles the bytecode
    serial = min(align_cpu(src, CARTPOLE, "serial", pycache) for _ in range(runs))
    pooled = min(align_cpu(src, CARTPOLE, "process", pycache) for _ in range(runs))
    load = os.getloadavg()[0]
    print(f"{src} (load {load:.1f} on {os.cpu_count()} cores):")
    print(f"  align --budget 4, CartPole, serial executor   {serial[0]:6.2f} CPU-s (goal <= {CPU_GOAL_S:g})  "
          f"report {serial[1] / 1000:7.1f} kB")
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
