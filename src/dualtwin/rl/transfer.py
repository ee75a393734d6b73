"""Train in one twin, evaluate in the other (the paper's Pattern 1 / Table 1).

The policy runs deterministically, with its training-time normalisation, in: the source env (where it was
trained), the target env as is, and (given aligned knobs) the target env with those knobs applied at every
reset. Each row gets per-episode rewards, mean ± sd and the ratio to the source mean. Episode ``i`` of every
row starts from the same seed (``seed + i``), so rows differ only by the twin and its knobs.

Output folder: ``transfer.json``, ``report.md`` and ``trajectory.png`` (episode 0: pole angle and cart
position over time, every row overlaid).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import package_versions, write_json, write_text
from dualtwin.errors import DualtwinError
from dualtwin.rl.policy import LoadedPolicy, check_contract, load_policy


@dataclass
class Trajectory:
    """Ground truth of one episode, sampled after every control period."""

    time_s: list[float] = field(default_factory=list)
    pole_angle_rad: list[float] = field(default_factory=list)
    cart_position_m: list[float] = field(default_factory=list)


@dataclass
class EvalRow:
    """One row of the transfer table."""

    label: str
    env_id: str
    knobs: dict[str, float] | None
    rewards: list[float]
    lengths: list[int]
    mean: float
    std: float
    ratio: float | None = None
    trajectory: Trajectory | None = field(default=None, repr=False)

    def summary(self) -> str:
        ratio = f" = {100 * self.ratio:.1f} %" if self.ratio is not None else ""
        return f"{self.mean:.1f} ± {self.std:.1f}{ratio}"


@dataclass
class TransferReport:
    """Source, target-before and (optionally) target-after-alignment rows, with ratios to the source."""

    policy_run: str
    source_env: str
    target_env: str
    episodes: int
    seed: int
    rows: list[EvalRow]
    aligned_knobs: dict[str, float] | None = None
    out_dir: Path | None = None

    def row(self, label: str) -> EvalRow:
        for r in self.rows:
            if r.label == label:
                return r
        raise KeyError(label)

    def to_dict(self) -> dict[str, Any]:
        rows = []
        for r in self.rows:
            item = asdict(r)
            item.pop("trajectory", None)
            rows.append(item)
        return {"policy_run": self.policy_run, "source_env": self.source_env, "target_env": self.target_env,
                "episodes": self.episodes, "seed": self.seed, "aligned_knobs": self.aligned_knobs,
                "std": "sample standard deviation (ddof=1) over episodes", "rows": rows,
                "versions": package_versions()}

    def markdown(self) -> str:
        lines = [
            "# Policy transfer", "",
            f"Policy `{self.policy_run}`, trained on `{self.source_env}`; target `{self.target_env}`. "
            f"{self.episodes} deterministic episodes per row, seeds {self.seed}..{self.seed + self.episodes - 1}.",
            "", "| Evaluated in | Env | Reward (mean ± sd) | vs source |", "|---|---|---|---|",
        ]
        for r in self.rows:
            ratio = f"{100 * r.ratio:.1f} %" if r.ratio is not None else "–"
            lines.append(f"| {r.label} | `{r.env_id}` | {r.mean:.1f} ± {r.std:.1f} | {ratio} |")
        if self.aligned_knobs:
            lines += ["", "Aligned knobs applied in the target:", ""]
            lines += [f"- `{k}` = {v:g}" for k, v in sorted(self.aligned_knobs.items())]
        lines += ["", "Per-episode rewards:", ""]
        lines += [f"- {r.label}: {', '.join(f'{x:g}' for x in r.rewards)}" for r in self.rows]
        lines += ["", "![trajectory](trajectory.png)", ""]
        return "\n".join(lines)


def run_episodes(policy: LoadedPolicy, env: Any, episodes: int, seed: int, record: bool = True
                 ) -> tuple[list[float], list[int], Trajectory | None]:
    """Deterministic episodes; episode ``i`` resets with ``seed + i``. Records episode 0's ground truth."""
    rewards: list[float] = []
    lengths: list[int] = []
    trajectory = Trajectory() if record else None
    period = float(getattr(env.unwrapped, "control_period", 0.0))
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        total, steps, done = 0.0, 0, False
        while not done:
            if trajectory is not None and i == 0:
                trajectory.time_s.append(round(steps * period, 9))
                trajectory.pole_angle_rad.append(float(info.get("true_pole_angle", math.nan)))
                trajectory.cart_position_m.append(float(info.get("true_cart_position", math.nan)))
            obs, reward, terminated, truncated, info = env.step(policy.predict(obs))
            total += float(reward)
            steps += 1
            done = terminated or truncated
        rewards.append(total)
        lengths.append(steps)
    return rewards, lengths, trajectory


