"""Parallel Webots-twin environments (issue 25, item 4): resident memory per environment and aggregate env
steps per second for N = 1, 2, 4, 8 CartPole environments, in one process (Gymnasium's ``SyncVectorEnv``: N
twins side by side, stepped in turn) and one process each (``AsyncVectorEnv``, forkserver).

Run: ``python bench/bench_webots_envs.py`` (``--envs 1,2,4`` picks N, ``--steps`` env steps per environment).
Memory: in one process (a fresh one per row), the growth of its resident set per environment made, after the
env's modules are imported (code is shared, not per env); one process each, the mean resident set of the
worker processes (everything each worker holds: Python, NumPy, Gymnasium, ODE and the twin). The anchor is a real Webots
instance, about 1.1 GB of RAM, and one environment per Webots process. Steps per second are wall-clock: on a
machine with fewer cores than N they show how the CPU is shared, not the speed-up of N cores.
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

ENV_ID = "dualtwin/CartPole-Webots-Continuous-v0"


def make_env() -> Any:
    """One CartPole Webots-twin env (module level, so worker processes can unpickle it)."""
    import gymnasium as gym

    from dualtwin.registration import register_envs

    register_envs()
    return gym.make(ENV_ID)


def rss_mb(pid: str = "self") -> float:
    """Resident set of a process (MB), from /proc."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _run(envs: Any, n: int, steps: int) -> float:
    """Wall seconds for ``steps`` vector steps of seeded random actions (after the reset)."""
    envs.reset(seed=0)
    envs.action_space.seed(0)
    actions = [envs.action_space.sample() for _ in range(steps)]
    start = time.perf_counter()
    for action in actions:
        envs.step(action)
    return time.perf_counter() - start


def in_process(n: int, steps: int) -> dict[str, float]:
    """Runs in a fresh process of its own (see main), so that no earlier row's memory is reused."""
    import gymnasium as gym

    import dualtwin.rl.env  # noqa: F401  (the env's modules, loaded before the baseline: code is not per env)

    before = rss_mb()
    envs = gym.vector.SyncVectorEnv([make_env for _ in range(n)])
    envs.reset(seed=0)
    per_env = (rss_mb() - before) / n
    wall = _run(envs, n, steps)
    envs.close()
    return {"rss_mb_per_env": per_env, "env_steps_per_s": n * steps / wall}


def one_process_each(n: int, steps: int) -> dict[str, float]:
    import gymnasium as gym

    envs = gym.vector.AsyncVectorEnv([make_env for _ in range(n)], context="forkserver")
    envs.reset(seed=0)
    per_env = float(np.mean([rss_mb(str(p.pid)) for p in envs.processes]))
    wall = _run(envs, n, steps)
    envs.close()
    return {"rss_mb_per_env": per_env, "env_steps_per_s": n * steps / wall}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", default="1,2,4,8")
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args(argv)
    counts = [int(v) for v in args.envs.split(",")]
    out: dict[str, Any] = {}
    print("== parallel Webots-twin environments (CartPole, 32 ms control period) ==")
    print(f"  {'N':>3}  {'mode':22s} {'RSS per env':>12}  {'env steps/s (all)':>18}")
    context = multiprocessing.get_context("forkserver")
    for n in counts:
        for mode in ("one process", "one process per env"):
            if mode == "one process":
                with ProcessPoolExecutor(1, mp_context=context) as pool:
                    row = pool.submit(in_process, n, args.steps).result()
            else:
                row = one_process_each(n, args.steps)
            out[f"{mode}/{n}"] = row
            print(f"  {n:3d}  {mode:22s} {row['rss_mb_per_env']:9.0f} MB  {row['env_steps_per_s']:18,.0f}")
    return out


if __name__ == "__main__":
    main()
