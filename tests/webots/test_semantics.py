"""Webots semantics of the ODE twin: joints, motors, masses, contacts, supervisor, reset, instability."""

from __future__ import annotations

import ctypes
import math

import pytest

from dualtwin.webots import ode
from dualtwin.webots.controller import Robot, Supervisor
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.physics import Simulation, SimulationUnstable
from tests.support.webots_scene import cart_pole, floor, node, world

G = 9.81


# ------------------------------------------------------------------------------------------ builders


def _arm(
    kind: str = "hinge",
    reverse: bool = True,
    params: dict | None = None,
    motor: Node | None = None,
    gravity: float = G,
    step_ms: float = 4.0,
) -> World:
    """A 1 kg bob on a hinge (axis y, bob at +x: gravity torque is positive) or a vertical slider.

    ``reverse``: the parent is the static environment (ODE reverse joint); otherwise the parent is a
    physics Solid fixed to the world through the static basis (§3.3).
    """
    params = dict(params or {})
    if kind == "hinge":
        params.setdefault("axis", (0.0, 1.0, 0.0))
        jp = node("HingeJointParameters", **params)
        bob_at = (0.5, 0.0, 0.0)
    else:
        params.setdefault("axis", (0.0, 0.0, 1.0))
        jp = node("JointParameters", **params)
        bob_at = (0.0, 0.0, 0.0)
    bob = node(
        "Solid",
        "BOB",
        name="bob",
        translation=bob_at,
        boundingObject=node("Sphere", radius=0.05),
        physics=node("Physics", density=-1.0, mass=1.0),
    )
    joint = node(
        "HingeJoint" if kind == "hinge" else "SliderJoint",
        "JOINT",
        jointParameters=jp,
        endPoint=bob,
        device=[motor, node("PositionSensor", name="sensor")]
        if motor is not None
        else [node("PositionSensor", name="sensor")],
    )
    if reverse:
        base = node(
            "Robot", "ARM", name="arm", translation=(0.0, 0.0, 1.0), children=[joint], supervisor=True
        )
    else:
        inner = node(
            "Solid",
            name="base",
            children=[joint],
            boundingObject=node("Box", size=(0.1, 0.1, 0.1)),
            physics=node("Physics", density=-1.0, mass=10.0),
        )
        base = node(
            "Robot", "ARM", name="arm", translation=(0.0, 0.0, 1.0), children=[inner], supervisor=True
        )
    return world(base, basicTimeStep=step_ms, gravity=gravity, physicsDisableTime=0.0)


def _supervisor(w) -> tuple[Simulation, Supervisor]:  # type: ignore[no-untyped-def]
    sim = Simulation(w)
    return sim, Supervisor(simulation=sim, robot_node=sim.robots[0].node)


# ------------------------------------------------------------------------------------------ joints


@pytest.mark.parametrize("reverse", [True, False])
def test_hinge_stops_hold(reverse: bool) -> None:
    sim = Simulation(_arm(reverse=reverse, params={"minStop": -0.3, "maxStop": 0.3}))
    assert sim.joints[0].reverse is reverse
    sim.step(int(2.0 / sim.dt))
    assert sim.joints[0].positions[0] == pytest.approx(0.3, abs=0.01)


@pytest.mark.parametrize("reverse", [True, False])
def test_slider_stops_hold(reverse: bool) -> None:
    sim = Simulation(_arm("slider", reverse=reverse, params={"minStop": -0.2, "maxStop": 0.3}))
    sim.step(int(2.0 / sim.dt))
    assert sim.joints[0].positions[0] == pytest.approx(-0.2, abs=0.005)


@pytest.mark.parametrize("reverse", [True, False])
def test_slider_spring_equilibrium(reverse: bool) -> None:
    # §4.5: spring rest = joint position 0 even with an initial ``position`` offset
    sim = Simulation(
        _arm(
            "slider",
            reverse=reverse,
            params={"springConstant": 100.0, "dampingConstant": 5.0, "position": 0.1},
        )
    )
    assert sim.joints[0].positions[0] == pytest.approx(0.1)
    sim.step(int(3.0 / sim.dt))
    assert sim.joints[0].positions[0] == pytest.approx(-G / 100.0, abs=1e-4)


