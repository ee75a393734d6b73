"""A robot binding and the models it names are untrusted (a downloaded robot): a wrong name in the binding or a
hostile physics step in the model is one error naming the file, exit 2, and no run folder left behind."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from dualtwin.cli import main
from dualtwin.robots.binding import BUNDLED

SUITE = {"suite_name": "s", "global_settings": {"TIME_STEP": 32},
         "scenarios": [{"name": "a", "duration_s": 0.1, "initial_angle": 0.1, "initial_cart_position": 0.0,
                        "wheel_velocity": 1.0}]}


def robot_folder(tmp_path: Path) -> Path:
    """A copy of the bundled CartPole (binding, MJCF, world) that a test may edit."""
    folder = tmp_path / "robot"
    shutil.copytree(BUNDLED / "cartpole", folder)
    (folder / "suite.json").write_text(json.dumps(SUITE))
    return folder


def suite_run(folder: Path, twin: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str], Path]:
    out = folder / "run"
    capsys.readouterr()
    code = main(["suite", "run", "--twin", twin, "--robot", str(folder / "binding.yaml"),
                 "--scenarios", str(folder / "suite.json"), "--out", str(out)])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    # MuJoCo's own warnings (a NaN in the XML) may precede it; the error is one line.
    return code, [line for line in err.splitlines() if not line.startswith("MuJoCo warning:")], out


@pytest.mark.parametrize(("field", "value"), [
    (("ground_truth", "pole_angle_rad", "joint"), "no_such_joint"),
    (("ground_truth", "cart_pos_m", "body"), ""),
    (("onboard", "pole_angle_rad", "sensors", 0), "cart"),
    (("actions", "wheel_velocity", "actuators", 2), "cartpole.xml"),
    (("initial_conditions", "initial_cart_position", "body"), "no such body"),
    (("initial_conditions", "initial_cart_position", "body"), "pole"),  # exists, cannot be teleported
    (("initial_conditions", "initial_cart_position", "body"), "pole_hinge"),  # webots: a joint's DEF
])
@pytest.mark.parametrize("twin", ["mujoco", "webots"])
def test_a_binding_naming_what_the_model_lacks_is_refused_before_the_run_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], twin: str, field: tuple[str | int, ...],
        value: str) -> None:
    folder = robot_folder(tmp_path)
    binding = yaml.safe_load((folder / "binding.yaml").read_text())
    node = binding
    for key in field[:-1]:
        node = node[key]
    node[field[-1]] = value
    (folder / "binding.yaml").write_text(yaml.safe_dump(binding))
    code, err, out = suite_run(folder, twin, capsys)
    assert code == 2, (err, binding)
    assert len(err) == 1, err
    path = ".".join(str(k) for k in field[:-1]) + (f"[{field[-1]}]" if isinstance(field[-1], int) else
                                                   f".{field[-1]}")
    assert str(folder / "binding.yaml") in err[0] and f"$.{path}" in err[0] and repr(value) in err[0], err
    assert not out.exists()


@pytest.mark.parametrize(("model", "old", "new", "message"), [
    ("cartpole.xml", 'timestep="0.002"', 'timestep="0"', "<option timestep> must be a positive number"),
    ("cartpole.xml", 'timestep="0.002"', 'timestep="nan"', "<option timestep> must be a positive number"),
    ("cartpole.xml", 'timestep="0.002"', 'timestep="1e-300"', "the most allowed"),
    ("cartpole.wbt", "basicTimeStep 8", "basicTimeStep 1e308", "not a whole number of physics steps"),
    ("cartpole.wbt", "basicTimeStep 8", "basicTimeStep 0.0001", "the most allowed"),
])
def test_a_hostile_physics_step_in_the_model_is_one_error(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          model: str, old: str, new: str, message: str) -> None:
    folder = robot_folder(tmp_path)
    text = (folder / model).read_text()
    assert old in text
    (folder / model).write_text(text.replace(old, new))
    code, err, out = suite_run(folder, "mujoco" if model.endswith(".xml") else "webots", capsys)
    assert code == 2
    assert len(err) == 1 and str(folder / model) in err[0] and message in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("model", ["cartpole.xml\x00", ""])
def test_a_model_path_the_os_cannot_take_is_one_error_naming_the_field(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], model: str) -> None:
    folder = robot_folder(tmp_path)
    binding = yaml.safe_load((folder / "binding.yaml").read_text())
    binding["twins"]["mujoco"]["model"] = model
    (folder / "binding.yaml").write_text(yaml.safe_dump(binding))
    code, err, out = suite_run(folder, "mujoco", capsys)
    assert code == 2
    assert len(err) == 1 and "$.twins.mujoco.model" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize(("insert", "message"), [
    ('<size nuser_body="1000000000"/>', "size nuser_body = 1e+09"),
    ('<asset><hfield name="ground" nrow="100000" ncol="100000" size="1 1 1 1"/></asset>',
     "<hfield name=\"ground\" nrow=\"100000\" ncol=\"100000\" size=\"1 1 1 1\"/> = 1e+10 samples"),
    ('<asset><texture name="sky" type="skybox" builtin="gradient" width="100000" height="100000"/></asset>',
     "texture 'sky' width x height = 6e+10"),
])
def test_a_model_asking_for_more_memory_than_a_machine_has_is_refused_before_mujoco_compiles_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], insert: str, message: str) -> None:
    """Before, MuJoCo tried to allocate it all when it compiled the model: the process hung (or, under a memory
    limit, ended in "Caught an unknown exception!", a traceback), for --twin webots too (the suite's checks
    compile the MJCF)."""
    folder = robot_folder(tmp_path)
    text = (folder / "cartpole.xml").read_text()
    head = text.index(">", text.index("<mujoco")) + 1
    (folder / "cartpole.xml").write_text(text[:head] + insert + text[head:])
    code, err, out = suite_run(folder, "mujoco", capsys)
    assert code == 2
    assert len(err) == 1 and str(folder / "cartpole.xml") in err[0] and message in err[0], err
    assert "more than the" in err[0] and not out.exists()


def test_a_huge_height_field_in_an_included_file_is_refused_before_mujoco_parses_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """MuJoCo's parser allocates a height field's samples as it reads the element, so the check reads the text:
    before, only the model file's own <hfield> elements were read, and one in a file it <include>s (here two
    levels down, in a sub-folder, named relative to the file that includes it, one way MuJoCo finds it) went
    through."""
    folder = robot_folder(tmp_path)
    (folder / "parts").mkdir()
    (folder / "parts" / "outer.xml").write_text('<mujoco><include file="ground.xml"/></mujoco>')
    # 10 001 x 10 001 samples: just past the limit (a regression would allocate 400 MB, not tens of GB)
    (folder / "parts" / "ground.xml").write_text(
        '<mujoco><asset><hfield name="ground" nrow="10001" ncol="10001" size="1 1 1 1"/></asset></mujoco>')
    text = (folder / "cartpole.xml").read_text()
    head = text.index(">", text.index("<mujoco")) + 1
    (folder / "cartpole.xml").write_text(text[:head] + '<include file="parts/outer.xml"/>' + text[head:])
    code, err, out = suite_run(folder, "mujoco", capsys)
    assert code == 2
    assert len(err) == 1 and str(folder / "parts" / "ground.xml") in err[0] and "1.0002e+08 samples" in err[0], err
    assert not out.exists()
