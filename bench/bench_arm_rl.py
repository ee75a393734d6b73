"""Arm reach benchmark (issue 19): PPO in the MuJoCo twin, transferred to the Webots twin; Table 1's arm rows.

Run: ``python bench/bench_arm_rl.py`` (or ``make bench``). Environment variables:

* ``DUALTWIN_BENCH_ARM_RL_RUN``: reuse this training run folder instead of training (marked ``[reused run]``);
* ``DUALTWIN_BENCH_ARM_RL_OUT``: keep every run, the alignment and the transfer reports there (default: a
  temporary folder, deleted at the end);
* ``DUALTWIN_BENCH_ARM_RL_EPISODES``: episodes per row (default 100);
* ``DUALTWIN_BENCH_ARM_RL_FINETUNE``: fine-tuning steps of the aligned and control policies (default 61,440;
  0 skips part (c)).

(a) PPO with the bundled ``ppo_arm_reach.yaml`` (seed 0, its own 20-minute wall budget) on
``Arm-Reach-MuJoCo-v0``. Goal: >= 95 % success (flange within 2 cm of the target) in MuJoCo.
(b) The final policy in the source twin and in ``Arm-Reach-Webots-v0`` (the nominal Webots arm), the same
seeded targets in every row (``dualtwin.rl.transfer``). Goal: >= 90 % success in Webots before alignment.
(c) Table 1 against a stand-in for a real arm: the Webots arm with the joint losses the converted model lacks
(the viscous joint damping ``bench/bench_arm.py`` hides in its stand-in, without its payload: the reach arm
carries none) and the big joints slowed to 1.6 rad/s. Rows: the source policy in the stand-in (before
alignment); the source's MuJoCo twin aligned to the stand-in with CMA-ES (the six joints' speed limits, on the
six joint steps of the arm suite),
the policy fine-tuned in the aligned twin (after alignment); the same fine-tuning in the nominal twin (the
control, so that what alignment adds beyond more training shows). Goal: >= 95 % after alignment.
(d) Control measured in the same run: a policy that never moves (all-zero actions) on the same targets, so the
success rates read against what a start next to the target gives for free.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

import dualtwin.rl  # noqa: F401 - registers the env ids
import dualtwin.rl.reach
import dualtwin.twins.mujoco
import dualtwin.twins.webots
from _common import eval_success_rates, output_folder, physics_files, training_run

SOURCE = "dualtwin/Arm-Reach-MuJoCo-v0"
TARGET = "dualtwin/Arm-Reach-Webots-v0"
#: The modules a transfer number depends on besides the robot files (hashed into the results).
ARM_MODULES = (dualtwin.twins.mujoco, dualtwin.twins.webots, dualtwin.rl.reach)
MUJOCO_GOAL, BEFORE_GOAL, AFTER_GOAL = 0.95, 0.90, 0.95
JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
# The stand-in for a real arm: bench/bench_arm.py's hidden viscous joint damping (N*m*s/rad, larger on the big
# joints) and the three big joints capped at 1.6 rad/s, about half of the datasheet's 180 deg/s (an arm run in a
# reduced-speed mode). Damping alone changes nothing visible: Webots' position loop is a velocity servo with
# 150 N*m behind it, so 8 N*m*s/rad at pi rad/s costs 25 N*m and the joint keeps its speed.
HIDDEN = {**{f"joint.{j}.damping": v for j, v in zip(JOINTS, (6.0, 8.0, 4.0, 0.6, 0.6, 0.3), strict=True)},
          **{f"motor.{j}.max_velocity": 1.6 for j in JOINTS[:3]}}
# Fitted: the six speed limits. Damping is not fitted: behind the velocity servo it leaves no trace in the joint
# steps (a 12-knob fit with it moved every damping knob far from the truth at no change in the objective), and
# the MuJoCo twin's damping knob is bounded to [0, 1], which the training's knob check enforces.
KNOBS = ["motor.*.max_velocity"]
BOUNDS = {"motor.*.max_velocity": (0.5, 4.0)}
ALIGN_BUDGET = 150


class Still:
    """The control policy: zero joint deltas (the arm holds its start pose)."""

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros(3, dtype=np.float32)


def describe_run(run: Path, reused: bool) -> dict[str, Any]:
    record = json.loads((run / "run.json").read_text())
    successes = eval_success_rates(run)
    timeline = record["evaluations"]
    first = next((e for e, s in zip(timeline, successes or [], strict=False) if s >= MUJOCO_GOAL), None)
    result = {"run": str(run), "reused": reused, "steps": record["num_timesteps"],
              "train_seconds": record["timings"]["train_seconds"], "eval_success_rates": successes,
              "first_eval_at_goal_steps": first["timesteps"] if first else None}
    note = " [reused run]" if reused else ""
    print(f"  {record['num_timesteps']:,} steps in {result['train_seconds']:.0f} s{note}; evaluation success "
          f"rates {', '.join(f'{s:.0%}' for s in successes or [])}")
    if first is not None:
        print(f"  first evaluation at >= {MUJOCO_GOAL:.0%}: {first['timesteps']:,} steps ({first['wall_seconds']:.0f} s)")
    return result


def rows_table(report: Any) -> list[dict[str, Any]]:
    rows = []
    for row in report.rows:
        rate = float(np.mean(row.successes)) if row.successes else float("nan")
        print(f"    {row.label:40s} success {100 * rate:5.1f} %  return {row.mean:6.3f} ± {row.std:.3f}  "
              f"mean length {np.mean(row.lengths):5.1f} periods")
        rows.append({"label": row.label, "env_id": row.env_id, "knobs": row.knobs, "success_rate": rate,
                     "mean_return": row.mean, "mean_length": float(np.mean(row.lengths))})
    return rows


def verdict(value: float, goal: float) -> str:
    return f"{100 * value:.1f} % (goal >= {100 * goal:.0f} %: {'met' if value >= goal else 'NOT met'})"


def align_to_stand_in(root: Path) -> tuple[Path, dict[str, Any]]:
    """CMA-ES over the per-joint speed limits of the MuJoCo arm, against the Webots stand-in's six joint steps."""
    from dualtwin.align import AlignConfig, run_align
    from dualtwin.align.objective import ObjectiveWeights
    from dualtwin.robots.binding import resolve_robot
    from dualtwin.suite.runner import SuiteRun
    from dualtwin.twins import make_twin

    robot = resolve_robot("arm")
    root.mkdir(parents=True, exist_ok=True)
    source = json.loads((robot.root / "suite.json").read_text())
    steps = [dict(s, duration_s=1.2) for s in source["scenarios"] if s["name"].startswith("step_")]
    suite = root / "suite.json"
    suite.write_text(json.dumps({"suite_name": "arm_reach_alignment", "global_settings": source["global_settings"],
                                 "scenarios": steps}, indent=1))
    reference = make_twin("webots", robot)
    reference.set_knobs(HIDDEN)
    SuiteRun(suite, "webots", robot, root / "reference", twin=reference).run()
    reference.close()
    # Joint angles only: the flange pose follows from them, and the objective scales each channel by its range.
    channels = [f"q{i}_rad" for i in range(1, 7)]
    start = time.perf_counter()
    result = run_align(AlignConfig(reference=str(root / "reference"), target="mujoco", robot=str(robot.path),
                                   suite=str(suite), knobs=list(KNOBS), optimizer="cma", budget=ALIGN_BUDGET,
                                   bounds=BOUNDS, channels=channels, workers=1, executor="process",
                                   weights=ObjectiveWeights(rmse=1.0, endpoint=0.5, dtw=0.0, event=0.0)),
                       root / "align")
    wall = time.perf_counter() - start
    print(f"  {len(result.knobs)} knobs, {result.evaluations} evaluations, {wall:.0f} s, objective "
          f"{result.objective_before:.4g} -> {result.objective_after:.4g} ({result.stop_reason})")
    for name, fit in result.knobs.items():
        truth = HIDDEN.get(name, 3.141592653589793 if name.endswith(".max_velocity") else 0.0)
        print(f"    {name:28s} {fit.fitted:8.4g} [stand-in {truth:g}]")
    return root / "align" / "knobs.json", {"evaluations": result.evaluations, "wall_seconds": round(wall, 1),
                                           "objective_before": result.objective_before,
                                           "objective_after": result.objective_after,
                                           "fitted": {k: f.fitted for k, f in result.knobs.items()}}


