"""One supervisor's field writes (a Solid's translation/rotation; a robot's customData and controllerArgs), read by
itself and by another supervisor before the step executes them (webots-on-ode.md §6: the write is "queued and executed at the beginning of the next
step", and until then the Solid is where the physics has it; §3.1/§6: a Solid's translation field follows the
physics, so a top-level Solid's translation is its getPosition()).

Only the supervisor that wrote reads its value back (its own request, not yet executed); another supervisor reads
the field as it is: the Solid's current pose, the other fields' values before the write. A rotation write leaves the translation field alone: it still
follows the physics. Supervisor s2 waits a real time before its step, long enough for s1 to read meanwhile (no
timing is asserted: the wait only orders the calls)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

WORLD = """
WorldInfo { basicTimeStep 8 }
DEF BOX Solid { translation 0 0 1 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }
DEF S1 Robot { name "s1" controller "reader" supervisor TRUE }
DEF S2 Robot { name "s2" controller "writer" supervisor TRUE }
"""

READER = """
import time
from controller import Supervisor
supervisor = Supervisor()
box = supervisor.getFromDef("BOX")
for _ in range(5):
    supervisor.step(8)
time.sleep(0.3)  # s2 has written meanwhile, and waits before its step
field, pose = box.getField("translation").getSFVec3f(), box.getPosition()
print("s1 reads the pose:", field == pose, field[0])
supervisor.step(8)
print("s1 reads after the step: x =", box.getField("translation").getSFVec3f()[0])
"""

WRITER = """
import time
from controller import Supervisor
supervisor = Supervisor()
box = supervisor.getFromDef("BOX")
for _ in range(5):
    supervisor.step(8)
pose = box.getPosition()
box.getField("rotation").setSFRotation([0.0, 0.0, 1.0, 0.5])
print("s2 translation after its rotation write is the pose:", box.getField("translation").getSFVec3f() == pose)
box.getField("translation").setSFVec3f([1.0, 0.0, 1.0])
print("s2 reads back", box.getField("translation").getSFVec3f(), box.getField("rotation").getSFRotation())
time.sleep(0.6)
supervisor.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_only_the_writing_supervisor_reads_back_a_pose_write_before_the_step(tmp_path: Path, isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"reader": READER, "writer": WRITER}, isolation)
    # the box fell from z = 1 for 5 steps: its pose is not the load value, so "the pose" is not the field as loaded
    assert lines_of(lines, "s2 ") == ["s2 translation after its rotation write is the pose: True",
                                      "s2 reads back [1.0, 0.0, 1.0] [0.0, 0.0, 1.0, 0.5]"]
    # s1 reads where the box is (x = 0, as loaded: it falls along z); once the step executed the write, x = 1
    assert lines_of(lines, "s1 ") == ["s1 reads the pose: True 0.0", "s1 reads after the step: x = 1.0"]


FIELDS_WORLD = """
WorldInfo { basicTimeStep 8 }
DEF A Robot { name "a" customData "init" controllerArgs [ "x" ] }
DEF S1 Robot { name "s1" controller "fields_reader" supervisor TRUE }
DEF S2 Robot { name "s2" controller "fields_writer" supervisor TRUE }
"""

FIELDS_READER = """
import time
from controller import Supervisor
supervisor = Supervisor()
robot = supervisor.getFromDef("A")
supervisor.step(8)
time.sleep(0.3)  # s2 has written meanwhile, and waits before its step
data, args = robot.getField("customData"), robot.getField("controllerArgs")
print("s1 before the step:", data.getSFString(), args.getCount(), args.getMFString(0))
supervisor.step(8)
print("s1 after the step:", data.getSFString(), args.getCount(), args.getMFString(0))
"""

FIELDS_WRITER = """
import time
from controller import Supervisor
supervisor = Supervisor()
robot = supervisor.getFromDef("A")
supervisor.step(8)
data, args = robot.getField("customData"), robot.getField("controllerArgs")
data.setSFString("fromS2")
args.setMFString(0, "y")
args.insertMFString(-1, "z")
print("s2 reads back:", data.getSFString(), args.getCount(), args.getMFString(0))
time.sleep(0.6)
supervisor.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_another_supervisor_reads_a_field_write_once_a_step_executed_it(tmp_path: Path, isolation: str) -> None:
    # webots-python-api.md Field: "Setters are queued and applied at the next step()"; §6: executed at the beginning
    # of the next step. s2's writes (an SF string, an MF item and an insertion) read back for s2 at once; s1 reads
    # the values as loaded until the step executed them
    lines = run_multi(tmp_path, FIELDS_WORLD, {"fields_reader": FIELDS_READER, "fields_writer": FIELDS_WRITER},
                      isolation)
    assert lines_of(lines, "s2 ") == ["s2 reads back: fromS2 2 y"]
    assert lines_of(lines, "s1 ") == ["s1 before the step: init 1 x", "s1 after the step: fromS2 2 y"]
