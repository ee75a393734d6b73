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
from dualtwin.http_bounds import bounded_client, is_reply_limit
from dualtwin.perception.onnx_policy import POLICY_CONTRACT, POLICY_FILE, OnnxPolicy
from dualtwin.reporting import Progress, ProgressCallback


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


#: The largest reply the client reads (the served policy's ONNX file is the largest, well under this).
MAX_REPLY_BYTES = 256 << 20


def _client(server_url: str, api_key: str | None, timeout: float) -> Any:
    import httpx

    headers = {"X-API-Key": api_key} if api_key else {}
    try:
        # a server is not trusted: each reply must end within the timeout (a trickling one hung deploy forever)
        return bounded_client(httpx.Client, reply_s=timeout, max_bytes=MAX_REPLY_BYTES, base_url=server_url.rstrip("/"),
                              headers=headers, timeout=timeout)
    except (httpx.InvalidURL, TypeError, ValueError) as exc:
        raise DualtwinError(f"--server {server_url!r}: not a usable URL ({exc})") from None


#: The env options a server may set (from the policy's training run): what shapes the policy's observations
#: and the physics it was trained on. The twin, robot and task are the user's choice (the env id); rendering and
#: the episode cap are the client's. Everything else a server sends is refused, not passed to ``make_env``.
SERVER_ENV_OPTIONS = ("continuous", "control_period", "knobs", "task_kwargs")


def check_env_kwargs(env_id: str, env_kwargs: Any, where: str = "/v1/info policy.env_kwargs") -> dict[str, Any]:
    """The server-supplied env options, checked against the env's declared options (names and types).

    Only :data:`SERVER_ENV_OPTIONS` are accepted, each against the type ``TwinEnv`` declares for it; the task's
    options (``task_kwargs``) against the task class's own signature; knob values must be finite numbers.

    Raises:
        DualtwinError: one line naming the JSON path of the first unknown or invalid option.
    """
    import gymnasium as gym

    from dualtwin.rl import check_env_id
    from dualtwin.rl.env import check_option, check_task_kwargs, declared_options

    if env_kwargs is None:
        return {}
    if not isinstance(env_kwargs, dict):
        raise DualtwinError(f"{where}: expected an object, got {type(env_kwargs).__name__}")
    spec = gym.spec(check_env_id(env_id))
    factory = gym.envs.registration.load_env_creator(spec.entry_point) if isinstance(spec.entry_point, str) \
        else spec.entry_point
    declared = declared_options(factory)
    checked: dict[str, Any] = {}
    for key, value in env_kwargs.items():
        if key not in SERVER_ENV_OPTIONS or key not in declared:
            allowed = [k for k in SERVER_ENV_OPTIONS if k in declared]
            raise DualtwinError(f"{where}.{key}: not an option a server may set for {env_id} "
                                f"(allowed: {', '.join(allowed)})")
        if key == "task_kwargs":
            # null is refused too (the env would take it as no options): a server sends the object it recorded.
            if not isinstance(value, dict):
                raise DualtwinError(f"{where}.task_kwargs: expected an object, got {type(value).__name__}")
            # The check every env, training run and lockstep policy uses, against the env's task.
            checked[key] = check_task_kwargs(str(spec.kwargs.get("task", "cartpole_balance")), value,
                                             f"{where}.task_kwargs")
        else:
            checked[key] = check_option(f"{where}.{key}", value, declared[key])
            if key == "control_period" and checked[key] <= 0:
                raise DualtwinError(f"{where}.control_period: must be > 0, got {value!r}")
    return checked


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


def _json(response: Any, what: str) -> Any:
    _check(response, what)
    try:
        return response.json()
    except ValueError:  # (DualtwinError is a ValueError too: checked above, outside the try)
        raise DualtwinError(f"{what}: the server's answer is not JSON") from None


#: What the client reads from ``/v1/info`` (JSON paths), checked before use: a server is not trusted either.
INFO_FIELDS = {"policy": dict, "policy.observation": list, "policy.action": dict, "policy.control_period_s": float,
               "perception": dict, "perception.resolution": list, "perception.camera": dict}


