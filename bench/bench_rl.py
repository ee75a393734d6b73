"""RL benchmark: PPO time-to-threshold on the MuJoCo twin, env throughput, and transfer to the Webots twin.

Run: ``python bench/bench_rl.py`` (or ``make bench``). Environment variables:

* ``DUALTWIN_BENCH_RL_SECONDS``: wall budget per training run (default 600);
* ``DUALTWIN_BENCH_RL_OUT``: keep the training runs, the alignment and the transfer report there (default: a
  temporary folder, deleted at the end);
* ``DUALTWIN_BENCH_RL_REUSE=1``: reuse the complete runs (and the alignment) already in ``DUALTWIN_BENCH_RL_OUT``
  instead of training again;
* ``DUALTWIN_BENCH_RL_RUN_<NAME>``: reuse this run folder for ``<NAME>`` (``CONTINUOUS``,
  ``CONTINUOUS_GROUND_TRUTH``, ``DISCRETE``, ``ALIGNED``, ``CONTROL``, ``DR``); ``DUALTWIN_BENCH_RL_ALIGN``: this
  alignment output folder (``knobs.json``, ``dr_ranges.json``).

A reused run is reported from its ``run.json`` (marked ``[reused run]``); the env throughput and Table 1 are
always measured in this run.

(a) PPO (bundled config, seed 0) on ``CartPole-MuJoCo-Continuous-v0`` until the mean evaluation reward reaches
990 of 1000 (the converged source of Table 1), and, with the supervisor's cart velocity instead of odometry, and
on ``CartPole-MuJoCo-v0``, until 950 of 1000; or until the budget runs out.
(b) Env steps/s with random actions: our MuJoCo env vs Gymnasium's ``InvertedPendulum-v5``, interleaved.
(c) ``dualtwin align --reference webots --target mujoco`` (least squares, the knobs, channel and held-out scenario of
``dualtwin demo`` and bench_align.py), then the
continuous policy of (a) fine-tuned (learning rate 3e-5) for 102,400 steps in the aligned MuJoCo twin
(``train(aligned=knobs.json, init_from=...)``), in the nominal MuJoCo twin (the control: the same fine-tuning
without alignment) and with its calibrated domain randomisation (``train(dr_ranges=dr_ranges.json, ...)``).
(d) Table 1: the nominal, aligned, control and DR policies in ``CartPole-Webots-Continuous-v0`` (10 episodes
each), with the source rows, mean ± sd and ratios to the one converged source; what alignment adds beyond
fine-tuning is the aligned row's ratio minus the control's.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import sys
import time
import types
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import dualtwin.rl  # noqa: F401 - registers the env ids
from _common import output_folder

THRESHOLD = 950.0
# Table 1's source must be converged, so that no fine-tuned row can gain by finishing its training.
SOURCE_THRESHOLD = 990.0
CONTINUOUS = "dualtwin/CartPole-MuJoCo-Continuous-v0"
DISCRETE = "dualtwin/CartPole-MuJoCo-v0"
WEBOTS = "dualtwin/CartPole-Webots-Continuous-v0"
GROUND_TRUTH_VELOCITY = {"task_kwargs": {"cart_velocity": "ground_truth"}}
FINE_TUNE_STEPS = 102_400


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
    result: dict[str, float] = {"ours_steps_per_s": round(best_ours),
                                "inverted_pendulum_steps_per_s": round(best_theirs)}
    print(f"  env steps/s, random actions: ours {best_ours:,.0f} (32 ms = 16 physics steps each)", end="")
    if theirs is not None:
        ratio = best_ours / best_theirs
        result["ratio"] = round(ratio, 3)
        print(f"; InvertedPendulum-v5 {best_theirs:,.0f} (40 ms = 2 physics steps); ratio {ratio:.2f}")
    else:
        print()
    return result


def summarise(out: Path, label: str, wall: float | None = None) -> dict[str, Any]:
    """What a (finished) training run reached, from its run.json; ``wall`` is None for a reused run."""
    record = json.loads((out / "run.json").read_text())
    # From the timeline rather than run.json's threshold_reached, which needs the run's own stop_reward
    # (fine-tuning runs have none).
    threshold = record["config"].get("stop_reward") or THRESHOLD
    reached = next((e for e in record["evaluations"] if e["mean_reward"] >= threshold), None)
    best = max(record["evaluations"], key=lambda e: e["mean_reward"], default=None)
    seconds = record["timings"]["train_seconds"]
    result = {"env_id": record["env_id"], "run": str(out), "reused": wall is None, "wall_seconds": round(seconds, 1),
              "steps": record["num_timesteps"], "steps_per_second": record["timings"]["session_steps_per_second"],
              "threshold_reached": reached, "best": best}
    reused = " [reused run]" if wall is None else ""
    if reached:
        print(f"  {label}: mean eval reward {reached['mean_reward']:.1f} >= {threshold:.0f} after "
              f"{reached['timesteps']:,} steps, {reached['wall_seconds']:.0f} s "
              f"({result['steps_per_second']:,.0f} steps/s incl. updates and evaluations){reused}")
    else:
        best_text = (f"best mean eval reward {best['mean_reward']:.1f} at {best['timesteps']:,} steps"
                     if best else "no evaluation")
        print(f"  {label}: threshold {threshold:.0f} not reached in {seconds:.0f} s / {record['num_timesteps']:,} "
              f"steps; {best_text} ({result['steps_per_second']:,.0f} steps/s){reused}")
    return result


def reusable(name: str, root: Path) -> Path | None:
    """``DUALTWIN_BENCH_RL_RUN_<NAME>``, else (with ``DUALTWIN_BENCH_RL_REUSE=1``) a complete ``root/name``."""
    given = os.environ.get(f"DUALTWIN_BENCH_RL_RUN_{name.upper()}")
    if given:
        return Path(given)
    out = root / name
    complete = (out / "run.json").is_file() and json.loads((out / "run.json").read_text()).get("status") == "complete"
    return out if os.environ.get("DUALTWIN_BENCH_RL_REUSE") == "1" and complete else None


def reused_or_fresh(name: str, root: Path) -> tuple[Path, bool]:
    """(run folder, whether it is a finished run to reuse); a fresh folder is emptied first."""
    reuse = reusable(name, root)
    if reuse is not None:
        return reuse, True
    out = root / name
    if out.exists():
        shutil.rmtree(out)
    return out, False


def train_to_threshold(name: str, env_id: str, root: Path, budget: float, env_kwargs: dict[str, Any] | None = None,
                       label: str | None = None, threshold: float = THRESHOLD, **train_kwargs: Any) -> dict[str, Any]:
    from dualtwin.rl.ppo_config import load_config
    from dualtwin.rl.train import train

    label = label or env_id.split("/")[-1]
    out, reused = reused_or_fresh(name, root)
    if reused:
        return summarise(out, label)
    base = load_config(None)
    # Extra env arguments go on top of the config's (which end episodes when the pole falls).
    merged = {**base.env_kwargs, **(env_kwargs or {})}
    if env_kwargs and "task_kwargs" in env_kwargs:
        merged["task_kwargs"] = {**base.env_kwargs.get("task_kwargs", {}), **env_kwargs["task_kwargs"]}
    config = base.model_copy(update={"stop_reward": threshold, "n_timesteps": 5_000_000,
                                     "max_wall_seconds": budget, "env_kwargs": merged})
    start = time.perf_counter()
    train(env_id, config, out, seed=0, progress_bar=False, **train_kwargs)
    return summarise(out, label, time.perf_counter() - start)


def fine_tune(name: str, root: Path, start: Path, label: str, **train_kwargs: Any) -> dict[str, Any]:
    """FINE_TUNE_STEPS of PPO from ``start``'s best policy in the aligned twin or with DR (not to a threshold)."""
    from dualtwin.rl.ppo_config import load_config
    from dualtwin.rl.train import train

    out, reused = reused_or_fresh(name, root)
    if reused:
        return summarise(out, label)
    # A tenth of the learning rate: at 3e-4 both fine-tunings drifted off the converged policy (DR: mean
    # evaluation reward 811 -> 306 within 100 k steps).
    config = load_config(None).model_copy(update={"n_timesteps": FINE_TUNE_STEPS, "learning_rate": 3e-5})
    started = time.perf_counter()
    train(CONTINUOUS, config, out, seed=0, progress_bar=False, init_from=start, **train_kwargs)
    return summarise(out, label, time.perf_counter() - started)


