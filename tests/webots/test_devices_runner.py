"""Unchanged Webots controllers use the new devices through the runner: two robots talk over a radio while one
reads a distance sensor and a lidar and the other draws on its display."""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Solid { translation 1.05 0 0.1 children [ Shape { geometry DEF WALL Box { size 0.1 2 1 } } ] boundingObject USE WALL }
Robot {
  name "sender"
  translation 0 0 0.1
  children [
    Emitter { name "radio" channel 5 }
    DistanceSensor { name "front" lookupTable [ 0 0 0, 2 2000 0 ] }
    Lidar { name "lidar" horizontalResolution 5 fieldOfView 0.5 numberOfLayers 1 maxRange 3 }
  ]
  controller "sender"
}
Robot {
  name "listener"
  translation 0 3 0.1
  children [
    Receiver { name "radio" channel 5 }
    Display { name "screen" width 8 height 4 }
  ]
  controller "listener"
}
"""

SENDER = """
from controller import Robot
robot = Robot()
ds = robot.getDevice("front")
lidar = robot.getDevice("lidar")
radio = robot.getDevice("radio")
ds.enable(8)
lidar.enable(8)
robot.step(8)
radio.send(f"{ds.getValue():.1f}")
centre = lidar.getRangeImage()[2]
robot.step(8)
print(f"sender front={ds.getValue():.1f} lidar={centre:.3f}")
"""

LISTENER = """
from controller import Robot, Display
robot = Robot()
radio = robot.getDevice("radio")
screen = robot.getDevice("screen")
radio.enable(8)
got = []
for _ in range(4):
    robot.step(8)
    while radio.getQueueLength() > 0:
        got.append((radio.getString(), round(radio.getSignalStrength(), 4)))
        radio.nextPacket()
screen.setColor(0x00FF00)
screen.fillRectangle(0, 0, 4, 4)
screen.imageSave(None, PNG_PATH)
print(f"listener got={got}")
"""


def test_controllers_use_radio_ranging_and_display(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "worlds").mkdir()
    png = tmp_path / "screen.png"
    (tmp_path / "worlds" / "devices.wbt").write_text(WORLD)
    # an absolute path: the runner gives all controllers one working directory (the first one's folder)
    listener = LISTENER.replace("PNG_PATH", repr(str(png)))
    for name, script in (("sender", SENDER), ("listener", listener)):
        (tmp_path / "controllers" / name).mkdir(parents=True)
        (tmp_path / "controllers" / name / f"{name}.py").write_text(script)
    assert run_world(tmp_path / "worlds" / "devices.wbt", duration_s=0.2) == 0
    out = capsys.readouterr().out
    assert "sender front=1000.0 lidar=1.000" in out  # the wall's face is 1 m ahead
    assert "listener got=[('1000.0', 0.1111)]" in out  # 3 m apart: 1/9
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
