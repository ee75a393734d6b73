"""RL benchmark: PPO time-to-threshold on the MuJoCo twin, env throughput, and transfer to the Webots twin.

Run: ``python bench/bench_rl.py`` (or ``make bench``). Environment variables:

* ``DUALTWIN_BENCH_RL_SECONDS``: wall budget per training run (default 600);
* ``DUALTWIN_BENCH_RL_OUT``: keep the training runs and transfer reports there (default: a temporary folder);
* ``DUALTWIN_ALIGNED_KNOBS``: aligned knobs file for the "after alignment" transfer row.

(a) PPO (bundled config, seed 0) on ``CartPole-MuJoCo-Continuous-v0`` (as registered: cart velocity from wheel
odometry; and with the supervisor's cart velocity instead) and ``CartPole-MuJoCo-v0`` until the mean evaluation
reward reaches 95 % of the episode cap (950 of 1000) or the budget runs out.
(b) Env steps/s with random actions: our MuJoCo env vs Gymnasium's ``InvertedPendulum-v5``, interleaved.
(c) Both continuous policies transferred to ``CartPole-Webots-Continuous-v0`` when the Webots twin exists.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import sys
import tempfile
import time
import types
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import dualtwin.rl  # noqa: F401 - registers the env ids

THRESHOLD = 950.0
CONTINUOUS = "dualtwin/CartPole-MuJoCo-Continuous-v0"
DISCRETE = "dualtwin/CartPole-MuJoCo-v0"
WEBOTS = "dualtwin/CartPole-Webots-Continuous-v0"
GROUND_TRUTH_VELOCITY = {"task_kwargs": {"cart_velocity": "ground_truth"}}


def env_steps_per_second(env: gym.Env[Any, Any], steps: int = 4000) -> float:
    env.action_space.seed(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def inverted_pendulum() -> gym.Env[Any, Any] | None:
    try:
        import imageio  # noqa: F401
    except ImportError:
        # Gymnasium's MuJoCo envs import imageio only to save rendered frames (gymnasium[mujoco] pulls it in);
        # stepping never touches it, so a placeholder keeps the comparison possible without that extra.
        sys.modules["imageio"] = types.ModuleType("imageio")
    try:
        return gym.make("InvertedPendulum-v5")
    except Exception as exc:  # noqa: BLE001 - any failure only skips the comparison
        print(f"  InvertedPendulum-v5 unavailable ({type(exc).__name__}: {exc}); skipping the comparison")
        return None


def throughput() -> dict[str, float]:
    ours = gym.make(CONTINUOUS)
    theirs = inverted_pendulum()
    best_ours = best_theirs = 0.0
    # Interleaved best-of-3, so load from other processes hits both alike.
    for _ in range(3):
        best_ours = max(best_ours, env_steps_per_second(ours))
        if theirs is not None:
            best_theirs = max(best_theirs, env_steps_per_second(theirs))
    result = {"ours_steps_per_s": round(best_ours), "inverted_pendulum_steps_per_s": round(best_theirs)}
    print(f"  env steps/s, random actions: ours {best_ours:,.0f} (32 ms = 16 physics steps each)", end="")
    if theirs is not None:
        ratio = best_ours / best_theirs
        result["ratio"] = round(ratio, 3)
        print(f"; InvertedPendulum-v5 {best_theirs:,.0f} (40 ms = 2 physics steps); ratio {ratio:.2f}")
    else:
        print()
    return result


def train_to_threshold(env_id: str, out: Path, budget: float, env_kwargs: dict[str, Any] | None = None,
                       label: str | None = None) -> dict[str, Any]:
    from dualtwin.rl.train import load_config, train

    config = load_config(None).model_copy(update={"stop_reward": THRESHOLD, "n_timesteps": 5_000_000,
                                                  "max_wall_seconds": budget, "env_kwargs": env_kwargs or {}})
    start = time.perf_counter()
    train(env_id, config, out, seed=0, progress_bar=False)
    wall = time.perf_counter() - start
    record = json.loads((out / "run.json").read_text())
    reached = record["timings"]["threshold_reached"]
    best = max(record["evaluations"], key=lambda e: e["mean_reward"], default=None)
    result = {"env_id": env_id, "wall_seconds": round(wall, 1), "steps": record["num_timesteps"],
              "steps_per_second": record["timings"]["session_steps_per_second"], "threshold_reached": reached,
              "best": best}
    name = label or env_id.split("/")[-1]
    if reached:
        print(f"  {name}: mean eval reward {reached['mean_reward']:.1f} >= {THRESHOLD:.0f} after "
              f"{reached['timesteps']:,} steps, {reached['wall_seconds']:.0f} s "
              f"({result['steps_per_second']:,.0f} steps/s incl. updates and evaluations)")
    else:
        best_text = (f"best mean eval reward {best['mean_reward']:.1f} at {best['timesteps']:,} steps"
                     if best else "no evaluation")
        print(f"  {name}: threshold {THRESHOLD:.0f} not reached in {wall:.0f} s / {record['num_timesteps']:,} steps; "
              f"{best_text} ({result['steps_per_second']:,.0f} steps/s)")
    return result


def transfer_to_webots(policy_run: Path, out: Path, label: str) -> dict[str, Any] | None:
    if importlib.util.find_spec("dualtwin.twins.webots") is None:
        print(f"  skipped: the Webots twin (dualtwin.twins.webots) is not available yet, so {WEBOTS} cannot run")
        return None
    from dualtwin.rl.transfer import transfer

    aligned = os.environ.get("DUALTWIN_ALIGNED_KNOBS") or None
    # The best evaluated policy: the final one may be a worse iterate when the budget ran out.
    report = transfer(policy_run, WEBOTS, aligned=aligned, episodes=10, seed=0, out_dir=out, which="best")
    print(f"  {label}:")
    for row in report.rows:
        print(f"    {row.label:<28} {row.summary()}")
    return report.to_dict()


def main() -> dict[str, Any]:
    import torch

    torch.set_num_threads(1)
    budget = float(os.environ.get("DUALTWIN_BENCH_RL_SECONDS", "600"))
    keep = os.environ.get("DUALTWIN_BENCH_RL_OUT")
    root = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="dualtwin-bench-rl-"))
    if keep and root.exists():
        shutil.rmtree(root)
    print("RL benchmark (PPO, bundled ppo_cartpole.yaml, seed 0, 1 torch thread)")
    results: dict[str, Any] = {"budget_seconds": budget}
    print("(b) env throughput")
    results["throughput"] = throughput()
    print(f"(a) PPO until mean eval reward >= {THRESHOLD:.0f}/1000 or {budget:.0f} s")
    results["continuous"] = train_to_threshold(CONTINUOUS, root / "continuous", budget)
    # The same task with the supervisor's cart velocity instead of odometry: in the MuJoCo twin the chassis
    # creeps on its soft tyre contacts, so the true cart velocity is not the velocity the wheels (which the
    # action sets) turn at, and a memoryless policy cannot tell them apart.
    results["continuous_ground_truth"] = train_to_threshold(
        CONTINUOUS, root / "continuous_ground_truth", budget, GROUND_TRUTH_VELOCITY,
        "CartPole-MuJoCo-Continuous-v0 (supervisor cart velocity)")
    results["discrete"] = train_to_threshold(DISCRETE, root / "discrete", budget)
    print(f"(c) transfer to {WEBOTS} (10 episodes, best evaluated policy)")
    if not os.environ.get("DUALTWIN_ALIGNED_KNOBS"):
        print("  (set DUALTWIN_ALIGNED_KNOBS to an aligned knobs file for the after-alignment row)")
    results["transfer"] = transfer_to_webots(root / "continuous", root / "transfer", "continuous")
    if not keep:
        shutil.rmtree(root, ignore_errors=True)
    runs = ("continuous", "continuous_ground_truth", "discrete")
    rewards = [results[k]["best"]["mean_reward"] for k in runs if results[k]["best"]]
    results["summary"] = {"best_rewards": rewards, "mean": float(np.mean(rewards)) if rewards else None}
    return results


if __name__ == "__main__":
    main()