def alignment(root: Path) -> Path:
    """The MuJoCo twin aligned to the Webots twin as ``dualtwin demo`` and bench_align.py align it, or a reused one."""
    given = os.environ.get("DUALTWIN_BENCH_RL_ALIGN")
    out = Path(given) if given else root / "align"
    if given or (os.environ.get("DUALTWIN_BENCH_RL_REUSE") == "1" and (out / "knobs.json").is_file()):
        print(f"  reusing {out}")
    else:
        from dualtwin.align import AlignConfig, run_align
        from dualtwin.demo import CHANNELS, HOLDOUT, KNOBS
        from dualtwin.robots.binding import BUNDLED

        if out.exists():
            shutil.rmtree(out)
        start = time.perf_counter()
        run_align(AlignConfig(reference="webots", target="mujoco", robot="cartpole",
                              suite=str(BUNDLED / "cartpole" / "suite.json"), knobs=list(KNOBS),
                              optimizer="lsq", budget=300, holdout=HOLDOUT, channels=CHANNELS), out)
        print(f"  least squares, {len(KNOBS)} knobs, {time.perf_counter() - start:.0f} s")
    fitted = json.loads((out / "knobs.json").read_text())["knobs"]
    ranges = json.loads((out / "dr_ranges.json").read_text())["knobs"]
    for name, entry in fitted.items():
        r = ranges[name]
        print(f"    {name:<36} {entry['nominal']:g} -> {entry['fitted']:.4g}; DR range [{r['low']:.4g}, "
              f"{r['high']:.4g}]")
    return out


