"""ODE stopping inside its step (an assertion of the libode8 build) no longer ends the process.

A hinge anchored 1e30 m away overflows within the first step: ODE reports "assertion !bSafeNormalize4Fault
failed" and calls abort(). The guarded step (``webots/native/ode_guard.c``) turns that into
``SimulationUnstable`` with ODE's message, and the world refuses to be stepped or reset again. The control runs
the same world with the guard turned off (``DUALTWIN_ODE_GUARD=0``): the process is killed by SIGABRT.

Everything runs in child processes, so a regression fails the test instead of ending pytest."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from dualtwin.webots import ode

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot {
  children [
    HingeJoint {
      jointParameters HingeJointParameters { anchor 1e30 1e30 0 }
      endPoint Solid {
        translation 0.1 0 0
        children [ Shape { geometry DEF B Box { size 0.1 0.1 0.1 } } ]
        boundingObject USE B
        physics Physics { density -1 mass 1 }
      }
    }
  ]
  boundingObject Box { size 0.1 0.1 0.1 }
  physics Physics { }
}
"""

SCRIPT = """
import sys
from dualtwin.errors import SimulationUnstable
from dualtwin.webots import load_world_text
from dualtwin.webots.physics import Simulation
sim = Simulation(load_world_text(sys.stdin.read()))
try:
    sim.step()
except SimulationUnstable as exc:
    print("step:", exc)
for call in (sim.step, sim.reset):
    try:
        call()
    except SimulationUnstable as exc:
        print(call.__name__ + ":", exc)
sim.close()
print("closed")
"""


def _run(guard: bool) -> subprocess.CompletedProcess[str]:
    env = {**ENV, "DUALTWIN_ODE_GUARD": "1" if guard else "0"}
    return subprocess.run([sys.executable, "-c", SCRIPT], input=WORLD, capture_output=True, text=True, timeout=120,
                          env=env, cwd=ROOT, check=False)


def test_an_assertion_inside_the_step_raises_and_the_world_is_not_stepped_again() -> None:
    if ode.guarded_step() is None:
        pytest.fail(f"the guarded step is not available here: {ode.guard_failure()}")
    done = _run(guard=True)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("step: ODE stopped inside the step to t=0.008s (ODE INTERNAL ERROR 1: assertion"), lines
    assert "bSafeNormalize4Fault" in lines[0] and lines[0].endswith("the world must be loaded again"), lines
    assert lines[1] == "step: simulation is unstable; call reset()", lines
    assert lines[2].startswith("reset: ODE stopped inside the step") and "cannot be reset: load it again" in lines[2]
    assert lines[3] == "closed"


def test_control_without_the_guard_the_same_world_aborts_the_process() -> None:
    done = _run(guard=False)
    assert done.returncode == -signal.SIGABRT, (done.returncode, done.stdout, done.stderr)
    assert "ODE INTERNAL ERROR 1: assertion" in done.stderr and "closed" not in done.stdout
