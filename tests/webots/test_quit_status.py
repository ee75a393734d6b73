"""``Supervisor.simulationQuit(status)`` ends the run with ``status`` (webots-python-api.md, Supervisor: "quit Webots
with exit status"), whatever the controllers do once it was asked for: in Webots the simulator exits with that status,
and a controller's traceback after it is only output in the console. Both isolations agree.

A controller that failed before the quit still makes the exit code 1 (our rule for a crashing controller, which the
reference does not have: Webots' own exit status never tells a controller's crash), so a run that went wrong is not
reported as a success because a supervisor later quit with 0.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.isolation_runs import run_in_both_modes

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "boss" controller "probe" supervisor TRUE }
Robot { translation 1 0 0 name "bot" controller "probe" supervisor TRUE }
"""

# The boss steps once, quits with STATUS and raises; the bot steps until its step says -1 (the quit) and raises.
AFTER_QUIT = """
from controller import Supervisor
robot = Supervisor()
if robot.getName() == "boss":
    robot.step(8)
    robot.simulationQuit(STATUS)
    raise RuntimeError("boss after the quit")
while robot.step(8) != -1:
    pass
raise RuntimeError("bot after its -1")
"""

# The bot raises before its first step, the boss quits with 0 two steps later.
BEFORE_QUIT = """
from controller import Supervisor
robot = Supervisor()
if robot.getName() == "bot":
    raise RuntimeError("bot before the quit")
robot.step(8)
robot.step(8)
robot.simulationQuit(0)
"""


@pytest.mark.parametrize("status", [3, 0])
def test_errors_after_simulation_quit_keep_its_status(tmp_path: Path, status: int) -> None:
    runs = run_in_both_modes(tmp_path, WORLD, AFTER_QUIT.replace("STATUS", str(status)))
    for mode, (out, err, code) in runs.items():
        assert code == status, mode  # was 1: the tracebacks after the quit decided the exit code
        assert out == ""
        # both tracebacks are still printed, as in Webots' console
        assert "RuntimeError: boss after the quit\n" in err and "RuntimeError: bot after its -1\n" in err, mode


def test_an_error_before_the_quit_still_fails_the_run(tmp_path: Path) -> None:
    runs = run_in_both_modes(tmp_path, WORLD, BEFORE_QUIT)
    for mode, (out, err, code) in runs.items():
        assert (code, out) == (1, ""), mode
        assert err.endswith("RuntimeError: bot before the quit\n"), mode
