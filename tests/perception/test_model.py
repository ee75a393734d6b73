"""The perception model: it learns (beats a constant predictor on held-out episodes) and ONNX matches PyTorch."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.perception.dataset import episode_identity, load_dataset
from dualtwin.perception.estimator import ACCEL_STD, StateEstimator, _Track
from dualtwin.perception.model import evaluate_perception, load_weights, stack_indices

pytestmark = pytest.mark.usefixtures("headless")


def test_model_folder_and_contract(tiny_model: Path) -> None:
    contract = json.loads((tiny_model / "perception_contract.json").read_text())
    assert contract["onnx"]["inputs"][0] == {**contract["onnx"]["inputs"][0], "dtype": "uint8",
                                             "shape": ["batch", 3, 48, 48, 3]}
    assert [s["name"] for s in contract["state"]] == ["cart_position", "cart_velocity", "pole_angle",
                                                      "pole_angular_velocity"]
    assert [s["unit"] for s in contract["state"]] == ["m", "m/s", "rad", "rad/s"]
    assert contract["frame_period_s"] == pytest.approx(0.032) and contract["camera"]["name"] == "perception"
    training = json.loads((tiny_model / "training.json").read_text())
    assert set(training["heldout_episodes"]).isdisjoint(training["train_episodes"])
    # Wall-clock time only in timing.json: training.json is the same for the same seed and inputs.
    assert "seconds" not in training and all("seconds" not in epoch for epoch in training["history"])
    timing = json.loads((tiny_model / "timing.json").read_text())
    assert len(timing["epoch_seconds"]) == training["epochs_run"] and timing["seconds"] >= 0


def test_beats_a_constant_predictor_on_heldout_episodes(tiny_model: Path, tiny_dataset: Path) -> None:
    report = evaluate_perception(tiny_model, tiny_dataset, velocity="frame-stack")
    training = json.loads((tiny_model / "training.json").read_text())
    assert report["heldout_episodes"] == sorted(training["heldout_episodes"]) and report["frames"] > 0
    assert report["excluded_training_episodes"] == len(training["train_episodes"])
    # The network itself (the Kalman filter's noise model trusts this tiny model little, so it is not judged here).
    mae, constant = report["mae"], report["mae_constant"]
    assert mae == report["mae_frame_stack"]
    # A few hundred steps on a few hundred frames of a falling pole: already far better than a constant.
    assert mae["pole_angle"] < 0.7 * constant["pole_angle"]
    assert mae["cart_position"] < 0.5 * constant["cart_position"]
    assert set(report["mae_kalman"]) == set(mae)


def test_onnx_matches_pytorch(tiny_model: Path, tiny_dataset: Path) -> None:
    import torch

    data = load_dataset(tiny_dataset)
    stacks = data.frames[stack_indices(data, np.arange(len(data)), 3)]
    with torch.no_grad():
        expected = load_weights(tiny_model)(torch.from_numpy(stacks)).numpy()
    got = StateEstimator.load(tiny_model).predict_stacks(stacks)
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-4)


def test_session_repeats_the_first_frame_and_keeps_k(tiny_model: Path, tiny_dataset: Path) -> None:
    data = load_dataset(tiny_dataset)
    estimator = StateEstimator.load(tiny_model)
    session = estimator.session("frame-stack")
    first = session.update(data.frames[0])
    np.testing.assert_allclose(first, estimator.predict_stacks(data.frames[[0, 0, 0]][None])[0], atol=1e-5)
    for i in range(1, 5):
        out = session.update(data.frames[i])
    assert len(session.frames) == 3
    np.testing.assert_allclose(out, estimator.predict_stacks(data.frames[[2, 3, 4]][None])[0], atol=1e-5)
    with pytest.raises(DualtwinError, match="frame must be uint8"):
        session.update(np.zeros((10, 10, 3), dtype=np.uint8))
    filtered = estimator.session(velocity="kalman")
    first = filtered.update(data.frames[0])
    assert first[1] == 0.0 and first[3] == 0.0  # velocities start at rest
    # Its positions are the newest frame's alone (the k-frame head lags): the first update is that prediction.
    np.testing.assert_allclose(first[[0, 2]], estimator.predict_single(data.frames[[0]])[0, [0, 2]], atol=1e-6)


def test_model_parts_match_the_whole_model(tiny_model: Path, tiny_dataset: Path) -> None:
    # Streams segment each frame once (perception_frame.onnx) and run the head on the last k moments.
    data = load_dataset(tiny_dataset)
    estimator = StateEstimator.load(tiny_model)
    assert estimator.parts is not None
    stacks = data.frames[stack_indices(data, np.arange(len(data)), 3)]
    whole = estimator.predict_stacks(stacks)
    moments = estimator.moments(data.frames)
    split = estimator.head(moments[stack_indices(data, np.arange(len(data)), 3)])
    np.testing.assert_allclose(split, whole, rtol=1e-4, atol=1e-5)
    assert np.abs(whole).max() > 0.01  # not a degenerate all-zero comparison


def test_kalman_track_rejects_noise_without_lag() -> None:
    dt = 0.032
    t = np.arange(400) * dt
    angle, rate = 0.1 * np.sin(2 * np.pi * t), 0.2 * np.pi * np.cos(2 * np.pi * t)  # a 1 Hz pole swing
    measured = angle + np.random.default_rng(0).normal(0.0, 0.003, len(t))
    track = _Track(0.003 ** 2, ACCEL_STD[2] ** 2 * dt, 0.25)
    estimate = np.array([track.update(float(z), dt)[1] for z in measured])
    finite_difference = np.r_[0.0, np.diff(measured) / dt]
    settled = slice(30, None)
    assert np.abs(estimate - rate)[settled].mean() < 0.9 * np.abs(finite_difference - rate)[settled].mean()
    # The estimate matches the true rate best at a delay of at most one control period (the α-β filter it
    # replaced: three).
    delays = [np.abs(estimate[30:] - rate[30 - d:len(t) - d]).mean() for d in range(5)]
    assert int(np.argmin(delays)) <= 1
    # A constant rate is tracked exactly once the filter settles.
    ramp = _Track(0.003 ** 2, ACCEL_STD[2] ** 2 * dt, 0.25)
    final = [ramp.update(0.5 * k * dt, dt) for k in range(200)][-1]
    assert final[1] == pytest.approx(0.5, abs=1e-6)


def _subset(dataset: Path, shard_index: int, out: Path) -> Path:
    """A copy of ``dataset`` that lists only one of its shards (a different shard list: a new fingerprint)."""
    shutil.copytree(dataset, out)
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["shards"] = manifest["shards"][shard_index:shard_index + 1]
    (out / "manifest.json").write_text(json.dumps(manifest))
    return out


def test_training_episodes_are_excluded_from_any_dataset_by_identity(tiny_model: Path, tiny_dataset: Path,
                                                                     tmp_path: Path) -> None:
    # Before episode identities, a subset of the training set (or a resumed extension of it) had another shard
    # list, counted as a different dataset and was scored entirely as held out: training frames included.
    contract = json.loads((tiny_model / "perception_contract.json").read_text())
    training = json.loads((tiny_model / "training.json").read_text())
    manifest = json.loads((tiny_dataset / "manifest.json").read_text())
    ids = {e: i for shard in manifest["shards"] for e, i in zip(range(shard["episodes"][0], shard["episodes"][1] + 1),
                                                                   shard["episode_ids"], strict=True)}
    assert ids[0] == episode_identity("dualtwin/CartPole-MuJoCo-Continuous-v0", 3, 0)
    assert sorted(contract["trained_on"]["episode_ids"]) == sorted(ids[e] for e in training["train_episodes"])
    train = set(training["train_episodes"])
    outcomes = []
    for k, shard in enumerate(manifest["shards"]):
        episodes = list(range(shard["episodes"][0], shard["episodes"][1] + 1))
        subset = _subset(tiny_dataset, k, tmp_path / f"subset{k}")
        held = [e for e in episodes if e not in train]
        if not held:
            with pytest.raises(DualtwinError, match="nothing is held out"):
                evaluate_perception(tiny_model, subset)
            outcomes.append("error")
            continue
        report = evaluate_perception(tiny_model, subset)
        assert report["heldout_episodes"] == held
        assert report["excluded_episodes"] == [e for e in episodes if e in train]
        assert report["excluded_training_episodes"] == len(episodes) - len(held)
        outcomes.append("scored")
    assert "error" in outcomes and "scored" in outcomes  # both cases were exercised


def test_identities_name_env_seed_and_episode() -> None:
    base = episode_identity("dualtwin/CartPole-MuJoCo-v0", 0, 1)
    assert base == episode_identity("dualtwin/CartPole-MuJoCo-v0", 0, 1)
    others = {episode_identity("dualtwin/CartPole-Webots-v0", 0, 1), episode_identity("dualtwin/CartPole-MuJoCo-v0",
                                                                                     1, 1),
              episode_identity("dualtwin/CartPole-MuJoCo-v0", 0, 2)}
    assert base not in others and len(others) == 3


def test_a_model_without_training_identities_cannot_be_evaluated(tiny_model: Path, tiny_dataset: Path,
                                                                 tmp_path: Path) -> None:
    old = tmp_path / "old_model"
    shutil.copytree(tiny_model, old)
    contract = json.loads((old / "perception_contract.json").read_text())
    del contract["trained_on"]["episode_ids"]
    (old / "perception_contract.json").write_text(json.dumps(contract))
    training = json.loads((old / "training.json").read_text())
    del training["train_episode_ids"]
    (old / "training.json").write_text(json.dumps(training))
    with pytest.raises(DualtwinError, match="does not record which episodes it trained on"):
        evaluate_perception(old, tiny_dataset)


def test_bad_models_fail_clearly(tiny_model: Path, tmp_path: Path) -> None:
    broken = tmp_path / "model"
    shutil.copytree(tiny_model, broken)
    (broken / "perception.onnx").write_bytes(b"\x00not onnx")
    with pytest.raises(DualtwinError, match="not a valid ONNX perception model"):
        StateEstimator.load(broken)