def _read_info(http: Any) -> dict[str, Any]:
    info = _json(http.get("/v1/info"), "GET /v1/info")
    for path, kind in INFO_FIELDS.items():
        node: Any = info
        for part in path.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, kind) and not (kind is float and isinstance(node, int)):
            raise DualtwinError(f"GET /v1/info: {path} is missing or not a {kind.__name__} (not a dualtwin RobotServer?)")
    resolution = info["perception"]["resolution"]
    if len(resolution) != 2 or not all(isinstance(v, int) and 0 < v <= 4096 for v in resolution):
        raise DualtwinError(f"GET /v1/info: perception.resolution must be [width, height] in 1..4096, got {resolution}")
    if not all(isinstance(t, dict) and isinstance(t.get("name"), str) for t in info["policy"]["observation"]):
        raise DualtwinError("GET /v1/info: policy.observation must list terms with a name")
    return info


def deploy(server_url: str, env_id: str, episodes: int, *, seed: int = 0, api_key: str | None = None,
           policy_dir: Path | str | None = None, max_steps: int | None = None, frame_format: str = "png",
           compare: bool = True, timeout: float = 10.0, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Run ``episodes`` episodes through the server (see :func:`_deploy`); a server that cannot be reached or
    answers out of protocol is a :class:`DualtwinError` naming the URL.
    """
    import httpx

    try:
        return _deploy(server_url, env_id, episodes, seed=seed, api_key=api_key, policy_dir=policy_dir,
                       max_steps=max_steps, frame_format=frame_format, compare=compare, timeout=timeout,
                       progress=progress)
    except httpx.TimeoutException as exc:
        raise DualtwinError(f"--server {server_url}: no answer within {timeout:g} s ({type(exc).__name__})") from None
    except httpx.TransportError as exc:
        if is_reply_limit(exc):
            raise DualtwinError(f"--server {server_url}: {exc}") from None
        raise DualtwinError(f"--server {server_url}: cannot reach the RobotServer ({type(exc).__name__}: "
                            f"{str(exc) or 'connection failed'})") from None


def _deploy(server_url: str, env_id: str, episodes: int, *, seed: int = 0, api_key: str | None = None,
            policy_dir: Path | str | None = None, max_steps: int | None = None, frame_format: str = "png",
            compare: bool = True, timeout: float = 10.0, progress: ProgressCallback | None = None) -> dict[str, Any]:
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
        progress: Called after each episode, through the server (stage ``deploy``) and with the privileged
            policy (stage ``deploy: privileged baseline``).

    Returns:
        Rewards per episode for both, their means and ratio, the estimate's error on the privileged
        observations, and request latency percentiles.
    """
    from dualtwin.rl import make_env
    from dualtwin.twins.camera import CameraSpec
    from dualtwin.twins.render import TwinCamera

    if episodes < 1:
        raise DualtwinError("episodes must be >= 1")
    with _client(server_url, api_key, timeout) as http:
        info = _read_info(http)
        # The policy's env arguments (task options such as odometry velocity) define what it observes. They come
        # from the server: checked against the env's declared options before anything is built with them.
        served_kwargs = info["policy"].get("env_kwargs") or {}
        if isinstance(served_kwargs, dict):
            served_kwargs = {k: v for k, v in served_kwargs.items() if k != "max_episode_steps"}
        kwargs = check_env_kwargs(env_id, served_kwargs)
        policy = OnnxPolicy.load(policy_dir) if policy_dir is not None else _served_policy(http, info)
        terms = info["policy"]["observation"]
        onboard = [i for i, t in enumerate(terms) if t.get("source") == "onboard"]
        privileged = [i for i, t in enumerate(terms) if t.get("source") != "onboard"]
        width, height = info["perception"]["resolution"]
        camera = dict(info["perception"]["camera"] or {})
        name = str(camera.pop("name", "camera"))
        spec = CameraSpec.from_dict(name, camera).with_size(width, height)
        if max_steps:
            kwargs["max_episode_steps"] = max_steps
        env = make_env(env_id, **kwargs)
        cap = getattr(env.spec, "max_episode_steps", None)
        twin_env: Any = env.unwrapped  # a dualtwin TwinEnv
        try:
            env_terms = [(t.name, t.source) for t in twin_env.task.observation_terms]
            wanted = [(t["name"], t.get("source")) for t in terms]
            # The server may take more from the camera than the env has on board (camera-only serving estimates
            # the pole angle the env reads from its encoder), never ask for a sensor the env does not have.
            fits = [n for n, _ in env_terms] == [n for n, _ in wanted] and all(
                ws != "onboard" or es == "onboard" for (_, es), (_, ws) in zip(env_terms, wanted, strict=True))
            if not fits or not np.isclose(twin_env.control_period, info["policy"]["control_period_s"]):
                raise DualtwinError(f"{env_id} observes {env_terms} every {twin_env.control_period} s; the "
                                    f"served policy expects {wanted} every {info['policy']['control_period_s']} s")
            camera_renderer = TwinCamera(twin_env.twin, spec, width, height)
            discrete = info["policy"]["action"].get("type") == "discrete"
            served, errors, latencies = [], [], []
            served_progress = Progress(progress, "deploy", episodes)
            baseline_progress = Progress(progress, "deploy: privileged baseline", episodes)
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
                        reply = _json(http.post("/v1/act", json=request), "POST /v1/act")
                        latencies.append(time.perf_counter() - start)
                        try:
                            estimate = reply["observation"]
                            errors.append([abs(float(estimate[terms[i]["name"]]) - float(obs[i])) for i in privileged])
                            action = _env_action(reply["action"], discrete)
                        except (KeyError, TypeError, ValueError):
                            raise DualtwinError("POST /v1/act: the answer lacks a valid 'observation' or 'action'") from None
                        if not env.action_space.contains(action):
                            raise DualtwinError(f"POST /v1/act: action {reply['action']!r} is outside the env's action "
                                                f"space {env.action_space}")
                        obs, reward, terminated, truncated, _ = env.step(action)
                        total += float(reward)
                        step += 1
                        done = terminated or truncated
                    served.append(total)
                    served_progress.advance(message=f"reward {total:g}")
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
                    baseline_progress.advance(message=f"reward {total:g}")
        finally:
            env.close()
    lat = np.asarray(latencies) * 1000.0
    mean_served = float(np.mean(served))
    mean_base = float(np.mean(baseline)) if baseline else None
    return {
        "server": server_url, "env_id": env_id, "episodes": episodes, "seed": seed, "frame_format": frame_format,
        # What the served loop actually estimates: only the policy's privileged inputs come from the camera; the
        # rest are the robot's own sensors (for the CartPole PPO policy: the pole rate only, not camera-only).
        "loop": ("camera_only" if not onboard else
                 "camera_only_with_wheel_odometry" if info.get("observation_mode") == "camera_only" else
                 "perception_" + "+".join(str(terms[i]["name"]) for i in privileged) + "_only"),
        "observation_mode": info.get("observation_mode"),
        "inputs_from_perception": [terms[i]["name"] for i in privileged],
        "inputs_from_onboard_sensors": [terms[i]["name"] for i in onboard],
        "perception_rewards": served, "privileged_rewards": baseline,
        "mean_perception_reward": mean_served, "mean_privileged_reward": mean_base,
        "ratio": mean_served / mean_base if mean_base else None,
        # Success: the pole kept within the task's band for every step of a full-length episode (reward = cap).
        "episode_cap": cap,
        "perception_success": (sum(r >= cap for r in served) / len(served)) if cap else None,
        "privileged_success": (sum(r >= cap for r in baseline) / len(baseline)) if cap and baseline else None,
        "estimate_mae": {terms[i]["name"]: float(v) for i, v in
                         zip(privileged, np.mean(errors, axis=0) if errors else [], strict=False)},
        "latency_ms": {"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)),
                       "requests": int(len(lat))},
    }
