"""Several controllers writing and reading, in the same steps, fields that another robot's devices and getters
depend on: what each prints is the same whichever request reaches the simulation first in real time.

S = shared/reference/webots-on-ode.md. S §6: a supervisor's write is "queued and executed at the beginning of the
next step", the writes of one step in the supervisors' scene-tree order, and a controller sees the world through
its steps ("Robot.step ... returns with sensor values updated"). So a robot reading a getter of its own device
(a DistanceSensor's lookup table, a motor's maxVelocity, an Emitter's channel) between a supervisor's write of the
field and the step that executes it reads the value before the write; from that step on, the new one. Expected
values are hand computations (shown), never runs of this code."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.multi_worlds import lines_of, run_multi
from tests.support.stress_worlds import run_stress

WORLD = """
WorldInfo { basicTimeStep 8 }
DEF R1 Robot {
  name "r1" controller "reader"
  children [
    DEF DS DistanceSensor { name "ds" lookupTable [ 0 0 0, 0.1 1000 0 ] }
    HingeJoint {
      device [ DEF M RotationalMotor { name "m" maxVelocity 10 maxTorque 5 minPosition -1 maxPosition 1 } ]
      endPoint Solid { }
    }
    DEF EM Emitter { name "em" channel 1 }
  ]
}
DEF S1 Robot { name "s1" controller "writer" supervisor TRUE }
"""

# r1 waits a real time after its step, long enough for s1 to write meanwhile: the wait only provokes the order in
# which a getter read before the executing step would see the write; the result must not depend on it
READER = """
import time
from controller import Robot
robot = Robot()
ds, m, em = robot.getDevice("ds"), robot.getDevice("m"), robot.getDevice("em")
def show(when):
    print("r1", when, f"t={robot.getTime():.3f}", ds.getLookupTable(), ds.getMaxValue(), m.getMaxVelocity(),
          m.getMaxTorque(), m.getMinPosition(), m.getMaxPosition(), m.getMultiplier(), em.getChannel())
robot.step(8)
time.sleep(0.3)
show("before")
robot.step(8)
show("after")
"""

WRITER = """
from controller import Supervisor
sup = Supervisor()
sup.step(8)
sup.getFromDef("DS").getField("lookupTable").setMFVec3f(1, [1.0, 3000.0, 0.0])
motor = sup.getFromDef("M")
for name, value in (("maxVelocity", 4.0), ("maxTorque", 2.0), ("minPosition", -0.5), ("maxPosition", 0.5),
                    ("multiplier", 2.0)):
    motor.getField(name).setSFFloat(value)
sup.getFromDef("EM").getField("channel").setSFInt32(7)
print("s1 wrote")
sup.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_robots_getters_follow_a_supervisors_write_from_the_step_that_executes_it(tmp_path: Path,
                                                                                      isolation: str) -> None:
    lines = run_multi(tmp_path, WORLD, {"reader": READER, "writer": WRITER}, isolation)
    assert lines_of(lines, "s1") == ["s1 wrote"]
    # before (t = 0.008, the write not executed yet): the load values; max value = the largest output, 1000
    # (webots-devices.md §0.3). After the step to 0.016, which executed it: the table [0 0 0, 1 3000 0] (max 3000)
    # and the motor's and emitter's written fields
    assert lines_of(lines, "r1") == [
        "r1 before t=0.008 [0.0, 0.0, 0.0, 0.1, 1000.0, 0.0] 1000.0 10.0 5.0 -1.0 1.0 1.0 1",
        "r1 after t=0.016 [0.0, 0.0, 0.0, 1.0, 3000.0, 0.0] 3000.0 4.0 2.0 -0.5 0.5 2.0 7",
    ]


def _r1(time: str, row: tuple[float, float], max_velocity: float, channel: int, value: int) -> str:
    """r1's line of the stress world (tests/support/stress_worlds.py) when the table's last row is ``row`` and no
    write comes between its two reads: the ray (as long as the last input) hits nothing, so the sample reads the
    last output, ``value`` (webots-devices.md §0.3)."""
    table = [0.0, 0.0, 0.0, row[0], row[1], 0.0]
    reads = f"table={table} maxVelocity={max_velocity} channel={channel}"
    return (f"r1 t={time} custom='' table={table} max={row[1]} value={value} maxVelocity={max_velocity} "
            f"channel={channel} {reads} custom=''")


