"""The reference policy: exported in the policy contract format, loadable without PyTorch, and it balances."""

from __future__ import annotations

from pathlib import Path

from dualtwin.perception.onnx_policy import OnnxPolicy
from dualtwin.perception.reference_policy import export_reference_policy
from dualtwin.rl import make_env


def test_reference_policy_balances_with_only_the_pole_rate_privileged(tmp_path: Path) -> None:
    export_reference_policy(tmp_path)
    policy = OnnxPolicy.load_exported(tmp_path)
    assert policy.privileged == ["pole_angular_velocity"] and not policy.discrete
    env = make_env("dualtwin/CartPole-MuJoCo-Continuous-v0", max_episode_steps=150,
                   **policy.contract["env_kwargs"])
    obs, _ = env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        obs, reward, terminated, truncated, _ = env.step(policy.action(obs))
        total += float(reward)
        done = terminated or truncated
    env.close()
    assert total == 150.0
