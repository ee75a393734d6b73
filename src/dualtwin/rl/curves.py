"""Learning curves of a training run: episode length against episode and against env steps (Figure 10's axes).

Read from the run's Monitor CSVs (``monitor/<i>.monitor.csv``: one row per finished training episode with its
reward ``r``, length ``l`` in control periods and wall time ``t`` since the env started). The envs of a vector
env finish episodes in parallel; the episodes are put in one sequence by the time they ended, and an episode's
env-step count is the sum of the lengths of the episodes before it and its own. That count is exact per env
and at most one episode per env off the vector env's own count (the other envs' unfinished episodes).

Written as ``learning_curve.csv`` and ``learning_curve.png`` into the run folder by :func:`write_learning_curve`.
The rolling mean (the paper's Figure 10 shows one) is over the last ``window`` episodes.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import write_bytes, write_text

ROLLING_WINDOW = 100


@dataclass(frozen=True)
class LearningCurve:
    """Training episodes in the order they ended."""

    episode: np.ndarray  # 1-based
    env_steps: np.ndarray  # cumulative env steps at the end of the episode
    length: np.ndarray  # control periods
    reward: np.ndarray
    rolling_length: np.ndarray  # mean length over the last `window` episodes
    window: int
    control_period_s: float | None = None

    def steps_to(self, length: float) -> int | None:
        """Env steps at which the rolling mean episode length first reaches ``length`` (None: never)."""
        hit = np.flatnonzero(self.rolling_length >= length)
        return int(self.env_steps[hit[0]]) if len(hit) else None


def _rolling(values: np.ndarray, window: int) -> np.ndarray:
    if not len(values):
        return values.astype(float)
    sums = np.cumsum(np.insert(values.astype(float), 0, 0.0))
    counts = np.minimum(np.arange(1, len(values) + 1), window)
    ends = np.arange(1, len(values) + 1)
    return (sums[ends] - sums[ends - counts]) / counts


def read_learning_curve(run: Path | str, window: int = ROLLING_WINDOW) -> LearningCurve:
    """The run's training episodes from its Monitor CSVs (empty arrays if none finished yet)."""
    folder = Path(run)
    rows: list[tuple[float, float, float]] = []
    for path in sorted((folder / "monitor").glob("*.monitor.csv")):
        with open(path, encoding="utf-8") as handle:
            lines = [line for line in handle if not line.startswith("#")]
        for row in csv.DictReader(lines):
            try:
                rows.append((float(row["t"]), float(row["r"]), float(row["l"])))
            except (KeyError, TypeError, ValueError):
                continue  # a line cut short by an interruption
    rows.sort(key=lambda item: item[0])
    reward = np.asarray([r for _, r, _ in rows], dtype=float)
    length = np.asarray([n for _, _, n in rows], dtype=float)
    period = None
    record = folder / "run.json"
    if record.is_file():
        try:
            period = json.loads(record.read_text(encoding="utf-8")).get("io", {}).get("control_period_s")
        except (OSError, json.JSONDecodeError, AttributeError):
            period = None
    return LearningCurve(np.arange(1, len(rows) + 1), np.cumsum(length).astype(np.int64), length, reward,
                         _rolling(length, window), window, period)


def curve_csv(curve: LearningCurve) -> str:
    out = io.StringIO()
    out.write("episode,env_steps,episode_length_steps,episode_reward,rolling_mean_length_steps\n")
    for i in range(len(curve.episode)):
        out.write(f"{curve.episode[i]},{curve.env_steps[i]},{curve.length[i]:g},{curve.reward[i]:g},"
                  f"{curve.rolling_length[i]:.6g}\n")
    return out.getvalue()


def plot_learning_curve(curve: LearningCurve, title: str = "") -> bytes:
    """PNG: episode length against episode (left) and against env steps (right), with the rolling mean."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    period = f"control periods of {1000 * curve.control_period_s:g} ms" if curve.control_period_s else \
        "control periods"
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, x, label in ((axes[0], curve.episode, "training episode [count]"),
                         (axes[1], curve.env_steps, f"env steps [{period}]")):
        ax.plot(x, curve.length, color="tab:blue", alpha=0.25, linewidth=0.6, label="episode")
        ax.plot(x, curve.rolling_length, color="tab:blue", linewidth=1.6,
                label=f"rolling mean, last {curve.window} episodes")
        ax.set_xlabel(label)
        ax.set_ylabel(f"episode length [{period}]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)
    return buffer.getvalue()


def write_learning_curve(run: Path | str, title: str = "", window: int = ROLLING_WINDOW) -> LearningCurve:
    """``learning_curve.csv`` and ``learning_curve.png`` in the run folder (atomic writes)."""
    folder = Path(run)
    curve = read_learning_curve(folder, window)
    write_text(folder / "learning_curve.csv", curve_csv(curve))
    write_bytes(folder / "learning_curve.png", plot_learning_curve(curve, title))
    return curve


def evaluation_line(entry: dict[str, Any], total: int) -> str:
    """One line per evaluation, as ``dualtwin train`` prints it."""
    return (f"eval at {entry['timesteps']:,}/{total:,} steps: mean reward {entry['mean_reward']:.1f} "
            f"± {entry['std_reward']:.1f}, mean length {entry.get('mean_length', float('nan')):.0f} "
            f"({entry['wall_seconds']:.0f} s)")


__all__ = ["ROLLING_WINDOW", "LearningCurve", "curve_csv", "evaluation_line", "plot_learning_curve",
           "read_learning_curve", "write_learning_curve"]
