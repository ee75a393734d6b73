"""Fixtures for the importers: a real Webots-twin suite run, and writers of real TSV, CSV and MCAP files."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import dualtwin.robots as robots_pkg
from dualtwin.divergence.runs import load_tsv
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.runner import SuiteRun
from tests.support.ros_messages import JOINT_STATE_DEF, ODOMETRY_DEF

CARTPOLE_SUITE = Path(robots_pkg.__file__).parent / "cartpole" / "suite.json"

EPOCH_NS = 1_700_000_000_123_456_789


@pytest.fixture(scope="session")
def cartpole_suite() -> Path:
    return CARTPOLE_SUITE


@pytest.fixture(scope="session")
def webots_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The bundled CartPole suite run on the Webots twin (real ODE), once per session."""
    out = tmp_path_factory.mktemp("webots") / "run"
    SuiteRun(CARTPOLE_SUITE, "webots", resolve_robot("cartpole"), out).run()
    return out


@pytest.fixture(scope="session")
def mujoco_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("mujoco") / "run"
    SuiteRun(CARTPOLE_SUITE, "mujoco", resolve_robot("cartpole"), out).run()
    return out


def _ground_truth(run: Path) -> list[tuple[list[str], np.ndarray]]:
    manifest = json.loads((run / "manifest.json").read_text())
    return [load_tsv(run / sc["ground_truth"]) for sc in manifest["scenarios"]]


@pytest.fixture
def write_paper_logs() -> Callable[..., Path]:
    """Write a run's ground truth as the paper's orchestrator would: messy on request."""

    def write(run: Path, folder: Path, *, decimals: int | None = 3, jitter_s: float = 0.002,
              late_periods: int = 1, wall_clock: bool = False, seed: int = 0) -> Path:
        rng = np.random.default_rng(seed)
        folder.mkdir(parents=True, exist_ok=True)
        clock = 1_700_000_000.0
        for i, (header, data) in enumerate(_ground_truth(run)):
            cols = [header.index("time_s"), header.index("pole_angle_rad"), header.index("cart_pos_m")]
            rows = data[late_periods:, cols].copy()
            rows[:, 0] += rng.uniform(-jitter_s, jitter_s, len(rows))
            if wall_clock:
                rows[:, 0] += clock
                clock += float(data[-1, 0]) + 0.5
            fmt = (lambda v: f"{v:.{decimals}f}") if decimals is not None else repr
            lines = ["time_s\tpole_angle_rad\tcart_pos_m"]
            lines += ["\t".join(fmt(float(v)) for v in row) for row in rows]
            (folder / f"simulation_log_SUP_{i}.tsv").write_text("\n".join(lines) + "\n")
        return folder

    return write


def _write_bag(path: Path, t_s: Sequence[float], joints: dict[str, Sequence[float]],
              odom: tuple[Sequence[float], Sequence[float]] | None = None, start_ns: int = EPOCH_NS,
              joint_topic: str = "/joint_states", odom_topic: str = "/odom",
              header_t_s: Sequence[float] | None = None) -> Path:
        from mcap_ros2.writer import Writer

        names = list(joints)
        with open(path, "wb") as handle:
            writer = Writer(handle)
            js = writer.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_DEF)
            od = writer.register_msgdef("nav_msgs/msg/Odometry", ODOMETRY_DEF) if odom else None
            for k, t in enumerate(t_s):
                ns = start_ns + round(t * 1e9)
                hs = ns if header_t_s is None else start_ns + round(header_t_s[k] * 1e9)
                header = {"stamp": {"sec": hs // 1_000_000_000, "nanosec": hs % 1_000_000_000}, "frame_id": "base"}
                writer.write_message(joint_topic, js, {
                    "header": header, "name": names, "position": [float(joints[n][k]) for n in names],
                    "velocity": [], "effort": []}, log_time=ns, publish_time=ns, sequence=k)
                if odom and od is not None:
                    x, yaw = float(odom[0][k]), float(odom[1][k])
                    msg: dict[str, Any] = {
                        "header": header, "child_frame_id": "base_link",
                        "pose": {"pose": {"position": {"x": x, "y": 0.0, "z": 0.0},
                                          "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2),
                                                          "w": math.cos(yaw / 2)}},
                                 "covariance": [0.0] * 36},
                        "twist": {"twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                                            "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                                  "covariance": [0.0] * 36}}
                    writer.write_message(odom_topic, od, msg, log_time=ns + 1000, publish_time=ns + 1000)
            writer.finish()
        return path


@pytest.fixture(scope="session")
def write_bag() -> Callable[..., Path]:
    """Write a real MCAP bag with the real ROS 2 writer: JointState and Odometry messages."""
    return _write_bag


@pytest.fixture(scope="session")
def cartpole_bags(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One bag per scenario of the CartPole suite, 100 Hz: wheel and pole joints, and odometry x."""
    folder = tmp_path_factory.mktemp("bags")
    for i, sc in enumerate(json.loads(CARTPOLE_SUITE.read_text())["scenarios"]):
        t = np.arange(0.0, sc["duration_s"] + 1e-9, 0.01)
        joints = {"wheel1": 2 * t, "pole_hinge": 0.1 * (i + 1) * np.sin(3 * t)}
        _write_bag(folder / f"scenario_{i}.mcap", t, joints, odom=(0.05 * t, 0 * t), start_ns=10**18 + i * 10**10)
    return folder


def tree_bytes(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def snapshot() -> Callable[[Path], dict[str, bytes]]:
    return tree_bytes


@pytest.fixture
def run_cli() -> Callable[..., tuple[int, str, str]]:
    """The installed ``dualtwin`` command in a real subprocess: exit code, stdout, stderr."""
    import subprocess
    import sys

    def run(*args: str) -> tuple[int, str, str]:
        proc = subprocess.run([sys.executable, "-c", "from dualtwin.cli import main; main()", *args],
                              capture_output=True, text=True, timeout=120)
        return proc.returncode, proc.stdout, proc.stderr

    return run