def test_the_stress_world_prints_the_same_in_every_run_and_mode(tmp_path: Path) -> None:
    # three process runs and one threads run, each controller waiting random real times before its calls
    runs = [run_stress(tmp_path / f"p{k}", "process") for k in range(3)] + [run_stress(tmp_path / "t", "threads")]
    assert all(run == runs[0] for run in runs)
    lines = runs[0]
    # the writes of step i (made after the step to t = 0.008·(i+1)) are executed by the step to 0.008·(i+2), which
    # r1 reads after: at 0.016 those of i = 0 (row [0.1 + 0, 1000·1], maxVelocity 10 + 0, channel 10 + 0), at 0.024
    # those of i = 1 (row [1.1, 2000], 11, 11); the sample of that step uses the executed table too
    r1 = lines_of(lines, "r1 ")
    assert r1[1] == _r1("0.016", (0.1, 1000.0), 10.0, 10, 1000)
    assert r1[2] == _r1("0.024", (1.1, 2000.0), 11.0, 11, 2000)
    # r1 sends its loop index after reading, on the channel executed then: 9 + i for i >= 1 (channel 1 at i = 0), so
    # 13 at i = 4, sent after the step to 0.040; r3 (channel 13) receives it with its next step, at 0.048, only then
    heard = [line for line in lines_of(lines, "r3 ") if "heard" in line]
    assert heard == ["r3 t=0.048 custom='' heard=4 custom=''"]
    # r2's customData: s2 is after s1 in the scene tree, so its write of step i wins, read from the step to
    # 0.008·(i+2) on (S §6, scene-tree order)
    assert lines_of(lines, "r2 t=0.024") == ["r2 t=0.024 custom='s2-1' channel=21 channel=21 custom='s2-1'"]


MOTOR_WORLD = """
WorldInfo { basicTimeStep 8 gravity 0 }
DEF R1 Robot {
  name "r1" controller "commander"
  children [
    HingeJoint {
      device [ DEF M RotationalMotor { name "m" } PositionSensor { name "ps" } ]
      endPoint Solid { physics Physics { density -1 mass 1 } boundingObject Sphere { radius 0.05 } }
    }
  ]
}
DEF S1 Robot { name "s1" controller "configurer" supervisor TRUE }
"""

# r1 waits a real time before its command, long enough for s1 to write meanwhile (only to provoke that order)
COMMANDER = """
import time
from controller import Robot
robot = Robot()
m, ps = robot.getDevice("m"), robot.getDevice("ps")
ps.enable(8)
m.setPosition(float("inf"))
m.setVelocity(0.0)
robot.step(8)
time.sleep(0.3)
m.setVelocity(1.5)
print("r1 before", m.getMaxVelocity(), m.getMultiplier())
robot.step(8)
print("r1 after", m.getMaxVelocity(), m.getMultiplier(), f"{ps.getValue() / 0.008:.2f}")
"""

