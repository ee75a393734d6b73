"""Helpers shared by the synchronisation tests: a short suite, wheel names, driving a twin, the state a twin is
really in, a tiny ONNX policy."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dualtwin.twins.base import Twin

WHEELS = ["wheel1", "wheel2", "wheel3", "wheel4"]
PIONEER_WHEELS = ["front left wheel", "back left wheel", "front right wheel", "back right wheel"]
SINE = {"kind": "sine", "amplitude": 6.0, "frequency_hz": 0.7}
SUITE = {
    "suite_name": "sync_test",
    "global_settings": {"TIME_STEP": 32},
    "scenarios": [
        {"name": "fall", "duration_s": 1.0, "initial_angle": 0.2},
        {"name": "sine", "duration_s": 1.0, "initial_angle": -0.1, "wheel_velocity": SINE},
        {"name": "drive", "duration_s": 1.0, "initial_angle": 0.05, "wheel_velocity": 4.0},
    ],
}
#: Nominal pole damping of the damped cart-pole; the "true" robot has twice as much.
NOMINAL_DAMPING = 0.05


def write_json(path: Path, data: object) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def drive(twin: Twin, actuators: list[str], speeds: list[float], steps: int, pole: float | None = 0.2) -> None:
    """Reset, tilt the pole (cart-pole), command the wheels and run ``steps`` periods."""
    twin.reset(seed=1)
    if pole is not None:
        twin.set_joint_state("pole_hinge", position=pole)
    for name, speed in zip(actuators, speeds, strict=True):
        twin.command(name, "velocity", speed)
    for _ in range(steps):
        twin.step()


def applied_state(twin: Twin):  # type: ignore[no-untyped-def]
    """The state a twin is really in: for Webots, run its queued supervisor writes without a physics step."""
    if twin.name == "webots":
        twin._written = None  # type: ignore[attr-defined]
        twin.sup.simulation.apply_pending()  # type: ignore[attr-defined]
    return twin.get_state()


def sign_policy(folder: Path, env_id: str = "dualtwin/CartPole-MuJoCo-v0") -> Path:
    """An exported-policy folder whose ONNX graph pushes the cart toward the pole's lean (discrete actions)."""
    import onnx
    from onnx import TensorProto, helper

    obs = helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["batch", 4])
    action = helper.make_tensor_value_info("action", TensorProto.INT64, ["batch"])
    weights = helper.make_tensor("w", TensorProto.FLOAT, [4, 1], [0.0, 0.2, 3.0, 0.5])
    nodes = [helper.make_node("MatMul", ["observation", "w"], ["score"]),
             helper.make_node("Reshape", ["score", "shape"], ["row"]),
             helper.make_node("Greater", ["row", "zero"], ["positive"]),
             helper.make_node("Cast", ["positive"], ["action"], to=TensorProto.INT64)]
    initializers = [weights, helper.make_tensor("shape", TensorProto.INT64, [1], [-1]),
                    helper.make_tensor("zero", TensorProto.FLOAT, [], [0.0])]
    graph = helper.make_graph(nodes, "sign", [obs], [action], initializers)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=9)
    folder.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(folder / "policy.onnx"))
    write_json(folder / "policy_contract.json", {"env_id": env_id, "env_kwargs": {}, "control_period_s": 0.032,
                                                 "action": {"type": "discrete", "n": 2}, "observation": []})
    return folder


def max_abs(values: object) -> float:
    return float(np.max(np.abs(np.asarray(values, dtype=float))))
