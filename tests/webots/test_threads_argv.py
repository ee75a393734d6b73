"""The threads runtime gives each controller ``sys.argv = [script, *controllerArgs]`` (shared by all, as its docs
say) and must give the caller of ``run_world`` its own ``sys.argv`` back. Each thread restored the argv it found when
it started, which could be another controller's: with A ending at its first step and B later, B put back A's argv,
and a script calling ``run_world`` twice saw the controllers' arguments in place of its own."""

from __future__ import annotations

import sys
from pathlib import Path

from tests.support.multi_worlds import run_multi

WORLD = """
WorldInfo { basicTimeStep 8 }
Robot { name "a" controller "quick" controllerArgs [ "--from-a" ] }
Robot { name "b" controller "slow" controllerArgs [ "--from-b" ] }
"""

QUICK = """
import sys
from controller import Robot
robot = Robot()
print("a", sys.argv[1:])
robot.step(8)
"""

SLOW = """
from controller import Robot
robot = Robot()
for _ in range(20):
    robot.step(8)
"""


def test_the_callers_argv_is_back_after_a_threads_run(tmp_path: Path) -> None:
    before = list(sys.argv)
    for attempt in range(5):  # (the threads start in turn: one of the orders is enough to lose it)
        # (what A reads may be B's arguments: the threads share sys.argv, the documented limit of this mode)
        lines = run_multi(tmp_path / str(attempt), WORLD, {"quick": QUICK, "slow": SLOW}, "threads", duration_s=0.2)
        assert len(lines) == 1 and lines[0].startswith("a ['--from-")
        assert sys.argv == before
