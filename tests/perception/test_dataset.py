"""Data collection: shards + manifest, labels in sync with time, and resume after a crash gives the same data."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.perception import dataset as ds
from dualtwin.perception.dataset import collect, load_dataset

pytestmark = pytest.mark.usefixtures("headless")
ENV = "dualtwin/CartPole-MuJoCo-Continuous-v0"
SMALL = {"max_steps": 6, "width": 24, "height": 24, "episodes_per_shard": 1, "seed": 5}


def test_tiny_dataset_has_shards_manifest_and_labels(tiny_dataset: Path) -> None:
    manifest = json.loads((tiny_dataset / "manifest.json").read_text())
    assert manifest["format"] == ds.FORMAT and manifest["complete"] and manifest["episodes_done"] == 6
    assert [s["file"] for s in manifest["shards"]] == ["shard-00000.npz", "shard-00001.npz", "shard-00002.npz"]
    assert manifest["twin"] == "mujoco" and manifest["resolution"] == [48, 48]
    assert manifest["camera"]["name"] == "perception" and manifest["randomization"]["enabled"]
    assert [s["name"] for s in manifest["state"]] == list(ds.STATE_NAMES)
    assert "numpy" in manifest["versions"]
    data = load_dataset(tiny_dataset)
    assert data.frames.shape[1:] == (48, 48, 3) and data.frames.dtype == np.uint8
    assert data.state.shape == (len(data), 4) and data.state.dtype == np.float32
    assert data.masks.shape == (len(data), 48, 48, 2) and data.masks.dtype == np.uint8
    assert (data.masks[..., 1].reshape(len(data), -1).max(axis=1) == 255).mean() > 0.5  # the cart is mostly seen
    assert sum(s["frames"] for s in manifest["shards"]) == len(data) == manifest["frames"]
    # Simulation time stamps, one control period apart, restarting with every episode.
    for episode in data.episodes:
        rows = data.episode == episode
        np.testing.assert_allclose(data.time_s[rows], 0.032 * (data.step[rows] + 1), atol=1e-9)
        assert data.step[rows][0] == 0
    # The labels are the supervisor's state, the observation the env's: the pole encoder agrees (MuJoCo's
    # sensors read at the start of the last physics step, 2 ms earlier).
    lag = np.abs(data.state[:, 3]) * 0.002 * 1.5 + 1e-3
    assert np.all(np.abs(data.state[:, 2] - data.observation[:, 2]) <= lag)


def test_resume_after_a_crash_equals_an_uninterrupted_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    whole = collect(ENV, 3, tmp_path / "whole", **SMALL)
    real = ds._episode
    calls = {"n": 0}

    def crash_on_third(*args: object, **kwargs: object) -> None:
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt("simulated crash")
        real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(ds, "_episode", crash_on_third)
    with pytest.raises(KeyboardInterrupt):
        collect(ENV, 3, tmp_path / "resumed", **SMALL)
    monkeypatch.setattr(ds, "_episode", real)
    partial = json.loads((tmp_path / "resumed" / "manifest.json").read_text())
    assert not partial["complete"] and len(partial["shards"]) == 2
    assert not any(p.name.endswith(".tmp") for p in (tmp_path / "resumed").iterdir())
    with pytest.raises(DualtwinError, match="not empty"):
        collect(ENV, 3, tmp_path / "resumed", **SMALL)
    with pytest.raises(DualtwinError, match="seed"):
        collect(ENV, 3, tmp_path / "resumed", **{**SMALL, "seed": 6}, resume=True)
    collect(ENV, 3, tmp_path / "resumed", **SMALL, resume=True)
    a, b = load_dataset(whole), load_dataset(tmp_path / "resumed")
    for key in ds.KEYS:
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    shards = [s["sha256"] for s in json.loads((whole / "manifest.json").read_text())["shards"]]
    assert shards == [s["sha256"] for s in json.loads((tmp_path / "resumed" / "manifest.json").read_text())["shards"]]


def test_a_modified_shard_is_detected(tmp_path: Path) -> None:
    out = collect(ENV, 1, tmp_path / "d", **SMALL)
    shard = out / "shard-00000.npz"
    shard.write_bytes(shard.read_bytes()[:-10])
    with pytest.raises(DualtwinError, match="sha256"):
        load_dataset(out)


@pytest.mark.parametrize("controller", ["random", "scripted"])
def test_controllers_and_the_webots_twin(tmp_path: Path, controller: str) -> None:
    env = "dualtwin/CartPole-Webots-Continuous-v0" if controller == "scripted" else ENV
    out = collect(env, 1, tmp_path / controller, controller=controller, randomize=False, **SMALL)
    data = load_dataset(out)
    assert data.manifest["controller"] == controller and len(data) == 6
    assert data.manifest["twin"] == ("webots" if "Webots" in env else "mujoco")


def test_noisy_policy_controller(tmp_path: Path) -> None:
    from dualtwin.perception.reference_policy import export_reference_policy

    export_reference_policy(tmp_path / "policy")
    out = collect(ENV, 1, tmp_path / "noisy", controller="noisy-policy", policy_run=tmp_path / "policy", **SMALL)
    data = load_dataset(out)
    assert data.manifest["policy"]["path"] == str((tmp_path / "policy").resolve()) and len(data) == 6
    assert np.all(np.abs(data.action) <= 1.0)


def test_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(DualtwinError, match="controller"):
        collect(ENV, 1, tmp_path / "x", controller="clever")
    with pytest.raises(DualtwinError, match="needs policy_run"):
        collect(ENV, 1, tmp_path / "y", controller="noisy-policy")
    assert not (tmp_path / "y").exists()  # a refused collection leaves no folder behind
    with pytest.raises(DualtwinError):
        collect(ENV, 1, tmp_path / "z", controller="noisy-policy", policy_run=tmp_path / "no-such-policy")
    assert not (tmp_path / "z").exists()
    with pytest.raises(DualtwinError, match="not a perception dataset"):
        load_dataset(tmp_path)
