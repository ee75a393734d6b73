"""Pioneer learning benchmark: PPO drives to a goal in the MuJoCo twin, then runs unchanged in the Webots twin.

Run: ``python bench/bench_pioneer_rl.py`` (or ``make bench``). Environment variables:

* ``DUALTWIN_BENCH_PIONEER_RUN``: reuse this training run folder instead of training (marked ``[reused run]``);
* ``DUALTWIN_BENCH_PIONEER_OUT``: keep the training run and the transfer report there (default: a temporary
  folder, deleted at the end);
* ``DUALTWIN_BENCH_PIONEER_EPISODES``: episodes per row (default 50).

(a) PPO with the bundled ``ppo_pioneer.yaml`` (seed 0, its own 15-minute wall budget) on
``Pioneer-DriveToGoal-MuJoCo-v0``.
(b) Transfer (``dualtwin.rl.transfer``): the final policy in the source twin and in
``Pioneer-DriveToGoal-Webots-v0``, the same seeded goals in both: mean return, success rate and the target/source
ratio of the mean return (goal: >= 90 %).
(c) Baseline measured in the same run: the hand-written proportional controller
(:func:`dualtwin.rl.drive_to_goal.proportional_action`) on the same goals in both twins, so the policy's ratio
can be read against what the physics difference alone does to a fixed feedback controller.

The sha256 of the robot files and twin modules is printed: a transfer number holds for those physics.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

import dualtwin.rl  # noqa: F401 - registers the env ids
import dualtwin.twins.mujoco
import dualtwin.twins.webots
from _common import eval_success_rates, output_folder, physics_files, training_run
from dualtwin.rl.drive_to_goal import proportional_action
from dualtwin.rl.ppo_config import DEFAULT_CONFIG

SOURCE = "dualtwin/Pioneer-DriveToGoal-MuJoCo-v0"
TARGET = "dualtwin/Pioneer-DriveToGoal-Webots-v0"
PPO_CONFIG = DEFAULT_CONFIG.parent / "ppo_pioneer.yaml"
GOAL_RATIO = 0.90


class Proportional:
    """The scripted controller behind the ``predict`` interface the transfer episode loop calls."""

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return proportional_action(obs)


def describe_run(run: Path, reused: bool) -> dict[str, Any]:
    record = json.loads((run / "run.json").read_text())
    timeline = record["evaluations"]
    successes = eval_success_rates(run)
    first_full = next((e["timesteps"] for e, s in zip(timeline, successes or [], strict=False) if s >= 1.0), None)
    result = {"run": str(run), "reused": reused, "steps": record["num_timesteps"],
              "train_seconds": record["timings"]["train_seconds"],
              "steps_per_second": record["timings"]["session_steps_per_second"],
              "eval_success_rates": successes, "first_all_success_steps": first_full}
    note = " [reused run]" if reused else ""
    print(f"  {record['num_timesteps']:,} steps in {result['train_seconds']:.0f} s "
          f"({result['steps_per_second']:,.0f} steps/s incl. updates and evaluations){note}")
    if first_full is not None:
        reached = next(e for e in timeline if e["timesteps"] == first_full)
        print(f"  first evaluation with every episode at its goal: {first_full:,} steps ({reached['wall_seconds']:.0f} s)"
              f"; evaluation success rates {', '.join(f'{s:.0%}' for s in successes or [])}")
    return result


def main() -> dict[str, Any]:
    import torch

    from dualtwin.rl import make_env
    from dualtwin.rl.transfer import run_episodes, transfer

    torch.set_num_threads(1)
    episodes = int(os.environ.get("DUALTWIN_BENCH_PIONEER_EPISODES", "50"))
    results: dict[str, Any] = {"episodes": episodes, "files_sha256": physics_files("pioneer3at", (dualtwin.twins.mujoco, dualtwin.twins.webots))}
    print("Pioneer learning benchmark (drive to a goal; PPO, bundled ppo_pioneer.yaml, seed 0, 1 torch thread)")
    print("  robot and twin files (sha256): " + ", ".join(f"{k} {v}" for k, v in results["files_sha256"].items()))
    with output_folder("DUALTWIN_BENCH_PIONEER_OUT", "pioneer-rl") as (root, keep):
        print("(a) training in the MuJoCo twin")
        start = time.perf_counter()
        run, reused = training_run(root, "DUALTWIN_BENCH_PIONEER_RUN", SOURCE, PPO_CONFIG, "ppo_pioneer")
        results["training"] = describe_run(run, reused)
        if not reused:
            results["training"]["wall_seconds"] = round(time.perf_counter() - start, 1)

        print(f"(b) transfer to the Webots twin, {episodes} episodes per row (seeds 0..{episodes - 1})")
        report = transfer(run, TARGET, episodes=episodes, seed=0, out_dir=root / "transfer")
        for row in report.rows:
            print(f"    {row.label:<28} {row.mean:.3f} ± {row.std:.3f}, success {100 * (row.success_rate or 0):.0f} %,"
                  f" mean length {np.mean(row.lengths):.0f} periods")
        ratio = report.rows[1].ratio
        results["transfer"] = report.to_dict()
        results["ratio"] = ratio
        verdict = "met" if ratio is not None and ratio >= GOAL_RATIO else "NOT met"
        print(f"  target / source mean return: {100 * (ratio or 0):.1f} % (goal >= {100 * GOAL_RATIO:.0f} %: "
              f"{verdict})")

        print("(c) baseline: the proportional controller on the same goals")
        baseline: dict[str, Any] = {}
        for label, env_id in (("source", SOURCE), ("target", TARGET)):
            env = make_env(env_id)
            try:
                rewards, lengths, _, successes = run_episodes(Proportional(), env, episodes, 0,  # type: ignore[arg-type]
                                                              record=False)
            finally:
                env.close()
            baseline[label] = {"mean": float(np.mean(rewards)), "success_rate": float(np.mean(successes or [0])),
                               "mean_length": float(np.mean(lengths))}
            print(f"    {label:<8} {baseline[label]['mean']:.3f}, success {100 * baseline[label]['success_rate']:.0f} %,"
                  f" mean length {baseline[label]['mean_length']:.0f} periods")
        baseline["ratio"] = baseline["target"]["mean"] / baseline["source"]["mean"]
        policy_vs_baseline = report.rows[0].mean / baseline["source"]["mean"]
        results["baseline"] = baseline
        print(f"  controller target / source: {100 * baseline['ratio']:.1f} %; PPO policy / controller in the "
              f"source twin: {100 * policy_vs_baseline:.1f} %")
        if keep:
            (root / "bench_pioneer_rl.json").write_text(json.dumps(results, indent=1, default=str))
    return results


if __name__ == "__main__":
    main()
