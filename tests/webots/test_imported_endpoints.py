"""A Solid a supervisor imports into a joint's empty ``endPoint`` becomes that joint's endPoint as at load (Webots
§4.1): with Physics it gets its own body, the ODE joint is made between the parent's body (here the static
world) and it, anchored where the parent (the supervisor's own robot) is now: it was moved after load, and the joint's position sensor and
motor act on it (also when a supervisor controller in its own process does it). Removing it leaves the joint
empty; another endPoint imported there is jointed the same way.

Expectations by hand. The pendulum is a sphere (radius r = 0.05 m, density 1000: m = 0.5236 kg) whose centre is
L below the anchor, swinging about a horizontal axis: a physical pendulum of period
T = 2π·sqrt((2/5·r² + L²) / (g·L)), 1.4213 s for L = 0.5 m and 1.0066 s for L = 0.25 m (g = 9.81; started 0.1 rad
out, the amplitude adds 0.06 %). A motor commanded to 0.5 rad turns it about the axis (0 1 0) to
anchor + R_y(0.5)·(0, 0, -L) = anchor + (-L·sin 0.5, 0, -L·cos 0.5): its weight needs 1.23 N·m of the 10 N·m
the motor has, so it gets there."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world

TS = 4
G = 9.81
R = 0.05
ANCHOR = (2.0, 0.0, 1.0)  # where the supervisor moves the frame before importing (it is at the origin at load)
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF FRAME Robot {{
  name "frame"
  supervisor TRUE
  children [
    DEF FREE HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 }}
      device [ PositionSensor {{ name "free sensor" }} ]
    }}
    Pose {{ translation 0 0.5 0 children [
      DEF DRIVEN HingeJoint {{
        jointParameters HingeJointParameters {{ axis 0 1 0 }}
        device [ RotationalMotor {{ name "motor" }} PositionSensor {{ name "driven sensor" }} ]
      }}
    ] }}
  ]
}}
"""


def pendulum(length: float, angle: float = 0.0, name: str = "bob") -> str:
    """A bob hanging ``length`` below the joint's anchor, turned ``angle`` about y (the joint's axis)."""
    x, z = -length * math.sin(angle), -length * math.cos(angle)
    return (f'DEF BOB Solid {{ translation {x} 0 {z} rotation 0 1 0 {angle} name "{name}" '
            f'boundingObject Sphere {{ radius {R} }} physics Physics {{ }} }}')


def period(length: float) -> float:
    return 2 * math.pi * math.sqrt((0.4 * R * R + length * length) / (G * length))


def _supervisor() -> Supervisor:
    sup = Supervisor(simulation=Simulation(load_world_text(WORLD)))
    for name in ("free sensor", "driven sensor"):
        sup.getDevice(name).enable(TS)
    sup.getFromDef("FRAME").getField("translation").setSFVec3f(list(ANCHOR))
    sup.step(TS)
    return sup


def _measured_period(sup: Supervisor, sensor: str, seconds: float, level: float) -> float:
    """Mean time between the upward crossings of ``level`` by a joint position over ``seconds``."""
    device = sup.getDevice(sensor)
    crossings = []
    previous = device.getValue() - level
    for _ in range(round(seconds * 1000 / TS)):
        sup.step(TS)
        value = device.getValue() - level
        if previous < 0.0 <= value:  # linear interpolation inside the step
            crossings.append(sup.getTime() - TS / 1000 * value / (value - previous))
        previous = value
    assert len(crossings) >= 3, crossings
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def _distance_to_anchor(sup: Supervisor, anchor: tuple[float, ...] = ANCHOR) -> float:
    return math.dist(sup.getFromDef("BOB").getPosition(), anchor)


def test_pendulum_imported_as_an_endpoint_swings_about_the_joint_where_it_is_now() -> None:
    sup = _supervisor()
    # the bob is put 0.1 rad out while the joint's position is 0: that pose is the joint's position 0 (§4.1), so
    # the position swings between 0 and -0.2 about -0.1, where the bob hangs straight down
    sup.getFromDef("FREE").getField("endPoint").importSFNodeFromString(pendulum(0.5, 0.1))
    sup.step(TS)
    assert sup.getDevice("free sensor").getValue() == pytest.approx(0.0, abs=1e-3)
    assert _distance_to_anchor(sup) == pytest.approx(0.5, abs=1e-3)
    low = 0.0
    assert _measured_period(sup, "free sensor", 4.5, level=-0.1) == pytest.approx(period(0.5), rel=0.01)
    for _ in range(round(period(0.5) * 1000 / TS)):
        sup.step(TS)
        low = min(low, sup.getDevice("free sensor").getValue())
    assert low == pytest.approx(-0.2, abs=5e-3)  # the other side of the swing, as far out as released
    assert _distance_to_anchor(sup) == pytest.approx(0.5, abs=1e-3)  # held by the joint, not falling


