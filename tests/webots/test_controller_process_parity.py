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


CONTACT_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF FLOOR Solid { name "floor" boundingObject Plane { } }
DEF BALL Solid {
  translation 0 0 0.049
  boundingObject Sphere { radius 0.05 }
  physics Physics { }
}
Robot { supervisor TRUE controller "probe" }
"""


def test_a_value_getter_called_with_arguments_raises_pythons_type_error(tmp_path: Path) -> None:
    """ContactPoint.getPoint takes no argument (webots-python-api.md, ContactPoint: ``getPoint ()``): calling it
    with one is Python's own TypeError for the method. A controller process raised NotImplementedError ('not
    available in a controller process') instead."""
    script = """
        from controller import Supervisor
        sup = Supervisor()
        ball = sup.getFromDef("BALL")
        ball.enableContactPointsTracking(8)
        sup.step(8)
        sup.step(8)
        point = ball.getContactPoints()[0]
        for args in ((), (1,)):
            try:
                point.getNodeId(*args)
                print("ok")
            except Exception as exc:
                print(type(exc).__name__, exc)
    """
    runs = run_in_both_modes(tmp_path, CONTACT_WORLD, script, 0.032)
    # Python's words for a one-parameter method (self) given a second positional argument
    expected = "ok\nTypeError ContactPoint.getNodeId() takes 1 positional argument but 2 were given\n"
    assert runs["threads"] == (expected, "", 0)
    assert runs["process"] == runs["threads"]
