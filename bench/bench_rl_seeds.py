"""Seed reliability: continuous PPO on the MuJoCo CartPole reaches >= 950 on every seed, each within 5 minutes.

Run: ``python bench/bench_rl_seeds.py``. Environment variables:

* ``DUALTWIN_BENCH_SEEDS`` (default ``0,1,2,3,4``): seeds to train;
* ``DUALTWIN_BENCH_SEEDS_BUDGET`` (default 300): wall seconds per seed;
* ``DUALTWIN_BENCH_SEEDS_CONFIG`` (default ``ppo_cartpole``): bundled config name or YAML path;
* ``DUALTWIN_BENCH_SEEDS_BASELINE=1``: also train the configuration before the fix (episodes that do not
  end when the pole falls, in one process) on the same seeds and budget, and print the ratio of
  steps-to-950 (a baseline measured in the same run);
* ``DUALTWIN_BENCH_SEEDS_OUT``: keep the runs there (default: a temporary folder, deleted at the end).

Each run stops at the first evaluation (5 deterministic episodes, every 20,480 steps) whose mean reward is
>= 950 of 1,000. Reported per seed: env steps and wall seconds to that evaluation, or the best reached. The
wall time depends on the machine's other load; steps-to-950 does not.
"""

from __future__ import annotations

import json
import os
import statistics
import time
from pathlib import Path
from typing import Any

import dualtwin.rl  # noqa: F401 - registers the env ids
from _common import output_folder

ENV_ID = "dualtwin/CartPole-MuJoCo-Continuous-v0"
THRESHOLD = 950.0


def train_seed(config_name: str, seed: int, out: Path, budget: float, baseline: bool = False) -> dict[str, Any]:
    from dualtwin.rl.ppo_config import load_config
    from dualtwin.rl.train import train

    config = load_config(config_name)
    update: dict[str, Any] = {"stop_reward": THRESHOLD, "n_timesteps": 5_000_000, "max_wall_seconds": budget}
    if baseline:
        update |= {"env_kwargs": {}, "vec_env": "dummy"}
    config = config.model_copy(update=update)
    start = time.perf_counter()
    train(ENV_ID, config, out, seed=seed, progress_bar=False)
    wall = time.perf_counter() - start
    record = json.loads((out / "run.json").read_text())
    reached = next((e for e in record["evaluations"] if e["mean_reward"] >= THRESHOLD), None)
    best = max(record["evaluations"], key=lambda e: e["mean_reward"], default=None)
    return {"seed": seed, "reached": reached is not None,
            "steps_to_950": reached["timesteps"] if reached else None,
            "seconds_to_950": reached["wall_seconds"] if reached else None,
            "steps": record["num_timesteps"], "wall_seconds": round(wall, 1),
            "best_mean_reward": best["mean_reward"] if best else None,
            "steps_per_second": record["timings"]["session_steps_per_second"]}


def line(label: str, r: dict[str, Any]) -> str:
    if r["reached"]:
        return (f"  {label} seed {r['seed']}: >= 950 after {r['steps_to_950']:,} steps, {r['seconds_to_950']:.0f} s "
                f"({r['steps_per_second']:,.0f} steps/s incl. updates and evaluations)")
    return (f"  {label} seed {r['seed']}: not reached in {r['wall_seconds']:.0f} s / {r['steps']:,} steps "
            f"(best {r['best_mean_reward']:.0f})")


def main() -> dict[str, Any]:
    import torch

    torch.set_num_threads(1)
    seeds = [int(s) for s in os.environ.get("DUALTWIN_BENCH_SEEDS", "0,1,2,3,4").split(",")]
    budget = float(os.environ.get("DUALTWIN_BENCH_SEEDS_BUDGET", "300"))
    config = os.environ.get("DUALTWIN_BENCH_SEEDS_CONFIG", "ppo_cartpole")
    baseline = os.environ.get("DUALTWIN_BENCH_SEEDS_BASELINE") == "1"
    print(f"PPO seed reliability: {ENV_ID}, config {config}, seeds {seeds}, {budget:.0f} s budget each, "
          f"{os.cpu_count()} cores")
    results: dict[str, Any] = {"config": config, "budget_seconds": budget, "seeds": {}}
    with output_folder("DUALTWIN_BENCH_SEEDS_OUT", "rl-seeds") as (root, _):
        rows = []
        for seed in seeds:
            rows.append(train_seed(config, seed, root / f"{config}_s{seed}", budget))
            print(line("fixed", rows[-1]), flush=True)
        results["seeds"] = rows
        hits = [r for r in rows if r["reached"]]
        results["reached"] = f"{len(hits)}/{len(rows)}"
        if hits:
            results["median_steps_to_950"] = statistics.median(r["steps_to_950"] for r in hits)
            results["median_seconds_to_950"] = statistics.median(r["seconds_to_950"] for r in hits)
        print(f"  reached 950 on {len(hits)}/{len(rows)} seeds"
              + (f"; median {results['median_steps_to_950']:,.0f} steps, {results['median_seconds_to_950']:.0f} s"
                 if hits else ""))
        if baseline:
            base = []
            for seed in seeds:
                base.append(train_seed(config, seed, root / f"baseline_s{seed}", budget, baseline=True))
                print(line("before the fix", base[-1]), flush=True)
            results["baseline"] = base
            # Runs that did not reach 950 count with the steps they used (a lower bound on their steps-to-950).
            fixed = statistics.median(r["steps_to_950"] or r["steps"] for r in rows)
            before = statistics.median(r["steps_to_950"] or r["steps"] for r in base)
            results["steps_ratio_before_over_fixed"] = round(before / fixed, 2)
            print(f"  baseline reached 950 on {sum(r['reached'] for r in base)}/{len(base)} seeds; median "
                  f"steps-to-950 before/after the fix >= {before / fixed:.1f}x (unreached runs count their steps)")
    return results


if __name__ == "__main__":
    print(json.dumps(main(), indent=1))
