"""A controller behaves the same run in its own process (the default, as Webots runs it) as run in a thread of the
runner (``isolation="threads"``, the real API classes): each test runs one script on one world in both modes and
asserts the same output and exit code, and what Webots' Python API says (webots-python-api.md)."""

from __future__ import annotations

from pathlib import Path

from tests.support.isolation_runs import run_in_both_modes

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF ME Robot {
  supervisor TRUE
  controller "probe"
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 }
      device [ RotationalMotor { name "rm" } PositionSensor { name "ps" } ]
      endPoint Solid { translation 0.3 0 0 boundingObject Sphere { radius 0.05 } physics Physics { } }
    }
    GPS { name "gps" }
  ]
}
"""


def test_robot_devices_is_the_name_to_device_dict_of_getdevice(tmp_path: Path) -> None:
    """webots-python-api.md, Robot: ``devices`` is a plain attribute, name -> device object, filled once in
    __init__, and ``getDevice`` returns that same (cached) object. A controller process had no ``devices`` at all
    (only attributes of plain data or single API objects were copied to the child, not a dict of devices)."""
    script = """
        from controller import Robot
        robot = Robot()
        print(sorted(robot.devices))
        print(all(robot.devices[name] is robot.getDevice(name) for name in robot.devices))
        print(type(robot.devices["rm"]).__name__, robot.devices["gps"].getName())
    """
    runs = run_in_both_modes(tmp_path, WORLD, script, 0.016)
    expected = "['gps', 'ps', 'rm']\nTrue\nMotor gps\n"
    assert runs["threads"] == (expected, "", 0)
    assert runs["process"] == runs["threads"]
