"""AlignConfig is the one field list: the align command's options are derived from it, and its saved form is stable."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import typer

from dualtwin.align import AlignConfig
from dualtwin.align.config import PREDICTION_FIELDS, derived_fields
from dualtwin.cli import app
from dualtwin.cli.model_options import cli_fields, option_name, option_names

#: Options of the command that are not settings of the fit (where to write, how to run it).
COMMAND_ONLY = {"out", "reference-run", "resume", "no-resume", "llm", "no-llm", "json", "help"}


def align_command() -> object:
    group = typer.main.get_command(app)
    return group.commands["align"]  # type: ignore[attr-defined]


def test_every_field_is_an_option_and_every_option_a_field() -> None:
    fields = {option_name(n, f) for n, f in cli_fields(AlignConfig).items()}
    options = option_names(align_command())
    assert fields == options - COMMAND_ONLY
    # The derived fields are filled in by run_align, never given.
    assert derived_fields() == {"reference_kind", "reference_sha256"}
    assert not {option_name(n, AlignConfig.model_fields[n]) for n in derived_fields()} & options


def test_help_lists_choices_and_descriptions() -> None:
    command = align_command()
    params = {p.name: p for p in command.params}  # type: ignore[attr-defined]
    def choices(name: str) -> list[str]:
        return [m.value for m in params[name].type_descriptor.annotation]

    assert choices("optimizer") == ["cma", "lsq"]
    assert choices("objective") == ["trajectory", "prediction"]
    assert choices("executor") == ["serial", "process", "ray"]
    assert params["knobs"].multiple and params["holdout"].multiple and params["horizons"].multiple
    assert params["budget"].help == AlignConfig.model_fields["budget"].description


def test_saved_config_keeps_its_format() -> None:
    base = {"reference": "webots", "target": "mujoco", "robot": "cartpole", "suite": "s.json", "knobs": ["k"]}
    trajectory = AlignConfig(**base).saved()
    # The trajectory objective's file lists no prediction field (folders written before stay resumable) ...
    assert not PREDICTION_FIELDS & set(trajectory)
    assert list(trajectory)[:3] == ["reference", "reference_kind", "reference_knobs"]
    assert list(trajectory)[-1] == "ensemble"
    # ... and the prediction objective's lists them after the shared ones, in this order.
    prediction = AlignConfig(**base, objective="prediction").saved()
    assert list(prediction)[len(trajectory):] == ["objective", "horizons", "stride", "scales", "reference_sha256"]
    assert AlignConfig(**base).digest() != AlignConfig(**base, seed=1).digest()


@pytest.mark.parametrize(("extra", "message"), [
    (["--bounds", "joint.pole_hinge.damping"], "--bounds: expected KEY=LOW,HIGH"),
    (["--budget", "1"], "--budget: Input should be greater than or equal to 2"),
    (["--weights", "dtw=-1"], "--weights dtw: Input should be greater than or equal to 0"),
    (["--optimizer", "newton"], "'newton' is not one of 'cma', 'lsq'"),
])
def test_bad_options_are_one_line_and_write_nothing(tmp_path: Path, extra: list[str], message: str) -> None:
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "align", "--reference", "webots", "--target",
                           "mujoco", "--robot", "cartpole", "--scenarios", "cartpole", "--knobs",
                           "joint.pole_hinge.damping", "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and "Traceback" not in done.stderr
    assert not out.exists()


def test_prediction_fields_are_refused_for_the_trajectory_objective(tmp_path: Path) -> None:
    from dualtwin.align import run_align
    from dualtwin.errors import DualtwinError

    config = AlignConfig(reference="webots", target="mujoco", robot="cartpole", knobs=["k"], horizons=[1, 2])
    with pytest.raises(DualtwinError, match="horizons apply only to the prediction objective"):
        run_align(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    assert json.loads(config.saved_json()) == config.saved()


def test_a_missing_suite_names_the_option_not_the_working_directory(tmp_path: Path) -> None:
    """An empty path default is "not given": without --scenarios the error names the option (it once said
    ".: is a directory", the empty default read as a path)."""
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "align", "--reference", "webots", "--target",
                           "mujoco", "--robot", "cartpole", "--knobs", "joint.pole_hinge.damping", "--out", str(out)],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == "error: the trajectory objective needs a suite (--scenarios)"
    assert not out.exists()
