"""Train in one twin, evaluate in the other (the paper's Pattern 1 / Table 1).

The policy runs deterministically, with its training-time normalisation, in the source env (where it was
trained) and in the target env. The paper's workflow for the other rows: align the *source* twin to the target
(``dualtwin align --reference webots --target mujoco``), train in the aligned source twin
(``dualtwin train --aligned knobs.json``) and validate that policy in the nominal target; likewise a policy
trained with the calibrated domain randomisation (``dualtwin train --dr dr_ranges.json``). The target is never
modified: it stands for the real system. Each row gets per-episode rewards, mean ± sd and the ratio to the
source mean. Episode ``i`` of every row starts from the same seed (``seed + i``), so rows differ only by the
policy, the twin and its knobs.

The control row. A policy fine-tuned in the aligned twin has had more training than the source policy, so
"after alignment" beating "before alignment" does not by itself show that alignment helped. The control is
the same fine-tuning (same start, steps and settings) in the *nominal* source twin
(``dualtwin train --init-from SOURCE`` without ``--aligned``), evaluated in the target:
``policy_control``. What alignment adds beyond fine-tuning is the aligned row's ratio minus the control row's
(``alignment_gain``). Every ratio is to the one source row, which should be converged (``source_converged``:
mean >= 99 % of the episode cap) so that no row can gain by finishing the source's training.

Output folder: ``transfer.json``, ``report.md`` and ``trajectory.png`` (episode 0: pole angle and cart
position over time, every row overlaid).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import package_versions, write_json, write_text
from dualtwin.errors import DualtwinError
from dualtwin.rl.policy import LoadedPolicy, check_contract, load_policy

AFTER_ALIGNMENT = "target (after alignment)"
CONTROL = "target (fine-tuned in the nominal twin)"
# A source is converged when it balances this share of the episode cap (990 of 1000).
CONVERGED = 0.99


@dataclass
class Trajectory:
    """Ground truth of one episode, sampled after every control period."""

    time_s: list[float] = field(default_factory=list)
    pole_angle_rad: list[float] = field(default_factory=list)
    cart_position_m: list[float] = field(default_factory=list)
    # Mobile-robot tasks (info "true_x"/"true_y", "goal_x"/"goal_y"): the path seen from above.
    x_m: list[float] = field(default_factory=list)
    y_m: list[float] = field(default_factory=list)
    goal: tuple[float, float] | None = None


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
    policy_run: str | None = None
    # Per episode, for tasks that report Gymnasium's info["is_success"] at the end of an episode.
    successes: list[bool] | None = None

    @property
    def success_rate(self) -> float | None:
        return sum(self.successes) / len(self.successes) if self.successes else None

    def summary(self) -> str:
        ratio = f" = {100 * self.ratio:.1f} %" if self.ratio is not None else ""
        success = f", success {100 * self.success_rate:.0f} %" if self.success_rate is not None else ""
        return f"{self.mean:.1f} ± {self.std:.1f}{ratio}{success}"


@dataclass
class TransferReport:
    """Source, target-before and (optionally) after-alignment and with-DR rows, with ratios to the source."""

    policy_run: str
    source_env: str
    target_env: str
    episodes: int
    seed: int
    rows: list[EvalRow]
    aligned: dict[str, Any] | None = None
    dr_ranges: dict[str, Any] | None = None
    out_dir: Path | None = None
    episode_cap: int | None = None

    @property
    def source_converged(self) -> bool | None:
        """Whether the source row balances >= 99 % of the episode cap (None: no cap known)."""
        if not self.episode_cap:
            return None
        return self.rows[0].mean >= CONVERGED * self.episode_cap

    @property
    def alignment_gain(self) -> float | None:
        """Target ratio after alignment minus the fine-tuning control's (None without both rows)."""
        labels = {r.label: r for r in self.rows}
        aligned, control = labels.get(AFTER_ALIGNMENT), labels.get(CONTROL)
        if aligned is None or control is None or aligned.ratio is None or control.ratio is None:
            return None
        return aligned.ratio - control.ratio

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
            item["success_rate"] = r.success_rate
            rows.append(item)
        return {"policy_run": self.policy_run, "source_env": self.source_env, "target_env": self.target_env,
                "episodes": self.episodes, "seed": self.seed, "aligned": self.aligned, "dr_ranges": self.dr_ranges,
                "episode_cap": self.episode_cap, "source_converged": self.source_converged,
                "alignment_gain": self.alignment_gain,
                "std": "sample standard deviation (ddof=1) over episodes", "rows": rows,
                "versions": package_versions()}

    def markdown(self) -> str:
        lines = [
            "# Policy transfer", "",
            f"Policy `{self.policy_run}`, trained on `{self.source_env}`; target `{self.target_env}`. "
            f"{self.episodes} deterministic episodes per row, seeds {self.seed}..{self.seed + self.episodes - 1}; "
            "ratios are to the source row.",
            "", "| Evaluated in | Env | Policy run | Reward (mean ± sd) | vs source |", "|---|---|---|---|---|",
        ]
        for r in self.rows:
            ratio = f"{100 * r.ratio:.1f} %" if r.ratio is not None else "–"
            lines.append(f"| {r.label} | `{r.env_id}` | `{r.policy_run}` | {r.mean:.1f} ± {r.std:.1f} | {ratio} |")
        if self.source_converged is False:
            lines += ["", f"**The source is not converged** ({self.rows[0].mean:.1f} < {CONVERGED:.0%} of the "
                      f"{self.episode_cap}-step cap): rows trained for longer can gain by finishing its training, "
                      "so their ratios overstate what transfer, alignment or DR did."]
        gain = self.alignment_gain
        if gain is not None:
            lines += ["", f"What alignment adds beyond the same fine-tuning in the nominal twin: "
                      f"{100 * gain:+.1f} percentage points of the source reward in the target "
                      f"({AFTER_ALIGNMENT} vs {CONTROL})."]
        if self.aligned:
            where = f" (`{self.aligned['file']}`, sha256 {self.aligned.get('sha256', '')[:12]})" \
                if self.aligned.get("file") else ""
            lines += ["", f"The after-alignment policy was trained with these knobs in the source twin{where}:", ""]
            lines += [f"- `{k}` = {v:g}" for k, v in sorted(self.aligned["values"].items())]
        if self.dr_ranges:
            lines += ["", "The DR policy was trained with values drawn at every reset from:", ""]
            lines += [f"- `{k}` in [{v['low']:g}, {v['high']:g}]" for k, v in sorted(self.dr_ranges.items())]
        lines += ["", "Per-episode rewards:", ""]
        lines += [f"- {r.label}: {', '.join(f'{x:g}' for x in r.rewards)}" for r in self.rows]
        if any(r.successes for r in self.rows):
            lines += ["", "Success rate (the task's `is_success` at the end of each episode):", ""]
            lines += [f"- {r.label}: {sum(r.successes)}/{len(r.successes)}" for r in self.rows if r.successes]
        lines += ["", "![trajectory](trajectory.png)", ""]
        return "\n".join(lines)


