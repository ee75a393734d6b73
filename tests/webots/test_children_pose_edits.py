"""A supervisor's edit of the ``translation`` or ``rotation`` of a Pose or Transform among a Solid's children moves
everything below it at the next step, as in Webots: the devices under it measure from where it puts them (a ray
sensor's distance, a GPS position, an accelerometer's centripetal reading at its new radius), the Shapes under it
are seen there by infra-red rays and cameras, Solids under it move (a DEF frame used in two Solids moves both),
a Solid merged into its parent's body takes its mass along, and a jointed Solid with its own body moves with its
joint. A reset puts everything back.

Expectations by hand; each test first checks the load state (the control), so code that leaves the cached
frames where the load put them fails the check after the edit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 2
H = TS / 1000


def _supervisor(scene: str, robot: str = "", gravity: float = 0.0) -> Supervisor:
    world = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity {gravity} }}
DirectionalLight {{ direction 0 0 -1 }}
{scene}
Robot {{ supervisor TRUE {robot} }}
"""
    sim = Simulation(load_world_text(world))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[-1].node)
    sup.step(TS)
    return sup


def _value(sup: Supervisor, name: str) -> float:
    sup.step(TS)
    return float(sup.getDevice(name).getValue())


_WALL = "Solid { translation 1 0 0.1 boundingObject Box { size 0.1 1 1 } }"  # near face at x = 0.95
_RAY = 'DistanceSensor { name "ds" lookupTable [ 0 0 0, 2 2 0 ] }'  # the distance in metres, up to 2 m


def test_a_distance_sensor_measures_from_where_its_moved_pose_puts_it_and_a_reset_puts_it_back() -> None:
    sup = _supervisor(_WALL, f"children [ DEF MOUNT Pose {{ children [ DEF DS {_RAY} ] }} ]")
    sup.getDevice("ds").enable(TS)
    assert _value(sup, "ds") == pytest.approx(0.95, abs=1e-9)
    mount = sup.getFromDef("MOUNT")
    mount.getField("translation").setSFVec3f([0.3, 0.0, 0.0])
    assert _value(sup, "ds") == pytest.approx(0.65, abs=1e-9)  # 0.3 m closer
    assert sup.getFromDef("DS").getPosition() == pytest.approx([0.3, 0.0, 0.0], abs=1e-12)
    mount.getField("rotation").setSFRotation([0.0, 0.0, 1.0, math.pi])
    assert _value(sup, "ds") == pytest.approx(2.0, abs=1e-9)  # looking away from the wall: nothing in range
    sup.simulationReset()
    sup.step(TS)
    sup.getDevice("ds").enable(TS)
    assert _value(sup, "ds") == pytest.approx(0.95, abs=1e-9)
    assert sup.getFromDef("DS").getPosition() == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)


def test_a_gps_below_two_poses_follows_the_outer_one_turned() -> None:
    # the GPS 0.1 m along the inner Pose's x, in the robot at (0, 0, 0.5): turning the outer Pose 90° about z
    # puts it at (0, 0.1, 0.5); moving the outer Pose by (0.2, 0, 0.1) then puts it at (0.2, 0.1, 0.6)
    robot = ('translation 0 0 0.5 children [ DEF OUTER Pose { children [ Pose { translation 0.1 0 0 children [ '
             'GPS { name "gps" } ] } ] } ]')  # fmt: skip
    sup = _supervisor("", robot)
    gps = sup.getDevice("gps")
    gps.enable(TS)
    sup.step(TS)
    assert gps.getValues() == pytest.approx([0.1, 0.0, 0.5], abs=1e-12)
    outer = sup.getFromDef("OUTER")
    outer.getField("rotation").setSFRotation([0.0, 0.0, 1.0, math.pi / 2])
    sup.step(TS)
    assert gps.getValues() == pytest.approx([0.0, 0.1, 0.5], abs=1e-12)
    outer.getField("translation").setSFVec3f([0.2, 0.0, 0.1])
    sup.step(TS)
    assert gps.getValues() == pytest.approx([0.2, 0.1, 0.6], abs=1e-12)


