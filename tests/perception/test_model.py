"""The perception model: it learns (beats a constant predictor on held-out episodes) and ONNX matches PyTorch."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.perception.dataset import load_dataset
from dualtwin.perception.estimator import StateEstimator
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


def test_beats_a_constant_predictor_on_heldout_episodes(tiny_model: Path, tiny_dataset: Path) -> None:
    report = evaluate_perception(tiny_model, tiny_dataset)
    assert report["same_dataset_as_training"] and report["frames"] > 0
    mae, constant = report["mae"], report["mae_constant"]
    # A few hundred steps on a few hundred frames of a falling pole: already far better than a constant.
    assert mae["pole_angle"] < 0.7 * constant["pole_angle"]
    assert mae["cart_position"] < 0.5 * constant["cart_position"]
    assert set(report["mae_alpha_beta"]) == set(mae)


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
    np.testing.assert_allclose(first, estimator.predict_stacks(data.frames[[0, 0, 0]][None])[0], atol=1e-6)
    for i in range(1, 5):
        out = session.update(data.frames[i])
    assert len(session.frames) == 3
    np.testing.assert_allclose(out, estimator.predict_stacks(data.frames[[2, 3, 4]][None])[0], atol=1e-6)
    with pytest.raises(DualtwinError, match="frame must be uint8"):
        session.update(np.zeros((10, 10, 3), dtype=np.uint8))
    filtered = estimator.session(velocity="alpha-beta")
    assert filtered.update(data.frames[0])[1] == 0.0  # velocities start at rest


def test_other_dataset_is_entirely_heldout_and_bad_models_fail_clearly(tiny_model: Path, tiny_dataset: Path,
                                                                       tmp_path: Path) -> None:
    copy = tmp_path / "data"
    shutil.copytree(tiny_dataset, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["shards"] = manifest["shards"][:1]
    (copy / "manifest.json").write_text(json.dumps(manifest))
    report = evaluate_perception(tiny_model, copy)
    assert not report["same_dataset_as_training"] and report["heldout_episodes"] == [0, 1]
    broken = tmp_path / "model"
    shutil.copytree(tiny_model, broken)
    (broken / "perception.onnx").write_bytes(b"\x00not onnx")
    with pytest.raises(DualtwinError, match="not a valid ONNX perception model"):
        StateEstimator.load(broken)
