"""Vector-env bench: env steps per CPU-second and per wall second of the batched MuJoCo vector env, against
the single env measured in the same run.

Run: ``python bench/bench_vector_env.py [--sizes 1 2 4 8 16 32 64] [--steps 300] [--nthread 1 0] [--sync]``.

Measured in one run, interleaved, on ``dualtwin/CartPole-MuJoCo-Continuous-v0`` with fixed random actions:

* ``single``: one ``gym.make`` env stepped in a loop (auto-reset by hand), the baseline of every ratio;
* ``physics``: ``mj_step`` alone over the single env's own trajectory (each period from its recorded state):
  the floor of any CPU figure, since a vector env runs the same physics;
* ``batch N/tK``: ``gym.make_vec(..., vectorization_mode="vector_entry_point", nthread=K)``, one
  ``mujoco.batch`` call per control period (dualtwin.rl.vector_env); K = 0 means all CPUs;
* ``sync N`` (with ``--sync``): ``gymnasium.vector.SyncVectorEnv`` of N single envs.

CPU time is the process's (all threads); ratios are to ``single`` within this run, best of ``--repeats``
interleaved rounds. Episodes are capped at 200 periods so that auto-resets are part of the measurement.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable

import gymnasium as gym
import mujoco
import numpy as np

import dualtwin

ENV_ID = "dualtwin/CartPole-MuJoCo-Continuous-v0"
EPISODE = 200
_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION


def measure(step: Callable[[int], object], steps: int, envs: int) -> tuple[float, float]:
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


def physics(steps: int, actions: np.ndarray) -> tuple[float, float]:
    """mj_step over the single env's trajectory: its states recorded first, then each period stepped again."""
    env = gym.make(ENV_ID, max_episode_steps=EPISODE)
    env.reset(seed=0)
    twin = env.unwrapped.twin
    m, d = twin.model, twin.data
    substeps = int(round(twin.control_period / m.opt.timestep))
    states = np.empty((steps, mujoco.mj_stateSize(m, _INTEGRATION)))
    for k in range(steps):
        mujoco.mj_getState(m, d, states[k], _INTEGRATION)
        _, _, term, trunc, _ = env.step(actions[k, 0])
        if term or trunc:
            env.reset()
    replay = mujoco.MjData(m)

    def step(k: int) -> None:
        mujoco.mj_setState(m, replay, states[k], _INTEGRATION)
        mujoco.mj_step(m, replay, nstep=substeps)

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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--steps", type=int, default=300, help="vector steps per measurement")
    parser.add_argument("--nthread", type=int, nargs="+", default=[1, 0], help="batch threads (0: all CPUs)")
    parser.add_argument("--repeats", type=int, default=2, help="interleaved rounds; the best of each is kept")
    parser.add_argument("--sync", action="store_true", help="also measure SyncVectorEnv of N single envs")
    args = parser.parse_args(argv)
    if min(args.sizes) < 1 or args.steps < 1 or args.repeats < 1 or min(args.nthread) < 0:
        print("bench_vector_env: sizes, steps and repeats must be >= 1, nthread >= 0", file=sys.stderr)
        return 2
    gym.register_envs(dualtwin)
    rng = np.random.default_rng(0)
    most = max(args.sizes)
    single_steps = args.steps * 4
    actions = rng.uniform(-1, 1, (max(args.steps, single_steps), most, 1)).astype(np.float32)
    best: dict[str, tuple[float, float]] = {}

    def keep(name: str, value: tuple[float, float]) -> None:
        old = best.get(name, (0.0, 0.0))
        best[name] = (max(old[0], value[0]), max(old[1], value[1]))

    for _ in range(args.repeats):
        keep("single", single(single_steps, actions))
        keep("physics", physics(single_steps, actions))
        for n in args.sizes:
            if args.sync:
                keep(f"sync {n}", vector("sync", n, args.steps, actions, 0))
            for nthread in args.nthread:
                keep(f"batch {n}/t{nthread}", vector("vector_entry_point", n, args.steps, actions, nthread))
    base_cpu, base_wall = best["single"]
    print(f"{ENV_ID}: env steps per CPU-second / per wall second, best of {args.repeats} interleaved rounds; "
          f"{os.cpu_count()} CPUs; batch N/tK: N envs on K batch threads (0: all CPUs)")
    print(f"{'path':<14} {'steps/CPU-s':>12} {'x single':>9} {'steps/s':>10} {'x single':>9}")
    for name, (cpu, wall) in best.items():
        print(f"{name:<14} {cpu:12.0f} {cpu / base_cpu:8.2f}x {wall:10.0f} {wall / base_wall:8.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