def test_an_accelerometer_on_a_spinning_robot_reads_the_centripetal_acceleration_at_its_new_radius() -> None:
    # a robot spinning at 2 rad/s about z in zero gravity; the accelerometer's Pose at 0.1 m from the axis:
    # |a| = ω²r = 0.4 m/s² (to a few 1e-6 of the step's finite turn); moved to 0.3 m: 1.2 m/s²
    omega = 2.0
    robot = ('angularVelocity 0 0 2 physics Physics { density -1 mass 1 } boundingObject Sphere { radius 0.05 } '
             'children [ DEF ARM Pose { translation 0.1 0 0 children [ Accelerometer { name "acc" } ] } ]')  # fmt: skip
    sup = _supervisor("", robot)
    acc = sup.getDevice("acc")
    acc.enable(TS)

    for _ in range(3):
        sup.step(TS)
    assert math.hypot(*acc.getValues()) == pytest.approx(omega**2 * 0.1, rel=1e-5)
    sup.getFromDef("ARM").getField("translation").setSFVec3f([0.3, 0.0, 0.0])
    for _ in range(3):
        sup.step(TS)
    assert math.hypot(*acc.getValues()) == pytest.approx(omega**2 * 0.3, rel=1e-5)


def test_a_light_sensor_sees_a_point_light_where_its_moved_pose_puts_it() -> None:
    # a PointLight of intensity 1 and attenuation 1/d² in a Solid 2 m ahead of the sensor: E = 1/4, read
    # through the default table (×1000) as 250; its Pose moved 1 m towards the sensor: d = 1 m, 1000
    scene = 'Solid { translation 2 0 0 children [ DEF LAMP Pose { children [ PointLight { attenuation 0 0 1 } ] } ] }'
    sup = _supervisor(scene, 'children [ LightSensor { name "light" } ]')
    sup.getDevice("light").enable(TS)
    assert _value(sup, "light") == pytest.approx(250.0, rel=1e-9)
    sup.getFromDef("LAMP").getField("translation").setSFVec3f([-1.0, 0.0, 0.0])
    assert _value(sup, "light") == pytest.approx(1000.0, rel=1e-9)


def test_an_infra_red_sensor_sees_a_shape_where_its_moved_pose_puts_it() -> None:
    # a Shape without boundingObject, its Pose among the target Solid's children: only visual rays see it
    scene = ('Solid { translation 1 0 0 children [ DEF SHIFT Pose { children [ Shape { geometry Box { size 0.1 1 1 } } '
             '] } ] }')  # fmt: skip
    sup = _supervisor(scene, 'children [ DistanceSensor { name "ir" type "infra-red" lookupTable [ 0 0 0, 2 2 0 ] } ]')
    sup.getDevice("ir").enable(TS)
    assert _value(sup, "ir") == pytest.approx(0.95, abs=1e-9)
    sup.getFromDef("SHIFT").getField("translation").setSFVec3f([-0.4, 0.0, 0.0])
    assert _value(sup, "ir") == pytest.approx(0.55, abs=1e-9)


def test_a_camera_sees_a_shape_where_its_moved_pose_puts_it() -> None:
    # a red box straight ahead fills the image centre; its Pose moved 3 m to the side takes it out of view
    scene = ('Solid { translation 2 0 0 children [ DEF SHIFT Pose { children [ Shape { appearance PBRAppearance { '
             'baseColor 1 0 0 } geometry Box { size 0.4 0.4 0.4 } } ] } ] }')  # fmt: skip
    sup = _supervisor(scene, 'children [ Camera { name "cam" width 16 height 12 } ]')
    cam = sup.getDevice("cam")
    cam.enable(TS)
    sup.step(TS)

    def red_centre() -> bool:
        image = np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(12, 16, 4)
        b, g, r = (int(v) for v in image[6, 8, :3])
        return r > 100 and g < 80 and b < 80

    assert red_centre()
    sup.getFromDef("SHIFT").getField("translation").setSFVec3f([0.0, 3.0, 0.0])
    sup.step(TS)
    assert not red_centre()


