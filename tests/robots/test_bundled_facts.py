"""The bundled Pioneer 3-AT-like robot and six-joint arm against the published facts, in both twins.

Each test cites the reference line it pins: ``ODE:L`` is a line of /work/shared/reference/webots-on-ode.md
(§7.2, the Pioneer 3-AT from Webots' Pioneer3at.proto) and ``UR:L`` one of
/work/shared/reference/arm-ur5e-facts.md. The Webots twin is read from the ODE scene its ``Simulation`` builds
(bodies, geoms, joints, motors), the MuJoCo twin from the compiled model after ``mj_forward``; every fact is
checked in both, and the two twins against each other. Where a model departs from the facts on purpose, the
test pins the departure that docs/guides/pioneer.md or docs/guides/arm.md documents.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import mujoco
import numpy as np
import pytest

from dualtwin.robots.binding import resolve_robot
from dualtwin.twins import make_twin
from dualtwin.webots import load_world, ode
from dualtwin.webots.physics import Simulation

Shape = tuple[str, tuple[float, ...], np.ndarray, np.ndarray]  # kind, ODE-style size, world centre, |z axis|


@pytest.fixture(scope="module", params=["pioneer3at", "arm", "arm_payload"])
def twins(request: pytest.FixtureRequest) -> Iterator[tuple[str, Simulation, Any, Any]]:
    robot = resolve_robot(request.param)
    sim = Simulation(load_world(robot.model_path("webots")))
    model = mujoco.MjModel.from_xml_path(str(robot.model_path("mujoco")))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    yield request.param, sim, model, data
    sim.close()


def _load(name: str) -> tuple[Simulation, Any, Any]:
    robot = resolve_robot(name)
    sim = Simulation(load_world(robot.model_path("webots")))
    model = mujoco.MjModel.from_xml_path(str(robot.model_path("mujoco")))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return sim, model, data


@pytest.fixture(scope="module")
def pioneer() -> Iterator[tuple[Simulation, Any, Any]]:
    sim, model, data = _load("pioneer3at")
    yield sim, model, data
    sim.close()


@pytest.fixture(scope="module")
def arm() -> Iterator[tuple[Simulation, Any, Any]]:
    sim, model, data = _load("arm")
    yield sim, model, data
    sim.close()


def ode_shapes(sim: Simulation) -> dict[str, list[Shape]]:
    """Collision primitives of every ODE body (by its root Solid's DEF; static Solids by their own) at load."""
    shapes: dict[str, list[Shape]] = {}
    for ptr, geom in sim.geoms.items():
        if geom.is_plane:
            continue
        cls = sim._lib.dGeomGetClass(ptr)
        size = ode.primitive_size(sim._lib, ptr, cls)
        assert size is not None
        pos, rot = ode.geom_pose(sim._lib, ptr)
        owner = geom.body.root if geom.body is not None else geom.solid  # a merged Solid counts as its body's
        key = owner.node.def_name or owner.name
        shapes.setdefault(key, []).append(
            (geom.kind.lower(), tuple(size), np.array(pos), np.abs([rot[2], rot[5], rot[8]])))
    return shapes


def mj_shapes(model: Any, data: Any) -> dict[str, list[Shape]]:
    """Collision geoms of every MuJoCo body, in the same form (a cylinder's size is radius, half length)."""
    kinds = {int(mujoco.mjtGeom.mjGEOM_BOX): "box", int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder"}
    shapes: dict[str, list[Shape]] = {}
    for g in range(model.ngeom):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue  # visual
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE or model.geom_bodyid[g] == 0:
            continue  # the floor and static world geoms
        kind = kinds[int(model.geom_type[g])]
        size = tuple(model.geom_size[g][: 3 if kind == "box" else 2])
        axis = np.abs(data.geom_xmat[g].reshape(3, 3)[:, 2])
        shapes.setdefault(model.body(model.geom_bodyid[g]).name, []).append(
            (kind, size, data.geom_xpos[g].copy(), axis))
    return shapes


def _sorted(shapes: list[Shape]) -> list[Shape]:
    return sorted(shapes, key=lambda s: (s[0], *np.round(s[2], 6), *np.round(s[1], 6)))


def _same_shapes(a: list[Shape], b: list[Shape]) -> bool:
    if len(a) != len(b):
        return False
    return all(x[0] == y[0] and np.allclose(x[1], y[1], atol=1e-9) and np.allclose(x[2], y[2], atol=1e-6)
               and np.allclose(x[3], y[3], atol=1e-6) for x, y in zip(_sorted(a), _sorted(b), strict=True))


def ode_joint_line(sim: Simulation, joint: Any) -> tuple[np.ndarray, np.ndarray]:
    """A Webots joint's axis and anchor in the world at load (the joint frame is its closest upper Pose)."""
    frame = joint.frame_rel if joint.parent is None else sim.solid_world_pose(joint.parent) * joint.frame_rel
    return np.array(frame.rotate(joint.axis_local[0])), np.array(frame.apply(joint.anchor_local))


def _world_inertia(model: Any, data: Any, body: str) -> np.ndarray:
    b = model.body(body).id
    rot = data.ximat[b].reshape(3, 3)
    return np.asarray(rot @ np.diag(model.body_inertia[b]) @ rot.T)


# --------------------------------------------------------------------------------------------------
# both twins of every robot agree on every number below


def test_twins_agree_on_bodies_joints_motors_and_shapes(twins: tuple[str, Simulation, Any, Any]) -> None:
    name, sim, model, data = twins
    # Mass, world CoM and full inertia tensor per body (the ODE body's origin is its CoM; axes are the world's
    # at load, as MuJoCo's are after mj_forward).
    for body in sim.bodies:
        body_name = str(body.root.node.def_name)
        b = model.body(body_name).id
        assert body.mass == pytest.approx(model.body_mass[b], rel=1e-6)
        assert np.allclose(body.pos[:3], data.xipos[b], atol=1e-5)
        ode_inertia = np.array(body.inertia).reshape(3, 3)
        assert np.allclose(ode_inertia, _world_inertia(model, data, body_name),
                           atol=1e-6 * max(1.0, np.abs(ode_inertia).max()))
    assert sum(b.mass for b in sim.bodies) == pytest.approx(model.body_mass.sum(), rel=1e-9)
    # Joint axes and anchors in the world; Webots motor limits against the MJCF's forcerange and motor record.
    for joint in sim.joints:
        j = model.joint(joint.node.def_name).id
        assert not model.jnt_limited[j]  # no hard stops in either twin (Webots: minStop = maxStop = 0)
        assert joint.params[0] is not None
        assert joint.params[0].fields["minStop"] == joint.params[0].fields["maxStop"] == 0.0
        axis, anchor = ode_joint_line(sim, joint)
        assert np.allclose(data.xaxis[j], axis, atol=1e-12) and np.allclose(data.xanchor[j], anchor, atol=1e-9)
        motor = joint.motors[0]
        assert motor is not None
        a = model.actuator(motor.name).id
        assert tuple(model.actuator_forcerange[a]) == (-motor.max_force, motor.max_force)
        data_ = model.numeric(f"webots_motor.{motor.name}").data
        assert data_[0] == pytest.approx(motor.max_velocity, rel=1e-5)
        assert tuple(data_[1:5]) == (motor.kp, motor.ki, motor.kd, motor.acceleration)
        limits = (motor.min_position, motor.max_position)
        assert tuple(data_[5:]) == (() if limits == (0.0, 0.0) else pytest.approx(limits, rel=1e-5))
        dof = model.jnt_dofadr[j]
        damping = joint.params[0].fields["dampingConstant"]
        assert (model.dof_damping[dof], model.dof_frictionloss[dof], model.dof_armature[dof]) == (damping, 0, 0)
        assert joint.static_friction == [0.0]
    # The same collision primitives, body by body.
    ode_by_body, mj_by_body = ode_shapes(sim), mj_shapes(model, data)
    ode_by_body.pop("RAMP", None)  # static: a world geom in MuJoCo
    assert set(ode_by_body) == set(mj_by_body), name
    for body_name, shapes in ode_by_body.items():
        assert _same_shapes(shapes, mj_by_body[body_name]), body_name
    # Physics steps: the converter gives MuJoCo the largest step <= 2 ms dividing basicTimeStep.
    assert model.opt.timestep == pytest.approx(min(sim.dt, 0.002))


# --------------------------------------------------------------------------------------------------
# Pioneer 3-AT (webots-on-ode.md §7.2)

WHEEL_ANCHORS = {  # ODE:L576-578 (DEF names, anchors); names ODE:L579-580
    "FRONT_LEFT_WHEEL": ((0.1331, 0.197, 0.11), "front left wheel"),
    "FRONT_RIGHT_WHEEL": ((0.1331, -0.197, 0.11), "front right wheel"),
    "BACK_LEFT_WHEEL": ((-0.1331, 0.197, 0.11), "back left wheel"),
    "BACK_RIGHT_WHEEL": ((-0.1331, -0.197, 0.11), "back right wheel"),
}
# ODE:L564-572 without the antennas (L569) and the four corner boxes (L571): pioneer.md says they are left out.
BODY_PRIMITIVES: list[tuple[str, tuple[float, ...], tuple[float, float, float], int]] = [
    ("box", (0.201, 0.0985, 0.1), (0.0, 0.0, 0.173), 2),  # MAIN_BODY_BOX, footprint 0.402 x 0.197 (L564-566)
    ("box", (0.166, 0.132, 0.1), (0.0, 0.0, 0.173), 2),  # BODY_BOX, footprint 0.332 x 0.264 (L564-566)
    ("cylinder", (0.19, 0.002), (0.064, 0.0, 0.273), 2),  # FRONT_TOP (L567)
    ("cylinder", (0.17, 0.002), (-0.0835, 0.0, 0.273), 2),  # BACK_TOP (L567)
    ("cylinder", (0.145, 0.025), (0.106, 0.0, 0.247), 2),  # FRONT_RING (L568)
    ("cylinder", (0.145, 0.025), (-0.104, 0.0, 0.247), 2),  # BACK_RING (L568)
    ("cylinder", (0.025, 0.2), (0.134, 0.0, 0.111), 1),  # FRONT_AXLE, axis robot y (L572)
    ("cylinder", (0.025, 0.2), (-0.132, 0.0, 0.111), 1),  # BACK_AXLE (L572)
]


def test_pioneer_masses(pioneer: tuple[Simulation, Any, Any]) -> None:
    sim, model, _ = pioneer
    masses = {b.root.node.def_name: b.mass for b in sim.bodies}
    assert masses.pop("pioneer") == model.body_mass[model.body("pioneer").id] == 8.8  # ODE:L562
    for joint in WHEEL_ANCHORS:
        assert masses.pop(f"{joint}_SOLID") == model.body_mass[model.body(f"{joint}_SOLID").id] == 0.8  # L583
    assert not masses
    assert sum(b.mass for b in sim.bodies) == pytest.approx(12.0) == model.body_mass.sum()  # ODE:L585


def test_pioneer_wheels(pioneer: tuple[Simulation, Any, Any]) -> None:
    sim, model, data = pioneer
    ode_by_body, mj_by_body = ode_shapes(sim), mj_shapes(model, data)
    joints = {j.node.def_name: j for j in sim.joints}
    assert set(joints) == set(WHEEL_ANCHORS)  # four hinges, no steering joint (ODE:L588)
    for joint_name, (anchor, wheel) in WHEEL_ANCHORS.items():
        joint = joints[joint_name]
        assert joint.kind == "hinge" and joint.axis_local == [(0.0, 1.0, 0.0)]  # ODE:L577
        assert joint.anchor_local == anchor and joint.child is not None  # ODE:L577-578
        assert joint.child.name == wheel  # ODE:L579-580
        j = model.joint(joint_name).id
        assert tuple(data.xaxis[j]) == (0.0, 1.0, 0.0)
        assert np.allclose(data.xanchor[j], anchor, atol=1e-12)
        # Cylinder radius 0.11, height 0.095, axis along robot y, centred on the anchor (ODE:L581-582, L584-585).
        for shapes in (ode_by_body[f"{joint_name}_SOLID"], mj_by_body[f"{joint_name}_SOLID"]):
            ((kind, size, centre, axis),) = shapes
            assert kind == "cylinder" and size == pytest.approx((0.11, 0.095 / 2), abs=1e-12)
            assert np.allclose(centre, anchor, atol=1e-12) and np.allclose(axis, (0, 1, 0), atol=1e-12)
        # I_axis 0.00484, I_radial 0.003022 kg m^2 (ODE:L583, derived from the cylinder and 0.8 kg).
        body = next(b for b in sim.bodies if b.root is joint.child)
        expected = np.diag([0.003022, 0.00484, 0.003022])
        assert np.allclose(np.array(body.inertia).reshape(3, 3), expected, atol=1e-6)
        assert np.allclose(_world_inertia(model, data, f"{joint_name}_SOLID"), expected, atol=1e-6)
    # Wheelbase 0.2662 m, track 0.394 m, axle height 0.11 m = the wheel radius (ODE:L584-585).
    anchors = np.array([a for a, _ in WHEEL_ANCHORS.values()])
    assert np.ptp(anchors[:, 0]) == pytest.approx(0.2662) and np.ptp(anchors[:, 1]) == pytest.approx(0.394)


def test_pioneer_body_shape_and_inertia(pioneer: tuple[Simulation, Any, Any]) -> None:
    sim, model, data = pioneer
    expected: list[Shape] = [(k, s, np.array(c), np.eye(3)[axis]) for k, s, c, axis in BODY_PRIMITIVES]
    assert _same_shapes(ode_shapes(sim)["pioneer"], expected)
    assert _same_shapes(mj_shapes(model, data)["pioneer"], expected)
    # Webots' derived inertia of all 14 primitives: CoM (0.0005, 0, 0.1830) m, diag(0.0787, 0.1454, 0.1589)
    # kg m^2 (ODE:L573-575). Without the corner boxes and antennas both twins sit within the ~4 % that
    # pioneer.md documents, and the CoM within 1.5 mm.
    body = next(b for b in sim.bodies if b.root.node.def_name == "pioneer")
    for com, inertia in ((np.array(body.pos[:3]), np.array(body.inertia).reshape(3, 3)),
                         (data.xipos[model.body("pioneer").id], _world_inertia(model, data, "pioneer"))):
        assert np.allclose(com, (0.0005, 0.0, 0.1830), atol=1.5e-3)
        assert np.abs(inertia - np.diag(np.diag(inertia))).max() < 1e-4  # off-diagonals < 1e-4 (L575)
        assert np.diag(inertia) == pytest.approx((0.0787, 0.1454, 0.1589), rel=0.04)


def test_pioneer_motors_and_sensors(pioneer: tuple[Simulation, Any, Any]) -> None:
    sim, model, _ = pioneer
    for joint in sim.joints:
        motor, sensor = joint.motors[0], joint.sensors[0]
        assert motor is not None and sensor is not None and joint.child is not None
        assert motor.name == joint.child.name and sensor.name == f"{motor.name} sensor"  # ODE:L586-588
        assert (motor.max_velocity, motor.max_force) == (6.4, 20.0)  # ODE:L586
        assert (motor.acceleration, motor.kp, motor.ki, motor.kd) == (-1.0, 10.0, 0.0, 0.0)  # ODE:L587
        assert (motor.min_position, motor.max_position) == (0.0, 0.0)  # unlimited position (ODE:L587)
        assert tuple(model.actuator(motor.name).forcerange) == (-20.0, 20.0)
        assert tuple(model.numeric(f"webots_motor.{motor.name}").data) == pytest.approx((6.4, 10, 0, 0, -1))
        assert model.sensor(sensor.name).type == mujoco.mjtSensor.mjSENS_JOINTPOS


def test_pioneer_contacts(pioneer: tuple[Simulation, Any, Any]) -> None:
    sim, model, _ = pioneer
    # Webots' defaults as the shipped world uses them (ODE:L592-594), here written out: one ContactProperties.
    (props,) = sim.contact_properties
    f = props.fields
    assert (f["material1"], f["material2"], f["coulombFriction"]) == ("default", "default", [1.0])
    assert (f["bounce"], f["bounceVelocity"], f["softERP"], f["softCFM"]) == (0.5, 0.01, 0.2, 0.001)
    assert {s.material for s in sim.solids} == {"default"}  # no contactMaterial anywhere (ODE:L560-561)
    assert [(r.name, r.self_collision) for r in sim.robots] == [("Pioneer 3-AT", False)]  # ODE:L558, L561
    assert any(g.is_plane for g in sim.geoms.values())  # the floor is a Plane (ODE:L595)
    # MuJoCo: mu 1 on every collision geom, plain 3-D friction; the floor a plane.
    collision = [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    assert {model.geom_friction[g][0] for g in collision} == {1.0}
    assert {model.geom_condim[g] for g in collision} == {3}
    assert model.geom("floor").type == mujoco.mjtGeom.mjGEOM_PLANE


@pytest.mark.parametrize("twin_name", ["webots", "mujoco"])
def test_pioneer_drives_forward_at_its_top_speed(twin_name: str) -> None:
    """A positive wheel velocity rolls the robot toward +x; 6.4 rad/s x 0.11 m = 0.704 m/s (ODE:L588-589)."""
    twin = make_twin(twin_name, resolve_robot("pioneer3at"))
    twin.reset(0)
    xs = []
    for _ in range(2):
        for _ in range(round(1.0 / twin.control_period)):
            for wheel in (w for _, w in WHEEL_ANCHORS.values()):
                twin.command(wheel, "velocity", 6.4)
            twin.step()
        xs.append(float(twin.body_position("pioneer")[0]))
    assert xs[0] > 0.5
    assert xs[1] - xs[0] == pytest.approx(6.4 * 0.11, rel=0.03)


# --------------------------------------------------------------------------------------------------
# The arm (arm-ur5e-facts.md)

JOINTS = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
LINKS = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"]
# UR's standard DH table (a, d, alpha) and link masses, CoMs in DH frame i (UR:L38-45).
DH = [(0.0, 0.1625, math.pi / 2), (-0.425, 0.0, 0.0), (-0.3922, 0.0, 0.0),
      (0.0, 0.1333, math.pi / 2), (0.0, 0.0997, -math.pi / 2), (0.0, 0.0996, 0.0)]
UR_MASSES = [3.761, 8.058, 2.846, 1.37, 1.3, 0.365]
UR_COMS = [(0.0, -0.02561, 0.00193), (0.2125, 0.0, 0.11336), (0.15, 0.0, 0.0265),
           (0.0, -0.0018, 0.01634), (0.0, 0.0018, 0.01634), (0.0, 0.0, -0.001159)]
# ROS 2 inertia diagonals (UR:L52), long axis of upper arm and forearm along W x, flange axis along W y (UR:L118).
INERTIA = [(0.007, 0.00648, 0.00657), (0.01506, 0.3339, 0.3325), (0.004, 0.0788, 0.0785),
           (0.00165, 0.00136, 0.00126), (0.00136, 0.00128, 0.00097), (0.000187, 0.000258, 0.000189)]
MAX_TORQUE = [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]  # size 3 for J1-J3, size 1 for the wrists (UR:L26, L28)
# The primitive approximation (UR:L99-114): link, axis, radius, length, centre in W at q = 0.
PRIMITIVES = [
    ("arm", 2, 0.075, 0.100, (0.0, 0.0, 0.050)), ("shoulder_link", 2, 0.060, 0.125, (0.0, 0.0, 0.1625)),
    ("shoulder_link", 1, 0.060, 0.090, (0.0, 0.030, 0.1625)),
    ("upper_arm_link", 1, 0.060, 0.130, (0.0, 0.138, 0.1625)),
    ("upper_arm_link", 0, 0.050, 0.305, (0.2125, 0.138, 0.1625)),
    ("upper_arm_link", 1, 0.060, 0.140, (0.425, 0.133, 0.1625)),
    ("forearm_link", 1, 0.055, 0.100, (0.425, 0.020, 0.1625)),
    ("forearm_link", 0, 0.038, 0.330, (0.620, 0.007, 0.1625)),
    ("forearm_link", 1, 0.040, 0.110, (0.8172, 0.006, 0.1625)),
    ("wrist_1_link", 1, 0.040, 0.085, (0.8172, 0.096, 0.1625)),
    ("wrist_1_link", 2, 0.040, 0.110, (0.8172, 0.1333, 0.1625)),
    ("wrist_2_link", 2, 0.038, 0.045, (0.8172, 0.1333, 0.095)),
    ("wrist_2_link", 1, 0.040, 0.108, (0.8172, 0.1333, 0.0628)),
    ("wrist_3_link", 1, 0.035, 0.045, (0.8172, 0.2104, 0.0628)),
]


def ur_chain() -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], np.ndarray]:
    """UR's DH chain at q = 0 in frame W (UR's DH base turned half a turn about z, UR:L92): each joint's axis
    and a point on it, each link's CoM, and the flange frame."""
    frame = np.diag([-1.0, -1.0, 1.0, 1.0])
    axes, points, coms = [], [], []
    for (a, d, alpha), com in zip(DH, UR_COMS, strict=True):
        axes.append(frame[:3, 2].copy())
        points.append(frame[:3, 3].copy())
        step = np.eye(4)
        c, s = math.cos(alpha), math.sin(alpha)
        step[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        step[:3, 3] = (a, 0.0, d)
        frame = frame @ step
        coms.append((frame @ np.array([*com, 1.0]))[:3])
    return axes, points, coms, frame


def test_arm_kinematics_follow_the_dh_table(arm: tuple[Simulation, Any, Any]) -> None:
    sim, model, data = arm
    axes, points, _, flange = ur_chain()
    joints = {j.node.def_name: j for j in sim.joints}
    assert list(joints) == JOINTS
    for name, axis, point in zip(JOINTS, axes, points, strict=True):
        j = model.joint(name).id
        for twin_axis, anchor in ((data.xaxis[j], data.xanchor[j]), ode_joint_line(sim, joints[name])):
            assert np.allclose(twin_axis, axis, atol=1e-12), name  # J1 z, J2-J4 y, J5 -z, J6 y (UR:L94)
            assert np.linalg.norm(np.cross(anchor - point, axis)) < 1e-9, name  # on UR's joint axis
    # Lateral offsets +0.138, -0.131, +0.1263 along y, summing to d4 (UR:L94; Webots and Menagerie, UR:L69, L79).
    lateral = [data.xanchor[model.joint(n).id][1] for n in ("shoulder_lift", "elbow", "wrist_2")]
    assert np.diff([0.0, *lateral]) == pytest.approx((0.138, -0.131, 0.1263), abs=1e-12)
    # The flange face (UR:L94), the wrist_3_link frame in both twins, about 850 mm from J1's axis (UR:L11).
    w3 = next(b for b in sim.bodies if b.root.node.def_name == "wrist_3_link")
    ode_flange = np.array(sim.solid_world_pose(w3.root).t)
    for face in (data.xpos[model.body("wrist_3_link").id], ode_flange):
        assert np.allclose(face, flange[:3, 3], atol=1e-12) and np.allclose(face, (0.8172, 0.2329, 0.0628))
        assert math.hypot(face[0], face[1]) == pytest.approx(0.850, abs=0.001)


def test_arm_masses_coms_and_inertia(arm: tuple[Simulation, Any, Any]) -> None:
    sim, model, data = arm
    _, _, coms, _ = ur_chain()
    bodies = {b.root.node.def_name: b for b in sim.bodies}
    for link, mass, com, inertia in zip(LINKS, UR_MASSES, coms, INERTIA, strict=True):
        b = model.body(link).id
        assert bodies[link].mass == model.body_mass[b] == mass  # UR:L40-45 (Webots' UR5e.proto too, UR:L77)
        # UR's CoMs through the DH chain; the model holds them rounded to the millimetre (UR:L95): <= 0.4 mm.
        for twin_com in (np.array(bodies[link].pos[:3]), data.xipos[b]):
            assert np.abs(twin_com - com).max() < 4.1e-4, link
        # The ROS 2 diagonals (UR:L52, L118); the forearm's ixz 0.00137 is left out (arm.md says so).
        for tensor in (np.array(bodies[link].inertia).reshape(3, 3), _world_inertia(model, data, link)):
            assert np.allclose(tensor, np.diag(inertia), atol=1e-9), link
    assert sum(b.mass for b in sim.bodies) == pytest.approx(17.70) == model.body_mass.sum()  # UR:L47
    # The base is fixed and carries no mass in either twin (UR:L101 gives it 4.0 / 3.0 kg; it never moves).
    assert model.body_mass[model.body("arm").id] == 0.0 and "arm" not in bodies


def test_arm_motors(arm: tuple[Simulation, Any, Any]) -> None:
    sim, model, _ = arm
    for joint, torque in zip(sim.joints, MAX_TORQUE, strict=True):
        motor = joint.motors[0]
        assert motor is not None and joint.sensors[0] is not None
        name = joint.node.def_name
        assert motor.name == name and joint.sensors[0].name == f"{name} sensor"
        assert motor.max_force == torque and tuple(model.actuator(name).forcerange) == (-torque, torque)
        # pi rad/s on every joint (UR:L13, L120); Webots' proto lets the wrists run at 2 pi (UR:L74), arm.md
        # says the model keeps UR's figure.
        assert motor.max_velocity == math.pi
        # +-360 degrees (UR:L12) as motor position limits, no hard stops (UR:L76); the elbow's +-pi is the
        # Webots proto's and Menagerie's (UR:L63, L74), as arm.md documents.
        limit = math.pi if name == "elbow" else 2 * math.pi
        assert (motor.min_position, motor.max_position) == (-limit, limit)
        # Webots' defaults: PID (10, 0, 0), unlimited acceleration (UR:L75).
        assert (motor.kp, motor.ki, motor.kd, motor.acceleration) == (10.0, 0.0, 0.0, -1.0)
        numeric = model.numeric(f"webots_motor.{name}").data
        assert tuple(numeric) == pytest.approx((math.pi, 10, 0, 0, -1, -limit, limit), rel=1e-5)
        # No damping, friction or armature (UR:L76, L88; Menagerie's 0.1 armature is not used, arm.md).
        dof = model.jnt_dofadr[model.joint(name).id]
        assert (model.dof_damping[dof], model.dof_frictionloss[dof], model.dof_armature[dof]) == (0, 0, 0)
        assert joint.params[0] is not None and joint.params[0].fields["dampingConstant"] == 0.0
    # A 2 ms physics step in both twins: UR's controller runs at 500 Hz (UR:L17).
    assert sim.dt == model.opt.timestep == 0.002


def test_arm_shapes_follow_the_primitive_table(arm: tuple[Simulation, Any, Any]) -> None:
    sim, model, data = arm
    expected: dict[str, list[Shape]] = {}
    for link, axis, radius, length, centre in PRIMITIVES:
        expected.setdefault(link, []).append(("cylinder", (radius, length / 2), np.array(centre), np.eye(3)[axis]))
    ode_by_body, mj_by_body = ode_shapes(sim), mj_shapes(model, data)
    for link, shapes in expected.items():
        assert _same_shapes(ode_by_body[link], shapes), link
        assert _same_shapes(mj_by_body[link], shapes), link
    assert not sim.robots[0].self_collision  # adjacent caps overlap: no self-collision (UR:L117)


def test_arm_payload_is_the_rated_payload() -> None:
    """arm_payload carries UR's rated 5 kg (UR:L10): a cube of 8 cm, its centre 4 cm out along the flange axis."""
    sim, model, data = _load("arm_payload")
    _, _, coms, flange = ur_chain()
    w3 = next(b for b in sim.bodies if b.root.node.def_name == "wrist_3_link")
    centre = flange[:3, 3] + np.array([0.0, 0.04, 0.0])
    expected = (0.365 * coms[5] + 5.0 * centre) / 5.365
    for mass, com in ((w3.mass, np.array(w3.pos[:3])), (model.body_mass[model.body("wrist_3_link").id],
                                                        data.xipos[model.body("wrist_3_link").id])):
        assert mass == pytest.approx(5.365)
        assert np.abs(com - expected).max() < 1e-4
    ((kind, size, cube_centre, _),) = [s for s in mj_shapes(model, data)["wrist_3_link"] if s[0] == "box"]
    assert size == pytest.approx((0.04, 0.04, 0.04)) and np.allclose(cube_centre, centre, atol=1e-9)
    sim.close()
