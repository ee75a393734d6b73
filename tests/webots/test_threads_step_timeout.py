"""The step timeout holds in both controller isolations: a controller that stops calling ``step`` (busy in a loop, or
blocked in a call that never returns) ends the run with one line and exit code 2, and the other controllers finish
(their ``step`` returns -1) with their output kept. The threads runtime ignored the timeout and hung for ever.

Each run is a fresh interpreter (a thread blocked for ever stays behind in it, as a daemon); the subprocess limit
is only there so that a hang fails the test instead of stalling the suite.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_S = 0.5

# One script for every robot (the threads runtime shares one working folder): the robot named "counter" counts its
# steps, the other gets stuck after its first step, busy in a loop or blocked in a call.
SCRIPT = """
    import threading
    from controller import Robot
    robot = Robot()
    if robot.getName() == "counter":
        n = 0
        while robot.step(8) != -1:
            n += 1
            print(f"counter {n}")
        print(f"counter done after {n}")
    else:
        robot.step(8)
        if robot.getName() == "busy":
            while True:
                pass
        threading.Event().wait()  # never set: blocked in a call, no Python code runs
"""


def _run(tmp_path: Path, isolation: str, robots: list[str]) -> subprocess.CompletedProcess[str]:
    project = tmp_path / isolation
    folder = project / "controllers" / "probe"
    folder.mkdir(parents=True)
    (folder / "probe.py").write_text(textwrap.dedent(SCRIPT), encoding="utf-8")
    nodes = "".join(f'Robot {{ translation {i} 0 0 name "{name}" controller "probe" }}\n'
                    for i, name in enumerate(robots))
    (project / "worlds").mkdir()
    world = project / "worlds" / "w.wbt"
    world.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n" + nodes, encoding="utf-8")
    code = (f"from dualtwin.webots.runner import run_world; raise SystemExit(run_world({str(world)!r}, None, None, "
            f"step_timeout_s={TIMEOUT_S}, isolation={isolation!r}))")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env,
                          cwd=project, check=False)


STOPPED = "Error: controller probe.py did not call step() for 0.5 s of real time (--step-timeout): stopped\n"


@pytest.mark.parametrize("isolation", ["threads", "process"])
@pytest.mark.parametrize("stuck", ["busy", "blocked"])
def test_a_controller_that_stops_stepping_ends_the_run_with_one_line(
    tmp_path: Path, isolation: str, stuck: str
) -> None:
    # The stuck robot comes first. Both step once (t = 8 ms); the other's second step waits for the stuck one's,
    # which never comes, until the timeout ends the run: that step returns -1, so it printed "counter 1" and ends
    # after 1 step, in either isolation.
    done = _run(tmp_path, isolation, [stuck, "counter"])
    assert (done.returncode, done.stderr) == (2, STOPPED)
    assert done.stdout == "counter 1\ncounter done after 1\n"


@pytest.mark.parametrize("isolation", ["threads", "process"])
def test_the_only_controller_blocked_ends_the_run(tmp_path: Path, isolation: str) -> None:
    """A lone controller too (the threads runtime ran it in its own thread, which nothing could then stop)."""
    done = _run(tmp_path, isolation, ["blocked"])
    assert (done.returncode, done.stdout, done.stderr) == (2, "", STOPPED)
