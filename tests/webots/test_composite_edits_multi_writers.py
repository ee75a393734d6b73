"""Two supervisors write the same device and motor fields in one step: the writes of a step are executed at the
beginning of the next one "in scene-tree order of supervisors" (webots-on-ode.md §6), so the one later in the tree
gives the value every controller reads after the step, whichever call reached the simulation first. Until the step
each writer reads back its own value (the rule of tests/webots/test_composite_multi_pending_writes.py).

The translation writes of this rule are tested in test_composite_supervisor_order.py; here an Emitter's channel (a
device field, D §5) and a RotationalMotor's maxVelocity. Each supervisor waits a given real time (its customData)
before its write, so the two runs differ only in which write arrives first (no timing is asserted)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

WORLD = """
WorldInfo {{ basicTimeStep 8 }}
Robot {{ name "a" controller "reader" children [
  DEF TX Emitter {{ name "tx" }}
  HingeJoint {{ device [ DEF M RotationalMotor {{ name "m" }} ] endPoint Solid {{ translation 0 0 0.3 }} }}
] }}
Robot {{ name "s1" controller "writer" supervisor TRUE customData "5 {s1}" }}
Robot {{ name "s2" controller "writer" supervisor TRUE customData "7 {s2}" }}
"""

READER = """
from controller import Robot
robot = Robot()
tx, motor = robot.getDevice("tx"), robot.getDevice("m")
while robot.step(8) != -1:
    if robot.getTime() > 0.03:
        print(f"a at {robot.getTime() * 1000:.0f} ms: channel {tx.getChannel()} maxVelocity {motor.getMaxVelocity():g}")
"""

WRITER = """
import time
from controller import Supervisor
supervisor = Supervisor()
value, delay = supervisor.getCustomData().split()
name = supervisor.getName()
steps = 0
while supervisor.step(8) != -1:
    steps += 1
    channel = supervisor.getFromDef("TX").getField("channel")
    if steps == 2:
        time.sleep(float(delay))  # real time only: the simulation waits for every controller
        channel.setSFInt32(int(value))
        supervisor.getFromDef("M").getField("maxVelocity").setSFFloat(float(value))
        print(f"{name} after its write reads {channel.getSFInt32()}")
    if steps == 4:
        print(f"{name} after the step reads {channel.getSFInt32()}")
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
@pytest.mark.parametrize("delays", [(0.0, 0.4), (0.4, 0.0)], ids=["first_writes_first", "last_writes_first"])
def test_the_supervisor_later_in_the_tree_gives_the_field_its_value(
        tmp_path: Path, isolation: str, delays: tuple[float, float]) -> None:
    world = WORLD.format(s1=delays[0], s2=delays[1])
    lines = run_multi(tmp_path, world, {"reader": READER, "writer": WRITER}, isolation, duration_s=0.05)
    # s1 is first in the scene tree and writes 5, s2 writes 7 after it: channel 7 and maxVelocity 7 from the step
    # that executed them (16 -> 24 ms) on, for the robot and both supervisors; before it each writer reads its own
    assert sorted(lines_of(lines, "s")) == ["s1 after its write reads 5", "s1 after the step reads 7",
                                            "s2 after its write reads 7", "s2 after the step reads 7"]
    assert lines_of(lines, "a ") == [f"a at {t} ms: channel 7 maxVelocity 7" for t in (32, 40, 48)]
