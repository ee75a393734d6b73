"""N MuJoCo-twin envs whose physics runs as one ``mujoco.batch.Batch``: one batched call per control period.

Each env is a :class:`~dualtwin.rl.env.TwinEnv` (its task, its twin, its seeds and knobs); only the physics
of a period moves out of the twin. A step writes every env's command through its task (the native motor law
keeps its targets in ``plugin_state``), copies each twin's integration state into the batch's row, steps every
row's substeps on the batch's C threads, and copies the rows back; then each task samples, rewards and
terminates as in ``TwinEnv.step``. A period is nothing but ``mj_step`` from the integration state once the
motor law is native (see :mod:`dualtwin.twins.motor_plugin`), so the results are bit-identical to N separate
envs (tests/rl/test_vector_env.py). Each simulation runs on its twin's own model (``Batch.set_models``), so
per-env knobs apply; resets run one env at a time through ``TwinEnv.reset``, as they would unbatched.

Episodes end and restart as in ``gymnasium.vector.SyncVectorEnv`` over ``gym.make`` envs: a ``TimeLimit`` of
``max_episode_steps`` truncates, and an env whose episode ended resets on its next step (autoreset mode
``NEXT_STEP``: that step returns the reset observation, reward 0, not done).

The gain is the Python a loop of single envs pays per env and the physics on threads: wall time scales with
cores; CPU time per env step cannot fall below the physics itself (bench/bench_vector_env.py).
"""

from __future__ import annotations

from typing import Any

import mujoco
import mujoco.batch
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.rl.env import TwinEnv
from dualtwin.twins.mujoco import MuJoCoTwin

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION.value
_BAD_STATE = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                               mujoco.mjtWarning.mjWARN_BADQACC)]


def batchable(twin: Any) -> MuJoCoTwin:
    """The twin, if a batch can run its physics; else why not (a DualtwinError)."""
    if not isinstance(twin, MuJoCoTwin):
        raise DualtwinError(f"a batched vector env needs the MuJoCo twin, not {getattr(twin, 'name', twin)!r}")
    if not twin.native_law:
        raise DualtwinError("the Python motor law acts between physics steps, which a batch cannot call back: "
                            "build the native law (dualtwin.twins.motor_plugin) to batch this twin")
    if twin.contact_semantics is not None:
        raise DualtwinError("Webots' friction pyramid (contact_semantics) acts between physics steps, which a "
                            "batch cannot call back: this robot cannot be batched")
    return twin


class TwinVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` TwinEnvs (same arguments) stepped through one batch on ``nthread`` threads (0: all CPUs).

    Registered as the ``vector_entry_point`` of the MuJoCo CartPole ids:
    ``gym.make_vec("dualtwin/CartPole-MuJoCo-Continuous-v0", num_envs=16, vectorization_mode="vector_entry_point")``.
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, *, max_episode_steps: int | None = None, nthread: int = 0,
                 **env_kwargs: Any) -> None:
        if num_envs < 1:
            raise DualtwinError(f"num_envs must be >= 1, got {num_envs}")
        if env_kwargs.get("render_mode") is not None:
            raise DualtwinError("the batched vector env does not render (make single envs for that)")
        self.envs = [TwinEnv(**env_kwargs) for _ in range(num_envs)]
        self.twins = [batchable(env.twin) for env in self.envs]
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.render_mode = None
        self.single_observation_space = self.envs[0].observation_space
        self._obs_shape = (num_envs, *(self.single_observation_space.shape or ()))
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.batch = mujoco.batch.Batch(self.twins[0].model, num_envs, nthread=nthread)
        self._rows = [self.batch.state[i] for i in range(num_envs)]
        self._models_stale = True  # a reset may change a twin's model (knobs): the batch reads it again
        self._elapsed = np.zeros(num_envs, dtype=np.int64)
        self._autoreset = np.zeros(num_envs, dtype=bool)
        # Acceleration-stage sensors (touch, force...) are what the last substep computed: copied from the
        # batch, as mj_step leaves them in the twin's data; refresh() recomputes the position/velocity ones.
        model = self.twins[0].model
        self._copy_sensors = bool(model.nsensor) and bool(
            (model.sensor_needstage == mujoco.mjtStage.mjSTAGE_ACC).any())
        self._sensordata = self.batch.bind("sensordata") if self._copy_sensors else None

    def _load(self, i: int) -> None:
        """Env i's twin state into its batch row (after a reset or a step of the twin itself)."""
        twin = self.twins[i]
        mujoco.mj_getState(twin.model, twin.data, self._rows[i], _INTEGRATION)

    def _reset_env(self, i: int, seed: int | None, options: dict[str, Any] | None) -> tuple[np.ndarray, dict]:
        obs, info = self.envs[i].reset(seed=seed, options=options)
        self._load(i)
        self._elapsed[i] = 0
        self._models_stale = True
        return obs, info

    def _set_models(self) -> None:
        if self._models_stale:
            self.batch.set_models([twin.model for twin in self.twins])
            self._models_stale = False

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        seeds = [None if seed is None else seed + i for i in range(self.num_envs)] if not isinstance(seed, list) \
            else seed
        if len(seeds) != self.num_envs:
            raise DualtwinError(f"reset: {len(seeds)} seeds for {self.num_envs} envs")
        obs = np.empty(self._obs_shape, dtype=np.float32)
        infos: dict[str, Any] = {}
        for i, s in enumerate(seeds):
            obs[i], info = self._reset_env(i, s, options)
            infos = self._add_info(infos, info, i)
        self._autoreset[:] = False
        self._set_models()
        return obs, infos

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        n = self.num_envs
        obs = np.empty(self._obs_shape, dtype=np.float32)
        rewards = np.zeros(n, dtype=np.float64)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        infos: dict[str, Any] = {}
        by_substeps: dict[int, list[int]] = {}
        for i, env in enumerate(self.envs):
            if self._autoreset[i]:
                obs[i], info = self._reset_env(i, None, None)
                infos = self._add_info(infos, info, i)
                continue
            twin = self.twins[i]
            env.task.apply_action(actions[i])
            twin.start_period()
            mujoco.mj_getState(twin.model, twin.data, self._rows[i], _INTEGRATION)
            # knobs may change the physics step (and so the substeps of a period) per env
            substeps = int(round(twin.control_period / twin.model.opt.timestep))
            by_substeps.setdefault(substeps, []).append(i)
        self._set_models()
        warnings = self.batch.warning
        before = warnings[:, _BAD_STATE, 1].sum(axis=1)
        for substeps, ids in by_substeps.items():
            self.batch.step(ids if len(ids) < n else None, nstep=substeps)
        bad = warnings[:, _BAD_STATE, 1].sum(axis=1) != before
        for ids in by_substeps.values():
            for i in ids:
                env, twin = self.envs[i], self.twins[i]
                mujoco.mj_setState(twin.model, twin.data, self._rows[i], _INTEGRATION)
                if self._sensordata is not None:
                    twin.data.sensordata[:] = self._sensordata[i]
                task = env.task
                try:
                    twin.finish_period(bool(bad[i]))
                except SimulationUnstable as exc:  # as TwinEnv.step: the episode ends, training goes on
                    obs[i], terminated[i] = task.observation(), True
                    info = {**task.info(), "unstable": str(exc)}
                else:
                    task.sample()
                    obs[i], rewards[i], terminated[i] = task.observation(), task.reward(), task.terminated()
                    info = task.info()
                self._elapsed[i] += 1
                truncated[i] = self.max_episode_steps is not None and self._elapsed[i] >= self.max_episode_steps
                infos = self._add_info(infos, info, i)
        self._autoreset = terminated | truncated
        return obs, rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()


__all__ = ["TwinVectorEnv", "batchable"]