@pytest.mark.parametrize("reverse", [True, False])
def test_hinge_spring_period(reverse: bool) -> None:
    k = 20.0
    sim = Simulation(
        _arm(reverse=reverse, params={"springConstant": k, "position": 0.1}, gravity=0.0, step_ms=1.0)
    )
    joint = sim.joints[0]
    samples = []
    for _ in range(3000):
        sim.step()
        samples.append((sim.time, joint.positions[0]))
    ups = [t0 for (t0, a0), (_, a1) in zip(samples, samples[1:], strict=False) if a0 < 0.0 <= a1]
    period = (ups[-1] - ups[0]) / (len(ups) - 1)
    inertia = 0.25 + 0.4 * 0.05**2
    assert period == pytest.approx(2 * math.pi * math.sqrt(inertia / k), rel=0.01)


def test_static_friction_brakes_an_unmotorised_joint() -> None:
    held = Simulation(_arm(params={"staticFriction": 6.0}))  # gravity torque 4.9 N·m < 6
    free = Simulation(_arm(params={"staticFriction": 3.0}))
    held.step(250)
    free.step(250)
    assert abs(held.joints[0].positions[0]) < 1e-3
    assert free.joints[0].positions[0] > 0.1


# ------------------------------------------------------------------------------------------ motors


@pytest.mark.parametrize("reverse", [True, False])
def test_motor_reaches_target_velocity(reverse: bool) -> None:
    sim, sup = _supervisor(_arm(reverse=reverse, motor=node("RotationalMotor", name="m"), gravity=0.0))
    motor = sup.getDevice("m")
    motor.setPosition(math.inf)
    motor.setVelocity(5.0)
    sup.step(400)
    p0 = sim.joints[0].positions[0]
    sup.step(400)
    assert (sim.joints[0].positions[0] - p0) / 0.4 == pytest.approx(5.0, rel=1e-3)
    assert sim.joint_velocity(sim.joints[0]) == pytest.approx(5.0, rel=1e-3)


def test_motor_velocity_is_torque_limited() -> None:
    # I = 0.251 kg·m²; 0.5 N·m gives 1.99 rad/s² so 5 rad/s is not reached within 1 s
    sim, sup = _supervisor(_arm(motor=node("RotationalMotor", name="m", maxTorque=0.5), gravity=0.0))
    motor = sup.getDevice("m")
    motor.setPosition(math.inf)
    motor.setVelocity(5.0)
    sup.step(1000)
    rate = -sim._lib.dJointGetHingeAngleRate(sim.joints[0].ptr)
    inertia = 0.25 + 0.4 * 0.05**2
    assert abs(rate) == pytest.approx(0.5 / inertia * 1.0, rel=0.02)
    assert abs(rate) < 5.0


def test_motor_torque_control_sign() -> None:
    sim, sup = _supervisor(_arm(motor=node("RotationalMotor", name="m"), gravity=0.0))
    sup.getDevice("m").setTorque(0.5)
    sup.step(1000)
    inertia = 0.25 + 0.4 * 0.05**2
    assert sim.joints[0].positions[0] == pytest.approx(0.5 / inertia / 2, rel=0.02)


@pytest.mark.parametrize("reverse", [True, False])
def test_position_control_converges(reverse: bool) -> None:
    sim, sup = _supervisor(_arm(reverse=reverse, motor=node("RotationalMotor", name="m", maxTorque=50.0)))
    motor = sup.getDevice("m")
    motor.setPosition(1.0)
    sup.step(3000)
    assert sim.joints[0].positions[0] == pytest.approx(1.0, abs=1e-3)
    assert motor.getTargetPosition() == 1.0


def test_initial_hold_keeps_a_loaded_joint_until_commanded() -> None:
    # §5.1: target position = initial position, target velocity = maxVelocity from the first step
    sim, sup = _supervisor(
        _arm(params={"position": 0.2}, motor=node("RotationalMotor", name="m", maxTorque=20.0))
    )
    free = Simulation(_arm(params={"position": 0.2}))
    motor = sup.getDevice("m")
    assert motor.getTargetPosition() == pytest.approx(0.2)
    assert motor.getVelocity() == motor.getMaxVelocity() == 10.0
    sup.step(2000)
    free.step(100)
    assert sim.joints[0].positions[0] == pytest.approx(0.2, abs=2e-3)
    assert free.joints[0].positions[0] > 0.7
    motor.setPosition(-0.5)
    sup.step(2000)
    assert sim.joints[0].positions[0] == pytest.approx(-0.5, abs=2e-3)


