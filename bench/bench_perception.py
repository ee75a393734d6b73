"""Perception benchmark: rendering speed, perception accuracy, and closed-loop control with perception in the loop.

Run: ``python bench/bench_perception.py`` (or ``make bench``); ``MUJOCO_GL`` defaults to ``egl`` here.

(a) Rendering: frames/s of the perception camera at 128x96 and 64x64 on both twins (goal >= 30 at 128x96).
(b) Accuracy: collect a randomised dataset in the MuJoCo twin (scripted balancing with noise), train the
    perception CNN, report MAE per quantity on held-out episodes, against a constant predictor; and on a
    dataset from the Webots twin (never seen in training). Goal: pole-angle MAE <= 0.02 rad.
(c) Closed loop: serve a policy + the perception model (uvicorn subprocess) and run episodes with on-board
    sensors and camera only (``deploy``) in both twins, against the privileged-state policy on the same reset
    seeds. Goal: >= 90 % of the privileged reward in both twins. This is *not* camera-only control: the
    CartPole policy reads cart position, cart velocity and pole angle from on-board sensors (wheel encoders,
    odometry, pole hinge encoder); perception supplies only the pole rate. The output names the loop
    (``perception_pole_angular_velocity_only``) and which inputs came from where. Camera-only control (wheel
    odometry on board, pole angle and rate from the camera, perception trained in the Webots twin) is measured by
    ``bench/bench_camera_only.py``.

Environment variables:

* ``DUALTWIN_POLICY_RUN``: policy for (c): a training run or an exported folder. Without it, PPO is trained on
  ``CartPole-MuJoCo-Continuous-v0`` for ``DUALTWIN_BENCH_PPO_SECONDS`` (default 900; 0 skips training); if that
  policy does not reach half the episode cap, the reference linear policy
  (:mod:`dualtwin.perception.reference_policy`) is used as well, and the output says so.
* ``DUALTWIN_BENCH_PERCEPTION_MODEL``: a trained perception model folder to use instead of training one here
  (its accuracy is still measured on the benchmark's datasets; e.g. the ``model`` folder of an earlier run).
* ``DUALTWIN_BENCH_EPISODES`` (default 60), ``DUALTWIN_BENCH_EPOCHS`` (default 12), ``DUALTWIN_BENCH_DEPLOY_EPISODES``
  (default 5), ``DUALTWIN_BENCH_PERCEPTION_OUT`` (keep the datasets and models there; default a temporary folder).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from _common import output_folder

os.environ.setdefault("MUJOCO_GL", "egl")  # a benchmark script, not library code

MUJOCO = "dualtwin/CartPole-MuJoCo-Continuous-v0"
WEBOTS = "dualtwin/CartPole-Webots-Continuous-v0"
GOAL_FPS, GOAL_POLE_MAE, GOAL_RATIO = 30.0, 0.02, 0.9


def rendering_speed() -> dict[str, Any]:
    from dualtwin.robots.binding import resolve_robot
    from dualtwin.twins import make_twin
    from dualtwin.twins.camera import camera_for
    from dualtwin.twins.render import TwinCamera

    robot = resolve_robot("cartpole")
    spec = camera_for(robot)
    out: dict[str, Any] = {}
    for twin_name in ("mujoco", "webots"):
        twin = make_twin(twin_name, robot)
        twin.reset(seed=0)
        for width, height in ((128, 96), (64, 64)):
            camera = TwinCamera(twin, spec, width, height)
            camera.render()
            best = 0.0
            for _ in range(3):  # best of three: other jobs share the machine
                start = time.perf_counter()
                for _ in range(100):
                    camera.render()
                best = max(best, 100 / (time.perf_counter() - start))
            camera.close()
            out[f"{twin_name}_{width}x{height}_fps"] = round(best, 1)
        twin.close()
    for key, value in out.items():
        print(f"  {key}: {value:.0f} frames/s" + (f" (goal >= {GOAL_FPS:.0f})" if "128x96" in key else ""))
    return out


def accuracy(root: Path, episodes: int, epochs: int) -> tuple[Path, dict[str, Any]]:
    from dualtwin.perception.dataset import collect
    from dualtwin.perception.model import evaluate_perception, train_perception

    start = time.perf_counter()
    data = collect(MUJOCO, episodes, root / "data-mujoco", seed=0, resume=(root / "data-mujoco").exists())
    collect_s = time.perf_counter() - start
    start = time.perf_counter()
    given = os.environ.get("DUALTWIN_BENCH_PERCEPTION_MODEL")
    model = Path(given) if given else train_perception(data, root / "model", epochs=epochs, seed=0, threads=2,
                                                       progress=lambda event: print(f"  {event.line()}", flush=True))
    train_s = time.perf_counter() - start
    if given:
        print(f"  using the trained model {given} (not trained here)")
    webots = collect(WEBOTS, max(4, episodes // 10), root / "data-webots", seed=1000,
                     resume=(root / "data-webots").exists())
    result: dict[str, Any] = {"episodes": episodes, "epochs": epochs, "collect_s": round(collect_s, 1),
                              "train_s": round(train_s, 1)}
    for label, dataset in (("mujoco_heldout", data), ("webots", webots)):
        for velocity in ("frame-stack", "kalman"):
            report = evaluate_perception(model, dataset, velocity=velocity)
            result[f"{label}_{velocity}"] = {k: report[k] for k in ("frames", "mae", "mae_constant")}
        report = result[f"{label}_frame-stack"]
        mae, const = report["mae"], report["mae_constant"]
        print(f"  {label} ({report['frames']} frames): MAE pole {mae['pole_angle']:.4f} rad (constant "
              f"{const['pole_angle']:.4f}), pole rate {mae['pole_angular_velocity']:.3f} rad/s "
              f"({const['pole_angular_velocity']:.3f}), cart {mae['cart_position']:.4f} m "
              f"({const['cart_position']:.4f}), cart velocity {mae['cart_velocity']:.3f} m/s "
              f"({const['cart_velocity']:.3f}); Kalman pole rate "
              f"{result[f'{label}_kalman']['mae']['pole_angular_velocity']:.3f} rad/s")
    print(f"  collect {collect_s:.0f} s, train {train_s:.0f} s; goal pole-angle MAE <= {GOAL_POLE_MAE} rad on "
          f"held-out MuJoCo frames: {'met' if result['mujoco_heldout_frame-stack']['mae']['pole_angle'] <= GOAL_POLE_MAE else 'NOT met'}")
    return model, result


def policies(root: Path) -> list[tuple[str, Path]]:
    """(label, exported policy folder) to run the closed loop with."""
    from dualtwin.perception.reference_policy import export_reference_policy
    from dualtwin.rl.export import export_policy

    given = os.environ.get("DUALTWIN_POLICY_RUN")
    out: list[tuple[str, Path]] = []
    if given:
        path = Path(given)
        if (path / "policy.onnx").is_file():
            out.append((f"given ({path})", path))
        else:
            export_policy(path, root / "policy-given", which="best" if (path / "best_model.zip").is_file() else "final")
            out.append((f"given run ({path})", root / "policy-given"))
        return out
    budget = float(os.environ.get("DUALTWIN_BENCH_PPO_SECONDS", "900"))
    if budget > 0:
        from dualtwin.rl.ppo_config import load_config
        from dualtwin.rl.train import train

        config = load_config(None).model_copy(update={"stop_reward": 950.0, "n_timesteps": 5_000_000,
                                                      "max_wall_seconds": budget})
        run = root / "ppo"
        train(MUJOCO, config, run, seed=0, progress_bar=False)
        record = json.loads((run / "run.json").read_text())
        best = max((e["mean_reward"] for e in record.get("evaluations", [])), default=0.0)
        which = "best" if (run / "best_model.zip").is_file() else "final"
        export_policy(run, root / "policy-ppo", which=which)
        print(f"  PPO ({budget:.0f} s budget, {record['num_timesteps']:,} steps): best mean eval reward {best:.1f}")
        out.append((f"PPO ({which})", root / "policy-ppo"))
        if best >= 500.0:
            return out
        print("  the PPO policy does not balance reliably: the reference linear policy is run as well")
    export_reference_policy(root / "policy-reference", MUJOCO)
    out.append(("reference linear policy", root / "policy-reference"))
    return out


def closed_loop(root: Path, model: Path, deploy_episodes: int) -> dict[str, Any]:
    import httpx

    from dualtwin.server.client import deploy

    results: dict[str, Any] = {}
    for label, policy in policies(root):
        import socket

        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = int(sock.getsockname()[1])
        code = ("from dualtwin.server.app import serve; "
                f"serve({str(policy)!r}, {str(model)!r}, host='127.0.0.1', port={port}, log_level='warning')")
        server = subprocess.Popen([sys.executable, "-c", code])
        url = f"http://127.0.0.1:{port}"
        try:
            deadline = time.monotonic() + 60
            while True:
                try:
                    if httpx.get(f"{url}/healthz", timeout=1).status_code == 200:
                        break
                except httpx.HTTPError:
                    if time.monotonic() > deadline or server.poll() is not None:
                        raise RuntimeError("the server did not start") from None
                    time.sleep(0.2)
            rows = {}
            for env_id in (MUJOCO, WEBOTS):
                report = deploy(url, env_id, deploy_episodes, seed=100)
                rows[env_id] = report
                ratio = report["ratio"]
                print(f"  {label} on {env_id.split('/')[-1]}, {report['loop']} (perception: "
                      f"{', '.join(report['inputs_from_perception'])}; on-board sensors: "
                      f"{', '.join(report['inputs_from_onboard_sensors'])})")
                print(f"    perception in the loop {report['mean_perception_reward']:.1f} vs "
                      f"privileged {report['mean_privileged_reward']:.1f} -> "
                      f"{'n/a' if ratio is None else f'{100 * ratio:.0f} %'} (goal >= {100 * GOAL_RATIO:.0f} %); "
                      f"estimate MAE {json.dumps({k: round(v, 3) for k, v in report['estimate_mae'].items()})}; "
                      f"request p50 {report['latency_ms']['p50']:.1f} ms")
            results[label] = rows
        finally:
            server.terminate()
            server.wait(timeout=10)
    return results


def main() -> dict[str, Any]:
    import torch

    torch.set_num_threads(2)
    episodes = int(os.environ.get("DUALTWIN_BENCH_EPISODES", "60"))
    epochs = int(os.environ.get("DUALTWIN_BENCH_EPOCHS", "12"))
    deploy_episodes = int(os.environ.get("DUALTWIN_BENCH_DEPLOY_EPISODES", "5"))
    print(f"Perception benchmark (MUJOCO_GL={os.environ.get('MUJOCO_GL')}; shared machine, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)")
    results: dict[str, Any] = {}
    with output_folder("DUALTWIN_BENCH_PERCEPTION_OUT", "perception") as (root, _):
        print("(a) rendering speed, perception camera")
        results["rendering"] = rendering_speed()
        print(f"(b) accuracy: {episodes} MuJoCo episodes (64x64, randomised), {epochs} epochs")
        model, results["accuracy"] = accuracy(root, episodes, epochs)
        print(f"(c) closed loop through the RobotServer, {deploy_episodes} episodes per twin")
        results["closed_loop"] = closed_loop(root, model, deploy_episodes)
    return results


if __name__ == "__main__":
    main()
