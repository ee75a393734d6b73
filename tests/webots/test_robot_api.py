"""Webots' Robot/Supervisor object model (issue 23): plain attributes a subclass may reassign, a runtime that keeps
its state off the user's object, read-only and settable properties, the deprecated getters, device node types as
Webots' integers, and devices built from a name or tag."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import (
    DistanceSensor,
    Keyboard,
    Motion,
    Motor,
    Node,
    PositionSensor,
    Robot,
    Supervisor,
)
from dualtwin.webots.node_types import NODE_TYPE_CONSTANTS, node_type_of
from dualtwin.webots.physics import Simulation
from dualtwin.webots.robot import link_of

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Solid { name "floor" boundingObject Plane { size 20 20 } }
DEF WALL Solid { translation 0.5 0 0.2 name "wall" boundingObject Box { size 0.1 2 0.4 } }
DEF ARM Robot {
  translation 0 0 0.2
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 }
      device [ RotationalMotor { name "m" maxTorque 50 maxVelocity 10 } PositionSensor { name "s" } ]
      endPoint Solid { translation 0 0.3 0 boundingObject Sphere { radius 0.05 } physics Physics { mass 1 } }
    }
    DistanceSensor { name "ds" lookupTable [ 0 0 0, 1 1000 0 ] }
  ]
  controller "<none>"
  supervisor TRUE
  customData "hello"
}
"""


class UserSupervisor(Supervisor):
    """A controller subclass using names a runtime might use for itself."""

    def __init__(self, sim: Simulation) -> None:
        super().__init__(simulation=sim, robot_node=sim.robots[0].node)
        self.keyboard = self.getKeyboard()  # the paper's CartPole2 does this
        self.keyboard.enable(8)
        for name in ("_mode", "_sensors", "_devices", "_runtime", "_sim", "_rec", "_client", "_keyboard",
                     "_link", "_pending_step", "_battery", "_robot"):
            setattr(self, name, f"user's {name}")


def _sim() -> Simulation:
    return Simulation(load_world_text(WORLD))


def test_a_subclass_may_reassign_keyboard_and_use_any_private_name() -> None:
    sup = UserSupervisor(_sim())
    ds = sup.getDevice("ds")
    ds.enable(8)
    motor = sup.getDevice("m")
    motor.setPosition(1.0)
    for _ in range(100):
        assert sup.step(8) != -1
    # the runtime still samples, drives and reports, none of it through the user's attributes
    assert ds.getValue() == pytest.approx(450.0, abs=1.0)  # the wall's face is 0.45 m ahead
    assert sup.getDevice("s") is not None
    assert sup.keyboard.getSamplingPeriod() == 8 and sup.keyboard.getKey() == -1
    assert sup.simulationGetMode() == Supervisor.SIMULATION_MODE_FAST
    assert sup._mode == "user's _mode" and sup._sensors == "user's _sensors"


def test_plain_attributes_are_webots_and_devices_are_built_once() -> None:
    sup = Supervisor(simulation=_sim(), robot_node=None)
    assert set(vars(sup)) >= {"devices", "keyboard", "mouse", "joystick"}
    assert set(sup.devices) == {"m", "s", "ds"}
    assert all(sup.getDevice(name) is device for name, device in sup.devices.items())
    assert isinstance(sup.keyboard, Keyboard) and sup.keyboard.getSamplingPeriod() == 0  # created disabled
    assert sup.getKeyboard() is sup.keyboard and sup.getMouse() is sup.mouse and sup.getJoystick() is sup.joystick
    assert isinstance(Robot.created, Robot)
    # only Webots' attributes and one name-mangled slot live on the object
    assert {k for k in vars(sup) if k.startswith("_")} == {"_Robot__link"}


def test_read_only_properties_refuse_assignment_and_settable_ones_set() -> None:
    sup = Supervisor(simulation=_sim())
    assert sup.name == sup.getName() == "robot"  # the default of the Robot's name field
    with pytest.raises(AttributeError):
        sup.name = "other"  # type: ignore[misc]
    with pytest.raises(AttributeError):
        sup.time = 3.0  # type: ignore[misc]
    sup.custom_data = "set by property"
    assert sup.getCustomData() == "set by property"
    sup.simulation_mode = Supervisor.SIMULATION_MODE_REAL_TIME
    sup.step(8)
    assert sup.simulationGetMode() == Supervisor.SIMULATION_MODE_REAL_TIME
    ds = sup.getDevice("ds")
    ds.sampling_period = 16
    assert ds.getSamplingPeriod() == 16
    sup.keyboard.sampling_period = 8
    assert sup.keyboard.getSamplingPeriod() == 8
    assert sup.basic_time_step == 8.0 and sup.number_of_devices == 3
    motor, sensor = sup.getDevice("m"), sup.getDevice("s")
    motor.target_position = 1.0  # a settable property really sets
    sensor.enable(8)
    for _ in range(200):
        sup.step(8)
    assert motor.getTargetPosition() == 1.0 and sensor.getValue() == pytest.approx(1.0, abs=1e-2)
    with pytest.raises(AttributeError):
        motor.max_velocity = 3.0  # type: ignore[misc]