def run_episodes(policy: LoadedPolicy, env: Any, episodes: int, seed: int, record: bool = True
                 ) -> tuple[list[float], list[int], Trajectory | None, list[bool] | None]:
    """Deterministic episodes; episode ``i`` resets with ``seed + i``. Records episode 0's ground truth.

    Returns rewards, lengths, episode 0's trajectory and, if the env reports ``info["is_success"]``, successes.
    """
    rewards: list[float] = []
    lengths: list[int] = []
    successes: list[bool] = []
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
                trajectory.x_m.append(float(info.get("true_x", math.nan)))
                trajectory.y_m.append(float(info.get("true_y", math.nan)))
                if "goal_x" in info:
                    trajectory.goal = (float(info["goal_x"]), float(info["goal_y"]))
            obs, reward, terminated, truncated, info = env.step(policy.predict(obs))
            total += float(reward)
            steps += 1
            done = terminated or truncated
        rewards.append(total)
        lengths.append(steps)
        if "is_success" in info:
            successes.append(bool(info["is_success"]))
    return rewards, lengths, trajectory, successes if len(successes) == episodes else None


def _stats(values: list[float]) -> tuple[float, float]:
    array = np.asarray(values, dtype=float)
    return float(array.mean()), float(array.std(ddof=1)) if len(array) > 1 else 0.0


def _companion(path: Path | str, which: str, main: LoadedPolicy, role: str) -> LoadedPolicy:
    """Load the aligned or DR-trained policy; it must have been trained on the main policy's source env id."""
    policy = load_policy(path, "best" if which == "best" else "final")
    if policy.env_id != main.env_id:
        raise DualtwinError(f"{path}: the {role} policy was trained on {policy.env_id!r}, the policy on "
                            f"{main.env_id!r}; all policies of one transfer report must come from the same env")
    return policy


def robot_and_task(env_id: str, kwargs: Mapping[str, Any] | None = None) -> tuple[str, str]:
    """The robot and task an env id runs (its registered arguments over the env's defaults, then ``kwargs``)."""
    import inspect

    import gymnasium as gym

    from dualtwin.rl.env import TwinEnv

    defaults = {name: p.default for name, p in inspect.signature(TwinEnv.__init__).parameters.items()
                if name in ("robot", "task")}
    merged = {**defaults, **dict(gym.spec(env_id).kwargs), **dict(kwargs or {})}
    return str(merged["robot"]), str(merged["task"])


