"""Hostile device fields in a world (and motor maxima edited at run time): the load corrects them with a warning,
the simulation runs, nothing allocates gigabytes or raises out of a step.

D = /work/shared/reference/webots-devices.md, O = .../webots-on-ode.md. Expected values are hand computations."""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor
from tests.support.sensor_worlds import sensor_world

TS = 8
MAX_RAYS = 2**22  # the bound the load puts on a Lidar's or RangeFinder's rays (hand-picked: 2048 x 2048)


# ------------------------------------------------------------------------------------------ depth devices


def test_a_lidar_of_too_many_rays_gets_fewer_layers() -> None:
    # 16384 columns, 1024 layers (D §3.1's check passes: 0.2·16384/1.5708 ≈ 2086 ≥ 1024): 16.8 M rays, whose
    # directions alone took gigabytes; cut to 2**22 // 16384 = 256 layers, with a warning
    sup = sensor_world('Lidar { name "lidar" horizontalResolution 16384 numberOfLayers 1024 }', "")
    lidar = sup.getDevice("lidar")
    assert lidar.getNumberOfLayers() == MAX_RAYS // 16384 == 256
    assert lidar.getHorizontalResolution() == 16384
    assert any("rays is more than dualtwin casts" in w and "numberOfLayers set to 256" in w
               for w in sup.simulation.build_warnings)


def test_a_range_finder_of_too_many_rays_gets_fewer_rows() -> None:
    sup = sensor_world('RangeFinder { name "rf" width 16384 height 16384 }', "")
    rf = sup.getDevice("rf")
    assert (rf.getWidth(), rf.getHeight()) == (16384, 256)
    assert any("height set to 256" in w for w in sup.simulation.build_warnings)


def test_a_lidar_within_the_ray_bound_is_kept() -> None:
    sup = sensor_world('Lidar { name "lidar" horizontalResolution 4096 numberOfLayers 64 verticalFieldOfView 1 }', "")
    assert sup.getDevice("lidar").getNumberOfLayers() == 64
    assert not any("rays is more" in w for w in sup.simulation.build_warnings)


@pytest.mark.parametrize(("device", "field", "value", "default"), [
    ('Lidar { name "d" verticalFieldOfView 1e308 }', "verticalFieldOfView", 1e308, 0.2),
    ('Lidar { name "d" verticalFieldOfView -1 }', "verticalFieldOfView", -1.0, 0.2),
    ('Lidar { name "d" fieldOfView 1e308 }', "fieldOfView", 1e308, 1.5708),
    ('Lidar { name "d" projection "planar" fieldOfView 4 }', "fieldOfView", 4.0, 1.5708),
    ('Lidar { name "d" tiltAngle -1e308 }', "tiltAngle", -1e308, 0.0),
    ('RangeFinder { name "d" fieldOfView 1e308 }', "fieldOfView", 1e308, 0.7854),
])
def test_a_depth_device_angle_out_of_range_takes_its_default(device: str, field: str, value: float,
                                                              default: float) -> None:
    # D §3.1: verticalFieldOfView in (0, π], fieldOfView ≤ π if planar, tiltAngle in [−π/2, π/2]. A vertical
    # field of view of 1e308 raised OverflowError out of the load (the layer check's bound was infinite); a field
    # of view of 1e308 gave NaN ray directions and a point cloud that raised ValueError
    sup = sensor_world(device, "")
    assert any(f"{field} {value:g} is out of range; using {default:g}" in w for w in sup.simulation.build_warnings)
    d = sup.getDevice("d")
    d.enable(TS)
    if hasattr(d, "enablePointCloud"):
        d.enablePointCloud()
    assert sup.step(TS) != -1
    image = d.getRangeImage()
    assert not any(math.isnan(r) for r in image)
    if hasattr(d, "getPointCloud"):
        assert len(d.getPointCloud()) == len(image)


# ------------------------------------------------------------------------------------------ motor maxima

