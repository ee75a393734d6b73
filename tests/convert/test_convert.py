"""Converter units: joint frames and refs, devices, cameras, contacts, names, lint, smoke test, bad input."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.convert import (
    ConversionError,
    camera_fovy_degrees,
    contact_solref,
    convert_world,
    convert_world_text,
    lint_spec,
    smoke_test,
    stop_solref,
    timestep_for,
)
from dualtwin.errors import DualtwinError
from dualtwin.geometry import axis_angle_matrix

HEADER = "#VRML_SIM R2023b utf8\n"
WHEEL = "boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 0.5 }"


def convert(text: str, robot: str | None = None):  # type: ignore[no-untyped-def]
    return convert_world_text(HEADER + text, "t.wbt", robot)


def forward(model: mujoco.MjModel, qpos: dict[str, float] | None = None) -> mujoco.MjData:
    data = mujoco.MjData(model)
    for name, value in (qpos or {}).items():
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_forward(model, data)
    return data


def test_timestep_divides_basic_time_step() -> None:
    assert timestep_for(32) == pytest.approx(0.002)
    assert timestep_for(8) == pytest.approx(0.002)
    assert timestep_for(5) == pytest.approx(0.001)
    assert timestep_for(1) == pytest.approx(0.001)
    assert timestep_for(0.75) == pytest.approx(0.00025)
    h = timestep_for(2.2)
    assert h <= 0.002 and abs(2.2e-3 / h - round(2.2e-3 / h)) < 1e-9


def test_world_options() -> None:
    conv = convert("WorldInfo { basicTimeStep 16 gravity 3.7 }\nDEF R Robot { physics Physics { } }")
    m = conv.compile()
    assert m.opt.timestep == pytest.approx(0.002)
    assert m.opt.gravity == pytest.approx([0, 0, -3.7])
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert m.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert 'angle="radian"' in conv.xml
    assert conv.control_period_ms == 16


HINGE = """
DEF R Robot {
  children [
    DEF J HingeJoint {
      jointParameters HingeJointParameters { position 0.3 axis 0 1 0 anchor 0.1 0 0.2 minStop -1 maxStop 1.2
                                             dampingConstant 0.7 springConstant 2 staticFriction 0.05 }
      device [ RotationalMotor { name "m" maxVelocity 7 maxTorque 3 controlPID 5 0.1 0.01 acceleration 20 }
               PositionSensor { name "m sensor" noise 0.01 } ]
      endPoint DEF ARM Solid { translation 0.4 0 0.5 rotation 0 1 0 0.3 @W }
    }
  ]
  physics Physics { density -1 mass 1 } boundingObject Box { size 0.1 0.1 0.1 }
}
""".replace("@W", WHEEL)


def test_hinge_ref_axis_anchor_and_dynamics() -> None:
    conv = convert(HINGE)
    m = conv.compile()
    j = m.joint("J")
    assert m.qpos0[m.jnt_qposadr[j.id]] == pytest.approx(0.3)  # position -> ref
    assert m.jnt_range[j.id] == pytest.approx([-1, 1.2])
    assert m.jnt_limited[j.id]
    assert m.dof_damping[m.jnt_dofadr[j.id]] == pytest.approx(0.7)
    assert m.jnt_stiffness[j.id] == pytest.approx(2)
    assert m.qpos_spring[m.jnt_qposadr[j.id]] == pytest.approx(0.0)  # spring rests at the zero position (§4.5)
    assert m.dof_frictionloss[m.jnt_dofadr[j.id]] == pytest.approx(0.05)
    # At qpos0 the child is where the file puts it; anchor and axis are where the file says (root frame = world).
    d = forward(m)
    arm = m.body("ARM").id
    assert d.xpos[arm] == pytest.approx([0.4, 0, 0.5])
    assert d.xmat[arm].reshape(3, 3) == pytest.approx(axis_angle_matrix((0, 1, 0, 0.3)))
    assert d.xanchor[j.id] == pytest.approx([0.1, 0, 0.2])
    assert d.xaxis[j.id] == pytest.approx([0, 1, 0])
    # At qpos = 0 the child is in its zero pose: rotated back by -position about the anchor.
    d0 = forward(m, {"J": 0.0})
    R = axis_angle_matrix((0, 1, 0, -0.3))
    expected = R @ (np.array([0.4, 0, 0.5]) - [0.1, 0, 0.2]) + [0.1, 0, 0.2]
    assert d0.xpos[arm] == pytest.approx(expected)
    assert d0.xmat[arm].reshape(3, 3) == pytest.approx(np.eye(3), abs=1e-12)


def test_stops_are_stiff_limits_from_world_erp_and_cfm() -> None:
    # basicTimeStep 8 ms -> MuJoCo 2 ms; the stops get WorldInfo ERP/CFM, as ODE gives them at creation.
    world = "WorldInfo { basicTimeStep 8 ERP 0.4 CFM 0.01 }\n"
    m = convert(world + HINGE).compile()
    j = m.joint("J").id
    inertia = 1.0 / m.dof_invweight0[m.jnt_dofadr[j]]
    assert m.jnt_solref[j] == pytest.approx([0.004, math.sqrt(0.008 / (4 * 0.002 * 0.4))])
    d = 1.0 / (1.0 + 0.01 * inertia / 0.002)
    assert d < 0.999
    assert m.jnt_solimp[j][:2] == pytest.approx([d, d])
    # Webots passes stopERP/stopCFM to ODE only when they change at run time: kept out, with a warning.
    own = convert(world + HINGE.replace("staticFriction 0.05", "staticFriction 0.05 stopERP 0.8 stopCFM 0"))
    assert own.compile().jnt_solref[j] == pytest.approx(m.jnt_solref[j])
    assert any("stopERP/stopCFM" in w for w in own.warnings)
    hard = convert("WorldInfo { basicTimeStep 8 CFM 0 }\n" + HINGE).compile()
    # CFM 0 is reset to 1e-5 (§1.1), a stop as hard as MuJoCo's range allows here
    assert hard.jnt_solimp[j][:2] == pytest.approx([0.9999, 0.9999])
    # One MuJoCo step of the mapped limit: b = 1/h removes the approach velocity, h k = ERP/H pushes out.
    timeconst, dampratio, _ = stop_solref(0.2, 1e-5, 0.008, 0.1, 0.002)
    b, k = 2 / timeconst, 1 / (timeconst * dampratio) ** 2
    assert b * 0.002 == pytest.approx(1.0) and k * 0.002 == pytest.approx(0.2 / 0.008)


def test_motor_and_sensor_names_and_parameters() -> None:
    conv = convert(HINGE)
    m = conv.compile()
    act = m.actuator("m")
    assert m.actuator_trnid[act.id, 0] == m.joint("J").id
    assert m.actuator_forcerange[act.id] == pytest.approx([-3, 3])
    num = m.numeric("webots_motor.m")
    assert m.numeric_data[num.adr[0]:num.adr[0] + 5] == pytest.approx([7, 5, 0.1, 0.01, 20])
    sensor = m.sensor("m sensor")
    assert m.sensor_type[sensor.id] == mujoco.mjtSensor.mjSENS_JOINTPOS
    assert m.sensor_noise[sensor.id] == pytest.approx(0.01)
    assert [j.name for j in conv.joints] == ["J"]
    assert conv.joints[0].motors == ["m"] and conv.joints[0].sensors == ["m sensor"]
    assert any(f.code == "sensor-noise-metadata" for f in conv.lint)


def test_joint_name_fallbacks_and_no_limits_when_stops_equal() -> None:
    text = """