def transfer(policy_run: Path | str, target_env_id: str, *, policy_aligned: Path | str | None = None,
             policy_dr: Path | str | None = None, policy_control: Path | str | None = None,
             episodes: int = 10, seed: int = 0,
             out_dir: Path | str | None = None, target_kwargs: dict[str, Any] | None = None,
             max_episode_steps: int | None = None, which: str = "final") -> TransferReport:
    """Evaluate policies trained in one twin in ``target_env_id``: the paper's Table 1.

    Rows: ``source`` (``policy_run`` in its own training env), ``target (before alignment)`` (the same policy in
    the target), and, when given, ``target (after alignment)`` (``policy_aligned``: trained with
    ``train(aligned=knobs.json)`` in the source twin aligned to the target) and ``target (with calibrated DR)``
    (``policy_dr``: trained with ``train(dr_ranges=dr_ranges.json)``). Each of those two also gets a row in
    its own training env. Ratios are to the ``source`` row's mean, as in the paper.

    Args:
        policy_run: training run folder (:func:`dualtwin.rl.train.train`) of the policy trained on the nominal twin.
        target_env_id: registered dualtwin env id to transfer to.
        policy_aligned: run folder of a policy trained in the aligned source twin (same env id as ``policy_run``).
        policy_dr: run folder of a policy trained with calibrated domain randomisation (same env id).
        policy_control: run folder of the control: the aligned policy's fine-tuning repeated in the nominal
            source twin (``train(init_from=...)`` without ``aligned``); rows ``source (fine-tuned, nominal
            twin)`` and ``target (fine-tuned in the nominal twin)``.
        episodes: episodes per row.
        seed: episode ``i`` resets with ``seed + i`` in every row.
        out_dir: write ``transfer.json``, ``report.md`` and ``trajectory.png`` here.
        target_kwargs: extra ``gym.make`` arguments for the target (e.g. ``knobs`` to stand in for another twin);
            the policy's ``task_kwargs`` are passed on unless given here.
        max_episode_steps: episode cap for every row (default: the training run's).
        which: ``"final"`` or ``"best"`` model of every run.
    """
    from dualtwin.rl import check_env_id, make_env

    if episodes < 1:
        raise DualtwinError(f"episodes must be >= 1, got {episodes}")
    check_env_id(target_env_id)
    policy = load_policy(policy_run, "best" if which == "best" else "final")
    trained_for = robot_and_task(policy.env_id, policy.env_kwargs)
    target_runs = robot_and_task(target_env_id, target_kwargs)
    if trained_for != target_runs:
        raise DualtwinError(
            f"{policy_run}: this policy was trained for robot {trained_for[0]!r}, task {trained_for[1]!r} "
            f"({policy.env_id}); {target_env_id} runs robot {target_runs[0]!r}, task {target_runs[1]!r}. Transfer "
            "moves a policy between the twins of one robot and task: pick that robot's env id in the other twin")
    companions: list[tuple[str, str, LoadedPolicy]] = []
    if policy_aligned is not None:
        aligned_policy = _companion(policy_aligned, which, policy, "aligned")
        record = _run_record(aligned_policy)
        if not record.get("aligned"):
            raise DualtwinError(f"{policy_aligned}: not trained in an aligned twin (run.json has no 'aligned' "
                                "knobs); train it with `dualtwin train --aligned knobs.json`")
        companions.append(("source (aligned twin)", AFTER_ALIGNMENT, aligned_policy))
    if policy_control is not None:
        control_policy = _companion(policy_control, which, policy, "control")
        control_record = _run_record(control_policy)
        if control_record.get("aligned") or control_record.get("dr_ranges") or not control_record.get("init_from"):
            raise DualtwinError(f"{policy_control}: the control must be fine-tuned in the nominal twin (train "
                                "--init-from SOURCE, without --aligned or --dr); run.json says otherwise")
        if policy_aligned is not None:
            _check_same_fine_tuning(_run_record(aligned_policy), control_record, policy_aligned, policy_control)
        companions.append(("source (fine-tuned, nominal twin)", CONTROL, control_policy))
    if policy_dr is not None:
        dr_policy = _companion(policy_dr, which, policy, "domain-randomised")
        if not _run_record(dr_policy).get("dr_ranges"):
            raise DualtwinError(f"{policy_dr}: not trained with domain randomisation (run.json has no "
                                "'dr_ranges'); train it with `dualtwin train --dr dr_ranges.json`")
        # Its source row is the nominal twin: randomisation is a training device, not the twin it runs in.
        companions.append(("source (trained with DR)", "target (with calibrated DR)", dr_policy))
    caps = {"max_episode_steps": max_episode_steps} if max_episode_steps is not None else {}
    limit = max_episode_steps or policy.max_episode_steps
    # The task (and so the observation and action meaning) carries over; twin-specific knobs do not.
    task = {"task_kwargs": policy.env_kwargs["task_kwargs"]} if policy.env_kwargs.get("task_kwargs") else {}
    target_args = {**task, **(target_kwargs or {}), **({"max_episode_steps": limit} if limit else {})}
    # Refuse before simulating anything if a policy cannot read this env's observations or drive its actions.
    probe: Any = make_env(target_env_id, **target_args)
    try:
        for _, _, p in [("", "", policy), *companions]:
            check_contract(p.contract, probe.unwrapped.io_contract(), target_env_id)
    finally:
        probe.close()

    plan: list[tuple[str, LoadedPolicy, str, Any]] = [
        ("source", policy, policy.env_id, lambda: policy.make_env(**caps)),
        ("target (before alignment)", policy, target_env_id, lambda: make_env(target_env_id, **target_args))]
    for source_label, target_label, p in companions:
        plan.append((source_label, p, p.env_id, lambda p=p: p.make_env(**caps)))
        plan.append((target_label, p, target_env_id, lambda: make_env(target_env_id, **target_args)))
    rows: list[EvalRow] = []
    for label, p, env_id, build in plan:
        env = build()
        try:
            rewards, lengths, trajectory, successes = run_episodes(p, env, episodes, seed)
            knobs = dict(getattr(env.unwrapped, "base_knobs", {}) or {}) or None
        finally:
            env.close()
        mean, std = _stats(rewards)
        rows.append(EvalRow(label, env_id, knobs, rewards, lengths, mean, std, trajectory=trajectory,
                            policy_run=str(p.run_dir), successes=successes))
    base = rows[0].mean
    for r in rows:
        r.ratio = r.mean / base if base > 0 else None
    aligned = _run_record(companions[0][2]).get("aligned") if policy_aligned is not None else None
    dr = _run_record(companions[-1][2]).get("dr_ranges") if policy_dr is not None else None
    report = TransferReport(str(policy_run), policy.env_id, target_env_id, episodes, seed, rows,
                            aligned=aligned, dr_ranges=dr, episode_cap=limit)
    if out_dir is not None:
        write_report(report, Path(out_dir))
    return report


