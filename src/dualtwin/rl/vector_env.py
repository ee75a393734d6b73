"""N MuJoCo-twin envs as one ``mujoco.batch.Batch``: one batched call per control period, the rest on arrays.

Each env is a :class:`~dualtwin.rl.env.TwinEnv` (its task, its twin, its seeds and knobs), used to reset it;
between resets the batch's state row *is* the env's state. A step writes every env's command into the rows'
``plugin_state`` (the native motor law, :mod:`dualtwin.twins.motor_plugin`, keeps its targets there), steps
all rows on the batch's C threads with the poses and sensors computed at the new state
(``stage=mjSTAGE_VEL``), reads the binding's channels as columns (:mod:`dualtwin.rl.batch_io`), and lets the
task compute observations, rewards and terminations on those columns (``CartPoleBalance.batch_outcome``):
no Python per env in the loop. A period is nothing but ``mj_step`` from the integration state once the motor
law is native, and the column arithmetic is the single env's, in its order, so the results are bit-identical
to N separate envs (tests/rl/test_vector_env.py). Each simulation runs on its twin's own model
(``Batch.set_models``), so per-env knobs apply.

An env whose episode needs Python per period or per reading (sensor noise, bias, resolution or delay, the
control delay: :func:`~dualtwin.rl.batch_io.plain_sensors`; a task without batch methods; a channel the
columns do not cover) runs that episode through its twin instead: its row is copied into the twin, stepped
with the others, and copied back, and the twin and task do the rest as ``TwinEnv.step`` does.

Episodes end and restart as in ``gymnasium.vector.SyncVectorEnv`` over ``gym.make`` envs: a ``TimeLimit`` of
``max_episode_steps`` truncates, and an env whose episode ended resets on its next step (autoreset mode
``NEXT_STEP``: that step returns the reset observation, reward 0, not done).

CPU time per env step cannot fall below the physics itself (bench/bench_vector_env.py gives both); wall time
also scales with the batch's threads.
"""

from __future__ import annotations

from typing import Any, Protocol, cast, runtime_checkable

import mujoco
import mujoco.batch
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.rl.batch_io import BatchChannels, Column, plain_sensors
from dualtwin.rl.env import TwinEnv
from dualtwin.twins import motor_plugin
from dualtwin.twins.mujoco import MuJoCoTwin

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION.value
_BAD_STATE = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                               mujoco.mjtWarning.mjWARN_BADQACC)]
_AUTORESET_OFF = int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
_POSES = mujoco.mjtStage.mjSTAGE_VEL.value
_SLOT = motor_plugin.SLOT


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


@runtime_checkable
class BatchTask(Protocol):
    """What the array path needs of a task (``CartPoleBalance`` has it): one velocity command for all its
    actuators, the tilt of one body, and its arithmetic on columns (see ``CartPoleBalance.batch_outcome``)."""

    actuators: list[str]
    cart_body: str

    def batch_channels(self) -> tuple[list[int], list[int]]: ...

    def batch_wheel_speeds(self, actions: Any) -> np.ndarray: ...

    def batch_outcome(self, onboard: np.ndarray, truth: np.ndarray, tilt: np.ndarray, previous_odometry: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any], np.ndarray]: ...

    def last_odometry(self) -> float: ...