def _stats(values: list[float]) -> tuple[float, float]:
    array = np.asarray(values, dtype=float)
    return float(array.mean()), float(array.std(ddof=1)) if len(array) > 1 else 0.0


def transfer(policy_run: Path | str, target_env_id: str, *, aligned: Path | str | dict[str, Any] | None = None,
             episodes: int = 10, seed: int = 0, out_dir: Path | str | None = None,
             target_kwargs: dict[str, Any] | None = None, max_episode_steps: int | None = None,
             which: str = "final") -> TransferReport:
    """Evaluate a trained policy in its source env and in ``target_env_id`` (before and after alignment).

    Args:
        policy_run: training run folder (:func:`dualtwin.rl.train.train`).
        target_env_id: registered dualtwin env id to transfer to.
        aligned: aligned knob values for the target (file or dict, see :func:`dualtwin.rl.apply_knobs`).
        episodes: episodes per row.
        seed: episode ``i`` resets with ``seed + i`` in every row.
        out_dir: write ``transfer.json``, ``report.md`` and ``trajectory.png`` here.
        target_kwargs: extra ``gym.make`` arguments for the target (e.g. ``knobs`` to stand in for another twin);
            the policy's ``task_kwargs`` are passed on unless given here.
        max_episode_steps: episode cap for every row (default: the training run's).
        which: ``"final"`` or ``"best"`` model of the run.
    """
    from dualtwin.rl import check_env_id, make_env
    from dualtwin.rl.randomize import apply_knobs, load_knob_values

    if episodes < 1:
        raise DualtwinError(f"episodes must be >= 1, got {episodes}")
    check_env_id(target_env_id)
    policy = load_policy(policy_run, "best" if which == "best" else "final")
    caps = {"max_episode_steps": max_episode_steps} if max_episode_steps is not None else {}
    source = policy.make_env(**caps)
    limit = max_episode_steps or policy.max_episode_steps
    # The task (and so the observation and action meaning) carries over; twin-specific knobs do not.
    task = {"task_kwargs": policy.env_kwargs["task_kwargs"]} if policy.env_kwargs.get("task_kwargs") else {}
    target_args = {**task, **(target_kwargs or {}), **({"max_episode_steps": limit} if limit else {})}
    target = make_env(target_env_id, **target_args)
    # Refuse before simulating anything if the policy cannot read this env's observations or drive its actions.
    target_env: Any = target.unwrapped
    check_contract(policy.contract, target_env.io_contract(), target_env_id)
    knobs = load_knob_values(aligned) if aligned is not None else None

    plan: list[tuple[str, str, Any, dict[str, float] | None]] = [
        ("source", policy.env_id, source, None), ("target (before alignment)", target_env_id, target, None)]
    if knobs is not None:
        aligned_env = apply_knobs(make_env(target_env_id, **target_args), knobs)
        plan.append(("target (after alignment)", target_env_id, aligned_env, knobs))
    rows: list[EvalRow] = []
    try:
        for label, env_id, env, row_knobs in plan:
            rewards, lengths, trajectory = run_episodes(policy, env, episodes, seed)
            mean, std = _stats(rewards)
            rows.append(EvalRow(label, env_id, row_knobs, rewards, lengths, mean, std, trajectory=trajectory))
    finally:
        for _, _, env, _ in plan:
            env.close()
    base = rows[0].mean
    for r in rows:
        r.ratio = r.mean / base if base > 0 else None
    report = TransferReport(str(policy_run), policy.env_id, target_env_id, episodes, seed, rows, knobs)
    if out_dir is not None:
        write_report(report, Path(out_dir))
    return report


def plot_trajectories(report: TransferReport, path: Path) -> None:
    """Episode 0 of every row: pole angle and cart position against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_pole, ax_cart) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for r in report.rows:
        if r.trajectory is None:
            continue
        t = r.trajectory
        ax_pole.plot(t.time_s, t.pole_angle_rad, label=f"{r.label} ({r.env_id})", linewidth=1.2)
        ax_cart.plot(t.time_s, t.cart_position_m, linewidth=1.2)
    ax_pole.axhline(0.3, color="grey", linestyle=":", linewidth=0.8)
    ax_pole.axhline(-0.3, color="grey", linestyle=":", linewidth=0.8)
    ax_pole.set_ylabel("pole angle [rad]")
    ax_cart.set_ylabel("cart position [m]")
    ax_cart.set_xlabel("time [s]")
    ax_pole.legend(fontsize=8, loc="best")
    ax_pole.set_title(f"Episode 0 (seed {report.seed}), ground truth")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)


def write_report(report: TransferReport, out: Path) -> None:
    """``transfer.json``, ``report.md`` and ``trajectory.png`` in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    plot_trajectories(report, out / "trajectory.png")
    write_json(out / "transfer.json", report.to_dict())
    write_text(out / "report.md", report.markdown())
    report.out_dir = out
