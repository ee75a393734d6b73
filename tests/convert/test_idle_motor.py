"""A motor whose maxTorque (maxForce) is 0 never drives its joint in Webots: its available torque starts at
maxTorque and setAvailableTorque takes min(f, maxTorque), so it stays 0; with available torque 0 the commanded
velocity is 0 and ODE's motor row holds only staticFriction (on-ODE §5.1-5.3). Webots users write it for a
passive joint that keeps its motor's name. The converter gave the actuator the force range [0, 0], which MuJoCo
refuses, so such a world did not convert at all ("converted model does not compile"); now the motor gets no
actuator (with a warning) and its joint swings freely, as in Webots.

The dual-twin check drops a 0.2 m pendulum (0.5 kg sphere of radius 0.02 m) from the horizontal under gravity
(the motor, in the binding of neither twin, cannot hold it). Hand computation of how far it swings: released
at rest from the horizontal, it passes the vertical (position pi/2 about +y, the sphere hanging below the axis) at
a quarter of the large-amplitude period, 1.18 (pi/2) sqrt(L/g) = 0.265 s (the sphere's own inertia, 2/5 m r^2,
adds 0.4 % to L), so after 0.16 s it has left the horizontal by well over 0.3 rad in both twins; the twins agree
within 0.02 rad (their integrators differ, a mass, axis or sign may not).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text

PENDULUM = world_text(
    'DEF R Robot { controller "<extern>" children [ DEF J HingeJoint {\n'
    "  jointParameters HingeJointParameters { axis 0 1 0 }\n"
    '  device [ PositionSensor { name "s" } RotationalMotor { name "m" maxTorque 0 } ]\n'
    "  endPoint DEF W Solid { translation 0.2 0 0 physics Physics { density -1 mass 0.5 } "
    "boundingObject Sphere { radius 0.02 } } } ] }", "basicTimeStep 4")


def test_a_zero_torque_motor_converts_without_an_actuator() -> None:
    conv = convert_world_text(PENDULUM, "idle.wbt")
    model = conv.compile()
    assert model.nu == 0
    assert [m.name for m in conv.motors] == []
    assert [w for w in conv.warnings if "motor 'm' has maxTorque/maxForce 0" in w]


def test_the_joint_swings_freely_in_both_twins(tmp_path: Path) -> None:
    with converted_twins(PENDULUM, tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(20):  # 0.16 s
            webots.step()
            mujoco_twin.step()
        assert webots.sensor("s") > 0.3
        assert mujoco_twin.sensor("s") == pytest.approx(webots.sensor("s"), abs=0.02)
