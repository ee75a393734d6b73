"""A position command of the Webots twin warns about maxVelocity exactly when Webots would: never.

webots-on-ode.md §5.2 and webots-devices.md §9: ``setVelocity(v)`` sets each motor it reaches (the commanded one
and its coupled siblings) to ``v·multiplier``, clipped to ±maxVelocity with a warning; ``setPosition`` alone warns
about no velocity. The twin's position command first gives the velocity the move runs at; it gave maxVelocity
itself, which a multiplier above 1 (or a sibling's) took past maxVelocity: a warning Webots never prints for a
position command. The velocity is now the largest that no motor clips, so each motor's target velocity is what
the clip gave before (the same motion).

Hand values (zero gravity, basicTimeStep 4 ms, 1 kg endPoints of 0.1 m cubes turning about their centre:
I = 1·(0.1² + 0.1²)/12 ≈ 1.7e-3 kg·m², so maxTorque 10 N·m brings them to 10 rad/s well within a step). Webots'
PID (Kp 10) asks 10·e for a position error e; u is clipped to |target velocity| (§5.3) while 10·e exceeds it.
"""

from __future__ import annotations

import pytest

from dualtwin.twins.webots import WebotsTwin
from tests.support.quiet_worlds import quiet_supervisor

TS = 4
PERIOD = 0.008


def _hinge(name: str, x: float, motor: str) -> str:
    return (f"DEF {name} HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 anchor {x} 0 0 }} "
            f"device [ {motor} ] endPoint Solid {{ name \"{name}\" translation {x} 0 0 "
            "physics Physics { density -1 mass 1 } boundingObject Box { size 0.1 0.1 0.1 } } }")


# grip::a is the group's first motor: grip::b's maxVelocity is harmonised at load to 6·|-0.5|/|3| = 1 (§9)
WORLD = (f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 physicsDisableTime 0 }}\n"
         'Robot { supervisor TRUE controller "<extern>" children [ '
         + _hinge("S", 0.0, 'RotationalMotor { name "solo" multiplier 2 maxVelocity 10 }')
         + _hinge("A", 0.5, 'RotationalMotor { name "grip::a" multiplier 3 maxVelocity 6 }')
         + _hinge("B", 1.0, 'RotationalMotor { name "grip::b" multiplier -0.5 maxVelocity 1 }')
         + " ] }\n")


def _twin() -> WebotsTwin:
    return WebotsTwin(quiet_supervisor(WORLD), PERIOD)


def _warnings(capfd: pytest.CaptureFixture[str]) -> list[str]:
    return [line for line in capfd.readouterr().err.splitlines() if "Warning" in line]


def test_a_multiplied_position_command_warns_of_nothing_and_moves_at_max_velocity(
    capfd: pytest.CaptureFixture[str]
) -> None:
    twin = _twin()
    _warnings(capfd)
    twin.command("solo", "position", 1.0)  # target 1·2 = 2 rad
    twin.step()
    assert _warnings(capfd) == []
    # e = 2 at first: the PID asks 20, clipped to maxVelocity 10 (the clip of 10·2 = 20 gave 10 before)
    assert twin.joint_velocity("S") == pytest.approx(10.0, abs=1e-6)
    for _ in range(50):  # 0.4 s: 0.2 s at 10 rad/s, then the PID's exponential approach (time constant 0.1 s)
        twin.step()
    assert twin.joint_position("S") == pytest.approx(2.0, abs=0.05)
    assert _warnings(capfd) == []


def test_a_coupled_position_command_warns_of_nothing_and_each_motor_runs_at_its_max_velocity(
    capfd: pytest.CaptureFixture[str]
) -> None:
    twin = _twin()
    _warnings(capfd)
    twin.command("grip::a", "position", 0.5)  # a: 0.5·3 = 1.5 rad, b: 0.5·-0.5 = -0.25 rad
    twin.step()
    assert _warnings(capfd) == []
    # before: setVelocity(6) made a 18 and b -3, clipped to 6 and -1 with two warnings; now the velocity 2 gives
    # a 2·3 = 6 and b 2·-0.5 = -1 (each PID asks more: 10·1.5 = 15, 10·0.25 = 2.5)
    assert twin.joint_velocity("A") == pytest.approx(6.0, abs=1e-6)
    assert twin.joint_velocity("B") == pytest.approx(-1.0, abs=1e-6)
    for _ in range(100):
        twin.step()
    assert twin.joint_position("A") == pytest.approx(1.5, abs=0.01)
    assert twin.joint_position("B") == pytest.approx(-0.25, abs=0.01)
    assert _warnings(capfd) == []


def test_a_velocity_command_past_max_velocity_once_multiplied_warns_as_webots_does(
    capfd: pytest.CaptureFixture[str]
) -> None:
    # the control: setVelocity(6) on a multiplier-2 motor asks 12 > 10, which Webots clips with a warning
    twin = _twin()
    _warnings(capfd)
    twin.command("solo", "velocity", 6.0)
    assert _warnings(capfd) == ["Warning: 'solo': requested velocity 12.0 exceeds maxVelocity 10.0"]
    twin.step()
    assert twin.joint_velocity("S") == pytest.approx(10.0, abs=1e-6)
