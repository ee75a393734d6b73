"""The batched MuJoCo vector env (dualtwin.rl.vector_env) against N separate envs, step for step."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence

import dualtwin
from dualtwin.errors import DualtwinError
from dualtwin.rl.vector_env import TwinVectorEnv, batchable
from dualtwin.twins.mujoco import MuJoCoTwin

gym.register_envs(dualtwin)

CONTINUOUS = "dualtwin/CartPole-MuJoCo-Continuous-v0"
# A narrow track ends episodes early (terminated) and a short cap truncates the others: both auto-resets.
# Discrete actions are full speed: a wider track for them.
TRACK = {CONTINUOUS: {"x_limit": 0.05}, "dualtwin/CartPole-MuJoCo-v0": {"x_limit": 0.2}}
CAP = 25


def _pair(env_id: str, n: int, **kwargs: object) -> tuple[gym.vector.VectorEnv, gym.vector.VectorEnv]:
    batched = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=CAP,
                           task_kwargs=TRACK[env_id], **kwargs)
    separate = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", max_episode_steps=CAP,
                            task_kwargs=TRACK[env_id])
    return batched, separate


def _actions(env_id: str, n: int, steps: int) -> np.ndarray:
    rng = np.random.default_rng(7)
    if env_id == CONTINUOUS:
        return rng.uniform(-1.0, 1.0, (steps, n, 1)).astype(np.float32)
    return rng.integers(0, 2, (steps, n))


@pytest.mark.parametrize("env_id", [CONTINUOUS, "dualtwin/CartPole-MuJoCo-v0"])
def test_batched_steps_are_bit_identical_to_separate_envs(env_id: str) -> None:
    n, steps = 3, 60
    batched, separate = _pair(env_id, n, nthread=2)
    assert isinstance(batched.unwrapped, TwinVectorEnv)
    obs_b, _ = batched.reset(seed=11)
    obs_s, _ = separate.reset(seed=11)
    assert batched.unwrapped.on_arrays.all()  # the array path is what is compared
    assert np.array_equal(obs_b, obs_s)
    ended = {"terminated": 0, "truncated": 0}
    for action in _actions(env_id, n, steps):
        out_b, out_s = batched.step(action), separate.step(action)
        for name, b, s in zip(("obs", "reward", "terminated", "truncated"), out_b[:4], out_s[:4], strict=True):
            assert b.dtype == s.dtype and np.array_equal(b, s), name
        ended["terminated"] += int(out_b[2].sum())
        ended["truncated"] += int(out_b[3].sum())
        assert np.array_equal(out_b[4]["true_cart_position"], out_s[4]["true_cart_position"])
    assert ended["terminated"] and ended["truncated"], ended  # both kinds of auto-reset were compared
    batched.close()
    separate.close()


def test_the_batch_steps_each_env_on_its_own_models_knobs() -> None:
    """Reset knobs change each twin's model; the batch must run on those models, not on its nominal copy."""
    n, options = 2, {"knobs": {"joint.pole_hinge.damping": 0.2, "geom.floor.friction": 0.3}}
    batched, separate = _pair(CONTINUOUS, n)
    nominal = gym.make_vec(CONTINUOUS, num_envs=n, vectorization_mode="sync", max_episode_steps=CAP,
                           task_kwargs=TRACK[CONTINUOUS])
    for env in (batched, separate, nominal):
        env.reset(seed=3, options=options if env is not nominal else None)
    diverged = False
    for action in _actions(CONTINUOUS, n, 15):
        obs_b, obs_s, obs_n = batched.step(action)[0], separate.step(action)[0], nominal.step(action)[0]
        assert np.array_equal(obs_b, obs_s)
        diverged |= not np.array_equal(obs_b, obs_n)
    assert diverged  # the control: the knobs do change these observations
    for env in (batched, separate, nominal):
        env.close()


