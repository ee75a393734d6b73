"""When a motor command acts and which position the position controller reads, basic step by basic step.

Webots (docs/reference/webots-on-ode.md §1.6, §5.3, §6): commands issued before ``robot.step`` call k act on the
physics of call k; before every basic step the P(ID) law reads the joint position of the previous step's end,
clamps its output to the target velocity and hands ``−u`` to the ODE motor row; sensors are read after the step.
For a sphere spinning about a hinge through its centre, with no gravity, the whole trajectory follows by hand:
ODE's motor row reaches ``u`` up to its CFM (ω' = ω + (u − ω)/(1 + CFM·I/h)) and ODE turns the body's quaternion
by 2·atan(h·ω'/2) per step. These tests pin our per-step trajectory to that, in process and in both controller
isolation modes, with controller steps of one and two basic steps, a command before the first step and later,
and with velocity saturation, a derivative term and an acceleration limit. Control: the same law with the
command one controller step late (what a wire sending commands after the step would give) is far off.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.runner import run_world

H = 0.016  # basicTimeStep 16 ms
CFM = 1e-5
MASS, RADIUS = 2.0, 0.1
INERTIA = 0.4 * MASS * RADIUS**2  # a solid sphere about its centre
TARGET = 1.2


def _world(controller: str = "<none>", motor: str = "") -> str:
    return f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 CFM {CFM} physicsDisableTime 0 }}
Robot {{
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 0 1 }}
      device [ RotationalMotor {{ name "m" maxTorque 1000 {motor} }} PositionSensor {{ name "ps" }} ]
      endPoint Solid {{
        boundingObject Sphere {{ radius {RADIUS} }}
        physics Physics {{ density -1 mass {MASS} }}
      }}
    }}
  ]
  controller "{controller}"
  supervisor TRUE
}}
"""


def _by_hand(steps: int, command_at: int, kp: float = 10.0, kd: float = 0.0, max_velocity: float = 10.0,
             acceleration: float = -1.0) -> list[float]:
    """Joint position after each basic step; the target becomes TARGET before basic step ``command_at``."""
    position = omega = current = previous = 0.0
    target = 0.0  # §5.1: held at the initial position until commanded
    out = []
    for n in range(steps):
        if n == command_at:
            target = TARGET
        error = target - position
        output = kp * error + kd * (error - previous) / H
        previous = error
        u = output if abs(output) < max_velocity else math.copysign(max_velocity, output)
        if acceleration >= 0:
            u = max(current - acceleration * H, min(current + acceleration * H, u))
        current = u
        omega += (u - omega) / (1.0 + CFM * INERTIA / H)
        position += 2.0 * math.atan(H * omega / 2.0)
        out.append(position)
    return out


CASES = {
    "saturated": ({}, ""),
    "unsaturated": ({"max_velocity": 100.0}, "maxVelocity 100"),
    "derivative": ({"kd": 0.05}, "controlPID 10 0 0.05"),
    "acceleration": ({"acceleration": 40.0}, "acceleration 40"),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("basic_steps_per_call", [1, 2])
@pytest.mark.parametrize("calls_before", [0, 2])
def test_position_control_follows_the_law_step_by_step(case: str, basic_steps_per_call: int,
                                                       calls_before: int) -> None:
    law, fields = CASES[case]
    sim = Simulation(load_world_text(_world(motor=fields)))
    robot = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    motor, sensor = robot.getDevice("m"), robot.getDevice("ps")
    ms = 16 * basic_steps_per_call
    sensor.enable(ms)
    readings = []
    for call in range(40 // basic_steps_per_call):
        if call == calls_before:
            motor.setPosition(TARGET)
        robot.step(ms)
        readings.append(sensor.getValue())
    command_at = calls_before * basic_steps_per_call
    expected = _by_hand(40, command_at, **law)[basic_steps_per_call - 1::basic_steps_per_call]
    assert readings == pytest.approx(expected, abs=1e-12)
    late = _by_hand(40, command_at + basic_steps_per_call, **law)[basic_steps_per_call - 1::basic_steps_per_call]
    assert max(abs(a - b) for a, b in zip(readings, late, strict=True)) > 0.05


CONTROLLER = """
    import sys
    from controller import Robot

    ms, calls_before = int(sys.argv[1]), int(sys.argv[2])
    robot = Robot()
    motor, sensor = robot.getDevice("m"), robot.getDevice("ps")
    sensor.enable(ms)
    for call in range(40 * 16 // ms):
        if call == calls_before:
            motor.setPosition(1.2)  # buffered: goes with the next step request
        robot.step(ms)
        print(repr(sensor.getValue()))
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_controller_command_acts_on_the_step_it_precedes_in_both_isolation_modes(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], isolation: str) -> None:
    folder = tmp_path / "controllers" / "servo"
    folder.mkdir(parents=True)
    (folder / "servo.py").write_text(textwrap.dedent(CONTROLLER))
    (tmp_path / "worlds").mkdir()
    expected = _by_hand(40, 2)[1::2]
    for ms, calls_before in ((32, 1), (16, 2)):
        world = tmp_path / "worlds" / "servo.wbt"
        world.write_text(_world("servo").replace('supervisor TRUE', f'controllerArgs [ "{ms}" "{calls_before}" ]'))
        assert run_world(world, isolation=isolation) == 0
        readings = [float(line) for line in capsys.readouterr().out.split()]
        assert readings[32 // ms - 1::32 // ms] == pytest.approx(expected, abs=1e-12)  # every 32 ms
