"""The converter against the Webots-on-ODE specification (sections 1-5) and MuJoCo's MJCF semantics, one fact per test.

S = /work/shared/reference/webots-on-ode.md (line numbers as of this writing); the project's restatement is
docs/reference/webots-on-ode.md. Each world is written here, converted with the public API, compiled by MuJoCo and
read back from the MjModel (after ``mj_forward`` for world-frame quantities); expected values are computed by hand
from the specification, and some tests also run the Webots twin on the same world. Facts pinned by the other files
of tests/convert (hinge ref/axis/anchor/damping/frictionloss, stiff stops, motor numerics, mass rules and their
agreement with the twin, cameras, contacts' softness) are not repeated.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.convert import convert_world, convert_world_text
from dualtwin.convert.conversion import Conversion
from dualtwin.geometry import axis_angle_matrix
from dualtwin.webots import load_world_text, ode
from dualtwin.webots.physics import Simulation

HEADER = "#VRML_SIM R2023b utf8\n"
BALL = 'boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 1 }'
# a 1 kg sphere (r 0.05) 0.5 m from a hinge: I = 0.5² + 0.4·0.05² (hand computation)
ARM_INERTIA = 0.25 + 0.4 * 0.05 * 0.05


def convert(text: str) -> Conversion:
    return convert_world_text(HEADER + text, "t.wbt")


def forward(model: mujoco.MjModel, qpos: dict[str, float] | None = None) -> mujoco.MjData:
    data = mujoco.MjData(model)
    for name, value in (qpos or {}).items():
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_forward(model, data)
    return data


def twin(text: str) -> Simulation:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world_text(HEADER + text))


def hinge_world(params: str, world: str = "gravity 0", devices: str = "") -> str:
    """A fixed robot with one hinge about y holding a 1 kg bob 0.5 m out along x."""
    return (f"WorldInfo {{ basicTimeStep 4 {world} physicsDisableTime 0 }}\n"
            f"DEF R Robot {{ children [ DEF J HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 {params} }}"
            f" device [ {devices} ] endPoint DEF BOB Solid {{ translation 0.5 0 0 {BALL} }} }} ] }}")


# ------------------------------------------------------------------------------------------ §1 world settings


@pytest.mark.parametrize("system", ["NUE", "EUN"])
def test_gravity_points_down_the_y_axis_in_nue_and_eun_worlds(system: str) -> None:
    # S l.34: NUE gravity is (0, -g, 0); l.50: EUN's down axis is -y too (UNVERIFIED there; the twin does it).
    # The converter keeps the file's coordinates, so MuJoCo's gravity must be the file's down axis.
    text = f'WorldInfo {{ coordinateSystem "{system}" gravity 3 }}\nDEF R Robot {{ physics Physics {{ }} }}'
    assert convert(text).compile().opt.gravity == pytest.approx([0, -3, 0])
    assert twin(text).gravity == pytest.approx((0, -3, 0))  # cross-check: the Webots twin's ODE gravity
    # control: ENU (the default) keeps z down
    assert convert("WorldInfo { gravity 3 }\nDEF R Robot { physics Physics { } }").compile().opt.gravity == \
        pytest.approx([0, 0, -3])


def test_world_without_world_info_steps_at_32_ms_under_9_81() -> None:
    # S l.34 and l.37: the WorldInfo defaults, gravity 9.81 and basicTimeStep 32 ms (MuJoCo steps 2 ms of them)
    conv = convert("DEF R Robot { physics Physics { } }")
    model = conv.compile()
    assert conv.control_period_ms == 32.0
    assert model.opt.timestep == pytest.approx(0.002)
    assert model.opt.gravity == pytest.approx([0, 0, -9.81])


def _stop_solref(text: str) -> np.ndarray:
    m = convert(text).compile()
    return np.concatenate([m.jnt_solref[m.joint("J").id], m.jnt_solimp[m.joint("J").id][:2]])


@pytest.mark.parametrize(("bad", "reset"), [("ERP 1.5", "ERP 0.2"), ("ERP -0.1", "ERP 0.2"),
                                            ("CFM 0", "CFM 0.00001"), ("CFM -1", "CFM 0.00001")])
def test_world_erp_and_cfm_out_of_range_are_reset_before_they_reach_the_stops(bad: str, reset: str) -> None:
    # S l.35-36: CFM <= 0 is reset to 1e-5 and ERP outside [0, 1] to 0.2; the stops get the world's values
    # (§4.2, l.346), so a world with a bad value converts as one with the reset value
    stops = "minStop -1 maxStop 1"
    assert _stop_solref(hinge_world(stops, f"gravity 0 {bad}")) == pytest.approx(
        _stop_solref(hinge_world(stops, f"gravity 0 {reset}")))
    sim = twin(hinge_world(stops, f"gravity 0 {bad}"))
    assert (sim.erp, sim.cfm) == (0.2, 0.00001) if "ERP" in bad else sim.cfm == 0.00001  # the twin resets too


def test_body_damping_that_is_not_converted_is_reported() -> None:
    # S l.82-92: a Physics damping (and WorldInfo.defaultDamping) slows every body each step; MuJoCo has no
    # per-body damping, so the converter must say it dropped it rather than drop it silently
    conv = convert("DEF R Robot { physics Physics { damping Damping { linear 0.5 } } boundingObject Box { } }")
    assert any("damping is not converted" in w.lower() for w in conv.warnings)
    world = convert("WorldInfo { defaultDamping Damping { } }\nDEF R Robot { physics Physics { } }")
    assert any("damping is not converted" in w.lower() for w in world.warnings)
    # control: no Damping node, no such line
    assert not any("damping is not converted" in w.lower() for w in convert("DEF R Robot { physics Physics { } }").warnings)


# ------------------------------------------------------------------------------------------ §3 Solids and geoms


def _geom(model: mujoco.MjModel, name: str) -> tuple[int, np.ndarray, np.ndarray]:
    g = model.geom(name).id
    d = forward(model)
    return int(model.geom_type[g]), model.geom_size[g].copy(), d.geom_xmat[g].reshape(3, 3)


def test_box_size_becomes_half_extents() -> None:
    # S l.285: Box size is the full extents; MuJoCo's box size is half of them
    m = convert("DEF R Robot { boundingObject Box { size 0.2 0.4 0.6 } physics Physics { } }").compile()
    kind, size, _ = _geom(m, "R")
    assert kind == mujoco.mjtGeom.mjGEOM_BOX
    assert size == pytest.approx([0.1, 0.2, 0.3])


@pytest.mark.parametrize(("node", "gtype"), [("Cylinder", mujoco.mjtGeom.mjGEOM_CYLINDER),
                                             ("Capsule", mujoco.mjtGeom.mjGEOM_CAPSULE)])
def test_cylinder_and_capsule_height_is_a_half_length_along_the_local_z_axis(node: str, gtype: int) -> None:
    # S l.287-288: height is the full length of the cylindrical part, along local z in both engines; MuJoCo's
    # size is (radius, half-length). Turned 90° about x, the axis lies along world -y.
    text = (f"DEF R Robot {{ boundingObject Pose {{ rotation 1 0 0 1.5707963267948966 children [ {node} "
            "{ radius 0.1 height 0.6 } ] } physics Physics { } }")
    kind, size, R = _geom(convert(text).compile(), "R")
    assert kind == gtype
    assert size[:2] == pytest.approx([0.1, 0.3])
    assert R[:, 2] == pytest.approx([0, -1, 0], abs=1e-12)


def test_sphere_radius_is_the_size() -> None:
    # S l.286
    kind, size, _ = _geom(convert("DEF R Robot { boundingObject Sphere { radius 0.3 } physics Physics { } }")
                          .compile(), "R")
    assert (kind, size[0]) == (mujoco.mjtGeom.mjGEOM_SPHERE, pytest.approx(0.3))


def test_plane_normal_is_the_upper_pose_z_axis() -> None:
    # S l.289: n = upper Pose rotation·(0, 0, 1), through the Pose's position (a static Solid's Plane)
    text = ('Solid { name "slope" translation 0 0 -1 rotation 1 0 0 0.3 boundingObject Plane { } }\n'
            "DEF R Robot { physics Physics { } boundingObject Sphere { radius 0.1 } }")
    m = convert(text).compile()
    g = m.geom("slope").id
    d = forward(m)
    assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE and m.geom_bodyid[g] == 0
    assert d.geom_xmat[g].reshape(3, 3)[:, 2] == pytest.approx([0, -math.sin(0.3), math.cos(0.3)])
    assert d.geom_xpos[g] == pytest.approx([0, 0, -1])


def test_a_scaled_transform_scales_sizes_and_mass() -> None:
    # S l.301 and l.252: geometries inside a scaled Transform use scaled sizes, mass ∝ s³ (density 1000 here)
    text = ("Transform { scale 2 2 2 translation 0 0 1 children [ Solid { name \"crate\" translation 0.5 0 0 "
            "boundingObject Box { size 0.1 0.2 0.3 } } ] }\n"
            "DEF R Robot { children [ Transform { scale 3 3 3 children [ Solid { name \"bump\" translation 0 0 0.1 "
            "boundingObject Sphere { radius 0.1 } physics Physics { } } ] } ] "
            "boundingObject Sphere { radius 0.1 } physics Physics { } }")
    m = convert(text).compile()
    kind, size, _ = _geom(m, "crate")
    assert size == pytest.approx([0.1, 0.2, 0.3])
    assert forward(m).geom_xpos[m.geom("crate").id] == pytest.approx([1.0, 0, 1])  # translation scaled too
    assert m.geom_size[m.geom("bump").id][0] == pytest.approx(0.3)
    sphere = 1000 * 4 / 3 * math.pi * 0.001
    assert m.body("R").mass[0] == pytest.approx(sphere * (1 + 27))


def test_a_pose_chain_composes_to_the_world_pose() -> None:
    # S l.214-217: translation/rotation are relative to the parent Pose; world pose = product of the ancestors'
    text = ("DEF R Robot { translation 1 0 0 rotation 0 0 1 1.5707963267948966 children [ "
            "Pose { translation 0 1 0 rotation 0 1 0 0.4 children [ DEF J HingeJoint { "
            f"endPoint DEF BOB Solid {{ translation 0 0 0.5 {BALL} }} }} ] }} ] }}")
    m = convert(text).compile()
    d = forward(m)
    Rz = axis_angle_matrix((0, 0, 1, math.pi / 2))
    Ry = axis_angle_matrix((0, 1, 0, 0.4))
    expected = np.array([1, 0, 0]) + Rz @ (np.array([0, 1, 0]) + Ry @ np.array([0, 0, 0.5]))
    bob = m.body("BOB").id
    assert d.xpos[bob] == pytest.approx(expected)
    assert d.xmat[bob].reshape(3, 3) == pytest.approx(Rz @ Ry)
    # the hinge (default axis 1 0 0, anchor 0 0 0) sits in the closest upper Pose (S l.312)
    j = m.joint("J").id
    assert d.xanchor[j] == pytest.approx([1, 0, 0] + Rz @ [0, 1, 0])
    assert d.xaxis[j] == pytest.approx(Rz @ Ry @ [1, 0, 0])


def test_a_rotation_axis_that_is_not_unit_length_is_normalised() -> None:
    # S l.216: the rotation axis is normalised before use
    m = convert(f"DEF R Robot {{ rotation 0 0 5 0.7 {BALL} }}").compile()
    assert forward(m).xmat[m.body("R").id].reshape(3, 3) == pytest.approx(axis_angle_matrix((0, 0, 1, 0.7)))


def test_custom_inertia_matrix_reaches_mujoco_in_fullinertia_order() -> None:
    # S l.231-233: mass, centerOfMass and [I11 I22 I33], [I12 I13 I23] about the CoM in Solid axes; MuJoCo's
    # fullinertia is Ixx Iyy Izz Ixy Ixz Iyz: the compiled body's inertia (ximat·diag·ximatᵀ) is the given one
    physics = "physics Physics { density -1 mass 3 centerOfMass [ 0.1 0.2 0 ] inertiaMatrix [ 0.2 0.3 0.4, 0.02 -0.03 0.05 ] }"
    m = convert(f"DEF R Robot {{ rotation 0 0 1 0.5 boundingObject Box {{ }} {physics} }}").compile()
    d = forward(m)
    b = m.body("R").id
    R = d.ximat[b].reshape(3, 3)
    world = R @ np.diag(m.body_inertia[b]) @ R.T
    Rs = axis_angle_matrix((0, 0, 1, 0.5))
    given = np.array([[0.2, 0.02, -0.03], [0.02, 0.3, 0.05], [-0.03, 0.05, 0.4]])
    assert m.body_mass[b] == pytest.approx(3.0)
    assert world == pytest.approx(Rs @ given @ Rs.T)
    assert d.xipos[b] == pytest.approx(Rs @ [0.1, 0.2, 0])


def test_a_physics_solid_on_a_static_basis_is_fixed_to_the_world() -> None:
    # S l.270-272: a Solid with Physics under a top Solid without Physics is fixed to the world: no joint, static
    text = ('Solid { name "table" children [ Solid { name "lamp" translation 0 0 1 boundingObject Box { } '
            "physics Physics { } } ] }\nDEF R Robot { physics Physics { } }")
    m = convert(text).compile()
    g = m.geom("lamp").id
    assert m.geom_bodyid[g] == 0 or m.body_weldid[m.geom_bodyid[g]] == 0
    assert forward(m).geom_xpos[g] == pytest.approx([0, 0, 1])


# ------------------------------------------------------------------------------------------ §4 joints


def test_slider_default_axis_is_z_and_its_axis_is_normalised() -> None:
    # S l.359: JointParameters axis defaults to 0 0 1 and a slider axis is normalised by Webots
    text = ("DEF R Robot { children [ DEF S SliderJoint { endPoint DEF A Solid { " + BALL + " } } "
            "DEF T SliderJoint { jointParameters JointParameters { axis 3 0 4 } endPoint DEF B Solid { " + BALL
            + " } } ] }")
    m = convert(text).compile()
    d = forward(m, {"S": 0.2, "T": 0.5})
    assert d.xaxis[m.joint("S").id] == pytest.approx([0, 0, 1])
    assert d.xpos[m.body("A").id] == pytest.approx([0, 0, 0.2])
    assert d.xpos[m.body("B").id] == pytest.approx([0.3, 0, 0.4])  # 0.5 m along the unit axis


def test_slider_stops_are_a_range_in_metres_not_clamped_to_pi() -> None:
    # S l.363: slider stops are minStop - offset .. maxStop - offset on ODE's measure, no ±π clamp
    text = ("DEF R Robot { children [ DEF S SliderJoint { jointParameters JointParameters { position 0.5 "
            "minStop -4 maxStop 5 } endPoint Solid { translation 0 0 0.5 " + BALL + " } } ] }")
    m = convert(text).compile()
    assert m.jnt_range[m.joint("S").id] == pytest.approx([-4, 5])


def test_hinge_stops_are_clamped_to_pi_about_the_initial_position() -> None:
    # S l.344-345: ODE's stops are -maxStop + offset and -minStop + offset, clamped into [-π, π]; with offset
    # = position = 1, minStop -3 gives an ODE stop π, so the joint stops at position 1 - π, not at -3
    text = hinge_world("position 1 minStop -3 maxStop 3")
    m = convert(text).compile()
    assert m.jnt_range[m.joint("J").id] == pytest.approx([1 - math.pi, 3])
    # cross-check: the Webots twin's ODE stops (Webots position = offset - ODE angle). Driving the twin onto
    # the stop would not do: upstream ODE does not unwrap its angle at ±π where Webots' fork does (S l.635)
    sim = twin(text)
    lib = ode.load()
    lo, hi = (lib.dJointGetHingeParam(sim.joints[0].ptr, p) for p in (ode.dParamLoStop, ode.dParamHiStop))
    assert [1 - hi, 1 - lo] == pytest.approx([1 - math.pi, 3])
    # control: no position, the stops within ±π pass as they are
    plain = convert(hinge_world("minStop -3 maxStop 3")).compile()
    assert plain.jnt_range[plain.joint("J").id] == pytest.approx([-3, 3])


def test_hidden_position_without_joint_parameters_is_the_reference() -> None:
    # S l.321: without jointParameters the offset is the hidden `position` field; the file pose is the pose there
    text = f"DEF R Robot {{ children [ DEF J HingeJoint {{ position 0.4 endPoint DEF BOB Solid {{ {BALL} }} }} ] }}"
    m = convert(text).compile()
    assert m.qpos0[m.jnt_qposadr[m.joint("J").id]] == pytest.approx(0.4)


@pytest.mark.parametrize("kind", ["hinge", "slider"])
def test_a_spring_rests_at_the_joint_zero_position(kind: str) -> None:
    # S l.385-393 (docs/reference §4.5): the spring's rest point is the joint's zero position, T = -K·position
    # - B·velocity, whatever the file's initial `position`; MuJoCo's spring rests at springref
    if kind == "hinge":
        text = hinge_world("position 0.3 springConstant 10 dampingConstant 5")
    else:
        text = ("WorldInfo { basicTimeStep 4 gravity 0 physicsDisableTime 0 }\nDEF R Robot { children [ DEF J "
                "SliderJoint { jointParameters JointParameters { axis 1 0 0 position 0.1 springConstant 40 "
                f"dampingConstant 20 }} endPoint DEF BOB Solid {{ translation 0.1 0 0 {BALL} }} }} ] }}")
    m = convert(text).compile()
    j = m.joint("J").id
    assert m.qpos_spring[m.jnt_qposadr[j]] == pytest.approx(0.0)
    assert m.dof_damping[m.jnt_dofadr[j]] == pytest.approx(5 if kind == "hinge" else 20)
    # both twins, left alone for 4 s (overdamped: slowest decay e^-2.25t for the hinge, e^-2.76t for the
    # slider), come to rest at 0
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    while d.time < 4.0:
        mujoco.mj_step(m, d)
    assert d.qpos[m.jnt_qposadr[j]] == pytest.approx(0.0, abs=1e-3)
    sim = twin(text)
    sim.step(1000)
    assert sim.joints[0].positions[0] == pytest.approx(0.0, abs=1e-3)


# ------------------------------------------------------------------------------------------ §2 contacts


def test_the_first_matching_contact_properties_wins_and_unmatched_pairs_get_the_defaults() -> None:
    # S l.154-157: the first ContactProperties whose materials match (either order) wins; none: mu 1
    text = ("WorldInfo { contactProperties [ ContactProperties { material1 \"rubber\" material2 \"floor\" "
            "coulombFriction [ 0.4 ] } ContactProperties { material1 \"floor\" material2 \"rubber\" "
            "coulombFriction [ 0.9 ] } ] }\n"
            'Solid { name "ground" contactMaterial "floor" boundingObject Plane { } }\n'
            'DEF R Robot { contactMaterial "rubber" boundingObject Sphere { radius 0.1 } physics Physics { } }')
    m = convert(text).compile()
    assert m.geom_friction[m.geom("R").id][0] == pytest.approx(0.4)
    other = convert(text.replace('"rubber" boundingObject', '"steel" boundingObject')).compile()
    assert other.geom_friction[other.geom("R").id][0] == pytest.approx(1.0)


# ------------------------------------------------------------------------------------------ §5 motors, sensors


def test_motor_defaults_give_ten_newton_metres_or_newtons() -> None:
    # S l.412: maxTorque and maxForce default to 10
    text = ("DEF R Robot { children [ HingeJoint { device [ RotationalMotor { name \"rot\" } ] endPoint Solid { "
            f"name \"a\" {BALL} }} }} SliderJoint {{ device [ LinearMotor {{ name \"lin\" }} ] endPoint Solid {{ "
            f"name \"b\" translation 0 1 0 {BALL} }} }} ] }}")
    m = convert(text).compile()
    for name in ("rot", "lin"):
        assert m.actuator_forcerange[m.actuator(name).id] == pytest.approx([-10, 10])


def test_the_damping_report_says_why_mujoco_cannot_carry_it() -> None:
    # S l.82-92: ODE scales each body's own velocities by (1 - d)^h a step; MuJoCo's joint damping acts on joint
    # rates (one coefficient for a free joint's six dofs), so the report says that rather than "no damping"
    conv = convert("DEF R Robot { physics Physics { damping Damping { linear 0.5 } } boundingObject Box { } }")
    (note,) = [w for w in conv.warnings if "damping" in w.lower()]
    assert "(1 - d)^h" in note and "joint rates" in note and "six dofs" in note


def test_a_motor_multiplier_is_carried_to_the_twin_not_dropped() -> None:
    # S l.429: setPosition(p) targets p·multiplier; the motor's numeric carries it (after minPosition/maxPosition,
    # written as 0 0 = no limits) for the MuJoCo twin (tests/convert/test_coupled_motors.py runs it)
    conv = convert(hinge_world("", devices='RotationalMotor { name "m" multiplier 2 }'))
    assert list(conv.compile().numeric("webots_motor.m").data) == [10, 10, 0, 0, -1, 0, 0, 2]
    assert not any("multiplier" in w for w in conv.warnings)


def test_position_sensor_reads_the_webots_position_including_its_offset() -> None:
    # S l.467: the value is the Webots joint position, the initial `position` included
    text = hinge_world("position 0.6", devices='PositionSensor { name "s" }')
    m = convert(text).compile()
    assert forward(m).sensor("s").data[0] == pytest.approx(0.6)


# ------------------------------------------------------------------------------------------ PROTO instances


def test_proto_fields_reach_the_converted_body(tmp_path: Path) -> None:
    # A PROTO instance's fields (IS-bound) set the expanded Robot's pose, mass and joint parameters
    (tmp_path / "Arm.proto").write_text(
        HEADER + "PROTO Arm [\n  field SFVec3f translation 0 0 0\n  field SFFloat armMass 1\n  field SFFloat stop 0.5\n]\n"
        "{\n  Robot { translation IS translation children [ DEF J HingeJoint { jointParameters "
        "HingeJointParameters { minStop -0.2 maxStop IS stop } endPoint Solid { name \"bob\" translation 0 0 0.5 "
        "boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass IS armMass } } } ] }\n}\n")
    (tmp_path / "w.wbt").write_text(HEADER + 'EXTERNPROTO "Arm.proto"\nArm { translation 0 2 0 armMass 4 stop 0.7 }\n')
    m = convert_world(tmp_path / "w.wbt").compile()
    bob = m.body("bob").id  # DEFs inside a PROTO stay inside it: the Solid keeps its name
    assert forward(m).xpos[bob] == pytest.approx([0, 2, 0.5])
    assert m.body_mass[bob] == pytest.approx(4.0)
    assert m.jnt_range[m.body_jntadr[bob]] == pytest.approx([-0.2, 0.7])
