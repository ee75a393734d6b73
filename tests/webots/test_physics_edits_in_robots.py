"""A Physics node a supervisor imports into (or removes from) a Solid inside a Robot acts as outside robots (Webots'
mass rules, §3.3) while the robot's devices keep working: the handles its controller holds (motors with their
commands, sensors with their sampling) go on acting on and reading the rebuilt physics, also from a controller in
its own process. The Solids below the edited one keep their motion: a body jointed below it keeps its spin and its
joint its position, instead of restarting from rest.

Expectations by hand (no gravity, basicTimeStep h = 4 ms, density 1000). A 0.2 m cube weighs 8 kg: one step of a
1 N force through the centre of mass of a body of mass M adds h/M to its speed: h/8 for the robot's own cube,
h/16 once the part (a second cube) is given Physics and merged into the robot's body. A Gyro on the part reads
the spin of the body it rides on (its frame is the body's, turned by nothing). The tip below the arm is a bar
centred on its hinge: its spin about the axis pushes nothing, so it keeps that spin whatever the arm does."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world
from tests.support.webots_scene import write_controllers

TS = 4
H = TS / 1000
CUBE = "boundingObject Box { size 0.2 0.2 0.2 }"
ROBOT = f"""DEF BOT Robot {{
  translation 0 0 1
  {{controller}}
  {CUBE}
  physics Physics {{ }}
  children [
    DEF PART Solid {{
      translation 0.4 0 0
      name "part"
      {CUBE}
      children [
        Gyro {{ name "gyro" }}
        HingeJoint {{
          jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 0 0.3 }}
          device [ RotationalMotor {{ name "m" }} PositionSensor {{ name "s" }} ]
          endPoint Solid {{ translation 0 0 0.3 name "rotor" boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }}
        }}
      ]
    }}
  ]
}}"""
ROTOR_MASS = 1000 * 4 / 3 * math.pi * 0.05**3


def _world(robot: str) -> str:
    return f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n{robot}\n"


def _kick(sup: Supervisor) -> float:
    """What one step of 1 N along x through the robot's centre of mass adds to its speed, from rest."""
    bot = sup.getFromDef("BOT")
    bot.resetPhysics()
    sup.step(TS)
    bot.addForce([1.0, 0.0, 0.0], False)
    sup.step(TS)
    return float(bot.getVelocity()[0])


def _robot(robot: str = ROBOT) -> Supervisor:
    sup = Supervisor(simulation=Simulation(load_world_text(_world(robot.replace("{controller}", "supervisor TRUE")))))
    for name in ("gyro", "s"):
        if sup.getDevice(name) is not None:
            sup.getDevice(name).enable(TS)
    return sup


def _rate(sup: Supervisor) -> float:
    before = sup.getDevice("s").getValue()
    sup.step(TS)
    return float((sup.getDevice("s").getValue() - before) / H)


def test_a_physics_node_imported_into_a_solid_of_a_robot_merges_into_its_body_and_its_removal_takes_it_out() -> None:
    start, end = ROBOT.index("        HingeJoint"), ROBOT.index("      ]\n    }")
    sup = _robot(ROBOT[:start] + ROBOT[end:])  # the part holds the gyro alone
    assert _kick(sup) == pytest.approx(H / 8, rel=1e-6)  # control: the part weighs nothing
    sup.getFromDef("PART").getField("physics").importSFNodeFromString("Physics { }")
    assert _kick(sup) == pytest.approx(H / 16, rel=1e-6)
    sup.getFromDef("PART").getField("physics").removeSF()
    assert _kick(sup) == pytest.approx(H / 8, rel=1e-6)


def test_the_devices_of_the_robot_keep_working_across_the_edit() -> None:
    sup = _robot()
    motor, gyro = sup.getDevice("m"), sup.getDevice("gyro")  # handles taken before the edit
    motor.enableTorqueFeedback(TS)
    motor.setPosition(math.inf)
    motor.setVelocity(1.0)
    for _ in range(5):
        sup.step(TS)
    sup.getFromDef("PART").getField("physics").importSFNodeFromString("Physics { }")
    assert _rate(sup) == pytest.approx(1.0, abs=1e-4)  # the command given before the edit still drives it
    motor.setVelocity(-1.0)
    sup.step(TS)
    # and a new one through the same handle: the motor turns the rotor (I = 2/5·m·r² about its own centre) from
    # 1 to -1 rad/s in one step, with a torque of I·Δω/h that its feedback reads (to 1 %: the body it is jointed
    # to turns a little the other way)
    rotor_inertia = 0.4 * ROTOR_MASS * 0.05**2
    assert motor.getTorqueFeedback() == pytest.approx(-rotor_inertia * 2.0 / H, rel=1e-2)
    for _ in range(2):
        sup.step(TS)
    assert _rate(sup) == pytest.approx(-1.0, abs=1e-4)
    bot = sup.getFromDef("BOT")
    bot.addTorque([0.0, 0.0, 0.01], False)
    sup.step(TS)
    assert gyro.getValues()[2] == pytest.approx(bot.getVelocity()[5], rel=1e-6)  # reads the merged body's spin
    assert abs(gyro.getValues()[2]) > 1e-4
    assert sup.getNumberOfDevices() == 3
    # the part's mass is in the robot's body (to 1 %: the rotor, jointed off the body's centre of mass, turns it
    # a little under a force through that centre; without the part's mass the speed is 1.9 times this)
    assert _kick(sup) == pytest.approx(H / (16 + ROTOR_MASS), rel=1e-2)


