"""The closed loop through the RobotServer says what perception supplies (issue 14): with the CartPole policy
that reads cart position, cart velocity (odometry) and pole angle from on-board sensors, only the pole rate
comes from the camera, so the loop is not "perception-only"."""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path

import pytest

from dualtwin.reporting import ProgressEvent

pytest.importorskip("uvicorn")
ENV = "dualtwin/CartPole-MuJoCo-Continuous-v0"


def test_deploy_names_its_loop_and_reports_progress(tmp_path: Path) -> None:
    import torch
    import uvicorn

    from dualtwin.perception.dataset import collect
    from dualtwin.perception.model import train_perception
    from dualtwin.perception.reference_policy import export_reference_policy
    from dualtwin.server.app import create_app
    from dualtwin.server.client import deploy

    torch.set_num_threads(1)
    try:
        data = collect(ENV, 2, tmp_path / "data", controller="random", max_steps=8, width=32, height=32)
    except Exception as exc:  # noqa: BLE001 - no headless GL here
        pytest.skip(f"headless rendering unavailable: {exc}")
    epochs: list[ProgressEvent] = []
    model = train_perception(data, tmp_path / "model", epochs=2, seed=0, threads=1, holdout=0.5,
                             progress=epochs.append)
    assert [(e.stage, e.done, e.total) for e in epochs] == [("perception train", 1, 2), ("perception train", 2, 2)]
    assert "MAE pole" in epochs[-1].message
    export_reference_policy(tmp_path / "policy", ENV)
    policy = tmp_path / "policy"

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    server = uvicorn.Server(uvicorn.Config(create_app(policy, model), log_level="warning", access_log=False))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 20
        while not server.started:
            assert time.monotonic() < deadline and thread.is_alive(), "uvicorn did not start"
            time.sleep(0.02)
        events: list[ProgressEvent] = []
        report = deploy(f"http://127.0.0.1:{sock.getsockname()[1]}", ENV, 2, max_steps=4, progress=events.append)
    finally:
        server.should_exit = True
        thread.join(timeout=10)
        sock.close()
    assert report["loop"] == "perception_pole_angular_velocity_only"
    assert report["inputs_from_perception"] == ["pole_angular_velocity"]
    assert report["inputs_from_onboard_sensors"] == ["cart_position", "cart_velocity", "pole_angle"]
    assert [(e.stage, e.done) for e in events] == [("deploy", 1), ("deploy", 2), ("deploy: privileged baseline", 1),
                                                   ("deploy: privileged baseline", 2)]
