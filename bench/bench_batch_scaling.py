"""Thread scaling of align's batched candidate evaluation (issue 25): one population of the arm through
``mujoco.batch`` at several thread counts, against the one-at-a-time loop in the same run.

Run: ``python bench/bench_batch_scaling.py [--threads 1 2 4 8 16] [--candidates 26] [--scenarios 8]
[--out scaling.json]``. Needs only numpy, mujoco, pydantic (and PyYAML for the binding) and the package's own
``src`` on ``PYTHONPATH``; the package import also pulls dtaidistance (through the divergence metrics).

The workload is a population of ``--candidates`` settings of 25 knobs of the MuJoCo ``arm_payload`` twin (per
joint damping, dry friction, armature and P gain, and the flange mass; seeded), each simulating the first
``--scenarios`` scenarios of the bundled ``arm_payload`` suite, as align's CMA-ES generation does
(`dualtwin.align.simulate.Evaluator`). Rows:

* ``loop``: the one-at-a-time path in this process (``Evaluator("serial", batch="off")``, today's serial
  executor: each candidate's scenarios run on one twin, ``twin.step()`` per control period);
* ``batch T``: one batch in this process on ``T`` threads (``Evaluator("process", workers=T,
  batch="threads")``): every candidate's control period stepped as one ``mujoco.batch`` call, with the poses
  and sensors of the new state computed on the batch's threads and every candidate's channels read from the
  batch's arrays at once; the Python between periods (commands, each twin's period bookkeeping) stays serial;
* ``pool T`` (T >= 2): align's default for a MuJoCo target (``Evaluator("process", workers=T)``): the
  population split into T chunks, each a one-thread batch in a worker of the process pool, so the Python
  between periods runs in parallel too (its CPU seconds are the workers', not counted in the row's).

Each row is timed best of ``--repeats`` after a warm pass (twins built, plugin loaded); CPU seconds are the
process's, all threads. Every row's traces are compared bit for bit with the loop's. The table gives wall s,
CPU s, candidates per wall second, and the speed-up over 1 thread and over the loop; ``--out`` writes it as
JSON. The Python between periods does not scale with threads: its share bounds the speed-up (Amdahl). The
``python share`` line gives it by CPU seconds (the 1-thread batch's physics runs on the calling thread, whose
CPU time inside the batch calls is measured), which a loaded machine does not distort as it does wall
seconds; the load average is printed with the table, since wall ratios mean something only on idle cores.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import mujoco
import mujoco.batch
import numpy as np

from dualtwin.align.simulate import Evaluator, SimJob, Traces
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.loader import load_suite

JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]


def population(n: int, seed: int = 0) -> list[dict[str, float]]:
    """``n`` seeded settings of the arm fit's 25 knobs (the ranges bench_arm's executors part draws from)."""
    rng = np.random.default_rng(seed)
    return [{**{f"joint.{j}.damping": float(rng.uniform(0, 10)) for j in JOINTS},
             **{f"joint.{j}.friction": float(rng.uniform(0, 1)) for j in JOINTS},
             **{f"joint.{j}.armature": float(rng.uniform(0, 0.05)) for j in JOINTS},
             **{f"motor.{j}.kp": float(rng.uniform(8, 12)) for j in JOINTS},
             "body.wrist_3_link.mass": float(rng.uniform(3, 6))} for _ in range(n)]


def digest(results: list[Traces]) -> str:
    """A hash of every sample of every channel (bit-for-bit comparison)."""
    h = hashlib.sha256()
    for traces in results:
        for sid in sorted(traces):
            h.update(f"{sid}/{traces[sid].status}".encode())
            for name in sorted(traces[sid].series):
                series = traces[sid].series[name]
                h.update(name.encode())
                h.update(np.ascontiguousarray(series.t).tobytes())
                h.update(np.ascontiguousarray(series.y).tobytes())
    return h.hexdigest()


class _BatchClock:
    """Wall seconds spent inside ``mujoco.batch.Batch.step`` (the physics) while installed, and the calling
    thread's CPU seconds there (all of the physics on one thread: the batch's threads include the caller's)."""

    def __init__(self) -> None:
        self.wall = 0.0
        self.thread_cpu = 0.0
        self._step = mujoco.batch.Batch.step

    def __enter__(self) -> _BatchClock:
        original = self._step

        def timed(batch: Any, *args: Any, **kwargs: Any) -> None:
            start, cpu = time.perf_counter(), time.thread_time()
            original(batch, *args, **kwargs)
            self.wall += time.perf_counter() - start
            self.thread_cpu += time.thread_time() - cpu

        mujoco.batch.Batch.step = timed  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        mujoco.batch.Batch.step = self._step  # type: ignore[method-assign]


