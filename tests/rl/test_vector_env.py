"""The batched MuJoCo vector env (dualtwin.rl.vector_env) against N separate envs, step for step."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

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


def test_the_batch_holds_each_envs_state_after_a_step() -> None:
    env = TwinVectorEnv(2, continuous=True)
    env.reset(seed=0)
    env.step(np.full((2, 1), 0.5, dtype=np.float32))
    import mujoco

    for i, twin in enumerate(env.twins):
        state = np.empty(env.batch.nstate)
        mujoco.mj_getState(twin.model, twin.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
        assert np.array_equal(state, env.batch.state[i], equal_nan=True)  # unused plugin slots hold NaN
        assert twin.data.time > 0.0
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
