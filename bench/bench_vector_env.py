"""Vector-env bench: env steps per CPU-second (and per wall second) of the batched MuJoCo vector env.

Run: ``python bench/bench_vector_env.py [--sizes 8 16] [--steps 300] [--nthread 0]``.

Measured in one run, interleaved, on ``dualtwin/CartPole-MuJoCo-Continuous-v0`` with fixed random actions:

* ``single``: today's path, one ``gym.make`` env stepped in a loop (auto-reset by hand);
* ``sync N``: ``gymnasium.vector.SyncVectorEnv`` of N such envs;
* ``batch N``: ``gym.make_vec(..., vectorization_mode="vector_entry_point")``, one ``mujoco.batch`` call per
  control period (dualtwin.rl.vector_env);
* ``physics``: ``mj_step`` alone for one control period of one env, the floor of any CPU figure.

CPU time is the process's (all threads); ratios are to ``single`` within this run. Episodes are capped at 200
periods so that auto-resets are part of the measurement.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import gymnasium as gym
import mujoco
import numpy as np

import dualtwin

ENV_ID = "dualtwin/CartPole-MuJoCo-Continuous-v0"
EPISODE = 200


def measure(step, steps: int, envs: int) -> tuple[float, float]:
    """(env steps per CPU-second, env steps per wall second) of ``steps`` calls of ``step``."""
    cpu, wall = time.process_time(), time.perf_counter()
    for k in range(steps):
        step(k)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    return steps * envs / cpu, steps * envs / wall


def single(steps: int, actions: np.ndarray) -> tuple[float, float]:
    env = gym.make(ENV_ID, max_episode_steps=EPISODE)
    env.reset(seed=0)

    def step(k: int) -> None:
        _, _, term, trunc, _ = env.step(actions[k, 0])
        if term or trunc:
            env.reset()

    try:
        return measure(step, steps, 1)
    finally:
        env.close()


def vector(mode: str, n: int, steps: int, actions: np.ndarray, nthread: int) -> tuple[float, float]:
    kwargs = {"nthread": nthread} if mode == "vector_entry_point" else {}
    env = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode=mode, max_episode_steps=EPISODE, **kwargs)
    env.reset(seed=0)
    try:
        return measure(lambda k: env.step(actions[k, :n]), steps, n)
    finally:
        env.close()


def physics(steps: int) -> tuple[float, float]:
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    twin = env.unwrapped.twin
    substeps = int(round(twin.control_period / twin.model.opt.timestep))
    try:
        return measure(lambda k: mujoco.mj_step(twin.model, twin.data, nstep=substeps), steps, 1)
    finally:
        env.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[8, 16])
    parser.add_argument("--steps", type=int, default=300, help="vector steps per measurement")
    parser.add_argument("--nthread", type=int, default=0, help="batch threads (0: all CPUs)")
    parser.add_argument("--repeats", type=int, default=2, help="interleaved rounds; the best of each is kept")
    args = parser.parse_args(argv)
    gym.register_envs(dualtwin)
    rng = np.random.default_rng(0)
    most = max(args.sizes)
    actions = rng.uniform(-1, 1, (max(args.steps * most, args.steps), most, 1)).astype(np.float32)
    best: dict[str, tuple[float, float]] = {}

    def keep(name: str, value: tuple[float, float]) -> None:
        old = best.get(name, (0.0, 0.0))
        best[name] = (max(old[0], value[0]), max(old[1], value[1]))

    for _ in range(args.repeats):
        keep("single", single(args.steps * 4, actions))
        keep("physics", physics(args.steps * 4))
        for n in args.sizes:
            keep(f"sync {n}", vector("sync", n, args.steps, actions, 0))
            keep(f"batch {n}", vector("vector_entry_point", n, args.steps, actions, args.nthread))
    base_cpu, base_wall = best["single"]
    print(f"{ENV_ID}: env steps per CPU-second / per wall second, best of {args.repeats} interleaved rounds; "
          f"{os.cpu_count()} CPUs, batch nthread={args.nthread}")
    print(f"{'path':<12} {'steps/CPU-s':>12} {'x single':>9} {'steps/s':>10} {'x single':>9}")
    for name, (cpu, wall) in best.items():
        print(f"{name:<12} {cpu:12.0f} {cpu / base_cpu:8.2f}x {wall:10.0f} {wall / base_wall:8.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
