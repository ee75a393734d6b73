"""Why PPO was seed-fragile on the CartPole: controlled runs that change one thing at a time.

Run: ``python bench/bench_rl_ablation.py VARIANT SEED [STEPS]`` (one run; the README's experiment table is a
set of these). Every run is continuous PPO on ``dualtwin/CartPole-MuJoCo-Continuous-v0`` from the bundled
``ppo_cartpole`` config, in one process (``vec_env: dummy``, so runs can share the cores), stopping at the first
evaluation >= 950 of 1,000 or after STEPS env steps (default 300,000). Variants:

* ``before``: the episode goes on when the pole falls (the old setup), gSDE with log std -3;
* ``terminate``: the episode ends at |pole| > 0.3 rad (the bundled config);
* ``terminate_white``: the same, with white Gaussian noise instead of gSDE (log std -1: 0.55 m/s);
* ``before_sde1``: the old setup with a larger gSDE scale (log std -1), to see whether exploration alone helps.

Prints one JSON line: the steps and wall seconds to >= 950 (or null) and the evaluation timeline.
``DUALTWIN_BENCH_ABLATION_OUT`` keeps the run (default: a temporary folder).
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import dualtwin.rl  # noqa: F401 - registers the env ids
from _common import output_folder

ENV_ID = "dualtwin/CartPole-MuJoCo-Continuous-v0"
BEFORE: dict[str, Any] = {"env_kwargs": {}}
VARIANTS: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    # name: (config fields, policy_kwargs fields)
    "before": (BEFORE, {}),
    "terminate": ({}, {}),
    "terminate_white": ({"use_sde": False}, {"log_std_init": -1.0}),
    "before_sde1": (BEFORE, {"log_std_init": -1.0}),
}


def main(variant: str, seed: int, steps: int) -> dict[str, Any]:
    import torch

    from dualtwin.rl.ppo_config import load_config
    from dualtwin.rl.train import train

    torch.set_num_threads(1)
    fields, policy = VARIANTS[variant]
    base = load_config("ppo_cartpole")
    config = base.model_copy(update={"stop_reward": 950.0, "n_timesteps": steps, "vec_env": "dummy", **fields,
                                     "policy_kwargs": base.policy_kwargs.model_copy(update=policy)})
    with output_folder("DUALTWIN_BENCH_ABLATION_OUT", "rl-ablation") as (root, _):
        out = root / f"{variant}_s{seed}"
        start = time.perf_counter()
        train(ENV_ID, config, out, seed=seed, progress_bar=False)
        wall = time.perf_counter() - start
        record = json.loads((out / "run.json").read_text())
    reached = next((e for e in record["evaluations"] if e["mean_reward"] >= 950), None)
    best = max(record["evaluations"], key=lambda e: e["mean_reward"], default=None)
    return {"variant": variant, "seed": seed, "steps": record["num_timesteps"], "wall_seconds": round(wall, 1),
            "steps_to_950": reached["timesteps"] if reached else None,
            "best_mean_reward": best["mean_reward"] if best else None,
            "evaluations": [(e["timesteps"], round(e["mean_reward"])) for e in record["evaluations"]]}


if __name__ == "__main__":
    if len(sys.argv) < 3 or sys.argv[1] not in VARIANTS:
        sys.exit(f"usage: bench_rl_ablation.py {{{','.join(VARIANTS)}}} SEED [STEPS]")
    print(json.dumps(main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 300_000)))