def main() -> dict[str, Any]:
    import torch

    from dualtwin.rl import make_env
    from dualtwin.rl.train import train
    from dualtwin.rl.transfer import run_episodes, transfer

    torch.set_num_threads(1)
    episodes = int(os.environ.get("DUALTWIN_BENCH_ARM_RL_EPISODES", "100"))
    finetune = int(os.environ.get("DUALTWIN_BENCH_ARM_RL_FINETUNE", "61440"))
    results: dict[str, Any] = {"episodes": episodes, "files_sha256": physics_files("arm", ARM_MODULES)}
    print("Arm reach benchmark (PPO, bundled ppo_arm_reach.yaml, seed 0, 1 torch thread; success = flange "
          "within 2 cm of the target)")
    print("  robot and twin files (sha256): " + ", ".join(f"{k} {v}" for k, v in results["files_sha256"].items()))
    with output_folder("DUALTWIN_BENCH_ARM_RL_OUT", "arm-rl") as (root, keep):
        print("(a) training in the MuJoCo twin")
        start = time.perf_counter()
        run, reused = training_run(root, "DUALTWIN_BENCH_ARM_RL_RUN", SOURCE, "ppo_arm_reach", "ppo_arm_reach")
        results["training"] = describe_run(run, reused)
        if not reused:
            results["training"]["wall_seconds"] = round(time.perf_counter() - start, 1)

        print(f"(b) the policy in both twins, {episodes} episodes per row (seeds 0..{episodes - 1})")
        report = transfer(run, TARGET, episodes=episodes, seed=0, out_dir=root / "transfer_nominal")
        results["nominal"] = rows_table(report)
        source_rate, target_rate = (r["success_rate"] for r in results["nominal"][:2])
        print(f"  MuJoCo success {verdict(source_rate, MUJOCO_GOAL)}; Webots success before alignment "
              f"{verdict(target_rate, BEFORE_GOAL)}")

        if finetune > 0:
            print("(c) Table 1 against the stand-in (Webots arm with hidden joint damping)")
            knobs, results["alignment"] = align_to_stand_in(root / "alignment")
            common = {"total_timesteps": finetune, "init_from": run, "progress_bar": False}
            aligned = root / "finetune_aligned"
            control = root / "finetune_control"
            for folder in (aligned, control):
                if folder.exists():
                    shutil.rmtree(folder)
            t0 = time.perf_counter()
            train(SOURCE, "ppo_arm_reach", aligned, seed=1, aligned=knobs, **common)  # type: ignore[arg-type]
            train(SOURCE, "ppo_arm_reach", control, seed=1, **common)  # type: ignore[arg-type]
            print(f"  fine-tuned {finetune:,} steps each (aligned and control) in {time.perf_counter() - t0:.0f} s")
            table = transfer(run, TARGET, policy_aligned=aligned, policy_control=control, episodes=episodes,
                             seed=0, out_dir=root / "transfer_stand_in", target_kwargs={"knobs": HIDDEN})
            results["stand_in"] = rows_table(table)
            by_label = {r["label"]: r["success_rate"] for r in results["stand_in"]}
            before = by_label["target (before alignment)"]
            after = by_label["target (after alignment)"]
            ctrl = by_label["target (fine-tuned in the nominal twin)"]
            print(f"  stand-in success before alignment {verdict(before, BEFORE_GOAL)}; after alignment "
                  f"{verdict(after, AFTER_GOAL)}; control (fine-tuned in the nominal twin) {100 * ctrl:.1f} %")

        print("(d) control: a policy that never moves, same targets")
        still: dict[str, float] = {}
        for label, env_id, kwargs in (("MuJoCo", SOURCE, {}), ("Webots", TARGET, {}),
                                      ("Webots stand-in", TARGET, {"knobs": HIDDEN})):
            env = make_env(env_id, **kwargs)
            try:
                _, _, _, successes = run_episodes(Still(), env, episodes, 0, record=False)  # type: ignore[arg-type]
            finally:
                env.close()
            still[label] = float(np.mean(successes or [False]))
            print(f"    {label:16s} success {100 * still[label]:.1f} %")
        results["still_policy"] = still
        if keep:
            (root / "bench_arm_rl.json").write_text(json.dumps(results, indent=1, default=str))
    return results


if __name__ == "__main__":
    main()
