"""A world holding a node whose effect this runtime does not simulate says so once, at load, in one line.

A Fluid pushes immersed Solids by buoyancy but not by drag or viscous resistance, so a world whose
ImmersionProperties ask for those says so (one that asks only for buoyancy says nothing). Before, such a world
ran silently: a box dropped into water fell through it as in air and nothing said why. The run's warnings (these, and the
physics plugin's) are printed as ``Warning: ...`` lines, as Webots prints its own, not as Python's
``file:line: UserWarning`` followed by a source line.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

from dualtwin.webots import load_world_text
from dualtwin.webots.physics import Simulation

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}

POOL = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 {info} }}
{extra}
Solid {{
  translation 0 0 1.5
  children [ Shape {{ geometry DEF B Box {{ size 0.2 0.2 0.2 }} }} ]
  boundingObject USE B
  physics Physics {{ density 500 }}
  immersionProperties [ ImmersionProperties {{ fluidName "fluid" {props} }} ]
}}
Solid {{ children [ Shape {{ geometry DEF P Plane {{ size 10 10 }} }} ] boundingObject USE P name "floor" }}
"""
FLUID = 'Fluid { translation 0 0 0.5 boundingObject Box { size 4 4 1 } }'
DRAG = "dragForceCoefficients 0.1 0 0"


def _build_warnings(text: str) -> list[str]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    try:
        return sim.build_warnings
    finally:
        sim.close()


def test_a_node_without_effect_here_is_named_once_at_load() -> None:
    text = POOL.format(info="", extra=f"{FLUID}\n{FLUID}", props=DRAG)
    said = _build_warnings(text)
    named = [w for w in said if "a Fluid node" in w]
    assert len(named) == 1, said  # once, however many there are
    assert "not simulated here" in named[0]


def test_a_fluid_says_that_drag_is_missing_and_buoyancy_is_not() -> None:
    said = _build_warnings(POOL.format(info="", extra=FLUID, props=DRAG))
    assert len(said) == 1, said
    assert "buoyancy of immersed Box" in said[0] and "is simulated" in said[0]
    assert "drag and viscous resistance" in said[0] and "are not simulated here" in said[0]


def test_a_fluid_world_asking_for_buoyancy_only_says_nothing() -> None:
    assert _build_warnings(POOL.format(info="", extra=FLUID, props="")) == []


def test_the_control_world_without_them_says_nothing() -> None:
    assert _build_warnings(POOL.format(info="", extra="", props=DRAG)) == []


def test_webots_run_prints_each_warning_as_one_webots_line(tmp_path: Path) -> None:
    world = tmp_path / "pool.wbt"
    world.write_text(POOL.format(info='physics "buoyancy_plugin"', extra=FLUID, props=DRAG), encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "webots", "run", str(world), "--duration", "0.1"],
                          capture_output=True, text=True, timeout=120, env=ENV, cwd=ROOT, check=False)
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert len([line for line in lines if "physics plugin 'buoyancy_plugin'" in line]) == 1, done.stderr
    assert len([line for line in lines if "a Fluid node" in line]) == 1, done.stderr
    assert all(line.startswith("Warning: ") for line in lines), done.stderr
    assert "UserWarning" not in done.stderr and ".py:" not in done.stderr


def test_the_command_line_shows_a_python_warning_as_one_line() -> None:
    from dualtwin.cli import _warning_line  # the formatter main() installs while a command runs

    text = _warning_line(UserWarning("first\nsecond"), UserWarning, "/somewhere/module.py", 12, "source()")
    assert text == "warning: first; second\n"
