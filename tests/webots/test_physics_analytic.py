"""Physics of the Webots twin against closed-form results (free fall, pendulum, incline)."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots.physics import Simulation
from tests.support.webots_scene import node, world

G = 9.81


def test_free_fall_matches_semi_implicit_euler() -> None:
    h = 0.01
    sim = Simulation(
        world(
            node(
                "Solid",
                translation=(0.0, 0.0, 10.0),
                boundingObject=node("Sphere", radius=0.1),
                physics=node("Physics"),
            ),
            basicTimeStep=10.0,
        )
    )
    body = sim.bodies[0]
    n = 100
    sim.step(n)
    # ODE integrates v first then x (semi-implicit Euler): z_n = z0 - g h^2 n(n+1)/2
    expected = 10.0 - G * h * h * n * (n + 1) / 2
    assert body.pos[2] == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert body.lvel[2] == pytest.approx(-G * h * n, rel=1e-12)
    t = n * h
    assert 10.0 - body.pos[2] == pytest.approx(0.5 * G * t * t, rel=0.02)  # ½gt² up to O(h)
    assert sim.time == pytest.approx(t)


def _pendulum(length: float, theta0: float, radius: float = 0.02, step_ms: float = 2.0) -> Simulation:
    s, c = math.sin(theta0), math.cos(theta0)
    bob = node(
        "Solid",
        name="bob",
        # endPoint pose in the file = pose at the joint position (spec §4.1)
        translation=(-length * s, 0.0, -length * c),
        rotation=(0.0, 1.0, 0.0, theta0),
        boundingObject=node("Sphere", radius=radius),
        physics=node("Physics", density=-1.0, mass=1.0),
    )
    hinge = node(
        "HingeJoint",
        jointParameters=node("HingeJointParameters", axis=(0.0, 1.0, 0.0), position=theta0),
        device=[node("PositionSensor", name="angle")],
        endPoint=bob,
    )
    base = node("Solid", name="pivot", translation=(0.0, 0.0, 2.0), children=[hinge])
    return Simulation(world(base, basicTimeStep=step_ms))


def _upward_crossings(samples: list[tuple[float, float]]) -> list[float]:
    out = []
    for (t0, a0), (t1, a1) in zip(samples, samples[1:], strict=False):
        if a0 < 0.0 <= a1:
            out.append(t0 + (t1 - t0) * (-a0) / (a1 - a0))
    return out


def test_small_angle_pendulum_period_within_one_percent() -> None:
    length, radius = 0.8, 0.02
    sim = _pendulum(length, 0.05, radius)
    joint = sim.joints[0]
    assert joint.reverse  # hinged to the static environment
    assert joint.positions[0] == pytest.approx(0.05)
    samples = []
    for _ in range(int(6.0 / sim.dt)):
        sim.step()
        samples.append((sim.time, joint.positions[0]))
    crossings = _upward_crossings(samples)
    assert len(crossings) >= 3
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    inertia = 0.4 * radius * radius + length * length  # about the pivot, m = 1
    theory = 2 * math.pi * math.sqrt(inertia / (G * length))
    assert period == pytest.approx(theory, rel=0.01)
    # amplitude is preserved by the (undamped) hinge to a few percent
    assert max(a for _, a in samples[-500:]) == pytest.approx(0.05, rel=0.05)


def _incline(theta: float, mu: float) -> tuple[Simulation, object]:
    """A 0.2 m cube resting on a static plane tilted by ``theta`` about y (the slope descends toward +x)."""
    contact = node("ContactProperties", material1="ramp", material2="block", coulombFriction=[mu], bounce=0.0)
    ramp = node(
        "Solid",
        name="ramp",
        rotation=(0.0, 1.0, 0.0, theta),
        boundingObject=node("Plane"),
        contactMaterial="ramp",
    )
    n = (math.sin(theta), 0.0, math.cos(theta))
    centre = tuple(0.1 * v for v in n)
    block = node(
        "Solid",
        name="block",
        translation=centre,
        rotation=(0.0, 1.0, 0.0, theta),
        boundingObject=node("Box", size=(0.2, 0.2, 0.2)),
        physics=node("Physics", density=-1.0, mass=1.0),
        contactMaterial="block",
    )
    sim = Simulation(world(ramp, block, basicTimeStep=4.0, contactProperties=[contact]))
    return sim, sim.bodies[0]


def _slope_coordinate(body, theta: float) -> float:  # type: ignore[no-untyped-def]
    # unit vector pointing down the slope
    d = (math.cos(theta), 0.0, -math.sin(theta))
    return body.pos[0] * d[0] + body.pos[2] * d[2]


def test_block_sticks_when_tan_below_mu() -> None:
    theta, mu = math.radians(15.0), 0.5
    assert math.tan(theta) < mu
    sim, body = _incline(theta, mu)
    s0 = _slope_coordinate(body, theta)
    sim.step(int(1.0 / sim.dt))
    assert abs(_slope_coordinate(body, theta) - s0) < 1e-3


@pytest.mark.parametrize(("degrees", "mu"), [(30.0, 0.2), (40.0, 0.5)])
def test_block_slides_with_expected_acceleration(degrees: float, mu: float) -> None:
    theta = math.radians(degrees)
    assert math.tan(theta) > mu
    sim, body = _incline(theta, mu)
    d = (math.cos(theta), 0.0, -math.sin(theta))
    sim.step(int(0.2 / sim.dt))
    t1, v1 = sim.time, body.lvel[0] * d[0] + body.lvel[2] * d[2]
    sim.step(int(0.8 / sim.dt))
    t2, v2 = sim.time, body.lvel[0] * d[0] + body.lvel[2] * d[2]
    accel = (v2 - v1) / (t2 - t1)
    assert accel == pytest.approx(G * (math.sin(theta) - mu * math.cos(theta)), rel=0.03)
