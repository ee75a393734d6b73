"""Sampling instants (issue 26 item 2): a sensor with period p is sampled at the end of the basic step where p
elapsed since the last sample, during ``Robot.step``, not when the step returns.

A free-falling body on ODE's semi-implicit Euler step is at ``z0 − g·dt²·n(n+1)/2`` after n steps, so the
height a GPS reports names the step it was sampled at. Control: the old runtime sampled due sensors once, at
the end of ``step``, i.e. at 96 ms, 192 ms, 288 ms for a 64 ms GPS under ``step(96)``.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

G, DT, Z0 = 9.81, 0.032, 10.0


def _supervisor(text: str) -> Supervisor:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 32 }\n" + text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _height(n: int) -> float:
    return Z0 - G * DT * DT * n * (n + 1) / 2


def test_a_sensor_reads_the_last_multiple_of_its_period_not_the_end_of_the_step() -> None:
    sup = _supervisor(
        f"Robot {{ supervisor TRUE translation 0 0 {Z0} physics Physics {{ density -1 mass 1 }} "
        'boundingObject Sphere { radius 0.1 } children [ GPS { name "gps" } Accelerometer { name "acc" } ] }'
    )
    gps = sup.getDevice("gps")
    gps.enable(64)
    readings = []
    for _ in range(3):
        sup.step(96)
        readings.append(gps.getValues()[2])
    # samples at 64 ms (step 2), 128 and 192 ms (steps 4, 6: the second step(96) ends at 192), 256 ms (step 8)
    assert readings == pytest.approx([_height(2), _height(6), _height(8)], abs=1e-12)
    assert readings[0] != pytest.approx(_height(3), abs=1e-6)  # control: not the state after the step
    assert gps.getSpeedVector()[2] == pytest.approx(-G * DT * 8, abs=1e-9)  # the speed of the same instant


def test_values_sampled_at_a_supervisor_move_refresh_only_at_the_next_sampling_instant() -> None:
    sup = _supervisor('DEF R Robot { supervisor TRUE children [ GPS { name "gps" } DistanceSensor { name "ds" '
                      "lookupTable [ 0 0 0, 5 5 0 ] } ] }\n"
                      "DEF WALL Solid { translation 2 0 0 boundingObject Box { size 0.2 4 4 } }")
    gps, ds = sup.getDevice("gps"), sup.getDevice("ds")
    gps.enable(96)
    ds.enable(96)
    translation = sup.getFromDef("R").getField("translation")
    wall = sup.getFromDef("WALL").getField("translation")
    for _ in range(3):
        sup.step(32)
    assert sup.getTime() == pytest.approx(0.096)
    assert gps.getValues() == [0.0, 0.0, 0.0] and ds.getValue() == pytest.approx(1.9)
    translation.setSFVec3f([0.5, 0.0, 0.0])  # made at 96 ms: applied by the next step
    wall.setSFVec3f([3.0, 0.0, 0.0])
    for t in (0.128, 0.160):
        sup.step(32)
        assert sup.getTime() == pytest.approx(t)
        assert gps.getValues() == [0.0, 0.0, 0.0] and ds.getValue() == pytest.approx(1.9)  # still the 96 ms sample
    sup.step(32)
    assert gps.getValues() == pytest.approx([0.5, 0.0, 0.0]) and ds.getValue() == pytest.approx(2.4)


def test_gps_speed_is_nan_until_the_first_sample() -> None:
    sup = _supervisor('Robot { supervisor TRUE children [ GPS { name "gps" } ] }')
    gps = sup.getDevice("gps")
    assert math.isnan(gps.getSpeed())
    gps.enable(64)
    sup.step(32)
    assert math.isnan(gps.getSpeed()) and all(math.isnan(v) for v in gps.getSpeedVector())
    sup.step(32)
    assert gps.getSpeed() == 0.0


def test_a_solid_without_physics_moves_by_its_velocity_fields_and_sensors_sample_it() -> None:
    # A Robot without Physics (no body: a kinematic Solid) with linearVelocity v and angularVelocity ω moves by
    # v·dt and turns by |ω|·dt about ω every basic step (32 ms here). Its GPS, 0.1 m along the robot's x, samples
    # every 64 ms: after 96 ms it still shows the 64 ms pose, and its speed vector is the last step's displacement
    # of the device origin over dt. Control: a Solid without velocity fields stays where it is.
    sup = _supervisor("""Robot { supervisor TRUE translation 1 2 3 linearVelocity 0.5 -0.25 1 angularVelocity 0 0 1
  children [ GPS { name "gps" translation 0.1 0 0 } ] }
