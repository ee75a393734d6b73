"""TouchSensor: a box resting on a bumper / force plate reads what statics says (Webots' semantics)."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

G = 9.81
BOX_MASS = 2.0
PLATE_MASS = 0.1


def _world(sensor_type: str, table: str = "[ ]", robot_physics: str = "", box_z: float = 0.06) -> Supervisor:
    # the plate's x axis points up (rotation about y by -π/2), its 2 cm thickness along x
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 4 }}
Solid {{ name "floor" boundingObject Plane {{ size 5 5 }} }}
DEF BOX Solid {{ translation 0 0 {box_z} name "box" boundingObject Box {{ size 0.1 0.1 0.1 }}
  physics Physics {{ mass {BOX_MASS} }} }}
Robot {{ supervisor TRUE {robot_physics}
  children [
    TouchSensor {{ name "plate" type "{sensor_type}" translation 0 0 0 rotation 0 1 0 -1.5708
      lookupTable {table} boundingObject Box {{ size 0.02 0.3 0.3 }} physics Physics {{ mass {PLATE_MASS} }} }}
  ]
}}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _settle(sup: Supervisor, name: str, seconds: float = 1.0) -> object:
    dev = sup.getDevice(name)
    dev.enable(4)
    for _ in range(int(seconds / 0.004)):
        sup.step(4)
    return dev


def test_force_plate_reads_the_weight_it_carries() -> None:
    plate = _settle(_world("force"), "plate")
    # the fixed joint carries the box and the plate itself
    assert plate.getValue() == pytest.approx((BOX_MASS + PLATE_MASS) * G, rel=0.01)


def test_force_plate_lookup_table_and_resolution() -> None:
    plate = _settle(_world("force", table="[ 0 0 0, 100 1000 0 ]"), "plate")
    assert plate.getValue() == pytest.approx(10 * (BOX_MASS + PLATE_MASS) * G, rel=0.01)


def test_force_3d_in_the_sensor_frame() -> None:
    plate = _settle(_world("force-3d"), "plate")
    fx, fy, fz = plate.getValues()
    # the push onto the robot is along the sensor's -x; the sideways components vanish at rest
    assert fx == pytest.approx(-(BOX_MASS + PLATE_MASS) * G, rel=0.01)
    assert abs(fy) < 0.01 and abs(fz) < 0.01
    assert math.isnan(plate.getValue())  # getValue is not for force-3d


def test_force_plate_on_a_dynamic_robot_pushed_with_a_known_force() -> None:
    # the robot is a heavy slab resting on the floor; the plate has its own body fixed to it
    sup = _world(
        "force",
        robot_physics="translation 0 0 0.03 boundingObject Pose { translation 0 0 -0.02 children [ "
        "Box { size 0.4 0.4 0.02 } ] } physics Physics { mass 5 }",
        box_z=0.09,
    )
    plate = _settle(sup, "plate")
    assert plate.getValue() == pytest.approx((BOX_MASS + PLATE_MASS) * G, rel=0.01)
    box = sup.getFromDef("BOX")
    push = 15.0
    for _ in range(100):
        box.addForce([0.0, 0.0, -push], False)
        sup.step(4)
    assert plate.getValue() == pytest.approx((BOX_MASS + PLATE_MASS) * G + push, rel=0.01)


def test_bumper_flags_contact_since_the_last_sample() -> None:
    # the plate floats 0.1 m above the floor (a floor contact would count too), the box 0.45 m above it
    sup = _world("bumper", robot_physics="translation 0 0 0.1", box_z=0.6)
    bumper = sup.getDevice("plate")
    bumper.enable(4)
    assert math.isnan(bumper.getValue())
    sup.step(4)
    assert bumper.getValue() == 0.0  # falling, nothing touches yet
    readings = []
    for _ in range(150):
        sup.step(4)
        readings.append(bumper.getValue())
    assert readings[-1] == 1.0  # resting on the plate
    assert readings[0] == 0.0 and set(readings) == {0.0, 1.0}
    # a long sampling period still reports the contacts of every step in between
    bumper.enable(400)
    sup.step(400)
    assert bumper.getValue() == 1.0


def test_force_sensor_without_physics_reads_lookup_zero() -> None:
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 4 }
Robot { supervisor TRUE children [ TouchSensor { name "t" type "force" lookupTable [ 0 3 0, 10 13 0 ] } ] }
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    dev = sup.getDevice("t")
    dev.enable(4)
    sup.step(4)
    assert dev.getValue() == 3.0
    assert dev.getType() == dev.FORCE


SENSOR_MASS = 2.0
_SENSOR = ('DEF T TouchSensor {{ name "t" type "{type}" translation 0.2 0 0 {rotation} lookupTable [ ] '
           'boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ mass 2 }} }}')
_HOLDERS = {
    "fixed": "{sensor}",  # a child Solid: Webots fixes it to its parent (webots-devices.md §2.2)
    "slider endPoint": "SliderJoint {{ jointParameters JointParameters {{ axis 1 0 0 }} endPoint {sensor} }}",
    "hinge endPoint": "HingeJoint {{ jointParameters HingeJointParameters {{ axis 1 0 0 }} endPoint {sensor} }}",
}


def _held(holder: str, sensor_type: str, rotation: str = "") -> Supervisor:
    sensor = _SENSOR.format(type=sensor_type, rotation=rotation)
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
Robot {{ translation 0 0 0.5 supervisor TRUE children [ {_HOLDERS[holder].format(sensor=sensor)} ] }}
"""
    return Supervisor(simulation=Simulation(load_world_text(text)), robot_node=None)


