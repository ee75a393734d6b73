"""The Pioneer's drive-to-goal task: reward, termination, success, contract and episode set-up, in both twins.

The conformance checks (check_env, determinism, vector envs) run over every registered id in test_env.py.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from tests.support.rl_runs import env_param

from dualtwin.errors import DualtwinError
from dualtwin.rl import DriveToGoal, TwinEnv
from dualtwin.rl.drive_to_goal import proportional_action

IDS = [env_param("dualtwin/Pioneer-DriveToGoal-MuJoCo-v0"), env_param("dualtwin/Pioneer-DriveToGoal-Webots-v0")]
OBS_NAMES = ["goal_distance", "goal_bearing_sin", "goal_bearing_cos", "left_wheel_speed", "right_wheel_speed"]


def run(env: gym.Env, seed: int, policy) -> tuple[list[float], dict, float, bool, bool]:  # type: ignore[no-untyped-def]
    obs, info = env.reset(seed=seed)
    start = info["goal_distance"]
    rewards: list[float] = []
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        rewards.append(float(reward))
    return rewards, info, start, terminated, truncated


@pytest.mark.parametrize("env_id", IDS)
def test_proportional_controller_reaches_the_goal_and_gets_the_bonus(env_id: str) -> None:
    env = gym.make(env_id)
    task: DriveToGoal = env.unwrapped.task
    for seed in (0, 3):
        rewards, info, start, terminated, truncated = run(env, seed, proportional_action)
        assert terminated and not truncated and info["is_success"]
        assert info["goal_distance"] <= task.success_radius
        # Progress telescopes: the return is the distance covered, plus the bonus, minus the time cost.
        expected = start - info["goal_distance"] + task.success_bonus - task.time_cost * len(rewards)
        assert sum(rewards) == pytest.approx(expected, abs=1e-9)
        assert rewards[-1] > task.success_bonus - 0.1 and max(rewards[:-1]) < 0.1
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_driving_away_loses_reward_and_leaves_the_area(env_id: str) -> None:
    env = gym.make(env_id)
    task: DriveToGoal = env.unwrapped.task

    def away(obs: np.ndarray) -> np.ndarray:  # turn the goal behind the robot, then drive
        return proportional_action(np.array([obs[0], -obs[1], -obs[2]]))

    rewards, info, start, terminated, truncated = run(env, 1, away)
    assert not info["is_success"] and sum(rewards) < -1.0
    assert info["goal_distance"] > start + 1.0
    if terminated:  # left the area before the time limit
        assert info["goal_distance"] > task.max_goal_distance + task.leave_margin
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_contract_and_wheel_commands(env_id: str) -> None:
    env = gym.make(env_id)
    assert env.spec is not None and env.spec.max_episode_steps == 250
    assert isinstance(env.action_space, gym.spaces.Box) and env.action_space.shape == (2,)
    contract = env.unwrapped.io_contract()
    terms = contract["observation"]["terms"]
    assert [t["name"] for t in terms] == OBS_NAMES
    assert [t["source"] for t in terms] == ["privileged"] * 3 + ["onboard"] * 2
    assert contract["action"]["scale"] == pytest.approx(6.4) and contract["task"]["name"] == "drive_to_goal"
    obs, _ = env.reset(seed=0)
    assert obs[3] == 0.0 and obs[4] == 0.0
    speeds = []
    for _ in range(30):  # left wheels back at half speed, right wheels forward at full speed
        obs, *_ = env.step(np.array([-0.5, 1.0], dtype=np.float32))
        speeds.append(obs[3:])
    # Averaged: while the wheels scrub sideways, MuJoCo's servos track within a few per cent, with jitter.
    assert np.mean(speeds[10:], axis=0) == pytest.approx([-3.2, 6.4], rel=0.05)
    env.close()


def test_start_heading_and_goal_are_random_and_seeded() -> None:
    env = gym.make("dualtwin/Pioneer-DriveToGoal-MuJoCo-v0")
    headings, distances, bearings = [], [], []
    for seed in range(12):
        obs, info = env.reset(seed=seed)
        headings.append(info["true_heading"])
        distances.append(info["goal_distance"])
        bearings.append(math.atan2(obs[1], obs[2]))
        assert math.hypot(info["true_x"], info["true_y"]) < 1e-3  # starts at the origin
        assert obs[0] == pytest.approx(math.hypot(info["goal_x"], info["goal_y"]), abs=1e-3)
    assert min(distances) >= 0.5 and max(distances) <= 2.5
    assert np.ptp(headings) > math.pi and np.ptp(bearings) > math.pi  # spread over the circle
    again, _ = env.reset(seed=5)
    assert again[0] == pytest.approx(distances[5]) and math.atan2(again[1], again[2]) == pytest.approx(bearings[5])
    env.close()


def test_bad_settings_and_bindings_are_clear_errors() -> None:
    with pytest.raises(DualtwinError, match="success_radius < min_goal_distance"):
        DriveToGoal(success_radius=0.6)
    with pytest.raises(DualtwinError, match="continuous"):
        DriveToGoal(continuous=False)
    with pytest.raises(DualtwinError, match="needs onboard channel 'left_wheel_rad'"):
        TwinEnv("mujoco", "cartpole", "drive_to_goal", continuous=True)
    with pytest.raises(DualtwinError, match="task 'drive_to_goal'.*x_limit"):
        gym.make("dualtwin/Pioneer-DriveToGoal-MuJoCo-v0", task_kwargs={"x_limit": 2.0})
    with pytest.raises(DualtwinError, match="cameras in the binding: none"):
        gym.make("dualtwin/Pioneer-DriveToGoal-MuJoCo-v0", render_mode="rgb_array")
    env = gym.make("dualtwin/Pioneer-DriveToGoal-MuJoCo-v0")
    env.reset(seed=0)
    with pytest.raises(DualtwinError, match="drive_to_goal .left, right.: the action is 2 numbers, none NaN"):
        env.step(np.array([0.1, 0.2, 0.3], dtype=np.float32))
    env.close()


class _Scripted:
    """The proportional controller behind the trained-policy interface that transfer's episode loop uses."""

    def __init__(self, away: bool = False) -> None:
        self.away = away

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return proportional_action(np.array([obs[0], -obs[1], -obs[2]]) if self.away else obs)