def _compare(env_id: str, n: int, steps: int, task_kwargs: dict[str, object], cap: int = CAP,
             options: dict | None = None, **kwargs: object) -> tuple[gym.vector.VectorEnv, dict[str, int]]:
    """Step a batched and a sync vector env with the same seeds and actions; assert every output is equal."""
    batched = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=cap,
                           task_kwargs=task_kwargs, **kwargs)
    separate = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", max_episode_steps=cap,
                            task_kwargs=task_kwargs, **kwargs)
    obs_b, info_b = batched.reset(seed=5, options=options)
    obs_s, info_s = separate.reset(seed=5, options=options)
    assert np.array_equal(obs_b, obs_s) and data_equivalence(info_b, info_s, exact=True)
    ended = {"terminated": 0, "truncated": 0}
    for action in _actions(env_id, n, steps):
        out_b, out_s = batched.step(action), separate.step(action)
        for name, b, s in zip(("obs", "reward", "terminated", "truncated"), out_b[:4], out_s[:4], strict=True):
            assert b.dtype == s.dtype and np.array_equal(b, s), name
        assert data_equivalence(out_b[4], out_s[4], exact=True), (out_b[4], out_s[4])
        ended["terminated"] += int(out_b[2].sum())
        ended["truncated"] += int(out_b[3].sum())
        ended["mixed"] = ended.get("mixed", 0) + int(0 < batched.unwrapped.on_arrays.sum() < n)
    for i in range(n):  # the states too, not only what the task reads of them
        state = separate.envs[i].unwrapped.twin.data
        assert np.array_equal(batched.unwrapped.batch.get_data(i).qpos, state.qpos)
    separate.close()
    return batched, ended


@pytest.mark.parametrize(("task_kwargs", "cap"), [
    ({"x_limit": 0.1, "terminate_on_fall": True, "balance_angle": 0.1}, 6),
    ({"x_limit": 0.08, "observation_ranges": [0.05, 0.1, 0.02, 0.5], "upright_angle": 0.2}, CAP),
    ({"x_limit": 0.05, "cart_velocity": "ground_truth"}, CAP),  # the supervisor's cart velocity: a column too
])
def test_other_task_settings_run_on_arrays_bit_identically(task_kwargs: dict[str, object], cap: int) -> None:
    batched, ended = _compare(CONTINUOUS, 3, 50, task_kwargs, cap)
    assert batched.unwrapped.on_arrays.all()
    assert ended["terminated"] and ended["truncated"], ended
    batched.close()


def test_a_step_on_arrays_runs_no_python_per_env() -> None:
    """The array path: no twin sensor read, no task sample, no twin command per env and step (the loop of
    single envs that it replaces). A reset still goes through each env's TwinEnv."""
    env = TwinVectorEnv(4, continuous=True, max_episode_steps=1000)
    env.reset(seed=0)
    calls = {"sensor": 0, "sample": 0, "command": 0}

    def counting(obj: object, name: str, key: str) -> None:
        method = getattr(obj, name)

        def wrapper(*args: object, **kwargs: object) -> object:
            calls[key] += 1
            return method(*args, **kwargs)
        setattr(obj, name, wrapper)

    for sub in env.envs:
        counting(sub.twin, "sensor", "sensor")
        counting(sub.twin, "command", "command")
        counting(sub.task, "sample", "sample")
    for _ in range(5):
        obs, *_ = env.step(np.full((4, 1), 0.3, dtype=np.float32))
    assert calls == {"sensor": 0, "sample": 0, "command": 0}, calls
    assert env.on_arrays.all() and np.isfinite(obs).all()
    env.close()


@pytest.mark.parametrize(("task_kwargs", "knobs"), [
    ({"x_limit": 0.05}, {"sensor.pole sensor.noise": 0.01, "sensor.wheel1 sensor.bias": 0.02}),
    ({"x_limit": 0.05}, {"control.delay_periods": 2}),
])
def test_envs_that_need_python_per_period_step_through_their_twins(task_kwargs: dict, knobs: dict | None) -> None:
    batched, ended = _compare(CONTINUOUS, 2, 40, task_kwargs, knobs=knobs)
    assert not batched.unwrapped.on_arrays.any()
    assert ended["terminated"] or ended["truncated"]
    batched.close()