class _Columns:
    """What the array path needs of the task and the binding, or why it cannot run (``reason``)."""

    def __init__(self, env: TwinEnv, batch: mujoco.batch.Batch) -> None:
        task, model = env.task, batchable(env.twin).model
        self.reason: str | None = None
        if not isinstance(task, BatchTask):
            self.reason = f"task {env.task_name!r} has no batch methods"
            return
        self.task: BatchTask = task
        channels = BatchChannels(env.robot, model, batch)
        spec = env.robot.spec
        onboard, truth = task.batch_channels()
        readers = [channels.reader(c) for c in spec.onboard.values()], [channels.reader(c) for c in spec.ground_truth.values()]
        tilt = channels.tilt(task.cart_body)
        self.shape = (len(spec.onboard), len(spec.ground_truth))
        self.onboard = [(i, read) for i in onboard if (read := readers[0][i]) is not None]
        self.truth = [(i, read) for i in truth if (read := readers[1][i]) is not None]
        if tilt is None or len(self.onboard) < len(onboard) or len(self.truth) < len(truth):
            self.reason = "a channel the task reads is not a column of the batch"
            return
        self.tilt: Column = tilt
        # Each actuator's plugin_state slots (velocity commands: mode, target position and velocity, gain...).
        section = spec.twins.get("mujoco")
        aliases = dict(section.aliases) if section else {}
        starts = []
        for name in task.actuators:
            a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, aliases.get(name, name))
            start = motor_plugin.state_address(model, a) if a >= 0 else -1
            if start < 0:
                self.reason = f"actuator {name!r} is not a native-law motor"
                return
            starts.append(start)
        #: per slot name, its column in plugin_state for every actuator
        self.slot = {name: np.array(starts) + index for name, index in _SLOT.items()}

    def sample(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        onboard, truth = np.full((n, self.shape[0]), np.nan), np.full((n, self.shape[1]), np.nan)
        for i, read in self.onboard:
            onboard[:, i] = read()
        for i, read in self.truth:
            truth[:, i] = read()
        return onboard, truth, self.tilt()


class TwinVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` TwinEnvs (same arguments) stepped through one batch on ``nthread`` threads (0: all CPUs).

    Registered as the ``vector_entry_point`` of the MuJoCo CartPole ids:
    ``gym.make_vec("dualtwin/CartPole-MuJoCo-Continuous-v0", num_envs=16, vectorization_mode="vector_entry_point")``.
    The batch's rows hold the envs' states (``batch.get_data(i)`` materialises one); the twins of
    :attr:`envs` hold them only right after a reset and for envs that step through their twin.
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
        self.num_envs = n = num_envs
        self.max_episode_steps = max_episode_steps
        self.render_mode = None
        self.single_observation_space = self.envs[0].observation_space
        self._obs_shape = (n, *(self.single_observation_space.shape or ()))
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        # persistent: a step that ends on mjSTAGE_VEL lets the next one continue from it (no extra work)
        self.batch = mujoco.batch.Batch(self.twins[0].model, n, nthread=nthread, persistent=True)
        self._rows = [self.batch.state[i] for i in range(n)]
        self._time = self.batch.bind("time")
        self._plugin_state = self.batch.bind("plugin_state")
        self._models_stale = True  # a reset may change a twin's model (knobs): the batch reads it again
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=bool)
        self._columns = _Columns(self.envs[0], self.batch)
        #: Per env: True while its episode runs on arrays (see the module docstring), False through its twin.
        self.on_arrays = np.zeros(n, dtype=bool)
        self._substeps = np.ones(n, dtype=np.int64)
        self._timestep = np.ones(n)
        self._odometry = np.zeros(n)
        self._obs = np.zeros(self._obs_shape, dtype=np.float32)  # the last observation (an unstable period's)
        self._last_obs = np.zeros(self._obs_shape, dtype=np.float32)
        self._info: dict[str, np.ndarray] = {}
        # Acceleration-stage sensors (touch, force...) are what the last substep computed: copied from the
        # batch into a twin that steps through the batch, as mj_step leaves them in its data.
        model = self.twins[0].model
        self._copy_sensors = bool(model.nsensor) and bool(
            (model.sensor_needstage == mujoco.mjtStage.mjSTAGE_ACC).any())
        self._sensordata = self.batch.bind("sensordata")

    # ------------------------------------------------------------------ resets
    def _reset_env(self, i: int, seed: int | None, options: dict[str, Any] | None) -> tuple[np.ndarray, dict]:
        env, twin = self.envs[i], self.twins[i]
        obs, info = env.reset(seed=seed, options=options)
        mujoco.mj_getState(twin.model, twin.data, self._rows[i], _INTEGRATION)
        self._elapsed[i] = 0
        self._models_stale = True
        # knobs may change the physics step (and so the substeps of a period) per env
        self._timestep[i] = twin.model.opt.timestep
        self._substeps[i] = int(round(twin.control_period / twin.model.opt.timestep))
        self.on_arrays[i] = self._columns.reason is None and plain_sensors(twin.model, env.knob_values)
        if self.on_arrays[i]:
            self._odometry[i] = cast(BatchTask, env.task).last_odometry()
            self._obs[i] = obs
            for key, value in info.items():
                self._info.setdefault(key, np.zeros(self.num_envs))[i] = value
        return obs, info

    def _set_models(self) -> None:
        if self._models_stale:
            self.batch.set_models([twin.model for twin in self.twins])
            self._models_stale = False

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env, or with ``options={"reset_mask": mask}`` only those where ``mask`` (bool, one per
        env) is True, as ``SyncVectorEnv`` does: the others keep their episode and their last observation."""
        seeds = [None if seed is None else seed + i for i in range(self.num_envs)] if not isinstance(seed, list) \
            else seed
        if len(seeds) != self.num_envs:
            raise DualtwinError(f"reset: {len(seeds)} seeds for {self.num_envs} envs")
        mask = np.ones(self.num_envs, dtype=bool)
        if options is not None and "reset_mask" in options:
            options = dict(options)
            mask = options.pop("reset_mask")
            if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (self.num_envs,) \
                    or not mask.any():
                raise DualtwinError(f"reset: options['reset_mask'] must be a bool array of shape ({self.num_envs},) "
                                    f"with at least one True, got {mask!r:.80}")
        obs = self._last_obs.copy()
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(mask).tolist():
            obs[i], info = self._reset_env(i, seeds[i], options)
            infos = self._add_info(infos, info, i)
        self._autoreset[mask] = False
        self._set_models()
        self._last_obs = obs.copy()
        return obs, infos

    # ------------------------------------------------------------------ steps
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        n = self.num_envs
        obs = np.empty(self._obs_shape, dtype=np.float32)
        rewards = np.zeros(n, dtype=np.float64)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(self._autoreset) if self._autoreset.any() else ():
            obs[i], info = self._reset_env(int(i), None, None)
            infos = self._add_info(infos, info, int(i))
        stepping = ~self._autoreset
        arrays = stepping & self.on_arrays
        twins = np.flatnonzero(stepping & ~self.on_arrays) if not arrays.all() else ()
        if arrays.any():
            self._command(arrays, actions)
        for i in twins:
            self.envs[i].task.apply_action(actions[i])
            self.twins[i].start_period()
            mujoco.mj_getState(self.twins[i].model, self.twins[i].data, self._rows[i], _INTEGRATION)
        self._set_models()
        started = self._time.copy()
        warnings = self.batch.warning
        before = warnings[:, _BAD_STATE, 1].sum(axis=1)
        periods = self._substeps[stepping]
        for substeps in periods[:1] if periods.size == 0 or periods.min() == periods.max() else np.unique(periods):
            ids = stepping & (self._substeps == substeps)
            self.batch.step(None if ids.all() else ids, nstep=int(substeps), stage=_POSES)
        bad = warnings[:, _BAD_STATE, 1].sum(axis=1) != before
        if arrays.any():
            self._outcome(arrays, started, bad, obs, rewards, terminated, infos)
        for i in twins:
            self._twin_outcome(int(i), bool(bad[i]), obs, rewards, terminated, infos)
        self._elapsed[stepping] += 1
        if self.max_episode_steps is not None:
            truncated[stepping] = self._elapsed[stepping] >= self.max_episode_steps
        self._autoreset = terminated | truncated
        self._last_obs = obs.copy()  # what a masked reset returns for the envs it leaves alone
        return obs, rewards, terminated, truncated, infos

    def _command(self, arrays: np.ndarray, actions: Any) -> None:
        """Every array env's velocity command into its row's plugin slots, as ``MuJoCoTwin.command`` writes
        them (``MotorState.set_velocity``: the command times the gain, clamped to the maximum velocity)."""
        rows = slice(None) if arrays.all() else np.flatnonzero(arrays)
        wheel = self._columns.task.batch_wheel_speeds(np.asarray(actions)[rows])
        state, slot = self._plugin_state[rows], self._columns.slot  # a view for all rows, else a copy
        limit = state[:, slot["max_velocity"]]
        v = wheel[:, None] * state[:, slot["gain"]]
        v = np.where(v < limit, v, limit)  # min(limit, v), then max(-limit, v): Python's picks, NaN included
        state[:, slot["target_velocity"]] = np.where(v > -limit, v, -limit)
        state[:, slot["torque_mode"]] = 0.0
        state[:, slot["target_position"]] = np.inf
        state[:, slot["saturated"]] = 0.0
        if not isinstance(rows, slice):
            self._plugin_state[rows] = state

    def _outcome(self, arrays: np.ndarray, started: np.ndarray, bad: np.ndarray, obs: np.ndarray,
                 rewards: np.ndarray, terminated: np.ndarray, infos: dict[str, Any]) -> None:
        n = self.num_envs
        onboard, truth, tilt = self._columns.sample(n)
        new_obs, reward, done, info, odometry = self._columns.task.batch_outcome(onboard, truth, tilt, self._odometry)
        # MuJoCo resets a simulation (time 0) when a step meets a bad qpos, qvel or qacc: a period that ended on
        # time was stable, as the twin's own check says (MuJoCoTwin._check_stable); the others are checked there.
        on_time = self._time > started + (self._substeps - 0.5) * self._timestep
        suspect = np.flatnonzero(arrays & ~on_time) if not self.twins[0].model.opt.disableflags & _AUTORESET_OFF \
            else np.flatnonzero(arrays)
        unstable: dict[int, str] = {}
        for i in suspect.tolist():
            message = self._instability(i, float(started[i]), bool(bad[i]))
            if message is not None:
                unstable[i] = message
        everyone = bool(arrays.all())
        rows: slice | np.ndarray = slice(None) if everyone else arrays  # whole arrays when every env is here
        keep: slice | np.ndarray = rows
        if unstable:
            keep = arrays.copy()
            keep[list(unstable)] = False
        obs[keep], rewards[keep], terminated[keep] = new_obs[keep], reward[keep], done[keep]
        self._obs[keep] = new_obs[keep]
        self._odometry[keep] = odometry[keep]
        for key, values in info.items():
            self._info.setdefault(key, np.zeros(n))[keep] = values[keep]
        for key, values in self._info.items():
            column = infos.get(key)
            if column is None:
                column, infos[f"_{key}"] = np.zeros(n), np.zeros(n, dtype=bool)
                infos[key] = column
            column[rows] = values[rows]
            infos[f"_{key}"][rows] = True
        for i, message in unstable.items():
            # as TwinEnv.step: the last observation, reward 0, the episode ends, training goes on
            obs[i], terminated[i] = self._obs[i], True
            infos = self._add_info(infos, {"unstable": message}, i)

    def _instability(self, i: int, started: float, bad: bool) -> str | None:
        """The twin's verdict on env i's period (its message if unstable): its row goes into the twin."""
        twin = self.twins[i]
        twin.data.time = started
        twin.start_period()
        mujoco.mj_setState(twin.model, twin.data, self._rows[i], _INTEGRATION)
        try:
            twin.finish_period(bad)
        except SimulationUnstable as exc:
            return str(exc)
        return None

    def _twin_outcome(self, i: int, bad: bool, obs: np.ndarray, rewards: np.ndarray, terminated: np.ndarray,
                      infos: dict[str, Any]) -> None:
        """Env i's period through its twin and task, as ``TwinEnv.step`` after ``twin.step()``."""
        env, twin = self.envs[i], self.twins[i]
        mujoco.mj_setState(twin.model, twin.data, self._rows[i], _INTEGRATION)
        if self._copy_sensors:
            twin.data.sensordata[:] = self._sensordata[i]
        task = env.task
        try:
            twin.finish_period(bad)
        except SimulationUnstable as exc:
            obs[i], terminated[i] = task.observation(), True
            info = {**task.info(), "unstable": str(exc)}
        else:
            task.sample()
            obs[i], rewards[i], terminated[i] = task.observation(), task.reward(), task.terminated()
            info = task.info()
        self._add_info(infos, info, i)

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()


__all__ = ["TwinVectorEnv", "batchable"]