def test_position_sensor_is_nan_before_first_sample_and_quantised() -> None:
    w = _arm(params={"position": 0.123456}, gravity=0.0)
    w.find_def("JOINT")["device"][0].fields["resolution"] = 0.01
    sim, sup = _supervisor(w)
    sensor = sup.getDevice("sensor")
    assert math.isnan(sensor.getValue())
    sensor.enable(8)
    assert sensor.getSamplingPeriod() == 8
    sup.step(4)
    assert math.isnan(sensor.getValue())  # sampling period not elapsed yet
    sup.step(4)
    assert sensor.getValue() == pytest.approx(0.12)


def test_position_sensor_noise_is_seeded() -> None:
    values = []
    for _ in range(2):
        w = _arm(gravity=0.0)
        w.find_def("JOINT")["device"][0].fields["noise"] = 0.1
        w.world_info().fields["randomSeed"] = 7
        sim, sup = _supervisor(w)
        sensor = sup.getDevice("sensor")
        sensor.enable(4)
        run = []
        for _ in range(5):
            sup.step(4)
            run.append(sensor.getValue())
        values.append(run)
    assert values[0] == values[1]
    assert len(set(values[0])) == 5


# ------------------------------------------------------------------------------------------ supervisor


def test_setting_joint_position_teleports_the_endpoint() -> None:
    sim, sup = _supervisor(_arm(motor=node("RotationalMotor", name="m", maxTorque=50.0), gravity=0.0))
    bob = sup.getFromDef("ARM.JOINT.BOB")
    assert bob is not None and bob.getTypeName() == "Solid"
    assert bob.getPosition() == pytest.approx([0.5, 0.0, 1.0])
    position = sup.getFromDef("JOINT").getField("jointParameters").getSFNode().getField("position")
    position.setSFFloat(1.0)
    assert bob.getPosition() == pytest.approx([0.5, 0.0, 1.0])  # queued until the next step
    sup.step(4)
    # rotation by +1 rad about +y through the anchor moves +x toward -z
    assert bob.getPosition() == pytest.approx([0.5 * math.cos(1.0), 0.0, 1.0 - 0.5 * math.sin(1.0)], abs=0.02)
    assert position.getSFFloat() == pytest.approx(1.0, abs=0.02)
    # §4.1: the motor target is unchanged, so position control pulls the joint back to 0
    assert sup.getDevice("m").getTargetPosition() == 0.0
    sup.step(2000)
    assert position.getSFFloat() == pytest.approx(0.0, abs=1e-3)


def test_translation_set_teleports_without_resetting_velocity() -> None:
    ball = node(
        "Solid",
        "BALL",
        translation=(0.0, 0.0, 5.0),
        boundingObject=node("Sphere", radius=0.1),
        physics=node("Physics"),
    )
    robot = node("Robot", "SUP", supervisor=True)
    sim = Simulation(world(ball, robot, basicTimeStep=10.0))
    sup = Supervisor(simulation=sim, robot_node=robot)
    handle = sup.getFromDef("BALL")
    sup.step(100)
    vz = handle.getVelocity()[2]
    assert vz == pytest.approx(-G * 0.1, rel=1e-9)
    field = handle.getField("translation")
    field.setSFVec3f([1.0, 2.0, 3.0])
    assert handle.getPosition()[2] == pytest.approx(5.0 - G * 0.01**2 * 55, rel=1e-9)
    sup.step(10)
    assert handle.getPosition()[:2] == pytest.approx([1.0, 2.0])
    assert handle.getPosition()[2] == pytest.approx(3.0 + (vz - G * 0.01) * 0.01, rel=1e-9)
    assert handle.getVelocity()[2] == pytest.approx(vz - G * 0.01, rel=1e-9)
    handle.resetPhysics()
    assert handle.getVelocity() == [0.0] * 6


def test_robot_step_returns_minus_one_at_duration() -> None:
    sim = Simulation(cart_pole())
    robot = Robot(simulation=sim, robot_node=sim.robots[0].node, duration=0.1)
    assert robot.getBasicTimeStep() == 16.0
    codes = []
    while (code := robot.step(32)) != -1:
        codes.append(code)
    assert codes == [0, 0, 0]
    assert robot.getTime() == pytest.approx(0.112)  # stops at the first basic step reaching 0.1 s
    assert robot.step(32) == -1


