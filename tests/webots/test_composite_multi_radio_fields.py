"""An Emitter's channel and range and a Receiver's channel set by one robot's controller, read by a supervisor as
fields and by the robot's restarted controller (webots-devices.md §5.1 fields, §5.3 setChannel/setRange: a range
above ``maxRange`` is clipped to it; emitter.md and receiver.md: setChannel "modifies the channel field of the
corresponding node", and Webots keeps the emitter's range in its field the same way; webots-python-api.md Node:
restartController starts a fresh controller, whose library reads the devices' fields when it connects).

The supervisor reads after two steps of its own: the robot's commands went with its first step, so they have been
applied whichever controller ran first."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

WORLD = """
WorldInfo { basicTimeStep 8 }
DEF A Robot { name "a" controller "radio" children [
  DEF TX Emitter { name "tx" range 3 maxRange 2.5 }
  DEF RX Receiver { name "rx" }
] }
DEF B Robot { name "b" controller "<none>" children [ DEF OTHER Receiver { name "rx" channel 4 } ] }
DEF S Robot { name "s" controller "reader" supervisor TRUE }
"""

RADIO = """
from controller import Robot
robot = Robot()
tx, rx = robot.getDevice("tx"), robot.getDevice("rx")
print("a starts with", tx.getChannel(), tx.getRange(), rx.getChannel())
if robot.getCustomData() == "":
    robot.setCustomData("configured")
    tx.setChannel(5)
    tx.setRange(4.0)
    rx.setChannel(-1)
while robot.step(8) != -1:
    pass
"""

READER = """
from controller import Supervisor
supervisor = Supervisor()
supervisor.step(8)
supervisor.step(8)
tx, rx, other = (supervisor.getFromDef(name) for name in ("TX", "RX", "OTHER"))
print("s reads", tx.getField("channel").getSFInt32(), tx.getField("range").getSFFloat(),
      rx.getField("channel").getSFInt32(), other.getField("channel").getSFInt32())
supervisor.getFromDef("A").restartController()
supervisor.step(8)
supervisor.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_channel_and_range_set_by_a_controller_are_the_device_fields(tmp_path: Path, isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"radio": RADIO, "reader": READER}, isolation, duration_s=0.05)
    # range 4 is clipped to maxRange 2.5 (the load value 3 too); channel -1 (all channels) is a valid channel.
    # Control: B's receiver, which no controller changed, keeps its channel 4
    assert lines_of(lines, "s ") == ["s reads 5 2.5 -1 4"]
    assert lines_of(lines, "a ") == ["a starts with 0 2.5 0", "a starts with 5 2.5 -1"]


RESET_RADIO = """
from controller import Robot
robot = Robot()
tx, rx = robot.getDevice("tx"), robot.getDevice("rx")
tx.setChannel(5)
rx.setChannel(-1)
robot.step(8)
robot.step(8)
robot.step(8)
print("a after the reset", tx.getChannel(), rx.getChannel())
while robot.step(8) != -1:
    pass
"""

RESET_READER = """
from controller import Supervisor
supervisor = Supervisor()
supervisor.step(8)
supervisor.simulationReset()
supervisor.step(8)
supervisor.step(8)
tx, rx = (supervisor.getFromDef(name) for name in ("TX", "RX"))
print("s after the reset", tx.getField("channel").getSFInt32(), rx.getField("channel").getSFInt32())
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_reset_gives_the_devices_the_channels_their_restored_fields_hold(tmp_path: Path, isolation: str) -> None:
    # simulationReset restores every field to its load value (webots-on-ode.md §6, the rule the twin follows for all
    # fields), the channels that setChannel wrote there too: the devices go by the restored fields, 0 and 0, as the
    # supervisor reads them, and not by the channels set before the reset (the device and its field disagreed:
    # getChannel 5 and -1 while the fields read 0 and 0)
    lines = run_multi(tmp_path, WORLD, {"radio": RESET_RADIO, "reader": RESET_READER}, isolation, duration_s=0.05)
    assert lines_of(lines, "s ") == ["s after the reset 0 0"]
    assert lines_of(lines, "a ") == ["a after the reset 0 0"]