@pytest.mark.parametrize("holder", list(_HOLDERS))
def test_a_force_sensor_at_the_end_of_a_joint_reads_what_its_joint_carries(
    holder: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # webots-devices.md §2.2-2.3: with Physics the sensor has its own body (never merged) and reads f1, the force
    # that what holds it applies to its parent. A joint's endPoint has no fixed joint: the joint holds it (the
    # reference is silent on this case), and it warned "needs Physics" and read lookup(0) = 0. The robot has no
    # Physics (static) and both joints' axes are horizontal through the sensor's centre, so the holder carries its
    # weight alone: f1 = (0, 0, -m g) = (0, 0, -2 × 9.81) = (0, 0, -19.62) N, pressing down on the robot.
    # force-3d with an empty table (raw newtons), sensor unrotated: R_sensorᵀ·f1 = (0, 0, -19.62).
    sup = _held(holder, "force-3d")
    values = _settle(sup, "t", 0.1).getValues()
    assert values == pytest.approx([0.0, 0.0, -SENSOR_MASS * G], rel=1e-3, abs=1e-3)
    # force: the sensor's x axis turned up (rotation about y by -π/2: x̂ = (0, 0, 1)), p = x̂·f1 = -19.62 < 0, so
    # the input is the push -p = 19.62 N
    sup = _held(holder, "force", "rotation 0 1 0 -1.5707963267948966")
    assert _settle(sup, "t", 0.1).getValue() == pytest.approx(SENSOR_MASS * G, rel=1e-3)
    assert "needs Physics" not in capsys.readouterr().err


@pytest.mark.parametrize("touch_first", [True, False])
def test_the_joint_force_is_read_alongside_the_motor_force_feedback(touch_first: bool) -> None:
    # ODE keeps one feedback buffer per joint, which Motor.enableForceFeedback also sets: the sensor reads through
    # whichever the joint has, in either order. A vertical slider whose motor holds the sensor carries its weight
    # along its axis: f1 = (0, 0, -2 × 9.81) N as above.
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { translation 0 0 0.5 supervisor TRUE children [
  SliderJoint { jointParameters JointParameters { axis 0 0 1 } device [ LinearMotor { name "m" maxForce 100 } ]
    endPoint TouchSensor { name "t" type "force-3d" translation 0.2 0 0 lookupTable [ ]
      boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 2 } } } ] }
"""
    sup = Supervisor(simulation=Simulation(load_world_text(text)), robot_node=None)
    touch, motor = sup.getDevice("t"), sup.getDevice("m")
    for enable in ((touch.enable, motor.enableForceFeedback) if touch_first
                   else (motor.enableForceFeedback, touch.enable)):
        enable(8)
    for _ in range(20):
        sup.step(8)
    assert touch.getValues() == pytest.approx([0.0, 0.0, -SENSOR_MASS * G], rel=1e-3, abs=1e-3)