# ------------------------------------------------------------------------------------------ masses


def _body_of(sim: Simulation, name: str):  # type: ignore[no-untyped-def]
    return next(b for b in sim.bodies if b.root.name == name)


def test_box_mass_from_density() -> None:
    sim = Simulation(
        world(
            node("Solid", name="b", boundingObject=node("Box", size=(0.1, 0.2, 0.3)), physics=node("Physics"))
        )
    )
    body = _body_of(sim, "b")
    m = 1000.0 * 0.1 * 0.2 * 0.3
    assert body.mass == pytest.approx(m)
    assert body.inertia[0] == pytest.approx(m * (0.2**2 + 0.3**2) / 12)
    assert body.inertia[4] == pytest.approx(m * (0.1**2 + 0.3**2) / 12)
    assert body.inertia[8] == pytest.approx(m * (0.1**2 + 0.2**2) / 12)


def test_cylinder_mass_adjusted_and_rotated_by_pose() -> None:
    # a Z-axis cylinder turned by a Pose to lie along y: the axial inertia moves to Iyy
    bo = node(
        "Pose", rotation=(1.0, 0.0, 0.0, math.pi / 2), children=[node("Cylinder", radius=0.1, height=0.4)]
    )
    sim = Simulation(
        world(node("Solid", name="c", boundingObject=bo, physics=node("Physics", density=-1.0, mass=2.0)))
    )
    body = _body_of(sim, "c")
    axial, radial = 2.0 * 0.1**2 / 2, 2.0 * (3 * 0.1**2 + 0.4**2) / 12
    assert body.mass == pytest.approx(2.0)
    assert body.inertia[0] == pytest.approx(radial)
    assert body.inertia[4] == pytest.approx(axial)
    assert body.inertia[8] == pytest.approx(radial)


def test_density_scaling_and_no_bounding_object() -> None:
    half = node(
        "Solid",
        name="half",
        boundingObject=node("Sphere", radius=0.1),
        physics=node("Physics", density=500.0),
    )
    bare = node(
        "Solid", name="bare", translation=(2.0, 0.0, 0.0), physics=node("Physics", density=-1.0, mass=3.0)
    )
    with pytest.warns(UserWarning, match="no boundingObject"):
        sim = Simulation(world(half, bare))
    assert _body_of(sim, "half").mass == pytest.approx(500.0 * 4 / 3 * math.pi * 0.1**3)
    body = _body_of(sim, "bare")
    assert body.mass == pytest.approx(3.0)
    assert body.inertia == pytest.approx((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0))


def test_merged_solids_sum_mass_centre_and_inertia() -> None:
    child = node(
        "Solid",
        name="child",
        translation=(0.3, 0.0, 0.0),
        boundingObject=node("Box", size=(0.1, 0.1, 0.1)),
        physics=node("Physics", density=-1.0, mass=1.0),
    )
    parent = node(
        "Solid",
        name="parent",
        translation=(0.0, 0.0, 1.0),
        children=[child],
        boundingObject=node("Box", size=(0.2, 0.2, 0.2)),
        physics=node("Physics", density=-1.0, mass=3.0),
    )
    sim = Simulation(world(parent))
    assert len(sim.bodies) == 1  # §3.3: one ODE body for the rigid assembly
    body = sim.bodies[0]
    assert body.mass == pytest.approx(4.0)
    com_x = 1.0 * 0.3 / 4.0
    assert body.com == pytest.approx((com_x, 0.0, 0.0))
    assert list(body.pos) == pytest.approx([com_x, 0.0, 1.0])  # body origin at the CoM
    i_parent, i_child = 3.0 * 0.08 / 12, 1.0 * 0.02 / 12
    iyy = i_parent + 3.0 * com_x**2 + i_child + 1.0 * (0.3 - com_x) ** 2
    assert body.inertia[0] == pytest.approx(i_parent + i_child)
    assert body.inertia[4] == pytest.approx(iyy)
    assert body.inertia[8] == pytest.approx(iyy)