@pytest.mark.parametrize("env_id", IDS)
def test_transfer_episodes_record_success_and_path(env_id: str, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from dualtwin.rl.transfer import EvalRow, TransferReport, run_episodes, write_report

    env = gym.make(env_id, max_episode_steps=200)
    rewards, lengths, path, successes = run_episodes(_Scripted(), env, 3, seed=0)  # type: ignore[arg-type]
    assert successes == [True, True, True] and all(n < 200 for n in lengths)
    assert path is not None and path.goal is not None and len(path.x_m) == lengths[0]
    start, end = np.array([path.x_m[0], path.y_m[0]]), np.array([path.x_m[-1], path.y_m[-1]])
    assert np.linalg.norm(end - path.goal) < np.linalg.norm(start - path.goal) - 0.3  # drove toward the goal
    away_rewards, _, _, away = run_episodes(_Scripted(away=True), env, 2, seed=0)  # type: ignore[arg-type]
    assert away == [False, False] and max(away_rewards) < min(rewards)
    env.close()
    row = EvalRow("source", env_id, None, away_rewards, [200, 200], -1.0, 0.0, successes=away)
    assert row.success_rate == 0.0 and "success 0 %" in row.summary()
    report = TransferReport("run", env_id, env_id, 2, 0, [row, EvalRow("target", env_id, None, rewards, lengths,
                                                                       1.0, 0.0, trajectory=path)])
    assert "- source: 0/2" in report.markdown() and report.to_dict()["rows"][0]["success_rate"] == 0.0
    write_report(report, tmp_path)
    assert (tmp_path / "trajectory.png").stat().st_size > 1000


def test_tasks_without_success_report_none() -> None:
    from dualtwin.rl.transfer import run_episodes

    env = gym.make("dualtwin/CartPole-MuJoCo-Continuous-v0", max_episode_steps=5)
    policy = type("Zero", (), {"predict": staticmethod(lambda obs: np.zeros(1, dtype=np.float32))})()
    assert run_episodes(policy, env, 1, seed=0)[3] is None
    env.close()
