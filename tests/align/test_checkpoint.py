"""CMA-ES checkpoints are data: no pickle, no path outside the output folder, and resume is exact."""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

import pytest

from dualtwin.align import AlignConfig, GenerationInfo, run_align
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from tests.support.align_runs import SUITE3, TRUE_DAMPING, record, write_suite

DAMPING = "joint.pole_hinge.damping"
KWARGS: dict[str, Any] = {"optimizer": "cma", "seed": 5, "budget": 24, "executor": "serial", "popsize": 4}


class _Payload:
    """Unpickling this writes a marker file: proof that a pickle from the folder was (not) loaded."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, ...]:
        return (Path.write_text, (self.marker, "unpickled"))


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory, robot: RobotBinding) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("checkpoint")
    suite = write_suite(root / "suite.json", {**SUITE3, "scenarios": [
        {"name": "fall", "duration_s": 0.5, "initial_angle": 0.3},
        {"name": "drive", "duration_s": 0.5, "initial_angle": 0.05, "wheel_velocity": 4.0}]})
    return suite, record(robot, suite, root / "ref", {DAMPING: TRUE_DAMPING})


def crashed_run(robot: RobotBinding, setup: tuple[Path, Path], out: Path, at: int = 2) -> Path:
    suite, ref = setup

    def crash(info: GenerationInfo) -> None:
        if info.iteration == at:
            raise RuntimeError("simulated crash")

    with pytest.raises(RuntimeError, match="simulated crash"):
        run_align(AlignConfig(reference=str(ref), target="mujoco", robot=str(robot.path), suite=str(suite),
                              knobs=[DAMPING], **KWARGS), out, callback=crash)
    return out / "checkpoint.json"


def test_resume_replays_to_the_uninterrupted_run_bit_for_bit(tmp_path: Path, robot: RobotBinding,
                                                             setup: tuple[Path, Path]) -> None:
    suite, ref = setup
    whole = run_align(AlignConfig(reference=str(ref), target="mujoco", robot=str(robot.path),
                                  suite=str(suite), knobs=[DAMPING], **KWARGS), tmp_path / "whole")
    checkpoint = crashed_run(robot, setup, tmp_path / "crashed")
    state = json.loads(checkpoint.read_text())
    assert state["schema"] == "dualtwin.align.checkpoint/2" and len(state["generations"]) == state["iteration"] == 2
    assert not [p for p in (tmp_path / "crashed").rglob("*") if p.suffix in (".pkl", ".pickle")]
    resumed = run_align(AlignConfig(reference=str(ref), target="mujoco", robot=str(robot.path),
                                    suite=str(suite), knobs=[DAMPING], **KWARGS), tmp_path / "crashed",
                        resume=True)
    assert resumed.fitted == whole.fitted and resumed.evaluations == whole.evaluations
    # Every generation's solutions, objective values, sigma and mean: equal as floats, not merely close.
    final = [json.loads((tmp_path / d / "checkpoint.json").read_text()) for d in ("whole", "crashed")]
    assert final[0]["generations"] == final[1]["generations"] and final[0]["trace"] == final[1]["trace"]
    assert len(final[0]["generations"]) > 2  # the resumed run went on past the crash


def test_checkpoint_paths_outside_the_folder_are_refused(tmp_path: Path, robot: RobotBinding,
                                                         setup: tuple[Path, Path]) -> None:
    suite, ref = setup
    checkpoint = crashed_run(robot, setup, tmp_path / "run")
    state = json.loads(checkpoint.read_text())
    outside = tmp_path / "evil.pkl"
    marker = tmp_path / "marker.txt"
    outside.write_bytes(pickle.dumps(_Payload(marker)))
    for value in ("../evil.pkl", str(outside), "sub/../../evil.pkl"):
        checkpoint.write_text(json.dumps({**state, "state_file": value}))
        with pytest.raises(DualtwinError, match="points outside the output folder") as info:
            run_align(AlignConfig(reference=str(ref), target="mujoco", robot=str(robot.path),
                                  suite=str(suite), knobs=[DAMPING], **KWARGS), tmp_path / "run", resume=True)
        assert "\n" not in str(info.value) and "state_file" in str(info.value)
    assert not marker.exists()


def test_an_old_pickle_checkpoint_is_never_unpickled(tmp_path: Path, robot: RobotBinding,
                                                     setup: tuple[Path, Path]) -> None:
    suite, ref = setup
    checkpoint = crashed_run(robot, setup, tmp_path / "run")
    state = json.loads(checkpoint.read_text())
    marker = tmp_path / "marker.txt"
    (tmp_path / "run" / "cma_state_0002.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    # The version-1 format: a checkpoint naming a pickled strategy inside the folder.
    old = {k: v for k, v in state.items() if k not in ("generations", "x0")}
    checkpoint.write_text(json.dumps({**old, "schema": "dualtwin.align.checkpoint/1",
                                      "state_file": "cma_state_0002.pkl"}))
    with pytest.raises(DualtwinError, match="never loaded"):
        run_align(AlignConfig(reference=str(ref), target="mujoco", robot=str(robot.path), suite=str(suite),
                              knobs=[DAMPING], **KWARGS), tmp_path / "run", resume=True)
    assert not marker.exists()


@pytest.mark.parametrize("damage", ["tampered fitness", "missing history", "not an object"])
def test_damaged_checkpoints_are_one_line_errors(tmp_path: Path, robot: RobotBinding, setup: tuple[Path, Path],
                                                 damage: str) -> None:
    suite, ref = setup
    checkpoint = crashed_run(robot, setup, tmp_path / "run")
    state = json.loads(checkpoint.read_text())
    if damage == "tampered fitness":
        # A changed objective value changes the next generation's samples: the replay notices.
        state["generations"][0]["fitness"] = [0.0] * len(state["generations"][0]["fitness"])
        checkpoint.write_text(json.dumps(state))
        match = "does not replay"
    elif damage == "missing history":
        del state["generations"]
        checkpoint.write_text(json.dumps(state))
        match = "damaged CMA checkpoint"
    else:
        checkpoint.write_text("[1, 2]")
        match = "cannot resume"
    with pytest.raises(DualtwinError, match=match) as info:
        run_align(AlignConfig(reference=str(ref), target="mujoco", robot=str(robot.path), suite=str(suite),
                              knobs=[DAMPING], **KWARGS), tmp_path / "run", resume=True)
    assert "\n" not in str(info.value)