def test_custom_inertia_matrix_and_centre_of_mass() -> None:
    phys = node(
        "Physics",
        density=-1.0,
        mass=2.0,
        centerOfMass=[(0.1, 0.0, -0.2)],
        inertiaMatrix=[(0.1, 0.2, 0.3), (0.01, 0.0, 0.0)],
    )
    solid = node(
        "Solid",
        name="s",
        translation=(1.0, 1.0, 1.0),
        boundingObject=node("Box", size=(1.0, 1.0, 1.0)),
        physics=phys,
    )
    sim = Simulation(world(solid))
    body = sim.bodies[0]
    assert body.mass == pytest.approx(2.0)
    assert body.com == pytest.approx((0.1, 0.0, -0.2))
    assert body.inertia == pytest.approx((0.1, 0.01, 0.0, 0.01, 0.2, 0.0, 0.0, 0.0, 0.3))
    assert list(body.pos) == pytest.approx([1.1, 1.0, 0.8])


def test_centre_of_mass_override_keeps_inertia() -> None:
    # the fixture pendulum's pole: density -1, mass 0.05, centerOfMass 0 0.061 -0.27
    phys = node("Physics", density=-1.0, mass=0.05, centerOfMass=[(0.0, 0.061, -0.27)])
    solid = node("Solid", name="pole", boundingObject=node("Box", size=(0.05, 0.02, 0.6)), physics=phys)
    body = Simulation(world(solid)).bodies[0]
    assert body.com == pytest.approx((0.0, 0.061, -0.27))
    assert body.inertia[0] == pytest.approx(0.05 * (0.02**2 + 0.6**2) / 12)


# ------------------------------------------------------------------------------------------ contacts


def test_contact_properties_matching() -> None:
    first = node("ContactProperties", material1="a", material2="b", coulombFriction=[0.3])
    second = node("ContactProperties", material1="b", material2="a", coulombFriction=[0.9])
    sim = Simulation(world(contactProperties=[first, second]))
    assert sim.contact_properties_for("a", "b") is first
    assert sim.contact_properties_for("b", "a") is first  # unordered, first match wins
    assert sim.contact_properties_for("a", "a") is None
    assert sim._surface_for("a", "c") is sim._default_surface
    default = sim._default_surface.template
    assert (
        default.mu == 1.0 and default.bounce == 0.5 and default.soft_cfm == 0.001 and default.soft_erp == 0.2
    )
    assert (
        default.mode == ode.dContactApprox1 | ode.dContactSoftCFM | ode.dContactSoftERP | ode.dContactBounce
    )


@pytest.mark.parametrize(("material", "mu"), [("ice", 0.25), ("default", 1.0)])
def test_sliding_distance_follows_matched_friction(material: str, mu: float) -> None:
    icy = node("ContactProperties", material1="ice", material2="default", coulombFriction=[0.25], bounce=0.0)
    block = node(
        "Solid",
        translation=(0.0, 0.0, 0.05),
        boundingObject=node("Box", size=(0.1, 0.1, 0.1)),
        physics=node("Physics", density=-1.0, mass=1.0),
        contactMaterial=material,
        linearVelocity=(2.0, 0.0, 0.0),
    )
    sim = Simulation(world(floor(), block, basicTimeStep=2.0, contactProperties=[icy]))
    sim.step(int(1.5 / sim.dt))
    assert sim.bodies[0].pos[0] == pytest.approx(2.0**2 / (2 * mu * G), rel=0.05)


def test_same_robot_parts_do_not_collide_and_bodies_jointed_to_world_ignore_static() -> None:
    # a pendulum hinged to a static base swings through a static floor (§2.3 rule 6)
    w = _arm(step_ms=4.0)
    w.nodes.append(node("Solid", name="floor", translation=(0.0, 0.0, 0.8), boundingObject=node("Plane")))
    sim = Simulation(w)
    lowest = 0.0
    for _ in range(150):
        sim.step()
        lowest = max(lowest, sim.joints[0].positions[0])
    assert lowest > 1.5  # the bob (z = 1 - 0.5·sin θ) went well below the plane at z = 0.8


# ------------------------------------------------------------------------------------------ instability


def _explosive() -> Simulation:
    return Simulation(_arm("slider", motor=node("LinearMotor", name="m", maxForce=1e300), gravity=0.0))


def test_diverging_state_raises_and_reset_recovers() -> None:
    sim, sup = _supervisor(_arm("slider", motor=node("LinearMotor", name="m", maxForce=1e300), gravity=0.0))
    sup.getDevice("m").setForce(1e300)
    with pytest.raises(SimulationUnstable):
        sup.step(40)
    assert sim.unstable
    with pytest.raises(SimulationUnstable):
        sim.step()
    sim.reset()
    assert not sim.unstable and sim.time == 0.0
    sim.step(10)
    fresh = _explosive()
    fresh.step(10)
    assert list(sim.bodies[0].pos) == list(fresh.bodies[0].pos)


