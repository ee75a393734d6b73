"""Run the determinism stress world (tests/support/stress_worlds.py) many times and compare the outputs byte for
byte: the runs of one isolation mode with each other, and the threads runs with the process runs.

    PYTHONPATH=src:. python scripts/stress_determinism.py --runs 50 --parallel 2 --busy 1

``--parallel`` runs that many worlds at once, ``--busy`` adds that many busy-loop processes (load, so that the
controllers' requests reach the simulation in varied real-time orders). Prints the number of distinct outputs per
mode and the first differing line of each output that differs from the first; exit code 1 if any differs."""

from __future__ import annotations

import argparse
import multiprocessing
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

#: one run, in its own interpreter (as ``dualtwin webots run`` is run): the sorted lines, or the error
_RUN = """
import sys, tempfile
from pathlib import Path
from tests.support.stress_worlds import run_stress
with tempfile.TemporaryDirectory() as folder:
    print("\\n".join(run_stress(Path(folder), sys.argv[1], float(sys.argv[2]))))
"""


def _one(args: tuple[str, float]) -> str:
    isolation, jitter_s = args
    done = subprocess.run([sys.executable, "-c", _RUN, isolation, str(jitter_s)], capture_output=True, text=True,
                          timeout=120, check=False, cwd=Path(__file__).resolve().parents[1])
    return done.stdout if done.returncode == 0 else f"FAILED {done.returncode}: {done.stderr.strip()[-500:]}"


def _busy() -> None:
    while True:
        pass


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--parallel", type=int, default=2)
    parser.add_argument("--busy", type=int, default=1)
    parser.add_argument("--jitter", type=float, default=0.002, help="largest random wait in the controllers (s)")
    parser.add_argument("--modes", default="process,threads")
    args = parser.parse_args()
    busy = [multiprocessing.Process(target=_busy, daemon=True) for _ in range(args.busy)]
    for process in busy:
        process.start()
    outputs: dict[str, list[str]] = {}
    try:
        with ThreadPoolExecutor(args.parallel) as pool:
            for mode in args.modes.split(","):
                outputs[mode] = list(pool.map(_one, [(mode, args.jitter)] * args.runs))
    finally:
        for process in busy:
            process.terminate()
    reference = next(iter(outputs.values()))[0]
    differs = False
    for mode, runs in outputs.items():
        distinct = set(runs)
        print(f"{mode}: {len(runs)} runs, {len(distinct)} distinct output(s), "
              f"{sum(run != reference for run in runs)} differ from the first {next(iter(outputs))} run")
        differs = differs or len(distinct - {reference}) > 0
        for run in sorted(distinct - {reference})[:3]:  # (three examples)
            differs = True
            first = next((a, b) for a, b in zip(reference.splitlines(), run.splitlines(), strict=False) if a != b)
            print("  first:", first[0], "\n  this: ", first[1])
    return 1 if differs else 0


if __name__ == "__main__":
    raise SystemExit(main())