def test_deprecated_getters_return_the_device_and_say_so(capsys: pytest.CaptureFixture[str]) -> None:
    sup = Supervisor(simulation=_sim())
    assert sup.getMotor("m") is sup.getDevice("m")
    assert sup.getDistanceSensor("ds") is sup.devices["ds"]
    err = capsys.readouterr().err
    assert "DEPRECATION: Robot.getMotor is deprecated, please use Robot.getDevice instead." in err
    assert "Robot.getDistanceSensor is deprecated" in err


def test_device_node_types_are_webots_integers() -> None:
    sup = Supervisor(simulation=_sim())
    assert sup.getDevice("m").getNodeType() == Node.ROTATIONAL_MOTOR == 57
    assert sup.getDevice("s").getNodeType() == Node.POSITION_SENSOR == 52
    assert sup.getDevice("ds").node_type == Node.DISTANCE_SENSOR == 42
    assert sup.getSelf().getType() == Node.ROBOT and sup.getFromDef("WALL").getType() == Node.SOLID


def test_devices_built_from_a_name_or_tag_as_in_webots() -> None:
    sup = Supervisor(simulation=_sim())
    by_name = DistanceSensor("ds")  # Webots: built from a name string, a sensor enables itself at basicTimeStep
    assert by_name.getSamplingPeriod() == 8 and by_name is not sup.devices["ds"]
    sup.step(8)
    assert math.isfinite(by_name.getValue())
    tag = sup.devices["m"]._tag
    assert Motor(tag).getName() == "m" and sup.getFromDevice(tag).getBaseTypeName() == "RotationalMotor"
    sensor = PositionSensor(sup.devices["s"]._tag)
    assert sensor.getSamplingPeriod() == 0  # a tag-built sensor is not enabled


def test_handles_on_one_device_share_its_state_as_in_webots() -> None:
    """Webots' controller library keeps a device's state per device: enabling it through a handle built by name
    enables the robot's own handle too, and both read the same values (sampled once per step)."""
    sup = Supervisor(simulation=_sim())
    own = sup.devices["ds"]
    assert own.getSamplingPeriod() == 0
    by_name = DistanceSensor("ds")
    assert by_name is not own and own.getSamplingPeriod() == 8
    sup.step(8)
    assert math.isfinite(own.getValue()) and own.getValue() == by_name.getValue()
    by_tag = DistanceSensor(own._tag)  # built from a tag: no enable of its own, the device's state
    assert by_tag.getSamplingPeriod() == 8 and by_tag.getValue() == own.getValue()
    by_tag.disable()
    assert own.getSamplingPeriod() == 0 and by_name.getSamplingPeriod() == 0
    assert list(link_of(sup)._sensors.values()) == []  # nothing left to sample


def test_webots_answers_without_a_gui() -> None:
    sup = Supervisor(simulation=_sim())
    assert sup.getSelected() is None
    assert sup.wwiReceiveText() is None
    assert sup.waitForUserInputEvent(Robot.EVENT_KEYBOARD, 100) == Robot.EVENT_NO_EVENT
    assert sup.mouse.getState().left is False and math.isnan(sup.mouse.getState().u)
    assert sup.joystick.isConnected() is False and sup.joystick.getPressedButton() == -1
    assert sup.getMode() == Robot.MODE_SIMULATION
    assert sup.movieIsReady() and not sup.movieFailed()


def test_step_begin_and_end_split_one_step() -> None:
    sup = Supervisor(simulation=_sim())
    assert sup.stepBegin(16) == 0
    assert sup.getTime() == 0.0  # nothing ran yet
    assert sup.stepEnd() == 0
    assert sup.getTime() == pytest.approx(0.016)


def test_keyboard_get_key_spells_keys_as_webots() -> None:
    sup = Supervisor(simulation=_sim())
    kb = sup.keyboard
    kb.enable(8)
    kb._keys = [Keyboard.SHIFT | ord("A"), Keyboard.UP, Keyboard.ALT | ord("X")]
    assert [kb.get_key(), kb.get_key(), kb.get_key(), kb.get_key()] == ["shift-a", "up", "alt-x", ""]


def test_node_constants_are_the_table_getnodetype_uses() -> None:
    assert {name: getattr(Node, name) for name in NODE_TYPE_CONSTANTS} == NODE_TYPE_CONSTANTS
    assert node_type_of("Pose") == 26 and node_type_of("Hinge2Joint") == Node.HINGE_2_JOINT


def test_motion_file_drives_the_motors(tmp_path: Path) -> None:
    path = tmp_path / "turn.motion"
    path.write_text("#WEBOTS_MOTION,V1.0,m,unknown\n00:00:000,Pose1,0,0\n00:00:800,Pose2,0.8,*\n")
    sup = Supervisor(simulation=_sim())
    sensor = sup.getDevice("s")
    sensor.enable(8)
    motion = Motion(str(path))
    assert motion.isValid() and motion.getDuration() == 800 and not motion.isOver()
    motion.play()
    for _ in range(150):
        sup.step(8)
    assert motion.isOver() and motion.getTime() == 800
    assert sensor.getValue() == pytest.approx(0.8, abs=1e-2)  # the last pose, reached by interpolation
    assert not Motion(str(tmp_path / "missing.motion")).isValid()
