"""After ``simulationReset()`` the controllers go on and their enabled sensors read the reset state at once.

Webots resets each sensor's sampling clock with the scene (its last update set far in the past), so every
enabled sensor is due at the step that returns at t = 0 and reads the state the world was loaded in; the next
sample follows one period later. The controller library keeps the last values it received: a reading is never
NaN again once it had a value (it was NaN for one step after a reset here).

The world: a pendulum whose bob is loaded off the vertical (its joint's ``position`` field 0.3, which Webots
takes as the sensor's reading there) and swings under gravity before the reset, a GPS on the bob. Expected
values by hand: after the reset the joint reads 0.3 and the GPS the bob's load translation (0.3, 0, 0.6),
neither the swung values (control: they differ by far more than the tolerance) nor NaN.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.physics import Simulation
from dualtwin.webots.supervisor import Supervisor

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot {
  supervisor TRUE
  controller "reader"
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 1 0 anchor 0 0 1 position 0.3 }
      device [ PositionSensor { name "ps" } ]
      endPoint Solid {
        translation 0.3 0 0.6
        children [ GPS { name "gps" } Shape { geometry Sphere { radius 0.05 } } ]
        boundingObject Sphere { radius 0.05 }
        physics Physics { density -1 mass 1 }
      }
    }
  ]
}
"""

READER = """
from controller import Supervisor
s = Supervisor()
ps, gps = s.getDevice("ps"), s.getDevice("gps")
ps.enable(16)
gps.enable(16)
for _ in range(20):
    s.step(8)
print("swung", ps.getValue(), *gps.getValues())
s.simulationReset()
for _ in range(3):
    s.step(8)
    print("after", s.getTime(), ps.getValue(), *gps.getValues())
"""


def _readings_in_process() -> tuple[list[float], list[list[float]]]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(WORLD))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    ps, gps = sup.getDevice("ps"), sup.getDevice("gps")
    ps.enable(16)
    gps.enable(16)
    for _ in range(20):
        sup.step(8)
    swung = [ps.getValue(), *gps.getValues()]
    sup.simulationReset()
    after = []
    for _ in range(3):
        sup.step(8)
        after.append([sup.getTime(), ps.getValue(), *gps.getValues()])
    return swung, after


def _check(swung: list[float], after: list[list[float]]) -> None:
    assert abs(swung[0] - 0.3) > 0.05  # control: the pendulum has swung, a stale reading would show it
    time0, position, *gps = after[0]
    assert time0 == 0.0
    assert position == pytest.approx(0.3, abs=1e-9)  # the reset state, read at once (was NaN)
    assert gps == pytest.approx([0.3, 0.0, 0.6], abs=1e-9)
    assert after[1][1:] == after[0][1:]  # period 16 ms: nothing new at 8 ms
    assert after[2][0] == pytest.approx(0.016) and after[2][1] != after[0][1]  # the next sample, one period on


def test_sensors_read_the_reset_state_at_the_reset_step() -> None:
    _check(*_readings_in_process())


def test_a_controller_process_reads_the_reset_state_at_the_reset_step(tmp_path: Path) -> None:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "w.wbt").write_text(WORLD)
    (tmp_path / "controllers" / "reader").mkdir(parents=True)
    (tmp_path / "controllers" / "reader" / "reader.py").write_text(READER)
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "webots", "run", str(tmp_path / "worlds" / "w.wbt"),
                           "--duration", "0.5"], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = [line.split() for line in done.stdout.splitlines() if line.startswith(("swung", "after"))]
    swung = [float(v) for v in lines[0][1:]]
    after = [[float(v) for v in line[1:]] for line in lines[1:]]
    _check(swung, after)