DEF STILL Solid { translation 0 0 1 }""")
    gps = sup.getDevice("gps")
    gps.enable(64)
    sup.step(96)
    t = 0.064

    def device_origin(time: float) -> list[float]:
        return [1 + 0.5 * time + 0.1 * math.cos(time), 2 - 0.25 * time + 0.1 * math.sin(time), 3 + time]

    assert gps.getValues() == pytest.approx(device_origin(t), abs=1e-12)
    before = device_origin(t - DT)
    speed = [(a - b) / DT for a, b in zip(device_origin(t), before, strict=True)]
    assert gps.getSpeedVector() == pytest.approx(speed, abs=1e-9)
    robot = sup.getSelf()
    assert robot.getPosition() == pytest.approx([1 + 0.5 * 0.096, 2 - 0.25 * 0.096, 3.096], abs=1e-12)
    assert robot.getVelocity() == pytest.approx([0.5, -0.25, 1, 0, 0, 1], abs=1e-12)
    assert robot.getField("translation").getSFVec3f() == pytest.approx(robot.getPosition(), abs=1e-12)
    assert sup.getFromDef("STILL").getPosition() == [0.0, 0.0, 1.0]


def test_enable_keeps_the_last_sample_until_the_next_one(capfd: pytest.CaptureFixture[str]) -> None:
    """Webots' controller library caches each sensor's last values and ``enable`` leaves that cache alone
    (webots-devices.md §0.2: a disabled device returns its cached value, NaN only if never sampled): a sensor
    re-enabled, or given a new period, reads its last sample until its next one falls due, never NaN.
    Control: the runtime before cleared the values on every enable, so these reads were NaN."""
    sup = _supervisor(
        f"Robot {{ supervisor TRUE translation 0 0 {Z0} physics Physics {{ density -1 mass 1 }} "
        'boundingObject Sphere { radius 0.1 } children [ GPS { name "gps" } DistanceSensor { name "ds" '
        "lookupTable [ 0 0 0, 20 20 0 ] rotation 0 1 0 1.5707963 } ] }\n"  # the ray points down at the floor: it reads the height
        "Solid { boundingObject Plane { size 100 100 } }"
    )
    gps, ds = sup.getDevice("gps"), sup.getDevice("ds")
    assert math.isnan(gps.getValues()[2])  # never sampled (a disabled read: the error line, the cached NaN)
    for sensor in (gps, ds):
        sensor.enable(32)
    sup.step(32)
    z1, d1 = gps.getValues()[2], ds.getValue()
    assert z1 == pytest.approx(_height(1), abs=1e-12) and d1 == pytest.approx(_height(1), abs=1e-9)
    for sensor in (gps, ds):
        sensor.disable()
    sup.step(64)
    assert gps.getValues()[2] == z1 and ds.getValue() == d1  # disabled: the cached (stale) values
    for sensor in (gps, ds):
        sensor.enable(64)  # a new period: due 64 ms from now
    assert gps.getValues()[2] == z1 and ds.getValue() == d1
    sup.step(32)
    assert gps.getValues()[2] == z1 and ds.getValue() == d1  # not due yet: still the sample of 32 ms
    sup.step(32)
    assert gps.getValues()[2] == pytest.approx(_height(5), abs=1e-12)  # sampled at 160 ms
    assert ds.getValue() == pytest.approx(_height(5), abs=1e-9)
    assert "called for a disabled device" in capfd.readouterr().err
