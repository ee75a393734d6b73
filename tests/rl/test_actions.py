"""One action rule over every registered env (dualtwin.rl.actions): values beyond the Box are clipped (±inf too),
NaN and a wrong number of values raise a DualtwinError naming the task, a discrete action is one integer.

Before the rule, the CartPole drove its wheels with a NaN action (the episode went on), the arm refused ±inf
while the Pioneer clipped it, and the discrete CartPole truncated 1.5 to 1 and raised ValueError on a string."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from tests.support.rl_runs import ALL_IDS

import dualtwin.rl  # noqa: F401  (registers the ids)
from dualtwin.errors import DualtwinError

BOX_IDS = [p for p in ALL_IDS if "Continuous" in str(p.id) or not str(p.id).startswith("CartPole")]
DISCRETE_IDS = [p for p in ALL_IDS if str(p.id).startswith("CartPole") and "Continuous" not in str(p.id)]


def _first_step(env: gym.Env, action: object) -> np.ndarray:
    env.reset(seed=3)
    return env.step(action)[0]


@pytest.mark.parametrize("env_id", BOX_IDS)
def test_box_actions_clip_beyond_the_bounds_and_refuse_nan(env_id: str) -> None:
    env = gym.make(env_id)
    try:
        space = env.action_space
        assert isinstance(space, gym.spaces.Box)
        size = space.shape[0]
        task = env.unwrapped.task.__class__.__name__
        at_bound = _first_step(env, np.ones(size, dtype=np.float32))
        assert np.array_equal(_first_step(env, np.full(size, np.inf)), at_bound), task
        assert np.array_equal(_first_step(env, np.full(size, 1e30)), at_bound), task
        assert not np.array_equal(_first_step(env, np.zeros(size)), at_bound)  # control: the action matters
        nan = np.zeros(size)
        nan[-1] = np.nan
        for bad in (nan, np.zeros(size + 1), "fast"):
            env.reset(seed=3)
            with pytest.raises(DualtwinError, match=rf": the action is {size} numbers?, none NaN, got"):
                env.step(bad)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", DISCRETE_IDS)
def test_a_discrete_action_is_one_integer(env_id: str) -> None:
    env = gym.make(env_id)
    try:
        one = _first_step(env, 1)
        for same in (np.int64(1), np.array(1), np.array([1]), 1.0, True):
            assert np.array_equal(_first_step(env, same), one), same
        assert not np.array_equal(_first_step(env, 0), one)  # control: the action matters
        for bad in (1.5, 2, -1, "a", [0, 1], np.nan):
            env.reset(seed=3)
            with pytest.raises(DualtwinError, match="cartpole_balance: the discrete action is one integer from 0 to 1"):
                env.step(bad)
    finally:
        env.close()


@pytest.mark.parametrize("continuous", [True, False])
def test_the_vector_env_takes_and_refuses_what_single_envs_do(continuous: bool) -> None:
    env_id = "dualtwin/CartPole-MuJoCo-Continuous-v0" if continuous else "dualtwin/CartPole-MuJoCo-v0"
    vec = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    try:
        vec.reset(seed=5)
        if continuous:
            good = np.array([[np.inf], [-1e30], [0.5]])
            vec.step(good)
            bad = np.array([[0.0], [np.nan], [0.0]])
            message = r"the action is 1 number per env, none NaN, got array\(\[nan\]\) for env 1"
        else:
            vec.step(np.array([1, 0, 1]))
            bad = np.array([0.0, 1.5, 1.0])
            message = "the discrete action is one integer from 0 to 1 per env"
        with pytest.raises(DualtwinError, match=message):
            vec.step(bad)
    finally:
        vec.close()