DEF R Robot { children [
  HingeJoint { device [ RotationalMotor { name "left wheel motor" } ] endPoint Solid { name "a" @W } }
  HingeJoint { endPoint Solid { name "b" translation 0 0.3 0 @W } }
] physics Physics { } }""".replace("@W", WHEEL)
    conv = convert(text)
    m = conv.compile()
    names = [m.joint(i).name for i in range(m.njnt)]
    assert names == ["R_free", "left wheel motor_joint", "joint2"]
    assert not m.jnt_limited[1]
    assert m.jnt_axis[1] == pytest.approx([1, 0, 0])  # HingeJointParameters default axis
    assert [m.body(i).name for i in range(m.nbody)] == ["world", "R", "a", "b"]


def test_slider_sign_and_position() -> None:
    text = """
DEF R Robot { children [
  DEF S SliderJoint { jointParameters JointParameters { position 0.1 axis 1 0 0 }
    device [ LinearMotor { name "lin" maxForce 40 } ]
    endPoint DEF CART Solid { translation 0.1 0 0 @W } }
] }""".replace("@W", WHEEL)
    conv = convert(text)
    m = conv.compile()
    s = m.joint("S").id
    assert m.jnt_type[s] == mujoco.mjtJoint.mjJNT_SLIDE
    assert m.qpos0[m.jnt_qposadr[s]] == pytest.approx(0.1)
    assert forward(m, {"S": 0.0}).xpos[m.body("CART").id] == pytest.approx([0, 0, 0])
    # Webots: a positive LinearMotor force pushes the endPoint along +axis (§4.3); same in MuJoCo.
    m.opt.gravity[:] = 0
    d = forward(m)
    d.ctrl[0] = 10.0
    for _ in range(50):
        mujoco.mj_step(m, d)
    assert d.xpos[m.body("CART").id][0] > 0.1
    assert any("fixed base" in w for w in conv.warnings)  # the robot has no Physics


def test_ball_and_hinge2_joints() -> None:
    text = """