def test_a_task_without_batch_methods_steps_through_its_twins() -> None:
    env_id = "dualtwin/Pioneer-DriveToGoal-MuJoCo-v0"
    batched = TwinVectorEnv(2, max_episode_steps=12, **gym.spec(env_id).kwargs)
    separate = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", max_episode_steps=12)
    assert np.array_equal(batched.reset(seed=2)[0], separate.reset(seed=2)[0])
    assert not batched.on_arrays.any()
    for action in np.random.default_rng(3).uniform(-1, 1, (20, 2, *batched.single_action_space.shape)):
        out_b, out_s = batched.step(action.astype(np.float32)), separate.step(action.astype(np.float32))
        assert all(np.array_equal(b, s) for b, s in zip(out_b[:4], out_s[:4], strict=True))
    batched.close()
    separate.close()


def test_envs_on_arrays_and_through_twins_step_together() -> None:
    """Reset knobs with sensor noise hold for the first episode only: as episodes end at different steps, some
    envs run on arrays while the others still step through their twins, in the same batch."""
    options = {"knobs": {"sensor.pole sensor.noise": 0.02, "joint.pole_hinge.damping": 0.1}}
    batched, ended = _compare(CONTINUOUS, 4, 60, {"x_limit": 0.05}, options=options)
    assert ended["mixed"] and batched.unwrapped.on_arrays.all(), ended
    batched.close()


def test_an_unstable_period_ends_the_episode_as_a_single_env_does() -> None:
    """A state MuJoCo rejects mid-period (bad qvel: it resets the simulation): last observation, reward 0,
    terminated, the twin's message in info["unstable"]; then the env resets."""
    n = 3
    batched, separate = _pair(CONTINUOUS, n)
    batched.reset(seed=1)
    separate.reset(seed=1)
    actions = _actions(CONTINUOUS, n, 4)
    for env in (batched, separate):
        env.step(actions[0])
    batched.unwrapped.batch.bind("qvel")[1, 6] = 1e11  # the first wheel spins beyond MuJoCo's limit
    separate.envs[1].unwrapped.twin.data.qvel[6] = 1e11
    out_b, out_s = batched.step(actions[1]), separate.step(actions[1])
    for b, s in zip(out_b[:4], out_s[:4], strict=True):
        assert np.array_equal(b, s)
    assert out_b[2][1] and not out_b[2][0] and out_b[1][1] == 0.0
    assert "numerically unstable" in out_b[4]["unstable"][1] and out_b[4]["unstable"][1] == out_s[4]["unstable"][1]
    assert list(out_b[4]["_unstable"]) == [False, True, False]
    out_b, out_s = batched.step(actions[2]), separate.step(actions[2])  # the reset step
    assert np.array_equal(out_b[0], out_s[0]) and not out_b[2].any()
    batched.close()
    separate.close()


def test_vector_env_checks() -> None:
    """What Gymnasium's env checker asks of an env, asked of the vector env: spaces, seeding determinism,
    fresh arrays every step, NEXT_STEP autoreset declared."""
    env = gym.make_vec(CONTINUOUS, num_envs=3, vectorization_mode="vector_entry_point", max_episode_steps=CAP)
    assert env.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(30)]
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=9)
        assert env.observation_space.contains(obs)
        run = [obs]
        for action in actions:
            out = env.step(action)
            assert env.observation_space.contains(out[0]) and out[1].shape == (3,)
            assert out[0] is not run[-1] and not np.shares_memory(out[0], run[-1])
            run.append(out[0])
        runs.append(run)
    assert data_equivalence(runs[0], runs[1], exact=True)
    other, _ = env.reset(seed=10)
    assert not np.array_equal(other, runs[0][0])
    # Gymnasium's vector wrappers read the infos and the autoreset mode: episode statistics after the cap
    stats = gym.wrappers.vector.RecordEpisodeStatistics(env)
    stats.reset(seed=0)
    ends = [stats.step(action)[4] for action in actions]
    assert any("episode" in info for info in ends)
    assert max(int(info["episode"]["l"].max()) for info in ends if "episode" in info) <= CAP
    env.close()


def test_a_twin_with_the_python_motor_law_is_refused_with_the_reason() -> None:
    env = gym.make(CONTINUOUS).unwrapped
    twin = env.twin
    assert isinstance(twin, MuJoCoTwin) and batchable(twin) is twin
    python_law = MuJoCoTwin(twin.spec, twin.control_period, native_law=False)
    with pytest.raises(DualtwinError, match="Python motor law"):
        batchable(python_law)
    with pytest.raises(DualtwinError, match="MuJoCo twin"):
        batchable(object())
    env.close()