def _check_same_fine_tuning(aligned: dict[str, Any], control: dict[str, Any], aligned_path: Path | str,
                            control_path: Path | str) -> None:
    """The control differs from the aligned fine-tuning only by the knobs: same start, steps, seed and config."""
    def key(record: dict[str, Any]) -> dict[str, Any]:
        config = {k: v for k, v in (record.get("config") or {}).items() if k != "env_kwargs"}
        return {"initial policy": (record.get("init_from") or {}).get("sha256"), "seed": record.get("seed"),
                "steps": record.get("total_timesteps"), "config": config}

    a, c = key(aligned), key(control)
    differ = [name for name in a if a[name] != c[name]]
    if differ:
        raise DualtwinError(f"{control_path}: not the same fine-tuning as {aligned_path} ({', '.join(differ)} "
                            "differ); the control must repeat it in the nominal twin")


def _run_record(policy: LoadedPolicy) -> dict[str, Any]:
    import json

    record: dict[str, Any] = json.loads((policy.run_dir / "run.json").read_text(encoding="utf-8"))
    return record


def plot_trajectories(report: TransferReport, path: Path) -> None:
    """Episode 0 of every row: pole angle and cart position against time, or the path for mobile robots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = [(r, r.trajectory) for r in report.rows
             if r.trajectory is not None and np.isfinite(r.trajectory.x_m).any()]
    if paths:
        fig, ax = plt.subplots(figsize=(6.5, 6))
        for r, t in paths:
            ax.plot(t.x_m, t.y_m, label=f"{r.label} ({r.env_id})", linewidth=1.2)
            ax.plot(t.x_m[:1], t.y_m[:1], marker="o", color="grey")
            if t.goal is not None:
                ax.plot(*t.goal, marker="*", markersize=14, color="black", linestyle="none")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(fontsize=8, loc="best")
        ax.set_title(f"Episode 0 (seed {report.seed}), ground truth path (o start, * goal)")
        _save(fig, path)
        return
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
    _save(fig, path)


def _save(fig: Any, path: Path) -> None:
    import matplotlib.pyplot as plt

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
