"""A PROTO robot's interface fields read by a supervisor while the robot's own controller changes the fields they
are bound to (webots-on-ode.md §7.1: ``<nodeField> IS <protoField>`` binds the body's field to the interface field;
webots-python-api.md Robot: setCustomData writes Robot.customData; webots-devices.md §5.3 and emitter.md:
Emitter.setChannel modifies the node's channel field). Bound, they are one value: Webots passes a change made
inside the instance up to the PROTO's field (most robots are PROTOs whose ``customData IS customData``, the
field a robot and a supervisor exchange data through), as it passes a supervisor's write of the PROTO's field
down to the body.

The supervisor reads after two steps of its own: the robot's commands went with its first step."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi

BOT = """
#VRML_SIM R2023b utf8
PROTO Bot [
  field SFString botName "bot"
  field SFString controller "<generic>"
  field SFString customData ""
  field SFInt32 radioChannel 0
]
{
  Robot {
    name IS botName
    controller IS controller
    customData IS customData
    children [ Emitter { name "tx" channel IS radioChannel } ]
  }
}
"""

WORLD = """
EXTERNPROTO "../protos/Bot.proto"
WorldInfo { basicTimeStep 8 }
DEF A Bot { botName "a" controller "bot" customData "init" radioChannel 2 }
DEF S Robot { name "s" controller "reader" supervisor TRUE }
"""

ROBOT = """
from controller import Robot
robot = Robot()
robot.setCustomData("fromA")
robot.getDevice("tx").setChannel(3)
robot.step(8)
robot.step(8)
robot.step(8)
print("a reads", robot.getCustomData())
"""

READER = """
from controller import Supervisor
supervisor = Supervisor()
bot = supervisor.getFromDef("A")
supervisor.step(8)
supervisor.step(8)
print("s reads", bot.getField("customData").getSFString(), bot.getField("radioChannel").getSFInt32(),
      bot.getField("botName").getSFString())
bot.getField("customData").setSFString("fromS")
print("s reads back", bot.getField("customData").getSFString())
supervisor.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_proto_robots_interface_fields_follow_what_its_controller_set(tmp_path: Path, isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"bot": ROBOT, "reader": READER}, isolation, protos={"Bot": BOT})
    # botName: a bound field nothing changed (control); the write of the PROTO's field reads back and reaches the
    # robot with the step it is applied in (its third step, 16 -> 24 ms)
    assert lines_of(lines, "s ") == ["s reads fromA 3 a", "s reads back fromS"]
    assert lines_of(lines, "a ") == ["a reads fromS"]


SAVER = """
from controller import Supervisor
supervisor = Supervisor()
supervisor.step(8)
supervisor.step(8)
supervisor.worldSave(supervisor.getCustomData())
"""


def test_world_save_writes_the_proto_field_the_robot_changed(tmp_path: Path) -> None:
    saved = tmp_path / "saved.wbt"
    world = WORLD.replace('controller "reader" supervisor TRUE', f'controller "saver" supervisor TRUE customData "{saved}"')
    run_multi(tmp_path / "run", world, {"bot": ROBOT, "saver": SAVER}, "threads", protos={"Bot": BOT})
    # Webots saves the fields' current values: the PROTO's customData and radioChannel the robot set; botName,
    # unchanged, as loaded (control)
    text = saved.read_text()
    bot = text[text.index("DEF A Bot {"):text.index("}", text.index("DEF A Bot {"))]
    assert 'customData "fromA"' in bot and "radioChannel 3" in bot and 'botName "a"' in bot
