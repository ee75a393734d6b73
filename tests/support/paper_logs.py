"""Paper-format recordings of the bundled CartPole suite with chosen starts, ends and clocks (shared by the
recorded-run and CLI tests)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualtwin.robots.binding import BUNDLED
from dualtwin.suite.loader import load_suite

SUITE = BUNDLED / "cartpole" / "suite.json"
PERIOD = 0.032


def write_logs(folder: Path, starts: list[float], ends: list[float], stamps: str = "simulation",
               seed: int = 0) -> Path:
    """The paper's orchestrator files for the bundled suite: the pole at the suite's initial angle, the cart
    moving linearly from ``starts[i]`` to ``ends[i]``; stamps from a simulation or a jittery wall clock."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    for i, sc in enumerate(load_suite(SUITE).scenarios):
        n = round(sc.duration_s / PERIOD)
        if stamps == "simulation":
            t = np.arange(1, n + 1) * PERIOD
        else:  # the OS wakes the sleeper on its 15.6 ms tick: gaps of 2, 3 or 4 ticks
            t = PERIOD + np.concatenate([[0.0], np.cumsum(rng.choice([0.0312, 0.0469, 0.0625], n - 1,
                                                                     p=[0.8, 0.15, 0.05]))])
            t = t[t <= sc.duration_s]
        angle = float(sc.inputs.get("initial_angle", 0.0))
        x = np.linspace(starts[i], ends[i], t.size)
        lines = ["time_s\tpole_angle_rad\tcart_pos_m"] + [f"{a:.4f}\t{angle:.4f}\t{b:.4f}" for a, b in zip(t, x, strict=True)]
        (folder / f"simulation_log_SUP_{i}.tsv").write_text("\n".join(lines) + "\n")
    return folder
