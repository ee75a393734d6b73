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