CONFIGURER = """
from controller import Supervisor
sup = Supervisor()
sup.step(8)
sup.getFromDef("M").getField("maxVelocity").setSFFloat(2.0)
sup.getFromDef("M").getField("multiplier").setSFFloat(2.0)
sup.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_motor_command_in_the_step_of_a_supervisors_write_uses_the_configuration_before_it(tmp_path: Path,
                                                                                              isolation: str) -> None:
    lines = run_multi(tmp_path, MOTOR_WORLD, {"commander": COMMANDER, "configurer": CONFIGURER}, isolation)
    # S §6: the writes (maxVelocity 2, multiplier 2) are executed at the beginning of the step to 0.016, after the
    # commands sent for it: setVelocity(1.5) is multiplied by 1 within maxVelocity 10 (webots-devices.md §9), then
    # the new maxVelocity 2 leaves 1.5 as it is. Whichever came first, the joint turns at 1.5 rad/s in that step: its
    # angle at 0.016 is 1.5·0.008 (the sphere's inertia 2/5·1·0.05² = 0.001 needs 0.001·1.5/0.008 = 0.19 N·m of the
    # 10 available to reach it in the step), read /0.008 as 1.50; the getters follow from that step
    assert lines_of(lines, "r1") == ["r1 before 10.0 1.0", "r1 after 2.0 2.0 1.50"]


LED_WORLD = """
WorldInfo { basicTimeStep 8 }
DEF R1 Robot { name "r1" controller "switcher" children [ DEF LED LED { name "led" color [ 1 0 0 ] } ] }
DEF S1 Robot { name "s1" controller "painter" supervisor TRUE }
"""

# r1 waits a real time before its set(), long enough for s1 to write meanwhile (only to provoke that order)
SWITCHER = """
import time
from controller import Robot
robot = Robot()
led = robot.getDevice("led")
robot.step(8)
time.sleep(0.3)
led.set(2)
print("r1 before", led.get())
robot.step(8)
led.set(2)
print("r1 after", led.get())
"""

PAINTER = """
from controller import Supervisor
sup = Supervisor()
sup.step(8)
sup.getFromDef("LED").getField("color").insertMFColor(-1, [0.0, 0.0, 1.0])
sup.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_an_led_value_is_checked_against_the_colours_the_steps_executed(tmp_path: Path, isolation: str) -> None:
    lines = run_multi(tmp_path, LED_WORLD, {"switcher": SWITCHER, "painter": PAINTER}, isolation)
    # webots-devices LED: a value 1..n selects one of the n colours, others are refused. In the step of s1's write
    # (a second colour) the LED has one colour: set(2) is refused, get() keeps 0; from the step that executes the
    # write (S §6) it has two, and set(2) is taken
    assert lines_of(lines, "r1") == ["r1 before 0", "r1 after 2"]


FIELDS_WORLD = """
WorldInfo { basicTimeStep 8 }
DEF R1 Robot {
  name "r1" controller "asker" model "old" controllerArgs [ "a" ]
  children [ DEF C Compass { name "c" lookupTable [ -1 -1 0, 1 1 0 ] } DEF IU InertialUnit { name "iu" } ]
}
DEF S1 Robot { name "s1" controller "renamer" supervisor TRUE }
"""

# r1 waits a real time before it reads, long enough for s1 to write meanwhile (only to provoke that order)
ASKER = """
import time
from controller import Robot
robot = Robot()
compass, unit = robot.getDevice("c"), robot.getDevice("iu")
unit.enable(8)
def show(when):
    print("r1", when, robot.getModel(), robot.getControllerArguments(), robot.getSynchronization(),
          compass.getLookupTable(), unit.getRollPitchYaw()[0], unit.getNoise())
robot.step(8)
time.sleep(0.3)
show("before")
robot.step(8)
show("after")
"""

RENAMER = """
from controller import Supervisor
sup = Supervisor()
sup.step(8)
r1 = sup.getFromDef("R1")
r1.getField("model").setSFString("new")
r1.getField("controllerArgs").setMFString(0, "b")
r1.getField("synchronization").setSFBool(False)
sup.getFromDef("C").getField("lookupTable").setMFVec3f(1, [1.0, 2.0, 0.0])
sup.getFromDef("IU").getField("xAxis").setSFBool(False)
sup.getFromDef("IU").getField("noise").setSFFloat(0.5)
sup.step(8)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_robots_own_field_getters_follow_a_write_from_the_step_that_executes_it(tmp_path: Path,
                                                                                   isolation: str) -> None:
    lines = run_multi(tmp_path, FIELDS_WORLD, {"asker": ASKER, "renamer": RENAMER}, isolation)
    # S §6: until the step to 0.016 executes s1's writes, r1 reads its model, arguments, synchronization (TRUE by
    # default), the compass's table and the inertial unit's axes and noise as loaded: the unit of a robot at rest at
    # the origin reads roll 0; from that step on, the written values: roll disabled (xAxis FALSE) reads NaN
    # (webots-devices InertialUnit), noise 0.5 (which moves pitch and yaw, not printed)
    assert lines_of(lines, "r1") == [
        "r1 before old ['a'] True [-1.0, -1.0, 0.0, 1.0, 1.0, 0.0] 0.0 0.0",
        "r1 after new ['b'] False [-1.0, -1.0, 0.0, 1.0, 2.0, 0.0] nan 0.5",
    ]