def test_replaced_endpoint_is_jointed_again() -> None:
    sup = _supervisor()
    end = sup.getFromDef("FREE").getField("endPoint")
    end.importSFNodeFromString(pendulum(0.5, 0.1))
    for _ in range(50):
        sup.step(TS)
    end.removeSF()
    sup.step(TS)
    assert sup.getFromDef("BOB") is None
    left_at = sup.getDevice("free sensor").getValue()  # the joint keeps its position without an endPoint
    end.importSFNodeFromString(pendulum(0.25, -0.1, name="short"))
    sup.step(TS)
    assert sup.getDevice("free sensor").getValue() == pytest.approx(left_at, abs=1e-3)
    level = left_at + 0.1  # where the short bob hangs straight down
    assert _measured_period(sup, "free sensor", 3.5, level) == pytest.approx(period(0.25), rel=0.01)
    assert _distance_to_anchor(sup) == pytest.approx(0.25, abs=1e-3)


def test_motor_of_the_joint_turns_the_imported_endpoint() -> None:
    sup = _supervisor()
    sup.getFromDef("DRIVEN").getField("endPoint").importSFNodeFromString(pendulum(0.5))
    motor = sup.getDevice("motor")
    motor.setPosition(0.5)
    for _ in range(round(2.0 * 1000 / TS)):
        sup.step(TS)
    anchor = (ANCHOR[0], ANCHOR[1] + 0.5, ANCHOR[2])
    assert sup.getDevice("driven sensor").getValue() == pytest.approx(0.5, abs=2e-3)
    expected = (anchor[0] - 0.5 * math.sin(0.5), anchor[1], anchor[2] - 0.5 * math.cos(0.5))
    assert sup.getFromDef("BOB").getPosition() == pytest.approx(expected, abs=2e-3)


def test_without_an_endpoint_nothing_swings() -> None:
    # control: the joint holds nothing before the import, so its sensor reads its initial position
    sup = _supervisor()
    for _ in range(100):
        sup.step(TS)
    assert sup.getDevice("free sensor").getValue() == 0.0
    assert sup.getDevice("driven sensor").getValue() == 0.0


RUNNER_SUPERVISOR = """
    from controller import Supervisor
    sup = Supervisor()
    sensor = sup.getDevice("driven sensor")
    sensor.enable(4)
    sup.step(4)
    sup.getFromDef("DRIVEN").getField("endPoint").importSFNodeFromString('{bob}')
    sup.getDevice("motor").setPosition(0.5)
    for _ in range(500):
        sup.step(4)
    with open("out.txt", "w") as out:
        out.write(" ".join(str(v) for v in [sensor.getValue(), *sup.getFromDef("BOB").getPosition()]))
"""


def test_supervisor_controller_imports_an_endpoint_and_drives_it(tmp_path: Path) -> None:
    # the same as the motor test above, from a supervisor controller in its own process ('dualtwin webots run'):
    # the frame stays at the origin, so the bob ends at (0, 0.5, 0) + (-0.5·sin 0.5, 0, -0.5·cos 0.5)
    folder = tmp_path / "controllers" / "sup"
    folder.mkdir(parents=True)
    (folder / "sup.py").write_text(textwrap.dedent(RUNNER_SUPERVISOR).replace("{bob}", pendulum(0.5)))
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(WORLD.replace("supervisor TRUE", 'supervisor TRUE controller "sup"'))
    assert run_world(world, None, 2.1) == 0
    values = [float(v) for v in (folder / "out.txt").read_text().split()]
    expected = [0.5, -0.5 * math.sin(0.5), 0.5, -0.5 * math.cos(0.5)]
    assert values == pytest.approx(expected, abs=2e-3)


LOOP_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{ supervisor TRUE children [
  HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }}
    endPoint DEF BOB Solid {{ translation 0.5 0 0 name "bob" boundingObject Sphere {{ radius {R} }} physics Physics {{ }}
      children [ DEF PIN {{pin}} ] }} }}
] }}
"""
STATIC = 'SolidReference { solidName "<static environment>" }'


@pytest.mark.parametrize("pin", ["BallJoint { }", "HingeJoint { jointParameters HingeJointParameters { axis 1 0 0 } }"])
def test_solid_reference_imported_as_an_endpoint_closes_the_loop_and_its_removal_opens_it(pin: str) -> None:
    # the bob, released level with its hinge, swings; pinned to the static environment by a second joint at its
    # centre (a loop through a SolidReference, §10), it is held where it is; unpinned, it swings on
    sup = Supervisor(simulation=Simulation(load_world_text(LOOP_WORLD.replace("{pin}", pin))))
    control = Supervisor(simulation=Simulation(load_world_text(LOOP_WORLD.replace("{pin}", pin))))
    for s in (sup, control):
        for _ in range(50):
            s.step(TS)
    sup.getFromDef("PIN").getField("endPoint").importSFNodeFromString(STATIC)
    pinned, free = sup.getFromDef("BOB").getPosition(), control.getFromDef("BOB").getPosition()
    for s in (sup, control):
        for _ in range(250):
            s.step(TS)
    assert math.dist(sup.getFromDef("BOB").getPosition(), pinned) < 1e-3  # (stopped within a step or two)
    assert math.dist(control.getFromDef("BOB").getPosition(), free) > 0.1  # without the pin it swings
    sup.getFromDef("PIN").getField("endPoint").removeSF()
    for _ in range(50):
        sup.step(TS)
    assert math.dist(sup.getFromDef("BOB").getPosition(), pinned) > 0.05  # (asleep by then: woken)