def test_nan_state_raises_simulation_unstable() -> None:
    sim = Simulation(
        world(
            node(
                "Solid",
                translation=(0.0, 0.0, 5.0),
                boundingObject=node("Sphere", radius=0.1),
                physics=node("Physics"),
            )
        )
    )
    sim.step(2)
    sim._lib.dBodySetPosition(sim.bodies[0].ptr, math.nan, 0.0, 0.0)
    with pytest.raises(SimulationUnstable, match="non-finite"):
        sim.step()
    sim.reset()
    sim.step(2)
    assert math.isfinite(sim.bodies[0].pos[0])


def test_nan_commands_are_rejected(capsys: pytest.CaptureFixture[str]) -> None:
    sim, sup = _supervisor(_arm(motor=node("RotationalMotor", name="m")))
    motor = sup.getDevice("m")
    motor.setVelocity(math.nan)
    motor.setPosition(math.nan)
    assert motor.getVelocity() == 10.0 and motor.getTargetPosition() == 0.0
    assert "NaN" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ reset


def _state(sim: Simulation) -> bytes:
    out = b""
    for body in sim.bodies:
        for view in (body.pos, body.R, body.lvel, body.avel):
            out += bytes(view)
    for joint in sim.joints:
        out += bytes((ctypes.c_double * len(joint.positions))(*joint.positions))
    return out


def _drive(sup: Supervisor, sim: Simulation) -> list[bytes]:
    trace = []
    wheels = [sup.getDevice(f"wheel{i}") for i in range(4)]
    for k in range(120):
        for i, wheel in enumerate(wheels):
            wheel.setPosition(math.inf)
            wheel.setVelocity(3.0 * math.sin(0.05 * k + i))
        sup.step(16)
        trace.append(_state(sim))
    return trace


def test_reset_restores_the_exact_initial_state() -> None:
    sim = Simulation(cart_pole(0.1))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    initial = _state(sim)
    first = _drive(sup, sim)
    # supervisor edits before the reset must be undone too
    cart = sup.getFromDef("CART")
    cart.getField("translation").setSFVec3f([1.0, 1.0, 0.5])
    sup.step(16)
    sup.simulationReset()
    assert sup.step(16) == 0 and sup.getTime() == 0.0
    assert _state(sim) == initial
    assert cart.getField("translation").getSFVec3f() == pytest.approx([0.0, 0.0, 0.08])
    assert sup.getDevice("wheel0").getTargetPosition() == pytest.approx(0.0)
    second = _drive(sup, sim)
    assert second == first  # byte-identical trajectories
    fresh = Simulation(cart_pole(0.1))
    assert _drive(Supervisor(simulation=fresh, robot_node=fresh.robots[0].node), fresh) == first


def test_reset_physics_zeroes_velocities_but_keeps_time_and_pose() -> None:
    sim, sup = _supervisor(_arm(gravity=G))
    sup.step(100)
    pose = list(sim.bodies[0].pos)
    sup.simulationResetPhysics()
    assert list(sim.bodies[0].lvel) == [0.0, 0.0, 0.0] and list(sim.bodies[0].avel) == [0.0, 0.0, 0.0]
    assert list(sim.bodies[0].pos) == pose and sim.time == pytest.approx(0.1)


def test_auto_disable_sleeps_resting_bodies_and_commands_wake_them() -> None:
    w = cart_pole()
    w.world_info().fields["physicsDisableTime"] = 0.5
    sim, sup = _supervisor(w)
    sup.step(2000)
    lib = sim._lib
    assert not any(lib.dBodyIsEnabled(b.ptr) for b in sim.bodies)
    wheel = sup.getDevice("wheel0")
    wheel.setPosition(math.inf)
    wheel.setVelocity(2.0)
    sup.step(16)
    assert lib.dBodyIsEnabled(sim.joints[0].child_body.ptr)


# ------------------------------------------------------------------------------------------ other joints and devices