def test_a_camera_draws_a_solid_imported_after_its_first_frame() -> None:
    # the scene drawn again after a supervisor changed it: a red box imported straight ahead fills the centre
    sup = _supervisor("", 'children [ Camera { name "cam" width 16 height 12 } ]')
    cam = sup.getDevice("cam")
    cam.enable(TS)
    sup.step(TS)

    def centre() -> list[int]:
        return [int(v) for v in np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(12, 16, 4)[6, 8, :3]]

    assert centre() == [0, 0, 0]  # nothing in view
    box = ('Solid { translation 2 0 0 children [ Shape { appearance PBRAppearance { baseColor 1 0 0 } geometry Box { '
           'size 0.4 0.4 0.4 } } ] }')  # fmt: skip
    sup.getRoot().getField("children").importMFNodeFromString(-1, box)
    sup.step(TS)
    b, g, r = centre()
    assert r > 100 and g < 80 and b < 80


def test_a_def_pose_used_in_two_solids_moves_the_solids_below_both() -> None:
    # a 0.2 m box Solid below DEF P in a Solid 1 m east and, USE'd, in a Solid 1 m north turned 90° (its x is
    # the world's y): near faces at 0.9 m; P moved 0.3 m along its x: both at 0.6 m
    scene = ('Solid { translation 1 0 0 children [ DEF P Pose { children [ Solid { boundingObject Box { size 0.2 0.2 '
             '0.2 } } ] } ] } Solid { translation 0 1 0 rotation 0 0 1 1.5707963267948966 children [ USE P ] }')  # fmt: skip
    sensors = ('children [ DistanceSensor { name "east" lookupTable [ 0 0 0, 2 2 0 ] } DistanceSensor { name "north" '
               'rotation 0 0 1 1.5707963267948966 lookupTable [ 0 0 0, 2 2 0 ] } ]')  # fmt: skip
    sup = _supervisor(scene, sensors)
    for name in ("east", "north"):
        sup.getDevice(name).enable(TS)
    assert [_value(sup, "east"), _value(sup, "north")] == pytest.approx([0.9, 0.9], abs=1e-9)
    sup.getFromDef("P").getField("translation").setSFVec3f([-0.3, 0.0, 0.0])
    assert [_value(sup, "east"), _value(sup, "north")] == pytest.approx([0.6, 0.6], abs=1e-9)


def test_a_merged_solid_moved_by_its_pose_takes_its_mass_along_and_a_reset_brings_it_back() -> None:
    # two 1 kg balls of radius 0.01 m, one at the body's origin, one merged 0.2 m away below DEF ARM: the centre
    # of mass halfway, I_z = 2·(2/5)·m·r² + (m/2)·d²; ARM moved to 0.4 m: the centre of mass at 0.2 m, I_z with d = 0.4
    ball = "physics Physics { density -1 mass 1 } boundingObject Sphere { radius 0.01 }"
    scene = f"DEF BODY Solid {{ {ball} children [ DEF ARM Pose {{ translation 0.2 0 0 children [ Solid {{ {ball} }} ] }} ] }}"
    sup = _supervisor(scene)
    body = sup.getFromDef("BODY")

    def spin_up() -> float:
        before = body.getVelocity()[5]
        body.addTorque([0.0, 0.0, 0.01], False)
        sup.step(TS)
        return body.getVelocity()[5] - before

    def inertia(d: float) -> float:
        return 2 * 0.4 * 1.0 * 0.01**2 + 0.5 * d**2

    assert body.getCenterOfMass() == pytest.approx([0.1, 0.0, 0.0], abs=1e-12)
    assert spin_up() == pytest.approx(0.01 * H / inertia(0.2), rel=1e-6)
    body.setVelocity([0.0] * 6)
    sup.getFromDef("ARM").getField("translation").setSFVec3f([0.4, 0.0, 0.0])
    sup.step(TS)
    assert body.getPosition() == pytest.approx([0.0, 0.0, 0.0], abs=1e-6)  # the Solid stays put (it turned 1e-6 rad)
    assert body.getCenterOfMass() == pytest.approx([0.2, 0.0, 0.0], abs=1e-6)
    assert spin_up() == pytest.approx(0.01 * H / inertia(0.4), rel=1e-6)
    sup.simulationReset()
    sup.step(TS)
    assert body.getCenterOfMass() == pytest.approx([0.1, 0.0, 0.0], abs=1e-12)
    assert spin_up() == pytest.approx(0.01 * H / inertia(0.2), rel=1e-6)


