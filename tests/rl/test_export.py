"""ONNX export: ONNX Runtime on raw observations == SB3 policy with its VecNormalize, for both action types."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest

from dualtwin.rl.export import export_policy
from dualtwin.rl.policy import load_policy


def observations(n: int = 3000) -> np.ndarray:
    rng = np.random.default_rng(0)
    # Typical ranges, plus a tail far outside them so VecNormalize's clipping is exercised too.
    scale = np.array([1.0, 1.0, 0.3, 2.0], dtype=np.float32)
    obs = rng.normal(size=(n, 4)).astype(np.float32) * scale
    obs[: n // 10] *= 50.0
    return obs


def run_onnx(path: Path, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    action, velocity = session.run(["action", "cart_velocity"], {"observation": obs})
    return action, velocity


def test_discrete_parity(discrete_run: Path, tmp_path: Path) -> None:
    path = export_policy(discrete_run, tmp_path)
    policy = load_policy(discrete_run)
    obs = observations()
    action, velocity = run_onnx(path, obs)
    expected = policy.predict(obs)
    differ = action != expected
    if differ.any():
        # Only an exact tie between the two logits could flip the argmax between float paths.
        import torch

        with torch.no_grad():
            logits = policy.model.policy.get_distribution(
                torch.as_tensor(policy.normalize(obs[differ]))).distribution.logits.numpy()
        assert np.all(np.abs(logits[:, 0] - logits[:, 1]) < 1e-4)
    assert differ.mean() < 1e-3
    np.testing.assert_allclose(velocity, np.where(action == 1, 1.5, -1.5))
    contract = json.loads((tmp_path / "policy_contract.json").read_text())
    assert [t["name"] for t in contract["observation"]] == [
        "cart_position", "cart_velocity", "pole_angle", "pole_angular_velocity"]
    assert [t["source"] for t in contract["observation"]] == ["onboard", "onboard", "onboard", "privileged"]
    assert contract["action"]["speed_table"] == [-1.5, 1.5]
    assert contract["control_period_s"] == pytest.approx(0.032) and contract["source_twin"] == "mujoco"
    assert contract["normalization"]["in_graph"] and len(contract["normalization"]["mean"]) == 4
    assert contract["onnx"]["opset"] == 17 and "onnxruntime" in contract["versions"]


def test_continuous_parity(continuous_run: Path, tmp_path: Path) -> None:
    path = export_policy(continuous_run, tmp_path)
    policy = load_policy(continuous_run)
    obs = observations()
    action, velocity = run_onnx(path, obs)
    expected = policy.predict(obs)
    assert action.shape == expected.shape == (len(obs), 1)
    np.testing.assert_allclose(action, expected, atol=2e-5)
    np.testing.assert_allclose(velocity, expected[:, 0] * 1.5, atol=3e-5)
    assert np.abs(velocity).max() <= 1.5 + 1e-6
    contract = json.loads((tmp_path / "policy_contract.json").read_text())
    assert contract["action"]["type"] == "box" and contract["action"]["scale"] == pytest.approx(1.5)


def test_pioneer_export_gives_both_wheel_commands(tmp_path: Path) -> None:
    from tests.support.rl_runs import train_tiny

    run = train_tiny(tmp_path / "run", "dualtwin/Pioneer-DriveToGoal-MuJoCo-v0", 512, {"eval_freq": 0})
    path = export_policy(run, tmp_path / "export")
    policy = load_policy(run)
    contract = json.loads((tmp_path / "export" / "policy_contract.json").read_text())
    names = [o["name"] for o in contract["onnx"]["outputs"]]
    assert names == ["action", "left_wheel_speed", "right_wheel_speed"]
    assert {o.get("unit") for o in contract["onnx"]["outputs"][1:]} == {"rad/s"}
    assert contract["onnx"]["outputs"][0]["shape"] == ["batch", 2]
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    n_obs = session.get_inputs()[0].shape[1]
    obs = np.random.default_rng(1).normal(size=(200, n_obs)).astype(np.float32)
    action, left, right = session.run(names, {"observation": obs})
    expected = policy.predict(obs)
    assert action.shape == expected.shape == (200, 2)
    np.testing.assert_allclose(action, expected, atol=2e-5)
    scale = contract["action"]["scale"]
    np.testing.assert_allclose(np.stack([left, right], axis=1), expected * scale, atol=1e-4 * scale)
