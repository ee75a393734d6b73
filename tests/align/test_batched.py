"""Align's candidates on a MuJoCo target as mujoco.batch calls: bit-identical to one job at a time, as one batch on
1 and 2 threads and as one single-thread batch per worker of a pool of 2.

The populations mix knobs that change what a batch must handle per simulation: masses (set_const per model),
damping and gains (plugin parameters), physics sub-steps (another step, so another group of the batch call),
control delays and sensor delays and noise (Python state of the twin between periods), and a candidate that
hits a failure threshold and leaves the batch early.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from dualtwin.align.config import AlignConfig
from dualtwin.align.core import fd_jacobian
from dualtwin.align.knobs import select_knobs, unit_from_values
from dualtwin.align.objective import build_spec
from dualtwin.align.simulate import BatchedSimulator, Evaluator, SimJob, Traces
from dualtwin.align.trajectory import TrajectoryProblem
from dualtwin.errors import SimulationUnstable
from dualtwin.robots.binding import resolve_robot
from dualtwin.suite.loader import load_suite
from dualtwin.twins import make_twin
from dualtwin.twins.mujoco_batch import TwinBatch, batch_reason

ARM_SCENARIOS = ("02_step_elbow", "11_sine_wrist_1_3hz", "18_fast_wrist")
# The last one continues from the one before it (reset "continue"), which is simulated too.
CARTPOLE_SCENARIOS = ("04_Impulse", "03_Step_Response_3")

POPULATIONS: dict[str, list[dict[str, float]]] = {
    "cartpole": [
        {},
        {"joint.pole_hinge.damping": 0.3, "body.pole.mass": 0.15},
        {"physics.substeps": 8.0, "motor.wheel1.kp": 30.0},
        {"control.delay_periods": 2.0, "sensor.pole sensor.delay": 3.0, "sensor.pole sensor.noise": 0.01},
        {"motor.wheel1.max_torque": 0.2, "motor.wheel2.max_torque": 0.2, "joint.pole_hinge.friction": 0.2},
        {"physics.substeps": 8.0, "joint.wheel1_hinge.armature": 0.1, "option.impratio": 10.0},
    ],
    "arm": [
        {},
        {"joint.elbow.damping": 0.5, "body.wrist_3_link.mass": 3.0},
        {"physics.substeps": 4.0, "motor.elbow.kp": 30.0},
        {"control.delay_periods": 1.0, "sensor.elbow sensor.delay": 2.0, "sensor.wrist_1 sensor.noise": 0.01},
        {"motor.wrist_1.max_torque": 2.0, "joint.wrist_1.friction": 0.3, "joint.wrist_1.armature": 0.1},
    ],
}


def _job(name: str) -> SimJob:
    robot = resolve_robot(name)
    suite = robot.root / "suite.json"
    return SimJob(str(robot.path), "mujoco", str(suite), ARM_SCENARIOS if name == "arm" else CARTPOLE_SCENARIOS,
                  (), 0)


def _flat(traces: Traces) -> list[tuple[str, str, str, np.ndarray, np.ndarray]]:
    return [(sid, name, traces[sid].status, traces[sid].series[name].t, traces[sid].series[name].y)
            for sid in sorted(traces) for name in sorted(traces[sid].series)]


def _same(a: list[Traces], b: list[Traces]) -> bool:
    if len(a) != len(b):
        return False
    for ta, tb in zip(a, b, strict=True):
        fa, fb = _flat(ta), _flat(tb)
        if [x[:3] for x in fa] != [x[:3] for x in fb]:
            return False
        if not all(np.array_equal(x[3], y[3]) and np.array_equal(x[4], y[4], equal_nan=True)
                   for x, y in zip(fa, fb, strict=True)):
            return False
    return True


def _map(jobs: list[SimJob], chunks: bool = False, **kwargs: Any) -> tuple[list[Traces], Any]:
    """The traces, and whether they ran as a batch (with ``chunks``: in how many pieces)."""
    with Evaluator(**kwargs) as evaluator:
        out = evaluator.map(jobs)
        return out, evaluator.batch_chunks if chunks else evaluator.batched


@pytest.mark.parametrize("robot_name", ["cartpole", "arm"])
def test_population_batched_is_bit_identical(robot_name: str) -> None:
    job = _job(robot_name)
    jobs = [job.with_knobs(values) for values in POPULATIONS[robot_name]]
    alone, batched = _map(jobs, kind="serial", batch="off")
    assert not batched
    # The population is not trivial: candidates differ, and on the CartPole one stops at a failure threshold.
    assert not _same(alone[:1], alone[1:2])
    one, batched_one = _map(jobs, kind="serial")  # the batch on one thread
    two, batched_two = _map(jobs, kind="process", workers=2, batch="threads")  # on two threads
    pooled, chunks = _map(jobs, kind="process", workers=2, pool_start=2, chunks=True)  # a batch per pool worker
    assert batched_one and batched_two and chunks == 2
    assert _same(one, alone)
    assert _same(two, alone)
    assert _same(pooled, alone)


def test_plain_twins_are_sampled_together_and_noisy_ones_alone() -> None:
    """The batched path reads the channels of every twin without sensor models from the batch's arrays at once
    (bit-identical, above); the candidate with sensor delay and noise reads its own through its twin."""
    job = _job("arm")
    jobs = [job.with_knobs(values) for values in POPULATIONS["arm"]]
    alone, _ = _map(jobs, kind="serial", batch="off")
    simulator = BatchedSimulator(job.robot, job.twin, job.suite, nthread=2)
    try:
        assert _same(simulator.map(jobs), alone)
        periods = sum(len(t.series["q1_rad"].t) for traces in alone for t in traces.values())
        noisy = sum(len(t.series["q1_rad"].t) for t in alone[3].values())
        # Every period of the plain candidates together, every period of the noisy one alone (scenarios that
        # continue from an unlisted one run it too, unlogged: hence at least).
        assert simulator.read_together >= periods - noisy > 0
        assert simulator.read_alone >= noisy > 0
        assert simulator.read_alone < simulator.read_together / 2
    finally:
        simulator.close()


def test_population_with_failure_leaves_batch_early(tmp_path: Path) -> None:
    """Candidates whose pole passes a (low) failure threshold at different times end their scenarios while the
    others go on."""
    robot = resolve_robot("cartpole")
    document = json.loads((robot.root / "suite.json").read_text())
    document["global_settings"]["failure_pole_angle_rad"] = 0.9
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps(document))
    job = SimJob(str(robot.path), "mujoco", str(suite), ("00_Step_Response", "04_Impulse"), (), 0)
    jobs = [job.with_knobs({"joint.pole_hinge.damping": d}) for d in (0.0, 0.3, 1.0, 0.6)]
    alone, _ = _map(jobs, kind="serial", batch="off")
    ends = [[t.end_time_s for t in traces.values()] for traces in alone]
    statuses = {t.status for traces in alone for t in traces.values()}
    assert {"failed", "completed"} <= statuses and len({tuple(e) for e in ends}) > 1, (statuses, ends)
    two, batched = _map(jobs, kind="process", workers=2, batch="threads")
    assert batched and _same(two, alone)
    pooled, chunks = _map(jobs, kind="process", workers=2, pool_start=2, chunks=True)  # one ends early
    assert chunks == 2 and _same(pooled, alone)
    few, chunks = _map(jobs[:3], kind="process", workers=2, pool_start=2, chunks=True)  # < 2 each: one batch here
    assert chunks == 1 and _same(few, alone[:3])


@pytest.mark.parametrize("robot_name", ["cartpole", "arm"])
def test_jacobian_batched_is_bit_identical(robot_name: str) -> None:
    job = _job(robot_name)
    patterns = (["joint.pole_hinge.damping", "body.pole.mass", "motor.wheel1.kp"] if robot_name == "cartpole"
                else ["joint.elbow.damping", "joint.wrist_1.friction", "body.wrist_3_link.mass", "motor.elbow.kp"])
    twin = make_twin("mujoco", resolve_robot(robot_name), load_suite(Path(job.suite)).global_settings.control_period_s)
    specs = select_knobs(twin.knobs(), patterns)
    twin.close()
    with Evaluator("serial", batch="off") as evaluator:
        reference = evaluator.map([job.with_knobs({patterns[0]: 0.2})])[0]
    scenarios = sorted(reference)
    channels = sorted({n for t in reference.values() for n in t.series if not n.startswith("onboard/")})
    train = build_spec(reference, scenarios, channels)
    u = unit_from_values(specs, {})
    results = {}
    for name, kwargs in (("alone", {"kind": "serial", "batch": "off"}), ("one", {"kind": "serial"}),
                         ("two", {"kind": "process", "workers": 2, "batch": "threads"}),
                         ("pooled", {"kind": "process", "workers": 2, "pool_start": 2})):
        with Evaluator(**kwargs) as evaluator:  # type: ignore[arg-type]
            problem = TrajectoryProblem(specs, job, train, None, evaluator, budget=100)
            results[name] = fd_jacobian(problem, u, 0.03, list(range(len(specs))), central=True)
            assert evaluator.batched == (name != "alone")
    jac, r0 = results["alone"]
    assert np.abs(jac).max() > 0  # the knobs move the residuals
    for name in ("one", "two", "pooled"):
        assert np.array_equal(results[name][0], jac) and np.array_equal(results[name][1], r0)


def test_twin_batch_reports_an_unstable_period_like_step() -> None:
    robot = resolve_robot("cartpole")
    twins = [make_twin("mujoco", robot, 0.032) for _ in range(3)]
    alone = [make_twin("mujoco", robot, 0.032) for _ in range(3)]
    batch = TwinBatch(twins, nthread=2)
    assert batch.step([0, 1, 2]) == [None, None, None]
    for twin in alone:
        twin.step()
    for group in (twins, alone):
        # MuJoCo resets this simulation (time 0) at its next step (a bad qvel warning).
        group[1].data.qvel[:] = np.nan
    outcome = batch.step([0, 1, 2])
    assert outcome[0] is None and outcome[2] is None
    assert isinstance(outcome[1], SimulationUnstable)
    with pytest.raises(SimulationUnstable):
        alone[1].step()
    for i in (0, 2):
        alone[i].step()
    for a, b in zip(twins, alone, strict=True):
        assert np.array_equal(a.data.qpos, b.data.qpos) and np.array_equal(a.data.qvel, b.data.qvel)
        assert a.time == b.time
    # Only the named twins step.
    batch.step([2])
    alone[2].step()
    assert twins[0].time == alone[0].time and twins[2].time == alone[2].time > alone[0].time
    assert np.array_equal(twins[2].data.qpos, alone[2].data.qpos)


def test_batch_reason_names_what_cannot_batch() -> None:
    robot = resolve_robot("cartpole")
    assert batch_reason(make_twin("mujoco", robot, 0.032)) is None
    python_law = make_twin("mujoco", robot, 0.032)
    python_law.native_law = False
    assert "motor law" in (batch_reason(python_law) or "")
    assert "not a MuJoCo twin" in (batch_reason(object()) or "")
    spec = mujoco.MjSpec.from_string("<mujoco><worldbody><body><joint name='j'/><geom size='0.1'/></body>"
                                     "</worldbody><actuator><motor name='m' joint='j'/></actuator>"
                                     "<sensor><actuatorpos name='a' actuator='m'/></sensor></mujoco>")
    from dualtwin.twins.mujoco import MuJoCoTwin

    assert "'a'" in (batch_reason(MuJoCoTwin(spec, 0.01)) or "")


def test_webots_target_keeps_the_executor(tmp_path: Path) -> None:
    job = _job("cartpole")
    webots = SimJob(job.robot, "webots", job.suite, ("04_Impulse",), (), 0)
    with Evaluator("serial") as evaluator:
        evaluator.map([webots, webots])
        assert not evaluator.batched


def test_batch_setting_is_saved_only_when_not_default() -> None:
    base = {"reference": "webots", "target": "mujoco", "robot": "cartpole", "knobs": ["*"]}
    assert "batch" not in AlignConfig(**base).saved()
    assert AlignConfig(**base, batch="off").saved()["batch"] == "off"
    with pytest.raises(ValueError):
        AlignConfig(**base, batch="maybe")


def test_a_small_map_does_not_start_the_pool_and_a_running_pool_takes_two_per_worker() -> None:
    """The pooled batch starts the pool for ``pool_start`` candidates per worker; then two per worker use it."""
    job = _job("cartpole")
    small = [job.with_knobs(values) for values in POPULATIONS["cartpole"]]  # 6 candidates: 3 per worker
    with Evaluator("process", workers=2, pool_start=4) as evaluator:
        alone = evaluator.map(small)
        assert evaluator.batch_chunks == 1  # below 4 per worker: one batch here, the pool not started
        evaluator.map(small + small[:2])  # 8 candidates: 4 per worker start it
        assert evaluator.batch_chunks == 2
        again = evaluator.map(small)
        assert evaluator.batch_chunks == 2 and _same(again, alone)