DEF R Robot { children [
  DEF B BallJoint { jointParameters BallJointParameters { anchor 0 0 0.1 } endPoint Solid { name "ball" translation 0 0 0.2 @W } }
  DEF H2 Hinge2Joint {
    jointParameters HingeJointParameters { axis 0 0 1 anchor 0.5 0 0 }
    jointParameters2 JointParameters { axis 0 1 0 }
    device [ RotationalMotor { name "steer" } ] device2 [ RotationalMotor { name "drive" } ]
    endPoint Solid { name "wheel" translation 0.5 0 0 @W } }
] physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }""".replace("@W", WHEEL)
    conv = convert(text)
    m = conv.compile()
    assert m.jnt_type[m.joint("B").id] == mujoco.mjtJoint.mjJNT_BALL
    d = forward(m, {"H2": 0.5})
    # The second axis turns with the first hinge.
    assert d.xaxis[m.joint("H22").id] == pytest.approx([-math.sin(0.5), math.cos(0.5), 0])
    assert {m.actuator(i).name for i in range(m.nu)} == {"steer", "drive"}
    assert conv.smoke().ok


def test_camera_fovy_and_look_axis() -> None:
    assert camera_fovy_degrees(math.pi / 2, 64, 64) == pytest.approx(90.0)
    assert camera_fovy_degrees(1.0, 640, 480) == pytest.approx(math.degrees(2 * math.atan(math.tan(0.5) * 0.75)))
    text = """
DEF R Robot { children [ Camera { name "cam" translation 0.1 0 0.2 rotation 0 0 1 1.5707963267948966
  fieldOfView 1.0 width 640 height 480 } ] physics Physics { } }"""
    conv = convert(text)
    m = conv.compile()
    cam = m.camera("cam")
    assert m.cam_fovy[cam.id] == pytest.approx(camera_fovy_degrees(1.0, 640, 480))
    d = forward(m)
    R = d.cam_xmat[cam.id].reshape(3, 3)
    # Webots (FLU, R2022a+): looks along the device's +x (here world +y after the 90° yaw), up = +z.
    assert -R[:, 2] == pytest.approx([0, 1, 0], abs=1e-9)
    assert R[:, 1] == pytest.approx([0, 0, 1], abs=1e-9)
    assert d.cam_xpos[cam.id] == pytest.approx([0.1, 0, 0.2])


def test_site_sensors() -> None:
    text = """
DEF R Robot { children [
  InertialUnit { name "imu" translation 0 0 0.1 } Gyro { name "gyro" } Accelerometer { name "accel" }
  GPS { name "gps" translation 0.2 0 0 } Compass { name "compass" }
  DistanceSensor { name "ds" translation 0.1 0 0 }
] physics Physics { } boundingObject Box { size 0.1 0.1 0.1 } }"""
    conv = convert(text)
    m = conv.compile()
    kinds = {m.sensor(i).name: m.sensor_type[i] for i in range(m.nsensor)}
    assert kinds == {"imu": mujoco.mjtSensor.mjSENS_FRAMEQUAT, "gyro": mujoco.mjtSensor.mjSENS_GYRO,
                     "accel": mujoco.mjtSensor.mjSENS_ACCELEROMETER, "gps": mujoco.mjtSensor.mjSENS_FRAMEPOS,
                     "compass": mujoco.mjtSensor.mjSENS_MAGNETOMETER, "ds": mujoco.mjtSensor.mjSENS_RANGEFINDER}
    d = forward(m)
    assert d.sensor("gps").data == pytest.approx([0.2, 0, 0])
    ds = m.site("ds").id
    assert d.site_xmat[ds].reshape(3, 3)[:, 2] == pytest.approx([1, 0, 0], abs=1e-9)  # rays along +x
    assert "gps_x_m" in conv.binding["onboard"]


def test_contact_properties_and_self_collision_bits() -> None:
    text = """
WorldInfo { basicTimeStep 16 contactProperties [ ContactProperties { material1 "floor" material2 "rubber"
  coulombFriction [ 0.3 ] softCFM 0.0001 softERP 0.5 bounce 0 } ] }
