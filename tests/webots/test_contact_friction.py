"""Contact friction as Webots fills ODE's dContact (§2.2): rolling friction's axis-dependent coefficients and
asymmetric Coulomb friction. Expected values are derived by hand from the ODE contact model."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

G = 9.81
THETA = 0.2  # ramp slope (rad)


def _sup(world: str, step: int = 8) -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\n{world}\nRobot {{ supervisor TRUE name \"s\" }}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Supervisor(simulation=sim, robot_node=sim.robots[-1].node)


def _ball_on_ramp(rolling: str) -> Supervisor:
    n = (math.sin(THETA), 0.0, math.cos(THETA))  # ramp top normal: +z turned by THETA about +y
    c = [0.2 * v for v in n]  # ball (r 0.1) resting on the ramp top (half thickness 0.1)
    return _sup(f"""WorldInfo {{ basicTimeStep 8 contactProperties [
  ContactProperties {{ material1 "ramp" material2 "ball" bounce 0 rollingFriction {rolling} }} ] }}
Solid {{ rotation 0 1 0 {THETA} contactMaterial "ramp" boundingObject Box {{ size 40 4 0.2 }} }}
DEF BALL Solid {{ translation {c[0]} {c[1]} {c[2]} contactMaterial "ball"
  boundingObject Sphere {{ radius 0.1 }} physics Physics {{ density -1 mass 1 }} }}""")


def _downhill_speed_and_spin(sup: Supervisor, seconds: float) -> tuple[float, float]:
    ball = sup.getFromDef("BALL")
    for _ in range(round(seconds / 0.008)):
        sup.step(8)
    v = ball.getVelocity()
    return v[0] * math.cos(THETA) - v[2] * math.sin(THETA), v[4]


def test_rho2_alone_leaves_the_second_friction_direction_without_friction() -> None:
    # rho2 > 0 sets dContactAxisDep, the same ODE bit as dContactMu2; Webots leaves mu2 = 0, so along the second
    # friction direction (downhill here: dPlaneSpace of the ramp normal) the ball slides freely, without turning.
    speed, spin = _downhill_speed_and_spin(_ball_on_ramp("0 0.05 0"), 1.0)
    assert speed == pytest.approx(G * math.sin(THETA) * 1.0, rel=0.02)  # frictionless slide: g·sinθ·t
    assert abs(spin) < 1e-6


def test_without_rolling_friction_the_ball_rolls() -> None:
    # control: a rolling solid sphere accelerates at 5/7·g·sinθ and turns about +y at v/r
    speed, spin = _downhill_speed_and_spin(_ball_on_ramp("0 0 0"), 1.0)
    assert speed == pytest.approx(5 / 7 * G * math.sin(THETA) * 1.0, rel=0.02)
    assert spin == pytest.approx(speed / 0.1, rel=0.02)


def _slide(coulomb: str, velocity: tuple[float, float], box_turn: float = 0.0) -> tuple[float, float]:
    sup = _sup(f"""WorldInfo {{ basicTimeStep 8 contactProperties [
  ContactProperties {{ material1 "floor" material2 "box" bounce 0 coulombFriction [ {coulomb} ] }} ] }}
Solid {{ contactMaterial "floor" boundingObject Plane {{ size 100 100 }} }}
DEF BOX Solid {{ translation 0 0 0.05 rotation 0 0 1 {box_turn} contactMaterial "box"
  boundingObject Box {{ size 0.4 0.4 0.1 }} physics Physics {{ density -1 mass 1 }} }}""")
    box = sup.getFromDef("BOX")
    box.setVelocity([velocity[0], velocity[1], 0.0, 0.0, 0.0, 0.0])
    for _ in range(300):
        sup.step(8)
    p = box.getPosition()
    return p[0], p[1]


def _stop(v: float, mu: float) -> float:
    """Slide length at initial speed v under Coulomb friction mu: v²/(2·mu·g), less v·h/2 for ODE's semi-implicit
    Euler steps (h = 8 ms: positions advance with the velocity after each step)."""
    return v * v / (2 * mu * G) - v * 0.008 / 2


def test_asymmetric_friction_uses_the_first_solid_friction_direction() -> None:
    # (a flat box, so that friction up to mu = 4 cannot tip it)
    # two values, box and plane both with friction directions along world x (α = 0): mu = m0 + m0 = 0.2 along
    # fdir1 (the floor's x), mu2 = m1 + m1 = 2 along y
    x, _ = _slide("0.1 1", (2.0, 0.0))
    assert x == pytest.approx(_stop(2.0, 0.2), rel=0.02)
    _, y = _slide("0.1 1", (0.0, 2.0))
    assert y == pytest.approx(_stop(2.0, 2.0), rel=0.02)


def test_asymmetric_friction_combines_with_the_angle_between_directions() -> None:
    # the box turned 90° about z: its friction direction is across the floor's (α = 90°):
    # mu = m0 + m1 = 1.1 along x, mu2 = m1 + m0 = 1.1 along y
    x, _ = _slide("0.1 1", (2.0, 0.0), box_turn=math.pi / 2)
    assert x == pytest.approx(_stop(2.0, 1.1), rel=0.02)


def test_symmetric_friction_slides_alike_in_every_direction() -> None:
    x, _ = _slide("0.1", (2.0, 0.0))  # control: one value is mu along both directions
    _, y = _slide("0.1", (0.0, 2.0))
    assert x == pytest.approx(_stop(2.0, 0.1), rel=0.02) and y == pytest.approx(x, rel=1e-6)
