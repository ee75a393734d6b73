"""``webots run`` refuses bad durations and controller fields that are paths (issue 14)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.webots.runner import run_world

WORLD = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
Robot {{
  children [ Solid {{ boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }} ]
  controller "{controller}"
}}
"""

# Writes a marker when executed: the tests check that refused scripts never ran.
EVIL = "from pathlib import Path\nPath({marker!r}).write_text('ran')\n"


def _project(root: Path, controller: str) -> Path:
    (root / "worlds").mkdir(parents=True)
    (root / "controllers").mkdir()
    world = root / "worlds" / "w.wbt"
    world.write_text(WORLD.format(controller=controller))
    return world


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dualtwin.cli", "webots", "run", *args], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize("value", ["nan", "-3"])
def test_cli_duration_must_be_finite_and_positive(tmp_path: Path, value: str) -> None:
    world = _project(tmp_path, "<none>")
    result = _cli(str(world), "--duration", value)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--duration" in lines[0] and "Traceback" not in result.stderr


@pytest.mark.parametrize("value", [0.0, float("inf"), float("-inf"), -1e-9])
def test_run_world_refuses_duration(tmp_path: Path, value: float) -> None:
    world = _project(tmp_path, "<none>")
    with pytest.raises(DualtwinError, match="--duration"):
        run_world(world, None, value)


def test_positive_duration_still_runs(tmp_path: Path) -> None:
    assert run_world(_project(tmp_path, "<none>"), None, 0.05) == 0


@pytest.mark.parametrize("kind", ["dotdot", "absolute", "nested", "backslash"])
def test_controller_field_is_a_name_not_a_path(tmp_path: Path, kind: str) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    marker = tmp_path / "marker"
    evil = outside / "evil.py"
    evil.write_text(EVIL.format(marker=str(marker)))
    project = tmp_path / "project"
    controller = {
        "dotdot": "../../outside/evil",
        "absolute": str(outside / "evil"),
        "nested": "sub/evil",
        "backslash": "..\\\\outside\\\\evil",
    }[kind]
    world = _project(project, controller)
    # a matching script at the spelled location must not be reached either
    nested = project / "controllers" / "sub" / "evil"
    nested.mkdir(parents=True)
    (nested / "evil.py").write_text(EVIL.format(marker=str(marker)))
    with pytest.raises(DualtwinError) as info:
        run_world(world, None, 0.05)
    message = str(info.value)
    assert "w.wbt:3:1" in message and "not a controller name" in message
    assert not marker.exists()


def test_controller_symlink_escaping_the_project_is_refused(tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    evil = tmp_path / "evil.py"
    evil.write_text(EVIL.format(marker=str(marker)))
    world = _project(tmp_path / "project", "ctl")
    folder = tmp_path / "project" / "controllers" / "ctl"
    folder.mkdir()
    (folder / "ctl.py").symlink_to(evil)
    with pytest.raises(DualtwinError, match="outside the project's controllers folder"):
        run_world(world, None, 0.05)
    assert not marker.exists()


def test_cli_refused_controller_is_one_line(tmp_path: Path) -> None:
    world = _project(tmp_path, "../x")
    result = _cli(str(world), "--duration", "1")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "not a controller name" in lines[0] and "Traceback" not in result.stderr


def test_named_controller_in_its_folder_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, "ok")
    (tmp_path / "controllers" / "ok").mkdir()
    (tmp_path / "controllers" / "ok" / "ok.py").write_text(
        "from controller import Robot\nr = Robot()\nwhile r.step(8) != -1: pass\nprint('done', r.getTime())\n"
    )
    assert run_world(world, None, 0.04) == 0
    assert "done 0.04" in capsys.readouterr().out


def test_world_that_is_a_pipe_is_one_error(tmp_path: Path) -> None:
    import os

    fifo = tmp_path / "w.wbt"
    os.mkfifo(fifo)
    with pytest.raises(DualtwinError, match="not a regular file"):
        run_world(fifo, None, 0.1)
