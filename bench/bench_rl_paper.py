"""The paper's PPO variants: Figure 10's three learning curves in one plot, and the published controller's task.

Run: ``python bench/bench_rl_paper.py [figure10] [code]`` (both by default). Environment variables:

* ``DUALTWIN_BENCH_PAPER_STEPS`` (default 1,000,000): env steps per training run;
* ``DUALTWIN_BENCH_PAPER_SECONDS`` (default 1800): wall budget per training run (whichever ends first);
* ``DUALTWIN_BENCH_PAPER_SEEDS`` (default ``0,1,2``): seeds of the published-controller variant;
* ``DUALTWIN_BENCH_PAPER_OUT``: keep the runs and ``figure10.png`` there (default: a temporary folder).

``figure10``: the text's discrete variant (``ppo_cartpole_text``: +-1.5 m/s, episodes end at |pole| > 0.3 rad
or 2,000 steps) in the Webots twin and in the MuJoCo twin, and the continuous variant
(``ppo_cartpole_continuous``) in the MuJoCo twin, seed 0. One plot of the rolling mean training-episode length
(last 100 episodes) against env steps, with the plateaus the paper reports beside ours: about 1,500 of 2,000
steps (discrete, Webots), about 400 (discrete, MuJoCo), continuous MuJoCo rising toward 500.

``code``: the published controller's variant (``ppo_cartpole_code``: +-5 rad/s wheels, 1,000-step episodes,
fixed observation ranges) in the Webots twin. Goal: rolling mean episode length >= 900 of 1,000 within 1 M steps
on 3 of 3 seeds; reported per seed as the env steps where the rolling mean first reached 900 (or the best).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import dualtwin.rl  # noqa: F401 - registers the env ids
from _common import output_folder

# (name, env id, config, the paper's reported plateau of the rolling mean episode length, how the paper puts it)
FIGURE_10 = [
    ("discrete_webots", "dualtwin/CartPole-Webots-v0", "ppo_cartpole_text", 1500.0, "about 1,500 of 2,000"),
    ("discrete_mujoco", "dualtwin/CartPole-MuJoCo-v0", "ppo_cartpole_text", 400.0, "about 400"),
    ("continuous_mujoco", "dualtwin/CartPole-MuJoCo-Continuous-v0", "ppo_cartpole_continuous", 500.0,
     "rising toward 500"),
]
CODE_ENV = "dualtwin/CartPole-Webots-v0"
CODE_GOAL = 900.0


def train_run(env_id: str, config_name: str, out: Path, seed: int, steps: int, seconds: float,
              stop: float | None = None) -> dict[str, Any]:
    """Train (or reuse a finished run, or one whose curve already reached ``stop``) and read its curve."""
    from dualtwin.rl.curves import read_learning_curve
    from dualtwin.rl.ppo_config import load_config
    from dualtwin.rl.train import train

    done = (out / "run.json").is_file() and json.loads((out / "run.json").read_text()).get("status") == "complete"
    if done or (stop is not None and (out / "monitor").is_dir() and read_learning_curve(out).steps_to(stop)):
        print(f"    reusing {out}")
    else:
        config = load_config(config_name).model_copy(update={"n_timesteps": steps, "max_wall_seconds": seconds,
                                                             "stop_episode_length": stop})
        train(env_id, config, out, seed=seed, progress_bar=False, resume=(out / "run.json").is_file(),
              report=lambda line: print(f"    {line}", flush=True))
    record = json.loads((out / "run.json").read_text())
    curve = read_learning_curve(out)
    final = float(curve.rolling_length[-1]) if len(curve.rolling_length) else None
    best = float(curve.rolling_length.max()) if len(curve.rolling_length) else None
    return {"run": str(out), "env_id": env_id, "config": config_name, "seed": seed,
            "steps": record["num_timesteps"], "train_seconds": record["timings"]["train_seconds"],
            "episodes": len(curve.episode), "final_rolling_length": final, "best_rolling_length": best,
            "steps_to_900": curve.steps_to(CODE_GOAL), "curve": curve}


def plot_figure10(results: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dualtwin.artifacts import write_bytes

    fig, ax = plt.subplots(figsize=(8, 4.8))
    colors = ["tab:blue", "tab:orange", "tab:green"]
    for (name, _, _, plateau, words), result, color in zip(FIGURE_10, results, colors, strict=True):
        curve = result["curve"]
        ax.plot(curve.env_steps, curve.rolling_length, color=color, linewidth=1.6, label=f"ours: {name}")
        ax.axhline(plateau, color=color, linestyle="--", linewidth=1.0, label=f"paper: {name}, {words}")
    ax.set_xlabel("env steps [control periods of 32 ms]")
    ax.set_ylabel("episode length, rolling mean of 100 [control periods]")
    ax.set_title("Figure 10: PPO learning curves (ours, seed 0) beside the paper's reported plateaus", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, metadata={"Software": None})
    plt.close(fig)
    write_bytes(path, buffer.getvalue())


def summary(label: str, r: dict[str, Any]) -> str:
    final = f"{r['final_rolling_length']:.0f}" if r["final_rolling_length"] is not None else "-"
    best = f"{r['best_rolling_length']:.0f}" if r["best_rolling_length"] is not None else "-"
    return (f"  {label}: {r['steps']:,} steps in {r['train_seconds']:.0f} s, {r['episodes']:,} episodes; rolling mean "
            f"episode length final {final}, best {best}")


def main(parts: list[str]) -> dict[str, Any]:
    import torch

    torch.set_num_threads(1)
    steps = int(os.environ.get("DUALTWIN_BENCH_PAPER_STEPS", "1000000"))
    seconds = float(os.environ.get("DUALTWIN_BENCH_PAPER_SECONDS", "1800"))
    seeds = [int(s) for s in os.environ.get("DUALTWIN_BENCH_PAPER_SEEDS", "0,1,2").split(",")]
    out: dict[str, Any] = {"steps": steps, "seconds": seconds}
    with output_folder("DUALTWIN_BENCH_PAPER_OUT", "rl-paper") as (root, _):
        if "figure10" in parts:
            print(f"Figure 10: {steps:,} steps or {seconds:.0f} s per run, seed 0")
            runs = []
            for name, env_id, config, _plateau, words in FIGURE_10:
                runs.append(train_run(env_id, config, root / name, 0, steps, seconds))
                print(summary(f"{name} (paper: {words})", runs[-1]), flush=True)
            plot_figure10(runs, root / "figure10.png")
            print(f"  plot: {root / 'figure10.png'}")
            out["figure10"] = [{k: v for k, v in r.items() if k != "curve"} | {"paper_plateau": p[3]}
                               for r, p in zip(runs, FIGURE_10, strict=True)]
        if "code" in parts:
            print(f"Published controller's variant in the Webots twin: rolling mean >= {CODE_GOAL:.0f} of 1,000 "
                  f"within {steps:,} steps, seeds {seeds}")
            rows = []
            for seed in seeds:
                # Stops once the rolling mean reaches the goal: the rest of the 1 M steps would measure nothing.
                rows.append(train_run(CODE_ENV, "ppo_cartpole_code", root / f"code_webots_s{seed}", seed, steps,
                                      seconds, stop=CODE_GOAL))
                reached = rows[-1]["steps_to_900"]
                print(summary(f"seed {seed}", rows[-1]) + (f"; >= 900 at {reached:,} steps" if reached else
                                                           "; 900 not reached"), flush=True)
            out["code"] = [{k: v for k, v in r.items() if k != "curve"} for r in rows]
            hits = sum(r["steps_to_900"] is not None for r in rows)
            print(f"  reached on {hits}/{len(rows)} seeds")
    return out


if __name__ == "__main__":
    start = time.perf_counter()
    result = main(sys.argv[1:] or ["figure10", "code"])
    print(json.dumps(result, indent=1))
    print(f"total {time.perf_counter() - start:.0f} s")
