"""A hinge's stops at ±π (clamped there, §4.2) hold a driven joint, as in Webots.

S = /work/shared/reference/webots-on-ode.md. S §4.2: LoStop = −maxStop + offset and HiStop = −minStop + offset,
both clamped into [−π, π]; Webots' ODE fork unwraps the hinge angle across ±π when it tests them (S §4.2 "Fork
difference", Appendix A.3), so a joint driven toward a clamped stop rests on it. Upstream ODE's angle wraps at ±π
(a stop there never held); ODE's zero follows the joint instead (physics/joints.py ``_rebase_hinge``). The
positions a driven joint rests at follow from the mapping by hand: ODE's angle is offset − position, so the
limits in position are offset − HiStop and offset − LoStop. A 1 N·m motor at 1 rad/s for 6 s would turn the
joint 6 rad without a stop (no gravity)."""

from __future__ import annotations

import math

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.hinge_arm import BOB, TS, load_arm

HEAVY_BASE = 'Solid { name "base" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { density -1 mass 1000 } '


def _arm(params: str, static_parent: bool, position: float = 0.0, motor: bool = True) -> Supervisor:
    bob_at = f"{0.5 * math.cos(position)} 0 {-0.5 * math.sin(position)}"  # the bob turned by position about y
    device = 'RotationalMotor { name "m" maxTorque 1 }' if motor else ""
    hinge = (f"HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 position {position} {params} }} "
             f"device [ {device} PositionSensor {{ name \"s\" }} ] endPoint {BOB.format(t=bob_at)} }}")
    _, sup = load_arm(hinge if static_parent else f"{HEAVY_BASE} children [ {hinge} ] }}")
    sup.getDevice("s").enable(TS)
    return sup


def _drive(sup: Supervisor, velocity: float, seconds: float = 6.0) -> float:
    m = sup.getDevice("m")
    m.setPosition(math.inf)
    m.setVelocity(velocity)
    for _ in range(round(seconds * 1000 / TS)):
        assert sup.step(TS) != -1
    return float(sup.getDevice("s").getValue())


@pytest.mark.parametrize("static_parent", [True, False])
def test_stops_clamped_to_pi_hold_the_joint_both_ways(static_parent: bool) -> None:
    # minStop −4 / maxStop 4: LoStop = −π, HiStop = π, the limits ±π; driven up, then down across the whole range
    sup = _arm("minStop -4 maxStop 4", static_parent)
    assert _drive(sup, 1.0) == pytest.approx(math.pi, abs=0.02)
    assert _drive(sup, -1.0, 8.0) == pytest.approx(-math.pi, abs=0.02)


@pytest.mark.parametrize("static_parent", [True, False])
def test_stops_are_clamped_about_the_load_offset(static_parent: bool) -> None:
    # position 2 at load: maxStop 6 gives LoStop = clamp(−6 + 2) = −π, a limit at 2 + π; minStop −3 gives
    # HiStop = clamp(3 + 2) = π, a limit at 2 − π
    sup = _arm("minStop -3 maxStop 6", static_parent, position=2.0)
    assert _drive(sup, 1.0) == pytest.approx(2.0 + math.pi, abs=0.02)
    assert _drive(sup, -1.0, 8.0) == pytest.approx(2.0 - math.pi, abs=0.02)


def test_a_reset_maps_the_stops_from_the_load_offset_again() -> None:
    sup = _arm("minStop -4 maxStop 4", True)
    assert _drive(sup, 1.0) == pytest.approx(math.pi, abs=0.02)
    sup.simulationReset()
    assert sup.step(TS) != -1  # (the reset takes effect at the end of this step, resetting the motor, §6)
    assert _drive(sup, -1.0) == pytest.approx(-math.pi, abs=0.02)


def test_a_spring_keeps_its_rest_position_while_odes_zero_follows_the_joint() -> None:
    # §4.5: the spring's rest is position 0; an arm with wide stops (±3) teleported to 2.5 (§4.1) swings back
    # through several re-based zeros and, damped, settles at 0
    sup = _arm("minStop -3 maxStop 3 springConstant 10 dampingConstant 1", True, motor=False)
    sup.getSelf().getField("children").getMFNode(0).getField("jointParameters").getSFNode().getField(
        "position").setSFFloat(2.5)
    for _ in range(round(20 * 1000 / TS)):
        assert sup.step(TS) != -1
    assert sup.getDevice("s").getValue() == pytest.approx(0.0, abs=1e-3)
