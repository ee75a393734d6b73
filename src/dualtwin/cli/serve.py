"""``dualtwin serve`` and ``dualtwin deploy``: the policy over HTTP (Pattern 3)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from dualtwin.cli.common import JsonOutput, app, console, report_progress
from dualtwin.errors import DualtwinError
from dualtwin.reporting import emit_json


@app.command("serve")
def serve(
    policy: Annotated[Path, typer.Option(help="exported policy folder (policy.onnx + policy_contract.json)")],
    perception: Annotated[Path, typer.Option(help="perception model folder")],
    host: Annotated[str, typer.Option(help="address to listen on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="port")] = 8000,
    api_key_env: Annotated[str | None, typer.Option(help="environment variable holding the API key")] = None,
    camera_only: Annotated[bool, typer.Option(
        help="camera-only: requests carry wheel odometry only; pole angle and rate come from the camera")] = False,
) -> None:
    """Serve the policy plus perception over HTTP (Pattern 3): POST /v1/act, GET /v1/info, GET /healthz."""
    import os

    from dualtwin.server.app import serve as run_serve

    api_key = None
    if api_key_env is not None:
        api_key = os.environ.get(api_key_env)
        if not api_key:
            raise DualtwinError(f"--api-key-env: environment variable {api_key_env} is not set")
    run_serve(policy, perception, host=host, port=port, api_key=api_key, camera_only=camera_only)


@app.command("deploy")
def deploy(
    server: Annotated[str, typer.Option(help="RobotServer URL, e.g. http://127.0.0.1:8000")],
    env: Annotated[str, typer.Option(help="registered env id to run closed-loop")],
    episodes: Annotated[int, typer.Option(help="episodes")] = 5,
    seed: Annotated[int, typer.Option(help="seed")] = 0,
    api_key_env: Annotated[str | None, typer.Option(help="environment variable holding the API key")] = None,
    json_out: JsonOutput = False,
) -> None:
    """Run a twin through the server with on-board sensors and camera only; compare with privileged state."""
    import os

    from dualtwin.server.client import deploy as run_deploy

    with report_progress() as progress:
        result = run_deploy(server, env, episodes, seed=seed,
                            api_key=os.environ.get(api_key_env) if api_key_env else None, progress=progress)
    if json_out:
        emit_json(result)
        return
    for line in deploy_summary(result):
        console.print(line, markup=False, highlight=False)


def deploy_summary(result: dict[str, Any]) -> list[str]:
    """The deploy result in a few lines (``--json`` prints all of it)."""
    def mean(value: Any) -> str:
        return "-" if value is None else f"{value:.1f}"

    def share(value: Any) -> str:
        return "-" if value is None else f"{100 * value:.0f} %"

    lines = [f"{result['env_id']} through {result['server']}: {result['episodes']} episode(s) from seed "
             f"{result['seed']}, loop {result['loop']}",
             f"  inputs from perception: {', '.join(result['inputs_from_perception']) or 'none'}; from on-board "
             f"sensors: {', '.join(result['inputs_from_onboard_sensors']) or 'none'}",
             f"  reward: served {mean(result['mean_perception_reward'])}, privileged "
             f"{mean(result['mean_privileged_reward'])}"
             + (f" (ratio {result['ratio']:.3f})" if result.get("ratio") is not None else ""),
             f"  full-length episodes (cap {result['episode_cap']}): served {share(result['perception_success'])}, "
             f"privileged {share(result['privileged_success'])}"]
    if result.get("estimate_mae"):
        lines.append("  estimate error (mean abs): " + ", ".join(f"{k} {v:.4g}" for k, v in
                                                                 result["estimate_mae"].items()))
    lat = result["latency_ms"]
    lines.append(f"  latency: p50 {lat['p50']:.1f} ms, p99 {lat['p99']:.1f} ms over {lat['requests']} requests")
    return lines