def table_1(runs: dict[str, Path], out: Path) -> dict[str, Any] | None:
    if importlib.util.find_spec("dualtwin.twins.webots") is None:
        print(f"  skipped: the Webots twin (dualtwin.twins.webots) is not available yet, so {WEBOTS} cannot run")
        return None
    from dualtwin.rl.transfer import transfer

    # The best evaluated policy of each run: the final one may be a worse iterate when the budget ran out.
    report = transfer(runs["continuous"], WEBOTS, policy_aligned=runs["aligned"], policy_dr=runs["dr"],
                      policy_control=runs["control"], episodes=10, seed=0, out_dir=out, which="best")
    for row in report.rows:
        print(f"    {row.label:<40} {row.summary()}")
    converged = "converged" if report.source_converged else "NOT converged (< 990): ratios overstate the gains"
    print(f"  source: {report.rows[0].mean:.1f} in MuJoCo, {converged}")
    if report.alignment_gain is not None:
        print(f"  alignment beyond the same fine-tuning in the nominal twin: {100 * report.alignment_gain:+.1f} "
              "percentage points of the source reward in Webots")
    print(f"  (report: {out / 'report.md'})")
    return report.to_dict()


def main() -> dict[str, Any]:
    import torch

    torch.set_num_threads(1)
    budget = float(os.environ.get("DUALTWIN_BENCH_RL_SECONDS", "600"))
    print("RL benchmark (PPO, bundled ppo_cartpole.yaml, seed 0, 1 torch thread)")
    results: dict[str, Any] = {"budget_seconds": budget}
    with output_folder("DUALTWIN_BENCH_RL_OUT", "rl") as (root, _):
        print("(b) env throughput")
        results["throughput"] = throughput()
        print(f"(a) PPO until mean eval reward >= {SOURCE_THRESHOLD:.0f} (source) or {THRESHOLD:.0f}/1000, "
          f"or {budget:.0f} s")
        results["continuous"] = train_to_threshold("continuous", CONTINUOUS, root, budget,
                                                   threshold=SOURCE_THRESHOLD)
        # The same task with the supervisor's cart velocity instead of odometry: in the MuJoCo twin the chassis
        # creeps on its soft tyre contacts, so the true cart velocity is not the velocity the wheels (which the
        # action sets) turn at, and a memoryless policy cannot tell them apart.
        results["continuous_ground_truth"] = train_to_threshold(
            "continuous_ground_truth", CONTINUOUS, root, budget, GROUND_TRUTH_VELOCITY,
            "CartPole-MuJoCo-Continuous-v0 (supervisor cart velocity)")
        results["discrete"] = train_to_threshold("discrete", DISCRETE, root, budget)
        print("(c) align the MuJoCo twin to the Webots twin (the knobs and DR ranges for Table 1)")
        aligned = alignment(root)
        # Fine-tuned from the nominal policy: from scratch, seed 0 PPO takes off only after ~450 k steps and other
        # random streams (these knobs, DR draws) can miss the 10-minute budget (see the README).
        start = Path(results["continuous"]["run"])
        results["aligned"] = fine_tune("aligned", root, start, "fine-tuned in the aligned MuJoCo twin",
                                       aligned=aligned / "knobs.json")
        results["control"] = fine_tune("control", root, start, "fine-tuned in the nominal MuJoCo twin (control)")
        results["dr"] = fine_tune("dr", root, start, "fine-tuned with calibrated DR", dr_ranges=aligned / "dr_ranges.json")
        print(f"(d) Table 1: transfer to {WEBOTS} (10 episodes per row, best evaluated policies)")
        runs = {name: Path(results[name]["run"]) for name in ("continuous", "aligned", "control", "dr")}
        results["transfer"] = table_1(runs, root / "transfer")
    names = ("continuous", "continuous_ground_truth", "discrete", "aligned", "control", "dr")
    rewards = [results[k]["best"]["mean_reward"] for k in names if results[k]["best"]]
    results["summary"] = {"best_rewards": rewards, "mean": float(np.mean(rewards)) if rewards else None}
    return results


if __name__ == "__main__":
    main()