def test_kinematic_joint_moves_endpoint_and_devices_follow() -> None:
    devices = [node("GPS", name="gps"), node("InertialUnit", name="imu"), node("Accelerometer", name="acc")]
    tip = node(
        "Solid",
        "TIP",
        translation=(0.5, 0.0, 0.0),
        boundingObject=node("Box", size=(0.1, 0.1, 0.1)),
        children=devices,
    )
    hinge = node(
        "HingeJoint",
        jointParameters=node("HingeJointParameters", axis=(0.0, 0.0, 1.0)),
        device=[node("RotationalMotor", name="m"), node("PositionSensor", name="s")],
        endPoint=tip,
    )
    robot = node("Robot", "R", translation=(0.0, 0.0, 1.0), children=[hinge], supervisor=True)
    sim = Simulation(world(robot, basicTimeStep=8.0))
    assert sim.joints[0].kinematic  # endPoint without Physics (§4.1)
    sup = Supervisor(simulation=sim, robot_node=robot)
    gps, imu, acc = (sup.getDevice(n) for n in ("gps", "imu", "acc"))
    for dev in (gps, imu, acc):
        dev.enable(8)
    motor = sup.getDevice("m")
    motor.setVelocity(1.0)
    motor.setPosition(math.pi / 2)
    sup.step(800)
    # §5.3: the kinematic speed ramps at maxTorque (10 rad/s², acceleration -1): 0.08 rad/s more per 8 ms step up to
    # 1 rad/s at step 13, so 100 steps cover 0.008·(0.08·(1 + … + 12) + 88·1.0)
    assert sim.joints[0].positions[0] == pytest.approx(0.008 * (0.08 * 78 + 88.0))
    sup.step(1600)
    assert gps.getValues() == pytest.approx([0.0, 0.5, 1.0], abs=1e-9)
    assert imu.getRollPitchYaw() == pytest.approx([0.0, 0.0, math.pi / 2])
    assert imu.getQuaternion() == pytest.approx([0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)])
    assert acc.getValues() == pytest.approx([0.0, 0.0, G])  # at rest an accelerometer reads +g
    geom = sim.solids[1].geoms[0]
    assert list(ode.vec3(sim._lib.dGeomGetPosition(geom.ptr))) == pytest.approx([0.0, 0.5, 1.0], abs=1e-9)


def test_gyro_reads_body_rate_in_device_frame() -> None:
    robot = node(
        "Robot",
        "F",
        rotation=(1.0, 0.0, 0.0, math.pi / 2),
        children=[node("Gyro", name="gyro")],
        boundingObject=node("Sphere", radius=0.1),
        physics=node("Physics"),
        angularVelocity=(0.0, 0.0, 2.0),  # hidden field: initial world-frame angular velocity
    )
    sim = Simulation(world(robot, gravity=0.0))
    sup = Supervisor(simulation=sim, robot_node=robot)
    gyro = sup.getDevice("gyro")
    gyro.enable(32)
    sup.step(32)
    # turned +90° about x, the device's +y axis points along world +z
    assert gyro.getValues() == pytest.approx([0.0, 2.0, 0.0], abs=1e-9)


def test_hinge2_positions_follow_webots_axes() -> None:
    wheel = node(
        "Solid",
        translation=(0.5, 0.0, 0.0),
        boundingObject=node("Sphere", radius=0.1),
        physics=node("Physics", density=-1.0, mass=1.0),
    )
    joint = node(
        "Hinge2Joint",
        jointParameters=node("HingeJointParameters", axis=(0.0, 0.0, 1.0), anchor=(0.5, 0.0, 0.0)),
        jointParameters2=node("JointParameters", axis=(0.0, 1.0, 0.0)),
        device=[node("RotationalMotor", name="steer", maxTorque=100.0)],
        device2=[node("RotationalMotor", name="spin", maxTorque=100.0)],
        endPoint=wheel,
    )
    base = node(
        "Solid",
        name="base",
        children=[joint],
        boundingObject=node("Box", size=(0.1, 0.1, 0.1)),
        physics=node("Physics", density=-1.0, mass=10.0),
    )
    robot = node("Robot", "R", translation=(0.0, 0.0, 1.0), children=[base], supervisor=True)
    sim = Simulation(world(robot, gravity=0.0, basicTimeStep=4.0))
    sup = Supervisor(simulation=sim, robot_node=robot)
    for name, axis in (("spin", 1), ("steer", 2)):
        motor = sup.getDevice(name)
        motor.setPosition(math.inf)
        motor.setVelocity(1.0)
        sup.step(400)
        # a positive command turns the endPoint about +axis (right-hand rule) and increases the position
        assert sim.bodies[-1].avel[axis] == pytest.approx(1.0, abs=1e-6)
        motor.setVelocity(0.0)
    sup.step(4)
    assert sim.joints[0].positions == pytest.approx([0.4, 0.4], abs=0.01)