def test_a_jointed_solid_with_its_own_body_moves_with_the_pose_above_its_joint() -> None:
    # a hinge and its endPoint (a 0.1 m thick wall with a body) below DEF ARM in a static Solid at (1, 0, 0.1):
    # its near face at 0.95 m from the sensor; ARM moved 0.3 m towards it: 0.65 m, and it stays there
    scene = ('Solid { translation 1 0 0.1 children [ DEF ARM Pose { children [ HingeJoint { jointParameters '
             'HingeJointParameters { axis 0 0 1 } endPoint DEF TIP Solid { physics Physics { } boundingObject Box { '
             'size 0.1 1 1 } } } ] } ] }')  # fmt: skip
    sup = _supervisor(scene, f"children [ {_RAY} ]")
    sup.getDevice("ds").enable(TS)
    assert _value(sup, "ds") == pytest.approx(0.95, abs=1e-9)
    sup.getFromDef("ARM").getField("translation").setSFVec3f([-0.3, 0.0, 0.0])
    assert _value(sup, "ds") == pytest.approx(0.65, abs=1e-9)
    for _ in range(20):
        sup.step(TS)
    assert sup.getFromDef("TIP").getPosition() == pytest.approx([0.7, 0.0, 0.1], abs=1e-9)
    sup.simulationReset()
    sup.step(TS)
    sup.getDevice("ds").enable(TS)
    assert _value(sup, "ds") == pytest.approx(0.95, abs=1e-9)
    assert sup.getFromDef("TIP").getPosition() == pytest.approx([1.0, 0.0, 0.1], abs=1e-12)


def test_a_solid_with_its_own_body_fixed_in_a_static_solid_moves_with_its_pose_and_is_held_there() -> None:
    # a wall with Physics in a static Solid: a body fixed to the world (§3.3); its Pose moved 0.3 m towards the
    # sensor: 0.65 m, and under gravity it stays there, held where it now is
    scene = ('Solid { translation 1 0 0.1 children [ DEF ARM Pose { children [ DEF WALL Solid { physics Physics { } '
             'boundingObject Box { size 0.1 1 1 } } ] } ] }')  # fmt: skip
    sup = _supervisor(scene, f"children [ {_RAY} ]", gravity=9.81)
    sup.getDevice("ds").enable(TS)
    assert _value(sup, "ds") == pytest.approx(0.95, abs=1e-9)
    sup.getFromDef("ARM").getField("translation").setSFVec3f([-0.3, 0.0, 0.0])
    assert _value(sup, "ds") == pytest.approx(0.65, abs=1e-9)
    for _ in range(50):
        sup.step(TS)
    # held: a free fall would have taken it 5 cm down in 0.1 s (the fixed joint's softness lets it sag 0.1 mm)
    assert sup.getFromDef("WALL").getPosition() == pytest.approx([0.7, 0.0, 0.1], abs=1e-3)


def test_a_compass_below_a_turned_transform_reads_north_in_its_new_frame() -> None:
    # north is the world's +y (ENU): (0, 1, 0) in the compass frame at load; the Transform turned 90° about z
    # brings the compass's x onto north: (1, 0, 0)
    sup = _supervisor("", 'children [ DEF TURN Transform { children [ Compass { name "compass" } ] } ]')
    compass = sup.getDevice("compass")
    compass.enable(TS)
    sup.step(TS)
    assert compass.getValues() == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    sup.getFromDef("TURN").getField("rotation").setSFRotation([0.0, 0.0, 1.0, math.pi / 2])
    sup.step(TS)
    assert compass.getValues() == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)


