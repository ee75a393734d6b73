"""Running unchanged Webots Python controllers headless (``run_world``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Solid { name "floor" boundingObject Plane { } }
DEF ARM Robot {
  translation 0 0 1
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 1 0 }
      device [ RotationalMotor { name "m" maxTorque 50 } PositionSensor { name "s" } ]
      endPoint Solid {
        translation 0.3 0 0
        boundingObject Sphere { radius 0.05 }
        physics Physics { density -1 mass 1 }
      }
    }
  ]
  controller "arm"
  controllerArgs [ "0.7" ]
  supervisor TRUE
}
"""

ARM = """
import os, sys
from controller import Supervisor

robot = Supervisor()
target = float(sys.argv[1])
motor = robot.getDevice("m")
sensor = motor.getPositionSensor()
sensor.enable(8)
motor.setPosition(target)
steps = 0
while robot.step(16) != -1:
    steps += 1
print(f"cwd={os.path.basename(os.getcwd())} name={robot.getName()} steps={steps} "
      f"t={robot.getTime():.3f} pos={sensor.getValue():.4f} self={robot.getSelf().getDef()}")
"""


def _project(tmp_path: Path, script: str) -> Path:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "controllers" / "arm").mkdir(parents=True)
    (tmp_path / "worlds" / "arm.wbt").write_text(WORLD)
    (tmp_path / "controllers" / "arm" / "arm.py").write_text(script)
    return tmp_path / "worlds" / "arm.wbt"


def test_runs_the_robot_controller_from_the_project_layout(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    world = _project(tmp_path, ARM)
    assert run_world(world, None, 1.0) == 0
    out = capsys.readouterr().out
    assert "cwd=arm name=robot steps=62 t=1.000" in out  # 62 full steps, the 63rd reaches 1 s
    assert "pos=0.7000" in out and "self=ARM" in out


def test_controller_override_and_exceptions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, ARM)
    bad = tmp_path / "bad.py"
    bad.write_text("from controller import Robot\nrobot = Robot()\nrobot.step(8)\nraise ValueError('boom')\n")
    assert run_world(world, bad, 1.0) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "ValueError: boom" in err and "bad.py" in err
    exiting = tmp_path / "exiting.py"
    exiting.write_text("import sys\nfrom controller import Robot\nRobot().step(8)\nsys.exit(3)\n")
    assert run_world(world, exiting, 1.0) == 3


def test_missing_controller_runs_without_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    world = _project(tmp_path, ARM)
    (tmp_path / "controllers" / "arm" / "arm.py").unlink()
    assert run_world(world, None, 0.1) == 0
    assert "no Python controller 'arm'" in capsys.readouterr().err
    assert run_world(world, None, None) == 2
