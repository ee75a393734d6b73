"""Camera-only Pattern 3: perception trained on Webots-twin frames, a policy served with wheel odometry only.

Structure, not success: a tiny Webots dataset and a one-epoch model (the bench measures accuracy and control).
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.errors import DualtwinError

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
pytestmark = pytest.mark.usefixtures("headless")

WEBOTS = "dualtwin/CartPole-Webots-Continuous-v0"
SIZE = 32
ODOMETRY = ["cart_position", "cart_velocity"]
CAMERA = ["pole_angle", "pole_angular_velocity"]


@pytest.fixture(scope="module")
def webots_model(tmp_path_factory: pytest.TempPathFactory, headless: None) -> tuple[Path, Path]:
    """(dataset, model): 3 short episodes collected in the Webots twin, one epoch of training."""
    import torch

    from dualtwin.perception.dataset import collect
    from dualtwin.perception.model import train_perception

    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("camera-only")
    data = collect(WEBOTS, 3, root / "data", controller="random", max_steps=10, width=SIZE, height=SIZE, seed=5)
    return data, train_perception(data, root / "model", epochs=1, seed=0, threads=1, holdout=0.34)


@pytest.fixture(scope="module")
def reference_policy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from dualtwin.perception.reference_policy import export_reference_policy

    out = tmp_path_factory.mktemp("policy") / "export"
    export_reference_policy(out)
    return out


def contract_of(folder: Path) -> dict[str, Any]:
    return json.loads((folder / "policy_contract.json").read_text())


def test_model_is_trained_on_webots_twin_frames_and_evaluated_on_heldout_episodes(
        webots_model: tuple[Path, Path]) -> None:
    from dualtwin.perception.model import evaluate_perception

    data, model = webots_model
    trained_on = json.loads((model / "perception_contract.json").read_text())["trained_on"]
    assert trained_on["twin"] == "webots" and trained_on["env_id"] == WEBOTS
    report = evaluate_perception(model, data, velocity="kalman")
    training = json.loads((model / "training.json").read_text())
    # Held out by episode identity: exactly the split's held-out episodes remain, none it trained on.
    assert report["heldout_episodes"] == training["heldout_episodes"]
    assert report["excluded_training_episodes"] == len(training["train_episodes"]) >= 1
    assert set(report["mae"]) >= {"pole_angle", "pole_angular_velocity"}


def test_contract_keeps_only_wheel_odometry_on_board(reference_policy: Path) -> None:
    from dualtwin.perception.camera_only import camera_only_contract

    original = contract_of(reference_policy)
    # The exported policy reads the pole hinge encoder on board: not camera-only.
    assert {t["name"]: t["source"] for t in original["observation"]}["pole_angle"] == "onboard"
    contract = camera_only_contract(original, ODOMETRY + CAMERA)
    sources = {t["name"]: t["source"] for t in contract["observation"]}
    assert sources == {"cart_position": "onboard", "cart_velocity": "onboard", "pole_angle": "camera",
                       "pole_angular_velocity": "camera"}
    assert contract["observation_mode"] == "camera_only"
    assert contract["camera_only"]["onboard"] == ODOMETRY and contract["camera_only"]["camera"] == CAMERA
    odometry = contract["odometry"]
    # Documented from the binding: the four wheel position sensors, scaled by the wheel radius.
    assert odometry["sensors"] == ["wheel1 sensor", "wheel2 sensor", "wheel3 sensor", "wheel4 sensor"]
    assert odometry["wheel_radius_m"] == pytest.approx(0.04) and "wheel_radius_m" in odometry["cart_position"]
    # Only the sources change: order, names and units are what the network was trained on.
    assert [(t["name"], t["unit"]) for t in contract["observation"]] == \
        [(t["name"], t["unit"]) for t in original["observation"]]
    assert "pole_angle" not in original.get("camera_only", {})  # the input was not modified


def test_contract_refuses_a_term_that_is_neither_odometry_nor_estimated(reference_policy: Path) -> None:
    from dualtwin.perception.camera_only import camera_only_contract

    with pytest.raises(DualtwinError, match="pole_angle"):
        camera_only_contract(contract_of(reference_policy), ["pole_angular_velocity"])


def test_odometry_must_read_the_driven_wheels(reference_policy: Path) -> None:
    from dualtwin.perception.camera_only import camera_only_contract

    contract = contract_of(reference_policy)
    contract["action"]["actuators"] = ["pole motor"]
    with pytest.raises(DualtwinError, match="not wheel odometry"):
        camera_only_contract(contract, ODOMETRY + CAMERA)
    contract = contract_of(reference_policy)
    contract["action"]["wheel_radius_m"] = 0.05
    with pytest.raises(DualtwinError, match="scale"):
        camera_only_contract(contract, ODOMETRY + CAMERA)


class Running:
    """uvicorn serving an app from a thread on a free loopback port (a real HTTP server)."""

    def __init__(self, app: Any) -> None:
        import uvicorn

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        self.server = uvicorn.Server(uvicorn.Config(app, log_level="warning", access_log=False, lifespan="on"))
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]}, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 20
        while not self.server.started:
            assert time.monotonic() < deadline and self.thread.is_alive(), "uvicorn did not start"
            time.sleep(0.02)

    def close(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=10)
        self.sock.close()


@pytest.fixture(scope="module")
def camera_only_server(webots_model: tuple[Path, Path], reference_policy: Path) -> Iterator[str]:
    from dualtwin.server.app import create_app

    running = Running(create_app(reference_policy, webots_model[1], camera_only=True))
    yield running.url
    running.close()


def test_served_request_schema_has_no_pole_angle_field(camera_only_server: str) -> None:
    import httpx

    from dualtwin.server.client import frame_payload

    schema = httpx.get(f"{camera_only_server}/openapi.json").json()
    sensors = schema["components"]["schemas"]["ActRequest"]["properties"]["sensors"]
    assert sorted(sensors["properties"]) == sorted(ODOMETRY) and sensors["additionalProperties"] is False
    info = httpx.get(f"{camera_only_server}/v1/info").json()
    assert info["observation_mode"] == "camera_only" and sorted(info["request"]["sensors"]) == sorted(ODOMETRY)
    assert info["request"]["estimated"] == CAMERA and info["odometry"]["wheel_radius_m"] == pytest.approx(0.04)
    frame = frame_payload(np.zeros((SIZE, SIZE, 3), dtype=np.uint8))
    # A pole encoder reading is refused, not ignored: the served policy cannot be fed one.
    body = {"session": "r", "frame": frame, "sensors": {"cart_position": 0.0, "cart_velocity": 0.0,
                                                        "pole_angle": 0.01}}
    refused = httpx.post(f"{camera_only_server}/v1/act", json=body)
    assert refused.status_code == 422 and "pole_angle" in refused.text
    body["sensors"] = {"cart_position": 0.0, "cart_velocity": 0.0}
    reply = httpx.post(f"{camera_only_server}/v1/act", json=body).json()
    assert reply["sources"] == {"cart_position": "onboard", "cart_velocity": "onboard", "pole_angle": "perception",
                                "pole_angular_velocity": "perception"}
    assert reply["observation"]["pole_angle"] == reply["estimate"]["pole_angle"]


def test_exported_camera_only_folder_is_served_camera_only(webots_model: tuple[Path, Path],
                                                          reference_policy: Path, tmp_path: Path) -> None:
    from dualtwin.perception.camera_only import export_camera_only
    from dualtwin.server.app import ServerModels

    out = export_camera_only(reference_policy, webots_model[1], tmp_path / "served")
    assert (out / "policy.onnx").read_bytes() == (reference_policy / "policy.onnx").read_bytes()
    assert contract_of(out)["observation_mode"] == "camera_only"
    # No flag needed: the contract says camera-only, so the server reads only the odometry.
    models = ServerModels.load(out, webots_model[1])
    assert models.policy.onboard == ODOMETRY and models.policy.privileged == CAMERA
    assert ServerModels.load(reference_policy, webots_model[1]).policy.onboard == ["cart_position", "cart_velocity",
                                                                                   "pole_angle"]


def test_deploy_runs_camera_only_in_the_webots_twin(camera_only_server: str) -> None:
    from dualtwin.server.client import deploy

    report = deploy(camera_only_server, WEBOTS, 1, seed=3, max_steps=6)
    assert report["loop"] == "camera_only_with_wheel_odometry" and report["observation_mode"] == "camera_only"
    assert report["inputs_from_onboard_sensors"] == ODOMETRY and report["inputs_from_perception"] == CAMERA
    assert set(report["estimate_mae"]) == set(CAMERA) and report["latency_ms"]["requests"] == 6
    assert report["episode_cap"] == 6 and report["perception_success"] in (0.0, 1.0)


def test_cli_camera_only_export_needs_a_perception_model(reference_policy: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    from dualtwin.cli import main

    code = main(["export", "--policy", str(reference_policy), "--out", str(tmp_path / "x"), "--camera-only"])
    err = capsys.readouterr().err
    assert code == 2 and "--perception" in err and "Traceback" not in err and not (tmp_path / "x").exists()


def test_training_continues_from_a_model_without_leaking_its_episodes(webots_model: tuple[Path, Path],
                                                                     tmp_path: Path) -> None:
    from dualtwin.perception.model import split_episodes, train_perception

    data, model = webots_model
    first = json.loads((model / "perception_contract.json").read_text())["trained_on"]["episode_ids"]
    out = train_perception(data, tmp_path / "more", epochs=1, seed=0, threads=1, holdout=0.34, init_from=model)
    contract = json.loads((out / "perception_contract.json").read_text())
    assert set(first) <= set(contract["trained_on"]["episode_ids"])
    training = json.loads((out / "training.json").read_text())
    assert training["init_from"]["weights_sha256"] and training["heldout_episodes"] == \
        json.loads((model / "training.json").read_text())["heldout_episodes"]
    # Another split that holds out an episode the first model trained on: refused, nothing scored on training data.
    trained = json.loads((model / "training.json").read_text())["train_episodes"]
    seed = next(s for s in range(1, 50) if set(split_episodes(np.arange(3), 0.34, s)[1]) & set(trained))
    with pytest.raises(DualtwinError, match="holds out"):
        train_perception(data, tmp_path / "leak", epochs=1, seed=seed, threads=1, holdout=0.34, init_from=model)
    assert not (tmp_path / "leak").exists()


def test_cli_refuses_a_negative_colour_jitter(webots_model: tuple[Path, Path], tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    from dualtwin.cli import main

    code = main(["perception", "train", "--data", str(webots_model[0]), "--out", str(tmp_path / "m"),
                 "--colour-jitter", "-1"])
    err = capsys.readouterr().err
    assert code == 2 and "--colour-jitter" in err and "Traceback" not in err and not (tmp_path / "m").exists()