Solid { name "ground" contactMaterial "floor" boundingObject Plane { } }
Solid { name "block" translation 3 0 0.5 boundingObject Box { size 1 1 1 } }
DEF R Robot { contactMaterial "rubber" translation 0 0 0.1 boundingObject Box { size 0.2 0.2 0.2 }
  physics Physics { density -1 mass 2 } }"""
    conv = convert(text)
    m = conv.compile()
    robot, ground = m.geom("R"), m.geom("ground")
    assert m.geom_friction[robot.id][0] == pytest.approx(0.3)
    assert m.geom_friction[ground.id][0] == pytest.approx(0.3)
    assert m.geom_type[ground.id] == mujoco.mjtGeom.mjGEOM_PLANE and m.geom_bodyid[ground.id] == 0
    assert m.geom_bodyid[m.geom("block").id] == 0  # static Solid -> world geom
    timeconst, dampratio, d = contact_solref(0.5, 0.0001, 0.016, 2.0, 0.002)
    assert m.geom_solref[robot.id] == pytest.approx([timeconst, dampratio])
    assert m.geom_solimp[robot.id][0] == pytest.approx(d)
    # robot geoms collide with the world, not with each other
    assert m.geom_contype[robot.id] & m.geom_conaffinity[ground.id]
    assert not (m.geom_contype[robot.id] & m.geom_conaffinity[robot.id])
    assert not any("'rubber'/'floor'" in w for w in conv.warnings)  # bounce 0 there
    assert any("'rubber'/'default'" in w for w in conv.warnings)  # the block: default ContactProperties


def test_contact_solref_derivation() -> None:
    # ODE spring-damper from ERP/CFM: k = ERP/(h CFM), b = (1-ERP)/CFM; timeconst = 2m/b, ζ = b/(2√(km)).
    h, erp, cfm, mass = 0.01, 0.2, 0.001, 10.0
    k, b = erp / (h * cfm), (1 - erp) / cfm
    timeconst, dampratio, d = contact_solref(erp, cfm, h, mass, 0.001)
    assert timeconst == pytest.approx(2 * mass / b)
    assert dampratio == pytest.approx(b / (2 * math.sqrt(k * mass)))
    assert d == pytest.approx(1 / (1 + cfm * mass / h))
    # The minimum, 2 MuJoCo steps / d (MuJoCo's 2 steps when d = 1): 1 g gives d = 1/(1 + 1e-7) -> 0.9999 (cap).
    assert contact_solref(erp, cfm, h, 0.001, 0.002)[0] == pytest.approx(0.004 / 0.9999)


def test_visual_shapes_are_massless_and_do_not_collide() -> None:
    conv = convert("DEF R Robot { children [ Shape { geometry Box { size 1 1 1 } } ] physics Physics { density -1 mass 1 } "
                   "boundingObject Box { size 0.1 0.1 0.1 } }")
    m = conv.compile()
    visual = m.geom("R_visual")
    assert m.geom_contype[visual.id] == 0 and m.geom_conaffinity[visual.id] == 0
    assert m.body_mass[m.body("R").id] == pytest.approx(1.0)  # not the 1000 kg of the visual box
    assert m.geom_group[visual.id] == 2 and m.geom_group[m.geom("R").id] == 3


def test_mesh_and_heightfield() -> None:
    text = """
Solid { name "terrain" boundingObject ElevationGrid { xDimension 3 yDimension 2 xSpacing 0.5 ySpacing 1
  height [ 0 0.1 0.2 0.3 0.4 0.5 ] } }
