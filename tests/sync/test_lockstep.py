"""Lockstep runs: re-sync policies, outputs, equivalence with separate suite runs, skipped episodes, policies."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualtwin.divergence.comparison import compare_runs
from dualtwin.divergence.runs import load_run, load_tsv
from dualtwin.divergence.trajectories import load_trajectories
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.suite.runner import SuiteRun
from dualtwin.sync import ResyncPolicy, run_lockstep
from dualtwin.twins import make_twin
from tests.support.sync_helpers import sign_policy

DAMPING = "joint.pole_hinge.damping"


def test_resync_policy_parsing() -> None:
    assert ResyncPolicy.parse("never") == ResyncPolicy()
    assert ResyncPolicy.parse("every:5").due(10, 0.0) and not ResyncPolicy.parse("every:5").due(7, 9.0)
    assert ResyncPolicy.parse("threshold:0.2").due(1, 0.3) and str(ResyncPolicy.parse("threshold:0.2")) == "threshold:0.2"
    for bad in ("always", "every:0", "every:x", "threshold:-1", "never:3"):
        with pytest.raises(DualtwinError, match="resync"):
            ResyncPolicy.parse(bad)


def test_never_is_the_open_loop_suite_run(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    """Without re-syncs, lockstep logs exactly what two separate suite runs log."""
    result = run_lockstep("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "ls",
                          secondary_knobs={DAMPING: 0.05})
    twin = make_twin("mujoco", cartpole)
    twin.set_knobs({DAMPING: 0.05})
    SuiteRun(suite, "mujoco", cartpole, tmp_path / "separate", twin=twin).run()
    for sid in ("00_fall", "01_sine", "02_drive"):
        lock = (tmp_path / "ls" / "secondary" / "scenarios" / sid / "ground_truth.tsv").read_text()
        alone = (tmp_path / "separate" / "scenarios" / sid / "ground_truth.tsv").read_text()
        assert lock == alone
    # The error grows with the horizon (here: the time since the episode start).
    by_h = result.error_by_horizon()
    assert by_h[1] < 1e-3 < by_h[25]
    assert all(e.resyncs == 0 and e.status == "completed" for e in result.episodes)
    # The twins' folders are ordinary suite runs.
    comparison = compare_runs(tmp_path / "ls" / "primary", tmp_path / "ls" / "secondary")
    assert comparison.summary_score > 0
    assert load_run(tmp_path / "ls" / "secondary").twin == "mujoco"


def test_every_1_between_identical_models_has_no_error(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    result = run_lockstep("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "ls", resync="every:1",
                          primary_knobs={DAMPING: 0.05}, secondary_knobs={DAMPING: 0.05})
    assert all(e.max_error < 1e-12 for e in result.episodes)
    assert [e.resyncs for e in result.episodes] == [e.steps for e in result.episodes]
    header, data = load_tsv(tmp_path / "ls" / "episodes" / "01_sine" / "state_diff.tsv")
    assert header[:5] == ["time_s", "error", "resynced", "horizon", "body/cart/x"]
    assert set(data[:, 3]) == {1.0} and np.max(np.abs(data[:, 4:])) < 1e-12


def test_resync_bounds_the_error_of_a_mismatched_model(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    kwargs = {"suite": suite, "primary_knobs": {DAMPING: 0.2}}
    never = run_lockstep("mujoco", "mujoco", cartpole, out_dir=tmp_path / "never", **kwargs)
    every = run_lockstep("mujoco", "mujoco", cartpole, out_dir=tmp_path / "every", resync="every:5", **kwargs)
    threshold = run_lockstep("mujoco", "mujoco", cartpole, out_dir=tmp_path / "thr", resync="threshold:0.05", **kwargs)
    worst = {name: max(e.max_error for e in r.episodes) for name, r in
             (("never", never), ("every", every), ("threshold", threshold))}
    assert worst["every"] < worst["never"] and worst["threshold"] < worst["never"]
    assert set(every.error_by_horizon()) == {1, 2, 3, 4, 5}
    assert 0 < sum(e.resyncs for e in threshold.episodes) < sum(e.steps for e in threshold.episodes)
    h = every.error_by_horizon()
    assert h[1] < h[5]  # within a re-sync interval the error grows


def test_webots_primary_outputs(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    result = run_lockstep("webots", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "ls", resync="every:5")
    manifest = json.loads((tmp_path / "ls" / "manifest.json").read_text())
    assert manifest["primary"] == "webots" and manifest["resync"] == "every:5" and manifest["seed"] == 0
    assert len(manifest["inputs"]["suite"]["sha256"]) == 64 and manifest["versions"]["mujoco"]
    assert [e["status"] for e in manifest["episodes"]] == ["completed"] * 3
    assert manifest["channels"]["body/cart/x"]["scale"] == 0.1
    trajectories, meta = load_trajectories(tmp_path / "ls" / "trajectories.npz")
    assert meta["twin"] == "webots" and [t.id for t in trajectories] == ["00_fall", "01_sine", "02_drive"]
    assert len(trajectories[1]) == result.episodes[1].steps and "wheel1" in trajectories[1].actuators
    # One-period errors after a re-sync are small next to the open-loop drift between the simulators.
    assert result.error_by_horizon()[1] < 0.2


def test_a_refused_resync_skips_the_episode(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    secondary = make_twin("mujoco", cartpole)
    secondary.max_penetration = -1.0  # type: ignore[attr-defined]  # every resting contact now counts as too deep
    result = run_lockstep("mujoco", secondary, cartpole, suite=suite, out_dir=tmp_path / "ls", resync="every:3")
    assert [e.status for e in result.episodes] == ["skipped"] * 3
    assert all(e.steps == 3 and e.failure and e.failure["reason"] == "penetration" for e in result.episodes)
    assert load_run(tmp_path / "ls" / "primary").scenarios == ()  # skipped episodes leave the twins' runs


def test_policy_episodes_act_on_the_primary(tmp_path: Path, cartpole: RobotBinding) -> None:
    policy = sign_policy(tmp_path / "policy")
    result = run_lockstep("webots", "mujoco", cartpole, policy=policy, out_dir=tmp_path / "ls", resync="every:10",
                          episodes=2, episode_steps=40)
    assert [e.id for e in result.episodes] == ["00_episode", "01_episode"]
    assert all(e.steps == 40 and e.rewards and set(e.rewards) == {"primary", "secondary"} for e in result.episodes)
    # The policy keeps the pole up on the primary, and the same actions do so on the secondary.
    assert all(e.rewards is not None and e.rewards["primary"] > 30 for e in result.episodes)
    manifest = json.loads((tmp_path / "ls" / "manifest.json").read_text())
    assert manifest["mode"] == "policy" and manifest["inputs"]["policy"]["kind"] == "onnx"


def test_bad_input(tmp_path: Path, cartpole: RobotBinding, suite: Path) -> None:
    with pytest.raises(DualtwinError, match="exactly one"):
        run_lockstep("mujoco", "mujoco", cartpole, out_dir=tmp_path / "a")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    with pytest.raises(DualtwinError, match="not empty"):
        run_lockstep("mujoco", "mujoco", cartpole, suite=suite, out_dir=tmp_path / "full")


@pytest.mark.parametrize(("damped", "resync", "failed_first"),
                         [("primary", "never", "secondary"), ("secondary", "threshold:0.02", "primary")])
def test_one_twin_at_a_time_gives_the_interleaved_results(tmp_path: Path, cartpole: RobotBinding, suite: Path,
                                                          damped: str, resync: str, failed_first: str) -> None:
    """Suite episodes run the primary first, then the secondary against it; the outputs are those of stepping
    both period by period, also when one twin hits a failure threshold first (the other's logs are cut)."""
    spec = json.loads(suite.read_text())
    spec["global_settings"]["failure_pole_angle_rad"] = 0.6
    tight = tmp_path / "suite.json"
    tight.write_text(json.dumps(spec))
    knobs = {f"{damped}_knobs": {DAMPING: 0.3}}
    runs = {mode: run_lockstep("mujoco", "mujoco", cartpole, suite=tight, out_dir=tmp_path / mode,
                               resync=resync, interleave=mode == "interleaved", **knobs)
            for mode in ("blocked", "interleaved")}
    statuses = [e.statuses for e in runs["blocked"].episodes]
    assert {"primary": "completed", "secondary": "completed", failed_first: "failed"} in statuses
    assert [e.to_dict() for e in runs["blocked"].episodes] == [e.to_dict() for e in runs["interleaved"].episodes]
    for name in ("00_fall", "01_sine", "02_drive"):
        files = [f"episodes/{name}/state_diff.tsv", f"primary/scenarios/{name}/ground_truth.tsv",
                 f"secondary/scenarios/{name}/onboard.tsv"]
        for file in files:
            assert (tmp_path / "blocked" / file).read_bytes() == (tmp_path / "interleaved" / file).read_bytes()
    blocked, _ = load_trajectories(tmp_path / "blocked" / "trajectories.npz")
    interleaved, _ = load_trajectories(tmp_path / "interleaved" / "trajectories.npz")
    assert all(np.array_equal(x.states, y.states) and np.array_equal(x.commands, y.commands, equal_nan=True)
               for x, y in zip(blocked, interleaved, strict=True))


@pytest.mark.parametrize(("field", "value", "message"), [
    ("env_kwargs", "abc", r"\$\.env_kwargs must be a JSON object"),
    ("env_kwargs", {"control_period": "x"}, r"\$\.env_kwargs\.control_period: Input should be a valid number"),
    ("env_kwargs", {"task": []}, r"\$\.env_kwargs\.task: Input should be a valid string"),
    ("action", 5, r"\$\.action must be an object"),
    ("env_id", 7, r"\$\.env_id must be a string"),
])
def test_a_hostile_policy_contract_is_named_before_the_twins_run(tmp_path: Path, cartpole: RobotBinding, field: str,
                                                                  value: object, message: str) -> None:
    """The contract is untrusted: each of these was a TypeError/ValueError/AttributeError traceback (fuzzing)."""
    policy = sign_policy(tmp_path / "policy")
    contract = json.loads((policy / "policy_contract.json").read_text())
    (policy / "policy_contract.json").write_text(json.dumps({**contract, field: value}))
    with pytest.raises(DualtwinError, match=f"policy_contract.json: {message}"):
        run_lockstep("mujoco", "mujoco", cartpole, policy=policy, out_dir=tmp_path / "ls", episodes=1,
                     episode_steps=5)
    assert not (tmp_path / "ls").exists()