def measure(evaluator: Evaluator, jobs: list[SimJob], repeats: int) -> dict[str, Any]:
    """Best-of-``repeats`` wall (and that pass's CPU) of one map of ``jobs``, after a warm pass."""
    evaluator.map(jobs)
    best: dict[str, Any] = {"wall_s": float("inf")}
    for _ in range(repeats):
        with _BatchClock() as clock:
            cpu, wall = time.process_time(), time.perf_counter()
            results = evaluator.map(jobs)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        if wall < best["wall_s"]:
            best = {"wall_s": wall, "cpu_s": cpu, "physics_wall_s": clock.wall,
                    "physics_thread_cpu_s": clock.thread_cpu, "digest": digest(results),
                    "batched": evaluator.batched}
    return best


def run(threads: list[int], candidates: int, scenarios: int, repeats: int) -> dict[str, Any]:
    robot = resolve_robot("arm_payload")
    suite = robot.root / "suite.json"
    ids = load_suite(suite).scenario_ids()[:scenarios]
    job = SimJob(str(robot.path), "mujoco", str(suite.resolve()), tuple(ids))
    jobs = [job.with_knobs(values) for values in population(candidates)]
    rows: list[dict[str, Any]] = []
    with Evaluator("serial", batch="off") as loop:
        rows.append({"row": "loop", "threads": 1, **measure(loop, jobs, repeats)})
    for t in threads:
        with Evaluator("process", workers=t, batch="threads") as batched:
            rows.append({"row": f"batch {t}", "threads": t, **measure(batched, jobs, repeats)})
    for t in [t for t in threads if t >= 2]:
        with Evaluator("process", workers=t) as pooled:
            rows.append({"row": f"pool {t}", "threads": t, **measure(pooled, jobs, repeats)})
    loop_wall = rows[0]["wall_s"]
    one = next((r["wall_s"] for r in rows[1:] if r["threads"] == 1), None)  # the 1-thread batch
    print(f"== align's batched evaluation: {candidates} candidates x {len(ids)} scenarios of arm_payload (25 knobs), "
          f"best of {repeats}; {os.cpu_count()} CPUs, mujoco {mujoco.__version__} ==")
    print(f"  {'row':9s} {'threads':>7s} {'wall s':>8s} {'CPU s':>8s} {'cand/s':>8s} {'vs 1 thread':>11s} "
          f"{'vs loop':>8s}  traces")
    for r in rows:
        r["candidates_per_s"] = candidates / r["wall_s"]
        r["speedup_vs_loop"] = loop_wall / r["wall_s"]
        r["speedup_vs_1_thread"] = (one / r["wall_s"]) if one and r["row"] != "loop" else None
        r["identical_to_loop"] = r["digest"] == rows[0]["digest"]
        vs_one = f"{r['speedup_vs_1_thread']:10.2f}x" if r["speedup_vs_1_thread"] else f"{'-':>11s}"
        print(f"  {r['row']:9s} {r['threads']:7d} {r['wall_s']:8.2f} {r['cpu_s']:8.2f} {r['candidates_per_s']:8.2f} "
              f"{vs_one} {r['speedup_vs_loop']:7.2f}x  {'identical' if r['identical_to_loop'] else 'DIFFER'}")
    first = next((r for r in rows[1:] if r["threads"] == 1), None)
    if first is not None:
        # By CPU seconds, which a loaded machine does not distort (the wall split is printed beside it).
        physics = first["physics_thread_cpu_s"]
        share = 1.0 - physics / first["cpu_s"]
        first["python_share"] = share
        print(f"  python share of the 1-thread batch: {share:.0%} of its CPU seconds (physics {physics:.2f} of "
              f"{first['cpu_s']:.2f} CPU s; by wall {1 - first['physics_wall_s'] / first['wall_s']:.0%}); "
              f"speed-up bound {1 / share:.2f}x over 1 thread")
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    if load is not None:
        print(f"  load average after the run: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs "
              "(wall ratios need idle cores)")
    return {"candidates": candidates, "scenarios": ids, "repeats": repeats, "cpus": os.cpu_count(), "load": load,
            "machine": platform.processor() or platform.machine(), "mujoco": mujoco.__version__,
            "rows": [{k: v for k, v in r.items() if k != "digest"} for r in rows]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--candidates", type=int, default=26, help="population size (align's CMA-ES: 4 + 3 ln n)")
    parser.add_argument("--scenarios", type=int, default=8, help="first N scenarios of the arm_payload suite")
    parser.add_argument("--repeats", type=int, default=1, help="timed passes per row (best kept)")
    parser.add_argument("--out", type=Path, help="write the table as JSON")
    args = parser.parse_args()
    if min(args.threads) < 1 or args.candidates < 2 or args.scenarios < 1 or args.repeats < 1:
        parser.error("threads >= 1, candidates >= 2, scenarios >= 1 and repeats >= 1")
    result = run(sorted(set(args.threads)), args.candidates, args.scenarios, args.repeats)
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
        print(f"  written: {args.out}")


if __name__ == "__main__":
    main()
