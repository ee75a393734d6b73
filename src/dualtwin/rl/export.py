"""Export a trained policy to ONNX with its normalisation and action scaling inside the graph, plus a contract.

``policy.onnx`` takes the raw observation (``observation``, float32 [batch, n], in the contract's order and
units) and returns ``action`` (what the Gymnasium env takes: the index for discrete policies, the clipped
values in [-1, 1] for continuous ones) and one float32 [batch] output per physical command the action
contract names, in its unit after the speed table or the scaling: ``cart_velocity`` (m/s) for the CartPole,
``left_wheel_speed`` and ``right_wheel_speed`` (rad/s) for the Pioneer. ``policy_contract.json`` says so in
data: observation names, units, order, on-board vs privileged, normalisation statistics, action
names/units/scaling, control period, env id, source twin and versions.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import package_versions, sha256_file, write_json
from dualtwin.errors import DualtwinError
from dualtwin.rl.policy import LoadedPolicy, load_policy

OPSET = 17
CONTRACT_VERSION = 1


def command_names(action: dict[str, Any]) -> list[str]:
    """The physical commands an action contract names (the ONNX outputs after ``action``)."""
    return [str(name) for name in action["names"]]


def _graph_module(policy: LoadedPolicy) -> Any:
    import torch
    from torch import nn

    contract = policy.contract
    action = contract["action"]
    discrete = action["type"] == "discrete"
    stats: Any = policy.vec_normalize
    n_obs = int(contract["observation"]["shape"][0])
    if stats is not None and stats.norm_obs:
        mean = np.asarray(stats.obs_rms.mean, dtype=np.float64)
        # Fold VecNormalize's (obs - mean) / sqrt(var + eps) into one scale in float64 before casting.
        inv_std = 1.0 / np.sqrt(np.asarray(stats.obs_rms.var, dtype=np.float64) + float(stats.epsilon))
        clip = float(stats.clip_obs)
    else:
        mean, inv_std, clip = np.zeros(n_obs), np.ones(n_obs), float("inf")
    sb3_policy: Any = policy.model.policy

    class Exported(nn.Module):
        mean: torch.Tensor
        inv_std: torch.Tensor
        speed_table: torch.Tensor
        policy: Any

        def __init__(self) -> None:
            super().__init__()
            self.policy = sb3_policy
            self.register_buffer("mean", torch.tensor(mean, dtype=torch.float32))
            self.register_buffer("inv_std", torch.tensor(inv_std, dtype=torch.float32))
            self.clip = clip
            if discrete:
                self.register_buffer("speed_table", torch.tensor(action["speed_table"], dtype=torch.float32))
            else:
                self.scale = float(action["scale"])

        def forward(self, observation: torch.Tensor) -> tuple[torch.Tensor, ...]:
            x = (observation - self.mean) * self.inv_std
            if np.isfinite(self.clip):
                x = torch.clamp(x, -self.clip, self.clip)
            features = self.policy.extract_features(x, self.policy.pi_features_extractor)
            latent = self.policy.mlp_extractor.forward_actor(features)
            out = self.policy.action_net(latent)
            if discrete:
                index = torch.argmax(out, dim=-1)
                return index, self.speed_table[index]
            # The Gaussian's mean is the deterministic action; SB3 clips it to the Box, then the env scales.
            clipped = torch.clamp(out, -1.0, 1.0)
            return (clipped, *(clipped[..., i] * self.scale for i in range(clipped.shape[-1])))

    return Exported().eval()


def export_policy(policy_run: Path | str, out_dir: Path | str, which: str = "final") -> Path:
    """Write ``policy.onnx`` and ``policy_contract.json`` for a training run into ``out_dir``; returns the ONNX path."""
    import torch

    policy = load_policy(policy_run, "best" if which == "best" else "final")
    contract = policy.contract
    if not contract or contract.get("action", {}).get("type") not in ("discrete", "box"):
        raise DualtwinError(f"{policy_run}: run.json has no usable I/O contract to export")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    module = _graph_module(policy)
    n_obs = int(contract["observation"]["shape"][0])
    example = torch.zeros((1, n_obs), dtype=torch.float32)
    commands = command_names(contract["action"])
    path = out / "policy.onnx"
    tmp = out / ".policy.onnx.tmp"
    # The TorchScript exporter (dynamo=False) needs no onnxscript (not a dependency) and handles this small MLP;
    # torch >= 2.9 marks it deprecated, so that warning is silenced here. Opset 17 as in SB3's export guide.
    with torch.no_grad(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning)
        torch.onnx.export(module, (example,), str(tmp), input_names=["observation"],
                          output_names=["action", *commands], opset_version=OPSET, dynamo=False,
                          dynamic_axes={name: {0: "batch"} for name in ("observation", "action", *commands)})
    tmp.replace(path)
    write_json(out / "policy_contract.json", _contract(policy, path))
    return path


def _contract(policy: LoadedPolicy, onnx_path: Path) -> dict[str, Any]:
    io = policy.contract
    action = io["action"]
    discrete = action["type"] == "discrete"
    stats: Any = policy.vec_normalize
    normalization: dict[str, Any] | None = None
    if stats is not None and stats.norm_obs:
        normalization = {"formula": "clip((observation - mean) / sqrt(var + epsilon), -clip, clip)",
                         "in_graph": True, "mean": [float(v) for v in stats.obs_rms.mean],
                         "var": [float(v) for v in stats.obs_rms.var], "epsilon": float(stats.epsilon),
                         "clip": float(stats.clip_obs)}
    outputs = [
        {"name": "action", "dtype": "int64" if discrete else "float32",
         "shape": ["batch"] if discrete else ["batch", len(command_names(action))],
         "meaning": "env action: index into speed_table" if discrete else "env action, clipped to [-1, 1]"},
        *({"name": name, "dtype": "float32", "shape": ["batch"], "unit": action["unit"], "meaning": action["scaling"]}
          for name in command_names(action)),
    ]
    return {
        "contract_version": CONTRACT_VERSION,
        "env_id": policy.env_id,
        "env_kwargs": policy.env_kwargs,
        "source_twin": io.get("twin"),
        "robot": io.get("robot"),
        "task": io.get("task"),
        "control_period_s": io.get("control_period_s"),
        "onnx": {"file": onnx_path.name, "sha256": sha256_file(onnx_path), "opset": OPSET,
                 "inputs": [{"name": "observation", "dtype": "float32", "shape": ["batch", io["observation"]["shape"][0]],
                             "meaning": "raw observation in the order below (normalised inside the graph)"}],
                 "outputs": outputs},
        "observation": io["observation"]["terms"],
        "normalization": normalization,
        "action": action,
        "policy_run": str(policy.run_dir),
        "versions": package_versions(),
    }
