"""The robot client: run a twin closed-loop through a RobotServer with on-board sensors and the camera only.

Each control period the client sends what a real robot has (the policy contract's ``onboard`` observations, as
the env computes them from the robot's own sensors, and a frame rendered from the perception model's camera)
and applies the action it gets back. The privileged state never enters a request; the client reads it only to
score (the env reward) and to report how far the server's estimate was from the truth.

For comparison the same episodes (same reset seeds) are run with the privileged-state policy evaluated locally
(the served ``policy.onnx`` on the env's full observation).
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.perception.onnx_policy import POLICY_CONTRACT, POLICY_FILE, OnnxPolicy


def encode_png(frame: np.ndarray) -> str:
    from PIL import Image

    buffer = io.BytesIO()
    # Level 1: the frames are tiny; faster encoding matters more than a few bytes.
    Image.fromarray(frame).save(buffer, format="PNG", compress_level=1)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def frame_payload(frame: np.ndarray, fmt: str = "png") -> dict[str, Any]:
    if fmt == "png":
        return {"png_base64": encode_png(frame)}
    if fmt == "raw":
        return {"data_base64": base64.b64encode(np.ascontiguousarray(frame, dtype=np.uint8).tobytes()).decode(),
                "shape": list(frame.shape), "dtype": "uint8"}
    raise DualtwinError(f"unknown frame format {fmt!r} (png or raw)")


def _client(server_url: str, api_key: str | None, timeout: float) -> Any:
    import httpx

    headers = {"X-API-Key": api_key} if api_key else {}
    return httpx.Client(base_url=server_url.rstrip("/"), headers=headers, timeout=timeout)


def _check(response: Any, what: str) -> Any:
    if response.status_code != 200:
        try:
            detail = response.json().get("detail")
        except ValueError:
            detail = response.text[:200]
        raise DualtwinError(f"{what}: server answered {response.status_code}: {detail}")
    return response


def _served_policy(http: Any, info: dict[str, Any]) -> OnnxPolicy:
    """The server's policy, fetched and checked against the sha256 it announces."""
    data = _check(http.get("/v1/policy.onnx"), "GET /v1/policy.onnx").content
    expected = info["policy"].get("onnx_sha256")
    if expected and hashlib.sha256(data).hexdigest() != expected:
        raise DualtwinError("the served policy.onnx does not match the sha256 in /v1/info")
    folder = Path(tempfile.mkdtemp(prefix="dualtwin-served-policy-"))
    (folder / POLICY_FILE).write_bytes(data)
    contract = {"observation": info["policy"]["observation"], "action": info["policy"]["action"],
                "control_period_s": info["policy"]["control_period_s"], "env_id": info["policy"].get("env_id")}
    (folder / POLICY_CONTRACT).write_text(json.dumps(contract), encoding="utf-8")
    return OnnxPolicy.load_exported(folder)


def _env_action(action: Any, discrete: bool) -> Any:
    return int(action) if discrete else np.asarray(action, dtype=np.float32).reshape(-1)