ROBOT = ("Robot {{ supervisor TRUE translation 0 0 1 boundingObject Box {{ size 0.1 0.1 0.1 }} "
         "physics Physics {{ density -1 mass 1 }} children [ {children} ] }}")
PROPELLER = ("Propeller {{ shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 1e-5 0 "
             'device RotationalMotor {{ name "prop" {motor} }} }}')
TRACK = ('Track {{ translation 0 0 -0.2 boundingObject Box {{ size 1 0.4 0.1 }} physics Physics {{ mass 5 }} '
         'device [ LinearMotor {{ name "belt" {motor} }} ] }}')
HINGE = ('HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }} device [ RotationalMotor {{ name "hinge" '
         '{motor} }} ] endPoint Solid {{ translation 0.5 0 0 boundingObject Sphere {{ radius 0.05 }} '
         "physics Physics {{ density -1 mass 1 }} }} }}")


def _sup(children: str) -> Supervisor:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} gravity 0 }}\n{ROBOT.format(children=children)}\n"
    return quiet_supervisor(text)


@pytest.mark.parametrize(("device", "template", "field", "getter"), [
    ("prop", PROPELLER, "maxTorque", "getMaxTorque"),
    ("belt", TRACK, "maxForce", "getMaxForce"),
    ("hinge", HINGE, "maxTorque", "getMaxTorque"),
    ("hinge", HINGE, "maxVelocity", "getMaxVelocity"),
])
@pytest.mark.parametrize("value", [-1e308, -3.0])
def test_a_negative_motor_maximum_in_the_world_is_made_positive(device: str, template: str, field: str,
                                                                getter: str, value: float) -> None:
    # a Propeller with maxTorque -1e308 clamped its torque into [1e308, -1e308], i.e. to +1e308: ODE stopped
    # inside the first step (SimulationUnstable out of step())
    sup = _sup(template.format(motor=f"{field} {value:g}"))
    assert any(f"{field} {value:g} is negative; using {-value:g}" in w for w in sup.simulation.build_warnings)
    motor = sup.getDevice(device)
    assert getattr(motor, getter)() == -value
    motor.setPosition(math.inf)
    motor.setVelocity(1.0)
    for _ in range(20):
        assert sup.step(TS) != -1


def test_a_negative_motor_maximum_edited_at_run_time_is_made_positive() -> None:
    sup = _sup(HINGE.format(motor=""))
    motor = sup.getDevice("hinge")
    assert sup.step(TS) != -1
    node = sup.getFromDevice(motor._tag)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        node.getField("maxTorque").setSFFloat(-5.0)
        assert sup.step(TS) != -1
    assert node.getField("maxTorque").getSFFloat() == 5.0
    assert any("maxTorque -5 is negative; using 5" in str(w.message) for w in caught)


@pytest.mark.parametrize(("device", "template"), [("prop", PROPELLER), ("belt", TRACK), ("hinge", HINGE)])
def test_a_negative_acceleration_in_the_world_is_unlimited(device: str, template: str) -> None:
    # O §5.1: acceleration -1 is unlimited; a Propeller spun up by -1e308 rad/s² a step stopped ODE in the step
    sup = _sup(template.format(motor="acceleration -1e308"))
    assert any("acceleration -1e+308 is negative; using -1 (unlimited)" in w for w in sup.simulation.build_warnings)
    motor = sup.getDevice(device)
    assert motor.getAcceleration() == -1.0
    motor.setPosition(math.inf)
    motor.setVelocity(1.0)
    for _ in range(20):
        assert sup.step(TS) != -1


def test_get_from_device_answers_a_propeller_motor_node() -> None:
    # R (Supervisor.getFromDevice): the device's node; for a Propeller's motor it answered None
    sup = _sup(PROPELLER.format(motor=""))
    node = sup.getFromDevice(sup.getDevice("prop")._tag)
    assert node is not None and node.getTypeName() == "RotationalMotor"
    assert node.getField("name").getSFString() == "prop"