def test_a_kinematic_joint_and_its_endpoint_move_with_the_pose_above_them() -> None:
    # a hinge whose endPoint has no Physics (kinematic) below DEF ARM in a static Solid at (1, 0, 0.1); ARM
    # moved 0.3 m towards the sensor: the endPoint's wall at 0.65 m; turned 0.5 rad about z as well: the ray
    # meets the turned 0.1 m thick wall at 0.7 - 0.05 / cos(0.5) m
    scene = ('Solid { translation 1 0 0.1 children [ DEF ARM Pose { children [ HingeJoint { jointParameters '
             'HingeJointParameters { axis 0 0 1 } endPoint DEF TIP Solid { boundingObject Box { size 0.1 1 1 } } } '
             '] } ] }')  # fmt: skip
    sup = _supervisor(scene, f"children [ {_RAY} ]")
    sup.getDevice("ds").enable(TS)
    assert _value(sup, "ds") == pytest.approx(0.95, abs=1e-9)
    arm = sup.getFromDef("ARM")
    arm.getField("translation").setSFVec3f([-0.3, 0.0, 0.0])
    assert _value(sup, "ds") == pytest.approx(0.65, abs=1e-9)
    arm.getField("rotation").setSFRotation([0.0, 0.0, 1.0, 0.5])
    assert _value(sup, "ds") == pytest.approx(0.7 - 0.05 / math.cos(0.5), abs=1e-9)


def test_a_propeller_below_a_turned_pose_pushes_along_its_new_shaft() -> None:
    # thrust t1·ω² = 1e-4·100² = 1 N on a 1 kg robot along the shaft (z); the Pose turned 90° about y puts the
    # shaft along x: the robot then gains 1 m/s² along x and no more along z
    robot = ('boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } children [ DEF MOUNT Pose { '
             'children [ Propeller { shaftAxis 0 0 1 thrustConstants 1e-4 0 torqueConstants 0 0 device '
             'RotationalMotor { name "prop" maxVelocity 200 maxTorque 1000 } } ] } ]')  # fmt: skip
    sup = _supervisor("", robot)
    prop = sup.getDevice("prop")
    prop.setPosition(math.inf)
    prop.setVelocity(100.0)
    for _ in range(100):  # full speed after 0.1 s
        sup.step(TS)
    drone = sup.getSelf()
    v0 = drone.getVelocity()
    for _ in range(100):
        sup.step(TS)
    v1 = drone.getVelocity()
    assert [(v1[0] - v0[0]) / 0.2, (v1[2] - v0[2]) / 0.2] == pytest.approx([0.0, 1.0], abs=1e-3)
    sup.getFromDef("MOUNT").getField("rotation").setSFRotation([0.0, 1.0, 0.0, math.pi / 2])
    sup.step(TS)
    v0 = drone.getVelocity()
    for _ in range(100):
        sup.step(TS)
    v1 = drone.getVelocity()
    assert [(v1[0] - v0[0]) / 0.2, (v1[2] - v0[2]) / 0.2] == pytest.approx([1.0, 0.0], abs=1e-3)


def test_a_box_asleep_on_a_platform_whose_pose_moves_away_wakes_and_falls() -> None:
    # a 0.1 m box resting on a static platform (no Physics) below DEF SLIDE; after 1.5 s at rest it sleeps
    # (physicsDisableTime 1 s); the platform moved 2 m aside: the box must wake and fall
    scene = ('Solid { children [ DEF SLIDE Pose { children [ Solid { boundingObject Box { size 1 1 0.1 } } ] } ] } '
             'DEF BOX Solid { translation 0 0 0.1 physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }')  # fmt: skip
    sup = _supervisor(scene, gravity=9.81)
    box = sup.getFromDef("BOX")
    for _ in range(750):
        sup.step(TS)
    z0 = box.getPosition()[2]
    assert z0 == pytest.approx(0.1, abs=1e-3)  # resting on the platform's top face at z = 0.05
    sup.getFromDef("SLIDE").getField("translation").setSFVec3f([2.0, 0.0, 0.0])
    for _ in range(50):
        sup.step(TS)
    assert box.getPosition()[2] < z0 - 0.01  # ½·g·t² = 4.9 cm in 0.1 s
