"""Vector-env bench: env steps per CPU-second and per wall second of the batched MuJoCo vector env, against
the single env measured in the same run.

Run: ``python bench/bench_vector_env.py [--sizes 1 2 4 8 16 32 64] [--nthread 1 2] [--rounds 210] [--sync]``.

Every path is built first, then the paths take turns, one chunk of ``--chunk`` env steps each per round
(``max(chunk, N)`` for N envs), on ``dualtwin/CartPole-MuJoCo-Continuous-v0`` with fixed random actions:

* ``single``: one ``gym.make`` env stepped in a loop (auto-reset by hand), the baseline of the ``x single``
  columns;
* ``single-py``: the same env with Webots' motor law in Python per physics step (``DUALTWIN_NATIVE_LAW=0``),
  the single env as issue 25 measured it before the law moved into MuJoCo's step: the baseline of the
  ``x issue`` column (the issue's goal is a vector env at >= 3x *that* single env per CPU-second);
* ``physics``: ``mj_step`` alone over the single env's own trajectory (each period from its recorded state):
  the floor of any CPU figure, since a vector env runs the same physics;
* ``batch N/tK``: ``gym.make_vec(..., vectorization_mode="vector_entry_point", nthread=K)``, one
  ``mujoco.batch`` call per control period (dualtwin.rl.vector_env); K = 0 means all CPUs;
* ``sync N`` (with ``--sync``): ``gymnasium.vector.SyncVectorEnv`` of N single envs.

A path's rate is its fastest chunk (per CPU-second and, separately, per wall second): other jobs on a shared
machine only ever add time to a chunk, and interleaving gives every path the same quiet moments. CPU time is
the process's (all threads). Episodes are capped at 200 periods and the default 210 rounds step even the
largest batch past one auto-reset.
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


class Path:
    """One way of stepping envs: ``step()`` advances ``per_call`` env steps; the fastest chunk is kept."""

    def __init__(self, name: str, step: Callable[[], object], per_call: int, close: Callable[[], object]) -> None:
        self.name, self.step, self.per_call, self.close = name, step, per_call, close
        self.cpu = self.wall = 0.0  # best env steps per second of either clock

    def chunk(self, env_steps: int) -> None:
        calls = max(1, env_steps // self.per_call)
        cpu, wall = time.process_time(), time.perf_counter()
        for _ in range(calls):
            self.step()
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        done = calls * self.per_call
        self.cpu = max(self.cpu, done / max(cpu, 1e-9))
        self.wall = max(self.wall, done / max(wall, 1e-9))


def single(actions: np.ndarray, python_law: bool = False) -> Path:
    saved = os.environ.get("DUALTWIN_NATIVE_LAW")
    if python_law:  # read when the twin is built: only this env gets the Python law
        os.environ["DUALTWIN_NATIVE_LAW"] = "0"
    try:
        env = gym.make(ENV_ID, max_episode_steps=EPISODE)
    finally:
        if saved is None:
            os.environ.pop("DUALTWIN_NATIVE_LAW", None)
        else:
            os.environ["DUALTWIN_NATIVE_LAW"] = saved
    if env.unwrapped.twin.native_law == python_law:
        raise SystemExit(f"bench_vector_env: the {'Python' if python_law else 'native'} motor law is unavailable")
    env.reset(seed=0)
    k = [0]

    def step() -> None:
        _, _, term, trunc, _ = env.step(actions[k[0] % len(actions), 0])
        k[0] += 1
        if term or trunc:
            env.reset()

    return Path("single-py" if python_law else "single", step, 1, env.close)


def physics(actions: np.ndarray) -> Path:
    """mj_step over the single env's trajectory: its states recorded first, then each period stepped again."""
    env = gym.make(ENV_ID, max_episode_steps=EPISODE)
    env.reset(seed=0)
    twin = env.unwrapped.twin
    m, d = twin.model, twin.data
    substeps = int(round(twin.control_period / m.opt.timestep))
    states = np.empty((len(actions), mujoco.mj_stateSize(m, _INTEGRATION)))
    for k in range(len(actions)):
        mujoco.mj_getState(m, d, states[k], _INTEGRATION)
        _, _, term, trunc, _ = env.step(actions[k, 0])
        if term or trunc:
            env.reset()
    replay = mujoco.MjData(m)
    k = [0]

    def step() -> None:
        mujoco.mj_setState(m, replay, states[k[0] % len(states)], _INTEGRATION)
        mujoco.mj_step(m, replay, nstep=substeps)
        k[0] += 1

    return Path("physics", step, 1, env.close)


def vector(name: str, mode: str, n: int, actions: np.ndarray, nthread: int) -> Path:
    kwargs = {"nthread": nthread} if mode == "vector_entry_point" else {}
    env = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode=mode, max_episode_steps=EPISODE, **kwargs)
    env.reset(seed=0)
    k = [0]

    def step() -> None:
        env.step(actions[k[0] % len(actions), :n])
        k[0] += 1

    return Path(name, step, n, env.close)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--nthread", type=int, nargs="+", default=[1, 2], help="batch threads (0: all CPUs)")
    parser.add_argument("--rounds", type=int, default=210, help="turns every path takes")
    parser.add_argument("--chunk", type=int, default=64, help="env steps per turn (at least one vector step)")
    parser.add_argument("--sync", action="store_true", help="also measure SyncVectorEnv of N single envs")
    args = parser.parse_args(argv)
    if min(args.sizes) < 1 or args.rounds < 1 or args.chunk < 1 or min(args.nthread) < 0:
        print("bench_vector_env: sizes, rounds and chunk must be >= 1, nthread >= 0", file=sys.stderr)
        return 2
    gym.register_envs(dualtwin)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (4096, max(args.sizes), 1)).astype(np.float32)
    paths = [single(actions), single(actions, python_law=True), physics(actions)]
    for n in args.sizes:
        if args.sync:
            paths.append(vector(f"sync {n}", "sync", n, actions, 0))
        paths += [vector(f"batch {n}/t{k}", "vector_entry_point", n, actions, k) for k in args.nthread]
    try:
        for _ in range(args.rounds):
            for path in paths:
                path.chunk(args.chunk)
    finally:
        for path in paths:
            path.close()
    base, issue = paths[0], paths[1]
    print(f"{ENV_ID}: env steps per CPU-second / per wall second, fastest of {args.rounds} interleaved chunks "
          f"of {args.chunk} env steps; {os.cpu_count()} CPUs; batch N/tK: N envs on K batch threads (0: all CPUs)")
    print(f"{'path':<14} {'steps/CPU-s':>12} {'x single':>9} {'x issue':>8} {'steps/s':>10} {'x single':>9}")
    for path in paths:
        print(f"{path.name:<14} {path.cpu:12.0f} {path.cpu / base.cpu:8.2f}x {path.cpu / issue.cpu:7.2f}x "
              f"{path.wall:10.0f} {path.wall / base.wall:8.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