def test_ball_joint_swings_freely() -> None:
    bob = node(
        "Solid",
        translation=(0.5, 0.0, 0.0),
        boundingObject=node("Sphere", radius=0.05),
        physics=node("Physics", density=-1.0, mass=1.0),
    )
    ball = node("BallJoint", jointParameters=node("JointParameters"), endPoint=bob)
    sim = Simulation(
        world(node("Solid", name="pivot", translation=(0.0, 0.0, 1.0), children=[ball]), basicTimeStep=4.0)
    )
    sim.step(1000)
    pos = sim.bodies[0].pos
    assert math.dist((pos[0], pos[1], pos[2]), (0.0, 0.0, 1.0)) == pytest.approx(0.5, abs=1e-3)


def test_elevation_grid_and_trimesh_support_bodies() -> None:
    heights = [0.3] * 12
    grid = node(
        "Solid",
        name="grid",
        boundingObject=node(
            "ElevationGrid", xDimension=4, yDimension=3, xSpacing=1.0, ySpacing=1.0, height=heights
        ),
    )
    ball = node(
        "Solid",
        translation=(1.2, 0.8, 1.0),
        boundingObject=node("Sphere", radius=0.1),
        physics=node("Physics"),
    )
    sim = Simulation(world(grid, ball, basicTimeStep=4.0))
    sim.step(500)
    assert list(sim.bodies[0].pos) == pytest.approx([1.2, 0.8, 0.4], abs=2e-3)
    points = [(-0.1, -0.1, -0.1), (0.1, -0.1, -0.1), (0.1, 0.1, -0.1), (-0.1, 0.1, -0.1),
              (-0.1, -0.1, 0.1), (0.1, -0.1, 0.1), (0.1, 0.1, 0.1), (-0.1, 0.1, 0.1)]  # fmt: skip
    faces = [0, 3, 2, 1, -1, 4, 5, 6, 7, -1, 0, 1, 5, 4, -1, 1, 2, 6, 5, -1, 2, 3, 7, 6, -1, 3, 0, 4, 7, -1]
    mesh = node("IndexedFaceSet", coord=node("Coordinate", point=points), coordIndex=faces)
    cube = node("Solid", translation=(0.0, 0.0, 0.5), boundingObject=mesh, physics=node("Physics"))
    sim = Simulation(world(floor(), cube, basicTimeStep=4.0))
    body = sim.bodies[0]
    assert body.mass == pytest.approx(8.0, rel=1e-6)  # 0.2³ m³ at 1000 kg/m³
    assert body.inertia[0] == pytest.approx(8.0 * 0.08 / 12, rel=1e-5)
    sim.step(500)
    assert body.pos[2] == pytest.approx(0.1, abs=2e-3)


def test_pid_output_matches_webots_formula() -> None:
    # §5.3: u = clamp(Kp·e + Ki·∫e + Kd·Δe/ts, ±Vt), with e_prev = 0 on the first step (derivative kick)
    for pid, expected in (((2.0, 0.0, 0.0), 2.0), ((0.0, 0.0, 0.01), 0.01 / 0.004)):
        sim, sup = _supervisor(_arm(motor=node("RotationalMotor", name="m", maxTorque=1e4), gravity=0.0))
        motor = sup.getDevice("m")
        motor.setControlPID(*pid)
        motor.setPosition(1.0)
        sup.step(4)
        assert sim.joints[0].positions[0] == pytest.approx(expected * 0.004, rel=1e-3)


def test_acceleration_limit_ramps_the_velocity() -> None:
    sim, sup = _supervisor(_arm(motor=node("RotationalMotor", name="m", maxTorque=100.0), gravity=0.0))
    motor = sup.getDevice("m")
    motor.setAcceleration(5.0)
    motor.setPosition(math.inf)
    motor.setVelocity(10.0)
    sup.step(200)  # 50 steps: the commanded velocity grows by 5·0.004 each step
    assert sim.joints[0].positions[0] == pytest.approx(0.02 * 0.004 * (50 * 51 / 2), rel=1e-3)
    assert sim.motors[0].current_velocity == pytest.approx(1.0)