def deploy(server_url: str, env_id: str, episodes: int, *, seed: int = 0, api_key: str | None = None,
           policy_dir: Path | str | None = None, max_steps: int | None = None, frame_format: str = "png",
           compare: bool = True, timeout: float = 10.0) -> dict[str, Any]:
    """Run ``episodes`` episodes of ``env_id`` through the server; compare with the privileged-state policy.

    Args:
        server_url: ``http://127.0.0.1:8000``.
        env_id: a registered dualtwin env id; its twin renders the camera frames.
        episodes: number of episodes (episode ``i`` resets with seed ``seed + i``, in both runs).
        seed: base seed.
        api_key: sent as ``X-API-Key``.
        policy_dir: the privileged-state policy for the comparison (default: the server's ``/v1/policy.onnx``).
        max_steps: episode length cap in control periods (default: the env's).
        frame_format: ``png`` or ``raw`` frames.
        compare: also run the privileged-state policy.
        timeout: seconds per request.

    Returns:
        Rewards per episode for both, their means and ratio, the estimate's error on the privileged
        observations, and request latency percentiles.
    """
    from dualtwin.perception.camera import CameraSpec
    from dualtwin.perception.render import TwinCamera
    from dualtwin.rl import make_env

    if episodes < 1:
        raise DualtwinError("episodes must be >= 1")
    with _client(server_url, api_key, timeout) as http:
        info = _check(http.get("/v1/info"), "GET /v1/info").json()
        policy = OnnxPolicy.load(policy_dir) if policy_dir is not None else _served_policy(http, info)
        terms = info["policy"]["observation"]
        onboard = [i for i, t in enumerate(terms) if t.get("source") == "onboard"]
        privileged = [i for i, t in enumerate(terms) if t.get("source") != "onboard"]
        width, height = info["perception"]["resolution"]
        camera = dict(info["perception"]["camera"] or {})
        name = str(camera.pop("name", "camera"))
        spec = CameraSpec.from_dict(name, camera).with_size(width, height)
        # The policy's env arguments (task options such as odometry velocity) define what it observes.
        kwargs = {k: v for k, v in (info["policy"].get("env_kwargs") or {}).items() if k != "max_episode_steps"}
        if max_steps:
            kwargs["max_episode_steps"] = max_steps
        env = make_env(env_id, **kwargs)
        twin_env: Any = env.unwrapped  # a dualtwin TwinEnv
        try:
            env_terms = [(t.name, t.source) for t in twin_env.task.observation_terms]
            wanted = [(t["name"], t.get("source")) for t in terms]
            if env_terms != wanted or not np.isclose(twin_env.control_period, info["policy"]["control_period_s"]):
                raise DualtwinError(f"{env_id} observes {env_terms} every {twin_env.control_period} s; the "
                                    f"served policy expects {wanted} every {info['policy']['control_period_s']} s")
            camera_renderer = TwinCamera(twin_env.twin, spec, width, height)
            discrete = info["policy"]["action"].get("type") == "discrete"
            served, errors, latencies = [], [], []
            try:
                for episode in range(episodes):
                    obs, _ = env.reset(seed=seed + episode)
                    total, step, done = 0.0, 0, False
                    while not done:
                        request = {
                            "session": f"deploy-{seed}-{episode}",
                            # Only what the robot measures itself: on-board terms and the camera.
                            "sensors": {terms[i]["name"]: float(obs[i]) for i in onboard},
                            "frame": frame_payload(camera_renderer.render(), frame_format),
                            "reset": step == 0, "time_s": float(twin_env.twin.time),
                        }
                        start = time.perf_counter()
                        reply = _check(http.post("/v1/act", json=request), "POST /v1/act").json()
                        latencies.append(time.perf_counter() - start)
                        estimate = reply["observation"]
                        errors.append([abs(estimate[terms[i]["name"]] - float(obs[i])) for i in privileged])
                        obs, reward, terminated, truncated, _ = env.step(_env_action(reply["action"], discrete))
                        total += float(reward)
                        step += 1
                        done = terminated or truncated
                    served.append(total)
            finally:
                camera_renderer.close()
            baseline: list[float] = []
            if compare:
                for episode in range(episodes):
                    obs, _ = env.reset(seed=seed + episode)
                    total, done = 0.0, False
                    while not done:
                        obs, reward, terminated, truncated, _ = env.step(policy.action(obs))
                        total += float(reward)
                        done = terminated or truncated
                    baseline.append(total)
        finally:
            env.close()
    lat = np.asarray(latencies) * 1000.0
    mean_served = float(np.mean(served))
    mean_base = float(np.mean(baseline)) if baseline else None
    return {
        "server": server_url, "env_id": env_id, "episodes": episodes, "seed": seed, "frame_format": frame_format,
        "perception_rewards": served, "privileged_rewards": baseline,
        "mean_perception_reward": mean_served, "mean_privileged_reward": mean_base,
        "ratio": mean_served / mean_base if mean_base else None,
        "estimate_mae": {terms[i]["name"]: float(v) for i, v in
                         zip(privileged, np.mean(errors, axis=0) if errors else [], strict=False)},
        "latency_ms": {"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)),
                       "requests": int(len(lat))},
    }
