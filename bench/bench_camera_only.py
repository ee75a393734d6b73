"""Camera-only Pattern 3 benchmark: perception trained in the Webots twin, a policy served with wheel odometry only.

Run: ``python bench/bench_camera_only.py``; ``MUJOCO_GL`` defaults to ``egl`` here. Goals (issue 17):

(a) Accuracy: a perception model trained on frames collected in the **Webots twin** (Pattern 2; scripted balancing
    with noise, 64x64, randomised) estimates the pole angle (<= 0.02 rad MAE) and the pole rate (Kalman filter on
    the newest-frame angle, <= 0.1 rad/s MAE) on held-out episodes: the split's held-out episodes (by episode
    identity), a second Webots collection with another seed, and a MuJoCo-twin collection (never seen).
(b) Closed loop: the policy exported camera-only (:func:`dualtwin.perception.camera_only.export_camera_only`:
    wheel odometry on board, pole angle and rate from the camera; no pole encoder) served by a RobotServer
    (uvicorn subprocess) runs 500-step episodes in both twins (``deploy``). Success = the pole within 0.3 rad for
    all 500 steps. Goal: >= 90 % in both twins. The privileged-state policy on the same seeds is the control.
(c) Latency: one robot at 50 Hz (requests on a fixed 20 ms schedule, each timed from its scheduled send, so waiting
    for a late answer counts) sending held-out Webots frames as PNG with its wheel odometry. Goal: p99 <= 20 ms.

Environment variables:

* ``DUALTWIN_POLICY_RUN``: the policy (a training run or an exported folder); default the reference linear policy
  with its camera gains (:data:`dualtwin.perception.reference_policy.CAMERA_GAINS`: odometry cart velocity, a
  stiffer position loop that keeps the cart near the image centre; needs no training).
* ``DUALTWIN_BENCH_PERCEPTION_MODEL``: a trained model folder instead of training here (still measured here).
* ``DUALTWIN_BENCH_EPISODES`` (30 Webots training episodes of at most 150 steps), ``DUALTWIN_BENCH_EPOCHS`` (8),
  then ``DUALTWIN_BENCH_FINETUNE_EPOCHS`` (6) more from those weights with a colour jitter of 0.4 (per-channel
  gain exp(U(-0.4, 0.4)); the data stay Webots-twin frames), ``DUALTWIN_BENCH_DEPLOY_EPISODES`` (10 per
  twin), ``DUALTWIN_BENCH_CAMERA_ONLY_OUT`` (keep everything there; default a temporary folder).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from _common import output_folder

os.environ.setdefault("MUJOCO_GL", "egl")  # a benchmark script, not library code

MUJOCO = "dualtwin/CartPole-MuJoCo-Continuous-v0"
WEBOTS = "dualtwin/CartPole-Webots-Continuous-v0"
GOAL_ANGLE, GOAL_RATE, GOAL_SUCCESS, GOAL_P99_MS = 0.02, 0.1, 0.9, 20.0
EPISODE_STEPS, RATE_HZ = 500, 50.0
COLOUR_JITTER = 0.4


def show(event: Any) -> None:
    print(f"  {event.line()}", flush=True)


def accuracy(root: Path, episodes: int, epochs: int) -> tuple[Path, dict[str, Any]]:
    from dualtwin.perception.dataset import collect
    from dualtwin.perception.model import evaluate_perception, train_perception

    start = time.perf_counter()
    sets = {
        "webots_split": collect(WEBOTS, episodes, root / "data-webots", seed=0, max_steps=150,
                                resume=(root / "data-webots").exists(), progress=show),
        "webots_seed1000": collect(WEBOTS, 8, root / "data-webots-1000", seed=1000, max_steps=150,
                                   resume=(root / "data-webots-1000").exists(), progress=show),
        "mujoco_seed2000": collect(MUJOCO, 8, root / "data-mujoco-2000", seed=2000, max_steps=150,
                                   resume=(root / "data-mujoco-2000").exists(), progress=show),
    }
    collect_s = time.perf_counter() - start
    given = os.environ.get("DUALTWIN_BENCH_PERCEPTION_MODEL")
    start = time.perf_counter()
    if given:
        model = Path(given)
        print(f"  using the trained model {given} (not trained here)")
    else:
        # Two stages: a one-cycle schedule of `epochs`, then `finetune` more epochs from those weights (same data,
        # seed and split) with a per-channel colour jitter. Measured: 8 epochs alone left the pole at 0.024 rad
        # (the segmentation had not yet found the ~1 px pole); a second cycle brought it to 0.005 rad on Webots
        # frames but 0.024 on MuJoCo-twin frames, whose pole is a brighter orange; the colour jitter closes that.
        finetune = int(os.environ.get("DUALTWIN_BENCH_FINETUNE_EPOCHS", "6"))
        model = train_perception(sets["webots_split"], root / "model-stage1", epochs=epochs, seed=0, threads=2,
                                 progress=show)
        if finetune > 0:
            model = train_perception(sets["webots_split"], root / "model", epochs=finetune, seed=0, threads=2,
                                     init_from=model, colour_jitter=COLOUR_JITTER, progress=show)
    train_s = time.perf_counter() - start
    trained_on = json.loads((model / "perception_contract.json").read_text())["trained_on"]
    result: dict[str, Any] = {"trained_on": trained_on, "collect_s": round(collect_s, 1),
                              "train_s": round(train_s, 1), "sets": {}}
    print(f"  model trained on {trained_on['frames']} frames of {trained_on['twin']} ({trained_on['env_id']}); "
          f"collect {collect_s:.0f} s, train {train_s:.0f} s")
    for label, data in sets.items():
        report = evaluate_perception(model, data, velocity="kalman")
        mae, const = report["mae"], report["mae_constant"]
        angle, rate = mae["pole_angle"], mae["pole_angular_velocity"]
        result["sets"][label] = {k: report[k] for k in ("frames", "heldout_episodes", "excluded_training_episodes",
                                                        "mae", "mae_constant", "mae_frame_stack")}
        met = angle <= GOAL_ANGLE and rate <= GOAL_RATE
        print(f"  {label}: {len(report['heldout_episodes'])} held-out episodes ({report['frames']} frames, "
              f"{report['excluded_training_episodes']} training episodes left out): pole angle "
              f"{angle:.4f} rad (constant {const['pole_angle']:.4f}), pole rate {rate:.3f} rad/s (constant "
              f"{const['pole_angular_velocity']:.3f}) -> {'met' if met else 'NOT met'} (goal <= {GOAL_ANGLE} rad, "
              f"<= {GOAL_RATE} rad/s)")
    return model, result


def policy_folder(root: Path) -> tuple[str, Path]:
    from dualtwin.perception.reference_policy import CAMERA_GAINS, export_reference_policy

    given = os.environ.get("DUALTWIN_POLICY_RUN")
    if not given:
        # The stiffer position loop: with the default gains (x 0.5) the cart drifted to where the fixed camera's
        # pole estimate is biased, and 0 of 10 MuJoCo and 1 of 10 Webots episodes lasted 500 steps.
        export_reference_policy(root / "policy", MUJOCO, gains=CAMERA_GAINS)
        return f"reference linear policy, gains (x, x', θ, θ') = {CAMERA_GAINS}", root / "policy"
    path = Path(given)
    if (path / "policy.onnx").is_file():
        return f"given ({path})", path
    from dualtwin.rl.export import export_policy
    from dualtwin.rl.runfiles import trusting_pickles

    with trusting_pickles(True):  # the user's own training run, named on the command line
        export_policy(path, root / "policy", which="best" if (path / "best_model.zip").is_file() else "final")
    return f"trained run ({path})", root / "policy"


class Server:
    """``serve`` in a subprocess on a free loopback port."""

    def __init__(self, policy: Path, model: Path) -> None:
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            self.port = int(sock.getsockname()[1])
        code = ("from dualtwin.server.app import serve; "
                f"serve({str(policy)!r}, {str(model)!r}, host='127.0.0.1', port={self.port}, log_level='warning')")
        self.url = f"http://127.0.0.1:{self.port}"
        self.process = subprocess.Popen([sys.executable, "-c", code])

    def __enter__(self) -> Server:
        import httpx

        deadline = time.monotonic() + 120
        while True:
            try:
                if httpx.get(f"{self.url}/healthz", timeout=1).status_code == 200:
                    return self
            except httpx.HTTPError:
                if time.monotonic() > deadline or self.process.poll() is not None:
                    raise RuntimeError("the server did not start") from None
                time.sleep(0.2)

    def __exit__(self, *exc: object) -> None:
        self.process.terminate()
        self.process.wait(timeout=10)


def closed_loop(url: str, deploy_episodes: int) -> dict[str, Any]:
    from dualtwin.server.client import deploy

    rows: dict[str, Any] = {}
    for env_id in (MUJOCO, WEBOTS):
        start = time.perf_counter()
        report = deploy(url, env_id, deploy_episodes, seed=100, max_steps=EPISODE_STEPS)
        report["seconds"] = round(time.perf_counter() - start, 1)
        rows[env_id] = report
        success, base = report["perception_success"], report["privileged_success"]
        print(f"  {env_id.split('/')[-1]}: loop {report['loop']} (on board: "
              f"{', '.join(report['inputs_from_onboard_sensors'])}; camera: "
              f"{', '.join(report['inputs_from_perception'])})")
        print(f"    success {100 * success:.0f} % ({deploy_episodes} episodes of {EPISODE_STEPS} steps; rewards "
              f"{[round(r) for r in report['perception_rewards']]}) vs privileged {100 * base:.0f} % -> "
              f"{'met' if success >= GOAL_SUCCESS else 'NOT met'} (goal >= {100 * GOAL_SUCCESS:.0f} %); closed-loop "
              f"estimate MAE {json.dumps({k: round(v, 4) for k, v in report['estimate_mae'].items()})}; "
              f"request p50 {report['latency_ms']['p50']:.1f} ms, p99 {report['latency_ms']['p99']:.1f} ms")
    return rows


def latency_at_50hz(url: str, data_dir: Path, model: Path, seconds: float = 10.0) -> dict[str, Any]:
    """One robot at 50 Hz: held-out Webots frames (PNG) + wheel odometry, on a fixed schedule."""
    import httpx
    import numpy as np

    from dualtwin.perception.dataset import episode_identities, load_dataset
    from dualtwin.perception.model import trained_episode_ids
    from dualtwin.server.client import frame_payload

    data = load_dataset(data_dir)
    contract = json.loads((model / "perception_contract.json").read_text())
    trained = trained_episode_ids(model, contract)
    ids = episode_identities(data.manifest)
    rows = np.flatnonzero([ids[int(e)] not in trained for e in data.episode])
    n = int(seconds * RATE_HZ)
    payloads = [frame_payload(data.frames[rows[i % len(rows)]]) for i in range(n)]
    latencies, late = [], 0
    with httpx.Client(base_url=url, timeout=5.0) as http:
        refused = http.post("/v1/act", json={"session": "probe", "frame": payloads[0], "sensors": {
            "cart_position": 0.0, "cart_velocity": 0.0, "pole_angle": 0.0}}).status_code
        begin = time.perf_counter() + 0.1
        for i in range(n):
            row = rows[i % len(rows)]
            scheduled = begin + i / RATE_HZ
            now = time.perf_counter()
            if now < scheduled:
                time.sleep(scheduled - now)
            elif now - scheduled > 1e-3:
                late += 1
            reply = http.post("/v1/act", json={
                "session": "robot-50hz", "reset": i == 0, "frame": payloads[i],
                "sensors": {"cart_position": float(data.observation[row, 0]),
                            "cart_velocity": float(data.observation[row, 1])}})
            if reply.status_code != 200:
                raise RuntimeError(f"POST /v1/act answered {reply.status_code}: {reply.text[:200]}")
            latencies.append(time.perf_counter() - scheduled)
    ms = np.asarray(latencies) * 1000.0
    out = {"requests": n, "rate_hz": RATE_HZ, "p50_ms": float(np.percentile(ms, 50)),
           "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max()), "sent_late": late,
           "pole_angle_sensor_refused_with": refused}
    print(f"  {n} requests at {RATE_HZ:g} Hz, PNG {data.frames.shape[2]}x{data.frames.shape[1]}: p50 "
          f"{out['p50_ms']:.1f} ms, p99 {out['p99_ms']:.1f} ms (goal <= {GOAL_P99_MS:g}: "
          f"{'met' if out['p99_ms'] <= GOAL_P99_MS else 'NOT met'}), max {out['max_ms']:.1f} ms; {late} sent > 1 ms "
          f"late; a request with a pole_angle sensor got {refused}")
    return out


def main() -> dict[str, Any]:
    import torch

    from dualtwin.perception.camera_only import export_camera_only

    torch.set_num_threads(2)
    episodes = int(os.environ.get("DUALTWIN_BENCH_EPISODES", "30"))
    epochs = int(os.environ.get("DUALTWIN_BENCH_EPOCHS", "8"))
    deploy_episodes = int(os.environ.get("DUALTWIN_BENCH_DEPLOY_EPISODES", "10"))
    print(f"Camera-only Pattern 3 benchmark (MUJOCO_GL={os.environ.get('MUJOCO_GL')}; shared machine, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)")
    results: dict[str, Any] = {}
    with output_folder("DUALTWIN_BENCH_CAMERA_ONLY_OUT", "camera-only") as (root, _):
        print(f"(a) accuracy: perception trained on {episodes} Webots-twin episodes, {epochs} epochs")
        model, results["accuracy"] = accuracy(root, episodes, epochs)
        label, policy = policy_folder(root)
        served = export_camera_only(policy, model, root / "policy-camera-only")
        contract = json.loads((served / "policy_contract.json").read_text())
        print(f"(b) closed loop, {label} served camera-only: on board {contract['camera_only']['onboard']}, "
              f"camera {contract['camera_only']['camera']}")
        with Server(served, model) as server:
            results["closed_loop"] = closed_loop(server.url, deploy_episodes)
            print("(c) RobotServer latency, one robot at 50 Hz")
            results["latency"] = latency_at_50hz(server.url, root / "data-webots", model)
        results["policy"] = label
        (root / "results.json").write_text(json.dumps(results, indent=1, default=str))
    return results


if __name__ == "__main__":
    main()
