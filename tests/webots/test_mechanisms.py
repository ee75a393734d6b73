"""Mechanisms: coupled motors ('name::suffix'), and later propellers, tracks and closed loops."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation


def _sup(body: str, step: int = 4) -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {step} gravity 0 }}\n{body}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _arm(name: str, multiplier: float, y: float) -> str:
    return f"""HingeJoint {{
  jointParameters HingeJointParameters {{ axis 0 0 1 anchor 0 {y} 0 }}
  device [ RotationalMotor {{ name "{name}" multiplier {multiplier} maxVelocity 5 maxTorque 50 }}
           PositionSensor {{ name "{name} sensor" }} ]
  endPoint Solid {{ translation 0.1 {y} 0 boundingObject Box {{ size 0.2 0.02 0.02 }} physics Physics {{ }} }}
}}"""


COUPLED = (
    "Robot { supervisor TRUE children [ "
    + _arm("gripper::left", 1.0, 0.2)
    + _arm("gripper::right", -2.0, -0.2)
    + _arm("other", 1.0, 0.6)
    + " ] }"
)


def _sensors(sup: Supervisor, names: list[str]) -> list:
    devs = [sup.getDevice(f"{n} sensor") for n in names]
    for d in devs:
        d.enable(4)
    return devs


def test_coupled_motors_follow_position_with_their_multipliers() -> None:
    sup = _sup(COUPLED)
    left, right, other = _sensors(sup, ["gripper::left", "gripper::right", "other"])
    sup.getDevice("gripper::left").setPosition(0.3)
    for _ in range(500):
        sup.step(4)
    assert left.getValue() == pytest.approx(0.3, abs=1e-3)
    assert right.getValue() == pytest.approx(-0.6, abs=1e-3)
    assert other.getValue() == pytest.approx(0.0, abs=1e-6)  # not a sibling
    # the sibling's controller-side target changed too (raw value times its own multiplier)
    assert sup.getDevice("gripper::right").getTargetPosition() == pytest.approx(-0.6)


def test_coupled_motors_relay_velocity_and_torque() -> None:
    sup = _sup(COUPLED)
    left, right = _sensors(sup, ["gripper::left", "gripper::right"])
    motor = sup.getDevice("gripper::right")  # commanding either motor moves both
    motor.setPosition(math.inf)
    motor.setVelocity(0.5)
    for _ in range(50):
        sup.step(4)
    a0, b0 = left.getValue(), right.getValue()
    for _ in range(100):
        sup.step(4)
    assert (left.getValue() - a0) / 0.4 == pytest.approx(0.5, rel=1e-3)
    assert (right.getValue() - b0) / 0.4 == pytest.approx(-1.0, rel=1e-3)
    sup.getDevice("gripper::left").setTorque(0.0)
    assert all(sup.getDevice(n)._record.torque_mode for n in ("gripper::left", "gripper::right"))
    assert not sup.getDevice("other")._record.torque_mode


# ------------------------------------------------------------------------------------------ propeller


def _drone(thrust: str, torque: str) -> Supervisor:
    return _sup(
        "DEF DRONE Robot { supervisor TRUE boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } "
        f"children [ Propeller {{ shaftAxis 0 0 1 thrustConstants {thrust} torqueConstants {torque} "
        'device RotationalMotor { name "prop" maxVelocity 200 maxTorque 1000 } } ] }'
    )


def test_propeller_thrust_and_torque_at_a_given_speed() -> None:
    sup = _drone("1e-4 0", "1e-6 0")
    prop = sup.getDevice("prop")
    prop.setPosition(math.inf)
    prop.setVelocity(100.0)
    for _ in range(50):  # spin-up at maxTorque = 1000 rad/s²: full speed after 0.1 s
        sup.step(4)
    drone = sup.getFromDef("DRONE")
    v0 = drone.getVelocity()
    for _ in range(125):
        sup.step(4)
    v1 = drone.getVelocity()
    # T = t1·ω² = 1 N on 1 kg along +z; Q = q1·ω² = 0.01 N·m applied as -Q about the shaft
    assert (v1[2] - v0[2]) / 0.5 == pytest.approx(1.0, rel=0.01)
    izz = 1.0 * (0.1**2 + 0.1**2) / 12
    assert (v1[5] - v0[5]) / 0.5 == pytest.approx(-0.01 / izz, rel=0.01)
    assert abs(v1[0]) < 1e-9 and abs(v1[1]) < 1e-9


def test_propeller_thrust_falls_with_inflow_speed() -> None:
    # m·dv/dt = t1·ω² − t2·ω·v: the drone reaches v∞ = t1·ω/t2 = 0.5 m/s with τ = m/(t2·ω) = 0.5 s
    sup = _drone("1e-4 0.02", "0 0")
    prop = sup.getDevice("prop")
    prop.setPosition(math.inf)
    prop.setVelocity(100.0)
    for _ in range(1500):
        sup.step(4)
    assert sup.getFromDef("DRONE").getVelocity()[2] == pytest.approx(0.5, rel=0.01)
    prop.setVelocity(0.0)  # spinning down, then no thrust at all
    for _ in range(50):
        sup.step(4)
    v = sup.getFromDef("DRONE").getVelocity()[2]
    sup.step(4)
    assert sup.getFromDef("DRONE").getVelocity()[2] == v


# ------------------------------------------------------------------------------------------ track


def _floor_world(body: str) -> Supervisor:
    text = (
        "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 4 }\n"
        f'Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}\n{body}\n'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def test_conveyor_track_carries_a_box_at_belt_speed() -> None:
    sup = _floor_world(
        'Robot { supervisor TRUE children [ Track { translation 0 0 0.2 name "belt" '
        "boundingObject Box { size 2 0.4 0.1 } physics Physics { mass 5 } "
        'device [ LinearMotor { name "belt motor" maxVelocity 1 } PositionSensor { name "belt sensor" } ] } ] }\n'
        "DEF BOX Solid { translation 0 0 0.3 boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } }"
    )
    motor, sensor = sup.getDevice("belt motor"), sup.getDevice("belt sensor")
    sensor.enable(4)
    motor.setPosition(math.inf)
    motor.setVelocity(0.3)
    for _ in range(500):
        sup.step(4)
    vx, vy, vz = sup.getFromDef("BOX").getVelocity()[:3]
    assert vx == pytest.approx(0.3, rel=0.01) and abs(vy) < 1e-6 and abs(vz) < 1e-3
    assert sensor.getValue() == pytest.approx(0.3 * 2.0, rel=0.01)  # belt travel over 2 s
    motor.setPosition(0.0)  # position control brings the belt back, and the box with it
    for _ in range(1000):
        sup.step(4)
    assert sensor.getValue() == pytest.approx(0.0, abs=1e-3)


def test_tracked_vehicle_drives_at_belt_speed() -> None:
    sup = _floor_world(
        'DEF V Robot { translation 0 0 0.06 supervisor TRUE children [ Track { name "t" '
        "boundingObject Box { size 0.4 0.3 0.1 } physics Physics { mass 2 } "
        'device [ LinearMotor { name "m" maxVelocity 1 } ] } ] physics Physics { mass 1 } '
        "boundingObject Pose { translation 0 0 0.1 children [ Box { size 0.1 0.1 0.05 } ] } }"
    )
    motor = sup.getDevice("m")
    motor.setPosition(math.inf)
    motor.setVelocity(-0.2)
    for _ in range(500):
        sup.step(4)
    vx, vy, _ = sup.getFromDef("V").getVelocity()[:3]
    assert vx == pytest.approx(-0.2, rel=0.01) and abs(vy) < 1e-6


# ------------------------------------------------------------------------------------------ closed loops


def _bar(length_x: float, length_z: float) -> str:
    """A thin bar from the Solid origin to (length_x, 0, length_z)."""
    size = (max(abs(length_x), 0.02), 0.02, max(abs(length_z), 0.02))
    return (
        f"boundingObject Pose {{ translation {length_x / 2} 0 {length_z / 2} children [ "
        f"Box {{ size {size[0]} {size[1]} {size[2]} }} ] }} physics Physics {{ density 500 }}"
    )


def _parallelogram(close: str) -> str:
    # base pivots at (0,0,0) and (0.4,0,0); two 0.3 m cranks hang down, a coupler joins their ends
    return f"""Robot {{ translation 0 0 1 supervisor TRUE children [
  HingeJoint {{
    jointParameters HingeJointParameters {{ axis 0 1 0 }}
    device [ RotationalMotor {{ name "crank" maxTorque 100 }} ]
    endPoint Solid {{ name "crank1" {_bar(0, -0.3)} children [
      HingeJoint {{
        jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 0 -0.3 }}
        endPoint DEF COUPLER Solid {{ name "coupler" translation 0 0 -0.3 {_bar(0.4, 0)} children [
          HingeJoint {{
            jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0.4 0 0 }}
            device [ PositionSensor {{ name "crank2 angle" }} ]
            endPoint Solid {{ name "crank2" translation 0.4 0 0 {_bar(0, 0.3)} children [
              HingeJoint {{
                jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 0 0.3 }}
                endPoint SolidReference {{ solidName "{close}" }}
              }}
            ] }}
          }}
        ] }}
      }}
    ] }}
  }}
] }}"""


def test_parallelogram_loop_keeps_the_coupler_level() -> None:
    sup = _floor_world(_parallelogram("<static environment>"))
    sensor = sup.getDevice("crank2 angle")
    sensor.enable(4)
    theta = 0.5
    sup.getDevice("crank").setPosition(theta)
    for _ in range(750):
        sup.step(4)
    coupler = sup.getFromDef("COUPLER")
    R = coupler.getOrientation()
    # the coupler translates without turning: its x axis stays horizontal
    assert abs(R[6]) < 2e-3 and abs(R[0] - 1.0) < 2e-3
    x, _, z = coupler.getPosition()  # the crank end: (0, 0, -0.3) turned by theta about +y, 1 m up
    assert x == pytest.approx(-0.3 * math.sin(theta), abs=2e-3)
    assert z == pytest.approx(1.0 - 0.3 * math.cos(theta), abs=2e-3)
    # the second crank turned with the first (relative to the level coupler)
    assert sensor.getValue() == pytest.approx(theta, abs=3e-3)


def test_without_the_loop_the_chain_swings_freely() -> None:
    # control: the same mechanism with an unknown reference (warned, not closed) does not keep the coupler level
    sup = _floor_world(_parallelogram("no such solid"))
    assert any("SolidReference 'no such solid'" in w for w in sup.simulation.build_warnings)
    sup.getDevice("crank").setPosition(0.5)
    for _ in range(750):
        sup.step(4)
    assert abs(sup.getFromDef("COUPLER").getOrientation()[6]) > 0.05


def test_simulation_reset_restores_belt_and_propeller_state() -> None:
    sup = _floor_world(
        'Robot { supervisor TRUE children [ Track { translation 0 0 0.2 name "belt" '
        "boundingObject Box { size 2 0.4 0.1 } physics Physics { mass 5 } "
        'device [ LinearMotor { name "belt motor" maxVelocity 1 } PositionSensor { name "belt sensor" } ] } ] }'
    )
    motor, sensor = sup.getDevice("belt motor"), sup.getDevice("belt sensor")
    sensor.enable(4)
    motor.setPosition(math.inf)
    motor.setVelocity(0.5)
    for _ in range(100):
        sup.step(4)
    assert sensor.getValue() == pytest.approx(0.2, rel=0.01)
    sup.simulationReset()
    sup.step(4)
    sup.step(4)
    assert sensor.getValue() == pytest.approx(0.0, abs=1e-9)  # back at 0 and held there


def test_track_force_control_uses_webots_formula() -> None:
    # Webots: v = F·dt / m (not integrated): 10 N on a 5 kg track body at dt = 4 ms gives 8 mm/s
    sup = _floor_world(
        'Robot { supervisor TRUE children [ Track { translation 0 0 0.2 name "belt" '
        "boundingObject Box { size 2 0.4 0.1 } physics Physics { mass 5 } "
        'device [ LinearMotor { name "belt motor" maxForce 10 } PositionSensor { name "belt sensor" } ] } ] }'
    )
    motor, sensor = sup.getDevice("belt motor"), sup.getDevice("belt sensor")
    sensor.enable(4)
    motor.setForce(25.0)  # clipped to the available force, 10 N
    for _ in range(250):
        sup.step(4)
    assert sensor.getValue() == pytest.approx(10 * 0.004 / 5 * 1.0, rel=1e-6)