DEF R Robot { translation 0 0 2 boundingObject IndexedFaceSet {
  coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0, 0 0 1 ] } coordIndex [ 0 2 1 -1 0 1 3 -1 0 3 2 -1 1 2 3 -1 ] }
  physics Physics { } }"""
    conv = convert(text)
    m = conv.compile()
    assert m.nmesh == 1 and m.nhfield == 1
    assert m.hfield_nrow[0] == 2 and m.hfield_ncol[0] == 3
    assert m.hfield_size[0][:3] == pytest.approx([0.5, 0.5, 0.5])
    # Tetrahedron volume 1/6 at density 1000.
    assert m.body_mass[m.body("R").id] == pytest.approx(1000 / 6)
    assert conv.smoke().ok


def test_lint_catches_each_trap() -> None:
    conv = convert("DEF R Robot { rotation 0 0 1 90 children [ HingeJoint { jointParameters HingeJointParameters "
                   "{ minStop -90 maxStop 90 } endPoint Solid { @W } } ] physics Physics { } }".replace("@W", WHEEL))
    codes = {f.code for f in conv.lint}
    assert {"rotation-in-degrees", "stop-in-degrees"} <= codes
    assert any(f.where.startswith("t.wbt:") for f in conv.lint)
    spec = mujoco.MjSpec.from_string("""<mujoco><compiler angle="radian"/><worldbody>
      <body name="a"><joint name="h" range="-180 180"/><geom size="0.1" contype="0" conaffinity="0"/>
        <site name="s"/></body>
      <body name="b"><inertial pos="0 0 0" mass="0" diaginertia="1 1 1"/><freejoint/><geom size="0.1"/></body>
      </worldbody><sensor><jointpos joint="h"/><framepos objtype="site" objname="s"/></sensor></mujoco>""")
    codes = {f.code for f in lint_spec(spec)}
    assert {"range-in-degrees", "visual-geom-mass", "non-positive-mass"} <= codes
    spec.sensors[0].objname = "missing"
    assert "sensor-target-missing" in {f.code for f in lint_spec(spec)}
    degree = mujoco.MjSpec.from_string('<mujoco><worldbody><body><joint range="-3.14 3.14"/><geom size="1"/>'
                                       '</body></worldbody></mujoco>')
    assert "range-in-radians" in {f.code for f in lint_spec(degree)}


def test_smoke_test_flags_an_exploding_model() -> None:
    # A stiff spring released far from rest with explicit Euler at 50 ms blows up.
    bad2 = mujoco.MjModel.from_xml_string("""<mujoco><option timestep="0.05" integrator="Euler"/><worldbody>
      <body><joint name="j" stiffness="1e9" ref="1" springref="0"/><geom size="0.1" mass="1e-3"/></body>
      </worldbody></mujoco>""")
    result = smoke_test(bad2, 0.5)
    assert not result.ok
    assert result.message
    good = convert(HINGE).smoke()
    assert good.ok and good.steps == 250 and not good.warnings


def test_errors_name_the_problem() -> None:
    with pytest.raises(ConversionError, match="world has no robot"):
        convert("Solid { }")
    with pytest.raises(ConversionError, match=r"t\.wbt:4:1: unsupported node Track"):
        convert("DEF R Robot {\n  children [\nTrack { } ] }")
    with pytest.raises(ConversionError, match=r"t\.wbt:\d+:\d+: unsupported node Cone"):
        convert("DEF R Robot { boundingObject Cone { } physics Physics { } }")
    with pytest.raises(ConversionError, match="2 robots"):
        convert("DEF A Robot { }\nDEF B Robot { }")
    with pytest.raises(ConversionError, match="no robot with DEF or name 'C'"):
        convert("DEF A Robot { }\nDEF B Robot { }", robot="C")
    assert convert("DEF A Robot { name \"first\" }\nDEF B Robot { }", robot="first").robot == "A"
    with pytest.raises(ConversionError, match="world file not found"):
        convert_world("/nonexistent/x.wbt")


def test_binding_needs_onboard_sensors(tmp_path: Path) -> None:
    conv = convert("DEF R Robot { children [ HingeJoint { device [ RotationalMotor { name \"m1\" } ] endPoint Solid "
                   "{ @W } } ] physics Physics { } }".replace("@W", WHEEL))
    with pytest.raises(DualtwinError, match="no on-board sensors"):
        conv.write(tmp_path / "r.xml", tmp_path / "binding.yaml")
    conv.write(tmp_path / "r.xml")
    assert (tmp_path / "r.xml").is_file()


def test_hostile_basic_time_step_is_read_as_webots_reads_it() -> None:
    # Found by fuzzing `dualtwin convert`: basicTimeStep 0 raised ZeroDivisionError and -8 a math domain error
    # (tracebacks) in the contact equivalences, and 1e-300 made the smoke test step forever.
    robot = "DEF R Robot { children [ HingeJoint { device [ RotationalMotor { name \"m1\" } ] endPoint Solid { @W } } ] " \
            "physics Physics { } }".replace("@W", WHEEL)
    for step in ("0", "-8"):
        conv = convert(f"WorldInfo {{ basicTimeStep {step} }}\n{robot}")
        assert conv.control_period_ms == 32.0  # Webots (and our twin) reset a step <= 0 to 32 ms
        assert any("basicTimeStep" in w and "not positive" in w for w in conv.warnings)
        assert conv.smoke().ok
    with pytest.raises(ConversionError, match=r"t\.wbt:2:\d+: WorldInfo\.basicTimeStep 1e-300 ms is below"):
        convert(f"WorldInfo {{ basicTimeStep 1e-300 }}\n{robot}")