CHAIN = """DEF BASE {base} { translation 0 0 1 children [
  HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }
    endPoint DEF ARM Solid { translation 0.5 0 0 boundingObject Sphere { radius 0.05 }
      children [ DEF TIP_JOINT HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }
        endPoint DEF TIP Solid { name "tip" boundingObject Box { size 0.2 0.02 0.02 } physics Physics { } } } ] } } ] }
Robot { name "supervisor" supervisor TRUE }"""


@pytest.mark.parametrize("base", ["Solid", "Robot"])
def test_a_body_jointed_below_the_edited_solid_keeps_its_spin_and_its_joint_position(base: str) -> None:
    sup = Supervisor(simulation=Simulation(load_world_text(_world(CHAIN.replace("{base}", base)))))
    position = sup.getFromDef("TIP_JOINT").getField("jointParameters").getSFNode().getField("position")
    sup.step(TS)
    tip, arm = sup.getFromDef("TIP"), sup.getFromDef("ARM")
    tip.setVelocity([0.0, 0.0, 0.0, 0.0, 0.0, 2.0])
    for _ in range(10):
        sup.step(TS)
    for edit in ("import", "remove"):
        read = position.getSFFloat()
        if edit == "import":
            arm.getField("physics").importSFNodeFromString("Physics { }")
        else:
            arm.getField("physics").removeSF()
        assert tip.getVelocity()[5] == pytest.approx(2.0, rel=1e-9)  # (the old code started it from rest)
        sup.step(TS)
        assert position.getSFFloat() == pytest.approx(read + 2.0 * H, rel=1e-6)  # read on from where it was
        for _ in range(20):
            sup.step(TS)
        assert tip.getVelocity()[5] == pytest.approx(2.0, rel=1e-6)
    sup.simulationReset()
    sup.step(TS)
    assert position.getSFFloat() == pytest.approx(0.0, abs=1e-9)  # the load position again


ARM_CONTROLLER = """
    import os
    from controller import Robot
    HERE = os.path.dirname(os.path.abspath(__file__))  # (threads share one working folder)
    robot = Robot()
    motor, sensor = robot.getDevice("m"), robot.getDevice("s")
    sensor.enable(4)
    motor.setPosition(float("inf"))
    motor.setVelocity(1.0)
    values = []
    while robot.step(4) != -1:
        values.append(sensor.getValue())
        if len(values) == 30:
            motor.setVelocity(-1.0)  # after the supervisor's edit, through the handle taken before it
    with open(os.path.join(HERE, "out.txt"), "w") as out:
        out.write(str((values[-1] - values[-2]) / 0.004))
"""
SUPERVISOR = """
    import os
    from controller import Supervisor
    HERE = os.path.dirname(os.path.abspath(__file__))
    sup = Supervisor()
    for _ in range(10):
        sup.step(4)
    sup.getFromDef("PART").getField("physics").importSFNodeFromString("Physics { }")
    bot = sup.getFromDef("BOT")
    bot.resetPhysics()
    sup.step(4)
    bot.addForce([1.0, 0.0, 0.0], False)
    sup.step(4)
    with open(os.path.join(HERE, "out.txt"), "w") as out:
        out.write(str(bot.getVelocity()[0]))
    while sup.step(4) != -1:
        pass
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_controller_drives_its_motor_across_a_supervisors_physics_edit(tmp_path: Path, isolation: str) -> None:
    write_controllers(tmp_path, {"arm": ARM_CONTROLLER, "sup": SUPERVISOR})
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(_world(ROBOT.replace("{controller}", 'controller "arm"')
                            + '\nRobot { name "boss" controller "sup" supervisor TRUE }'))
    assert run_world(world, None, 0.2, isolation=isolation) == 0
    speed = float((tmp_path / "controllers" / "sup" / "out.txt").read_text())
    assert speed == pytest.approx(H / (16 + ROTOR_MASS), rel=1e-2)  # the part merged into the robot's body
    rate = float((tmp_path / "controllers" / "arm" / "out.txt").read_text())
    assert rate == pytest.approx(-1.0, abs=1e-4)  # the controller's handle still drives the joint


def test_a_physics_node_imported_into_the_robot_itself_makes_it_a_body_its_devices_following() -> None:
    # a static robot (no Physics) with a GPS: given Physics, its 8 kg cube takes one step of 1 N as h/8, and its
    # GPS (a handle taken before) follows it as it drifts at that speed
    sup = Supervisor(simulation=Simulation(load_world_text(_world(
        f'DEF BOT Robot {{ translation 0 0 1 supervisor TRUE {CUBE} children [ GPS {{ name "gps" }} ] }}'))))
    gps = sup.getDevice("gps")
    gps.enable(TS)
    bot = sup.getFromDef("BOT")
    bot.addForce([1.0, 0.0, 0.0], False)
    sup.step(TS)
    assert bot.getVelocity()[0] == 0.0  # control: static
    bot.getField("physics").importSFNodeFromString("Physics { }")
    bot.addForce([1.0, 0.0, 0.0], False)
    sup.step(TS)
    assert bot.getVelocity()[0] == pytest.approx(H / 8, rel=1e-9)
    for _ in range(99):
        sup.step(TS)
    assert gps.getValues() == pytest.approx([H / 8 * 100 * H, 0.0, 1.0], rel=1e-6)
