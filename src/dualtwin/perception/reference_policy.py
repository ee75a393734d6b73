"""A hand-written privileged-state policy in the exported-policy format, for smoke tests and benchmarks.

When no trained policy is at hand, the perception pipeline and the RobotServer still need a policy that balances
the pole, to show whether control with perception in the loop keeps the reward of privileged-state control
(here perception supplies only the pole rate; the other inputs are on-board sensors). This one is a
linear state feedback for the continuous CartPole with **odometry cart velocity** (``task_kwargs:
{cart_velocity: odometry}``): the wheels are velocity servos, so the odometry velocity is the last command,
and the policy adds an acceleration ``a = 25 θ + 4 θ' + 0.5 x + 1 x'`` over one control period::

    cart velocity = x' + a · dt,        action = clip(cart velocity / max speed, -1, 1)

Its only privileged input is the pole's angular velocity. The files are exactly what
:func:`dualtwin.rl.export_policy` writes (``policy.onnx`` with inputs/outputs ``observation`` ->
``action``, ``cart_velocity`` and ``policy_contract.json``), so everything downstream treats it as a trained
policy; ``policy_run`` in the contract says ``reference``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import package_versions, sha256_file, write_json
from dualtwin.errors import DualtwinError

GAINS = (0.5, 1.0, 25.0, 4.0)  # x, x', θ, θ' (acceleration per unit)
#: A stiffer position loop for camera-only control: with a fixed camera the pole estimate's bias grows with the
#: cart's distance from the image centre, and a bias b holds the cart at 25 b / k_x from it (see the README).
CAMERA_GAINS = (2.0, 2.0, 25.0, 4.0)
ENV_KWARGS: dict[str, Any] = {"task_kwargs": {"cart_velocity": "odometry"}}
OPSET = 17


def export_reference_policy(out_dir: Path | str, env_id: str = "dualtwin/CartPole-MuJoCo-Continuous-v0",
                            gains: tuple[float, float, float, float] = GAINS) -> Path:
    """Write the reference policy (``policy.onnx`` + ``policy_contract.json``) into ``out_dir``.

    ``gains`` (x, x', θ, θ'): :data:`GAINS` by default; :data:`CAMERA_GAINS` hold the cart nearer the centre.
    """
    import torch
    from torch import nn

    from dualtwin.rl import make_env

    env = make_env(env_id, **ENV_KWARGS)
    try:
        twin_env: Any = env.unwrapped
        io = twin_env.io_contract()
        dt = float(twin_env.control_period)
    finally:
        env.close()
    action = io["action"]
    if action.get("type") != "box" or [t["name"] for t in io["observation"]["terms"]] != [
            "cart_position", "cart_velocity", "pole_angle", "pole_angular_velocity"]:
        raise DualtwinError(f"{env_id}: the reference policy is for the continuous CartPole only")
    scale = float(action["scale"])
    # cart velocity = x' + dt (g · state): one linear layer, then the env's clip and scaling.
    weight = np.asarray(gains, dtype=np.float64) * dt
    weight[1] += 1.0

    class Reference(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.linear = nn.Linear(4, 1, bias=False)
            with torch.no_grad():
                self.linear.weight.copy_(torch.tensor(weight, dtype=torch.float32).reshape(1, 4) / scale)

        def forward(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            clipped = torch.clamp(self.linear(observation), -1.0, 1.0)
            return clipped, clipped[..., 0] * scale

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "policy.onnx"
    tmp = out / ".policy.onnx.tmp"
    with torch.no_grad(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning)
        torch.onnx.export(Reference().eval(), (torch.zeros(1, 4),), str(tmp), input_names=["observation"],
                          output_names=["action", "cart_velocity"], opset_version=OPSET, dynamo=False,
                          dynamic_axes={"observation": {0: "batch"}, "action": {0: "batch"},
                                        "cart_velocity": {0: "batch"}})
    tmp.replace(path)
    write_json(out / "policy_contract.json", {
        "contract_version": 1, "env_id": env_id, "env_kwargs": ENV_KWARGS, "source_twin": io.get("twin"),
        "robot": io.get("robot"), "task": io.get("task"), "control_period_s": dt,
        "onnx": {"file": path.name, "sha256": sha256_file(path), "opset": OPSET,
                 "inputs": [{"name": "observation", "dtype": "float32", "shape": ["batch", 4],
                             "meaning": "raw observation in the order below"}],
                 "outputs": [{"name": "action", "dtype": "float32", "shape": ["batch", 1],
                              "meaning": "env action, clipped to [-1, 1]"},
                             {"name": "cart_velocity", "dtype": "float32", "shape": ["batch"], "unit": "m/s",
                              "meaning": action["scaling"]}]},
        "observation": io["observation"]["terms"], "normalization": None, "action": action,
        "policy_run": "reference", "reference": {"gains": dict(zip(["x", "x_dot", "theta", "theta_dot"], gains,
                                                                   strict=True)),
                                                 "law": "cart velocity = x' + dt * (gains . state)"},
        "versions": package_versions(),
    })
    return path
