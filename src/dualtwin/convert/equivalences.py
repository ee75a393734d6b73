"""The converter's ODE -> MuJoCo equivalences: what each Webots physics setting becomes in MuJoCo, and why.

Pure functions and constants, no MjSpec walking (that is :mod:`dualtwin.convert.webots_to_mjcf`). Each entry's
docstring records the reasoning behind the mapping, so a change to one equivalence is a change to one function.
Section numbers (§) refer to the Webots-on-ODE specification in ``docs/reference/webots-on-ode.md``.

Overview (one line each; details in the functions):

* world step: :func:`timestep_for` (a MuJoCo step that divides ``basicTimeStep``), gravity :func:`world_gravity`,
  ERP/CFM as Webots resets them :func:`world_erp_cfm`, what the MJCF cannot carry :func:`world_notes`,
  ``implicitfast`` integrator, ``pyramidal`` cone (ODE's friction pyramid);
* contact softness ``softERP``/``softCFM`` -> ``solref``/``solimp``: :func:`contact_solref`, per material pair
  :func:`contact_pair`;
* friction ``coulombFriction`` -> ``friction``: :func:`coulomb_friction`;
* joint stops (ODE hard limits with the world ERP/CFM) -> ``solreflimit``/``solimplimit``: :func:`stop_solref`,
  ranges :func:`hinge_stop_range` (ODE's ±pi clamp about the initial position);
* joint damping, springs (resting at the joint's zero position) and static friction -> ``damping``,
  ``stiffness``, ``frictionloss``:
  :func:`apply_joint_dynamics`;
* motors (velocity/position control through Webots' PID, torque limits, multiplier) -> ``general`` actuator
  limits plus a ``webots_motor.*`` numeric the MuJoCo twin reads: :func:`motor_numeric`;
* cameras (FLU device frame, horizontal field of view) -> MuJoCo camera frame and ``fovy``:
  :func:`camera_rotation`, :func:`camera_fovy_degrees`; distance sensors: :func:`rangefinder_rotation`;
* a moving body without Physics (kinematic in Webots) -> :data:`KINEMATIC_MASS`;
* Damping nodes: not converted, :data:`DAMPING_NOTE` says why. Walked with the model, in their own modules:
  initial velocities -> keyframe (:mod:`dualtwin.convert.initial_state`), coupled motors' limits
  (:mod:`dualtwin.convert.coupled`), sensor resolution (:mod:`dualtwin.convert.sensor_models`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from dualtwin.geometry import axis_angle_matrix, matrix_from_quat

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "CONTACT_FRICTION_TAIL",
    "DAMPING_NOTE",
    "IDLE_MOTOR_NOTE",
    "KINEMATIC_MASS",
    "MAX_TIMESTEP_MS",
    "apply_joint_dynamics",
    "camera_fovy_degrees",
    "camera_rotation",
    "contact_effective_mass",
    "contact_pair",
    "contact_solref",
    "coulomb_friction",
    "friction_solref",
    "hinge2_axes",
    "hinge2_second_axis",
    "hinge_stop_range",
    "kinematic_joint_notes",
    "limit_solimp",
    "motor_numeric",
    "rangefinder_rotation",
    "set_scalar",
    "stop_solref",
    "timestep_for",
    "world_erp_cfm",
    "world_gravity",
    "world_notes",
]

MAX_TIMESTEP_MS = 2.0
#: Mass (kg) given to a moving body that has none. A Webots endPoint without Physics is moved kinematically;
#: MuJoCo rejects massless moving bodies, so it gets a token mass (and a warning).
KINEMATIC_MASS = 1e-3
#: MuJoCo's torsional and rolling friction of converted geoms (ODE has neither; Webots' rollingFriction is
#: reported, not converted): MuJoCo's defaults.
CONTACT_FRICTION_TAIL = (0.005, 0.0001)
#: Why a Damping node (Physics.damping, WorldInfo.defaultDamping) is not converted. ODE (§1.4) multiplies each
#: body's own world-frame velocities, the centre of mass's linear one and the angular one, by (1 - d)^h every
#: step, whatever joints hold the body. MuJoCo's joint ``damping`` acts on joint rates instead: relative to the
#: parent body below a joint, on the frame origin's velocity for a free joint, and with one coefficient for all
#: six dofs of a free joint (mass and inertia would need two, and an anisotropic inertia one per axis); its
#: ``viscosity`` is a medium's drag on the geoms' shapes. So no MJCF attribute gives ODE's decay, not even
#: for a free body, and the converter reports the node instead of writing an approximation.
DAMPING_NOTE = ("is not converted: ODE scales each body's own centre-of-mass and angular velocity by (1 - d)^h "
                "every step, MuJoCo's joint damping acts on joint rates (one coefficient for a free joint's six "
                "dofs) and its viscosity on geom shapes, so no MJCF attribute reproduces it")
#: Why a motor with maxTorque/maxForce 0 gets no actuator. Its available torque is 0 from load on and a controller
#: cannot raise it (setAvailableTorque takes min(f, maxTorque)), so Webots never drives the joint: u = 0 and ODE's
#: motor row holds only staticFriction (on-ODE §5.1-5.3), which the joint's frictionloss already is. MuJoCo refuses a
#: force range [0, 0], and an actuator without one would let the MuJoCo twin assume its default torque.
IDLE_MOTOR_NOTE = ("has maxTorque/maxForce 0: Webots never drives its joint (available torque 0, on-ODE §5.2-5.3), "
                   "so it gets no MuJoCo actuator and the joint moves freely (its staticFriction kept)")
#: Webots' coulombFriction -1 means infinite friction; MuJoCo needs a number.
INFINITE_FRICTION = 100.0


def timestep_for(basic_time_step_ms: float) -> float:
    """A MuJoCo timestep (s) <= 2 ms that divides Webots' basicTimeStep exactly.

    The largest of 2, 1, 0.5, 0.25 ms that divides ``basicTimeStep``, else ``basicTimeStep / k`` <= 2 ms: a
    control period is then a whole number of MuJoCo steps, and 2 ms keeps MuJoCo's contacts stable where
    Webots' ODE steps at 16 or 32 ms.
    """
    for h in (2.0, 1.0, 0.5, 0.25):
        ratio = basic_time_step_ms / h
        if h <= basic_time_step_ms and abs(ratio - round(ratio)) < 1e-9:
            return h / 1000.0
    k = max(1, math.ceil(basic_time_step_ms / MAX_TIMESTEP_MS))
    return basic_time_step_ms / k / 1000.0


def world_notes(info: dict[str, Any]) -> list[str]:
    """What of a WorldInfo the MJCF cannot carry: a coordinate system other than ENU is converted as written (the
    gravity follows it, the model is not rotated), and ``defaultDamping`` has no MuJoCo equivalent
    (:data:`DAMPING_NOTE` says why)."""
    notes = []
    system = str(info.get("coordinateSystem", "ENU"))
    if system.upper() in ("NUE", "EUN"):
        notes.append("WorldInfo coordinateSystem is NUE or EUN: converted as written (no rotation to ENU)")
    elif system.upper() != "ENU":  # read as ENU, as the Webots twin reads it (and says so)
        notes.append(f'WorldInfo coordinateSystem "{system}" is not "ENU", "NUE" or "EUN": converted as ENU')
    if info.get("defaultDamping") is not None:
        notes.append(f"WorldInfo defaultDamping {DAMPING_NOTE}")
    return notes


def world_gravity(world_info: Mapping[str, Any]) -> list[float]:
    """WorldInfo ``gravity`` (a magnitude) along the world's down axis (§1.1): -z in ENU, -y in NUE and EUN.

    The converter keeps the file's coordinates (no rotation to ENU), so gravity is written in them.
    """
    g = float(world_info.get("gravity", 9.81))
    y_down = str(world_info.get("coordinateSystem", "ENU")).upper() in ("NUE", "EUN")
    return [0.0, -g, 0.0] if y_down else [0.0, 0.0, -g]


def world_erp_cfm(world_info: Mapping[str, Any]) -> tuple[float, float]:
    """WorldInfo ERP and CFM as Webots hands them to ODE (§1.1): an ERP outside [0, 1] is reset to 0.2, a CFM
    <= 0 to 1e-5. The joint stops get these (:func:`stop_solref`)."""
    erp, cfm = float(world_info.get("ERP", 0.2)), float(world_info.get("CFM", 1e-5))
    return (erp if 0.0 <= erp <= 1.0 else 0.2), (cfm if cfm > 0.0 else 1e-5)


def camera_fovy_degrees(field_of_view: float, width: int, height: int) -> float:
    """Webots horizontal field of view (rad) -> MuJoCo vertical ``fovy`` (degrees).

    ``fovy = degrees(2 atan(tan(fov/2) h/w))``: the same pinhole, measured on the other image side.
    """
    return math.degrees(2.0 * math.atan(math.tan(field_of_view / 2.0) * height / width))


#: MuJoCo camera axes (x right, y up, z back) in a FLU Webots camera's device frame (looks along +x, +z up).
FLU_TO_MUJOCO_CAMERA = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def camera_rotation(device_R: FloatArray, *, old_cameras: bool) -> FloatArray:
    """The MuJoCo camera frame of a Webots Camera whose device frame is ``device_R``.

    R2022a+ Webots devices use the FLU convention: a Camera looks along its +x axis with +z up. R2021b and
    older worlds (NUE) look along -z with +y up, which is MuJoCo's camera convention already. So FLU cameras
    are turned so that MuJoCo's (-z, +y) land on the device's (+x, +z); old cameras are taken as they are.
    """
    if old_cameras:
        return device_R
    result: FloatArray = device_R @ FLU_TO_MUJOCO_CAMERA
    return result


def rangefinder_rotation(device_R: FloatArray) -> FloatArray:
    """Site frame of a DistanceSensor: Webots rays leave along the device's +x, MuJoCo's rangefinder along +z.

    Only the ray direction is mapped here: MuJoCo's rangefinder casts one ray along the site's +z. The MuJoCo twin
    casts the sensor's Webots rays from this site, each device-frame direction (x, y, z) being (-z, y, x) in the
    site frame (:mod:`dualtwin.twins.mujoco_rays`), and their distance goes through Webots' lookupTable
    (:mod:`dualtwin.convert.sensor_models`).
    """
    result: FloatArray = device_R @ axis_angle_matrix((0.0, 1.0, 0.0, math.pi / 2))
    return result


def contact_solref(soft_erp: float, soft_cfm: float, step_s: float, mass: float,
                   mujoco_step_s: float) -> tuple[float, float, float]:
    """ODE softERP/softCFM at Webots' step -> MuJoCo (timeconst, dampratio) and solimp ``d``.

    ODE's contact constraint is a spring-damper with k = ERP/(h CFM), b = (1-ERP)/CFM (h = basicTimeStep).
    For an effective mass m this is ω = sqrt(k/m), ζ = b / (2 sqrt(k m)); MuJoCo's (timeconst, dampratio)
    spring has ω = 1/(timeconst ζ), hence timeconst = 2 m / b and dampratio = ζ. m is chosen by
    :func:`contact_effective_mass`. solimp d = 1/(1 + CFM m / h) plays the role of ODE's regularisation.

    timeconst is at least 2 h'/d (h' the MuJoCo step). MuJoCo damps a contact with b' = 2/(d timeconst) in its
    reference acceleration, applied through an impedance that reaches 1 when several rows push one body (each
    row's regulariser sees only its own diagonal); h' b' > 1 then reverses the approach velocity every step and
    a stiff contact (small softCFM, so small d) bounces back faster than it hit, where ODE without ``bounce``
    only pushes the penetration out at softERP (§2.2). With d = 1 this is MuJoCo's own 2-step minimum.

    This matches the response shape, not ODE's per-point stiffness or static sink: a MuJoCo row gives
    f = (a_ref - a)/R, a_ref = -B v - K d r, R = (1-d)/d Â, with Â = 2 mu^2 (1 + mu^2) (w1 + w2)/impratio on
    the pyramid (w = ``body_invweight0``), and the 4 edge rows of a condim-3 point sum to a spring 4Kd/R, a
    damper 4B/R and an added mass 4/R: 195 kN/m for the Pioneer's wheels against ODE's 25 kN/m (sink 0.076 vs
    0.60 mm). The exact per-point map (B = 1/h, R = 4/(h(b + k h)), Kd = k R/4, MuJoCo step h) gives ODE's
    sink but shares the larger R with the friction rows, which then creep; it missed the Pioneer's held-out
    goals by more, so it is not used (docs, Pioneer results).
    """
    erp = min(max(soft_erp, 1e-6), 1.0)
    cfm = max(soft_cfm, 1e-12)
    k = erp / (step_s * cfm)
    b = max((1.0 - erp) / cfm, 1e-9)
    m = max(mass, 1e-6)
    dampratio = b / (2.0 * math.sqrt(k * m))
    d = min(max(1.0 / (1.0 + cfm * m / step_s), 0.5), 0.9999)
    timeconst = max(2.0 * m / b, 2.0 * mujoco_step_s / d)
    return timeconst, min(dampratio, 1e3), d


def contact_effective_mass(robot_mass: float, contact_bodies: int) -> float:
    """The mass m of :func:`contact_solref`: the robot's mass shared by its bodies with collision geoms.

    ODE's softness acts per contact point on whatever mass is behind it; one number per robot keeps every
    robot geom on one spring. A robot without mass uses 1 kg.
    """
    return robot_mass / contact_bodies if robot_mass > 0 else 1.0


def limit_solimp(d: float) -> list[float]:
    """A constant impedance ``d`` as MuJoCo's 5-number solimp (width 1 mm, midpoint 0.5, power 2)."""
    return [d, d, 0.001, 0.5, 2.0]


def coulomb_friction(props: Mapping[str, Any]) -> float:
    """ContactProperties ``coulombFriction`` -> MuJoCo sliding ``friction``.

    The first value (an asymmetric pair is reported and uses its first value); -1, Webots' infinite friction,
    becomes :data:`INFINITE_FRICTION`.
    """
    mu = float((props.get("coulombFriction") or [1.0])[0])
    if mu < 0:  # -1 = infinite friction in Webots
        mu = INFINITE_FRICTION
    return mu


def contact_pair(props: Mapping[str, Any], m_eff: float, step_s: float,
                 mujoco_step_s: float) -> tuple[float, list[float], list[float]]:
    """One material pair's ContactProperties -> (friction, solref, solimp) for the geoms that meet on it.

    ``bounce`` has no MuJoCo equivalent (MuJoCo contacts have no restitution model), so only softERP/softCFM
    shape the contact; the converter warns when a pair has bounce.
    """
    mu = coulomb_friction(props)
    timeconst, dampratio, d = contact_solref(float(props.get("softERP", 0.2)), float(props.get("softCFM", 0.001)),
                                             step_s, m_eff, mujoco_step_s)
    return mu, [timeconst, dampratio], limit_solimp(d)


def stop_solref(stop_erp: float, stop_cfm: float, step_s: float, inertia: float,
                mujoco_step_s: float) -> tuple[float, float, float]:
    """ODE stop ERP/CFM at Webots' step -> MuJoCo ``solreflimit`` (timeconst, dampratio) and solimp ``d``.

    Webots stops are hard ODE limits with the WorldInfo ERP/CFM (ODE's defaults at joint creation; Webots
    passes ``stopERP``/``stopCFM`` only when they change at run time, §4.2). In one ODE step of length H a
    violated stop loses its approach velocity and is pushed out at ERP r / H; CFM leaves a blend
    d = 1/(1 + CFM m / h) of the unconstrained motion (m the joint's effective inertia, 1/``dof_invweight0``).
    A MuJoCo limit with impedance d and reference acceleration -b v - k r does the same in one MuJoCo step h
    when b = 1/h and h k = ERP / H: ``solreflimit`` = (2h, sqrt(H / (4 h ERP))), ``solimplimit`` d
    (<= 0.9999), so the joint rests on its stop with ODE's static offset CFM m a H / ERP instead of MuJoCo's
    default soft limit (0.02 s, d 0.9-0.95), which sinks a loaded CartPole pole 2.3 mrad past its stop.
    """
    erp = min(max(stop_erp, 1e-6), 1.0)
    timeconst = 2.0 * mujoco_step_s
    dampratio = math.sqrt(step_s / (4.0 * mujoco_step_s * erp))
    d = 1.0 / (1.0 + max(stop_cfm, 0.0) * max(inertia, 1e-9) / mujoco_step_s)
    return timeconst, dampratio, min(max(d, 0.5), 0.9999)


def friction_solref(cfm: float, inertia: float, mujoco_step_s: float) -> tuple[float, float, float]:
    """A joint's ``staticFriction`` row, ODE's velocity-0 motor row at the world CFM, as MuJoCo's ``frictionloss``
    softness: ``solreffriction`` (timeconst, dampratio) and solimp ``d``.

    Webots' static friction is a joint motor with target velocity 0 and force limit ``staticFriction`` (on-ODE
    §4.5), a row with the world CFM (§5.3), so below its limit it holds the joint still within one step. MuJoCo's
    default friction softness (solref 0.02 s, impedance 0.9) lets a loaded joint creep at about
    ``load (1 - d) / (d m b)``: a 1 kg pendulum 0.3 m long on a 5 N·m friction slid at 0.034 rad/s where ODE holds
    it. As for a stop (:func:`stop_solref`): b = 1/h (timeconst 2h; a friction row has no position, so the damping
    ratio plays no part and is 1) and d = 1/(1 + CFM m / h).
    """
    d = 1.0 / (1.0 + max(cfm, 0.0) * max(inertia, 1e-9) / mujoco_step_s)
    return 2.0 * mujoco_step_s, 1.0, min(max(d, 0.5), 0.9999)


def hinge_stop_range(lo: float, hi: float, offset: float = 0.0) -> tuple[float, float]:
    """Hinge ``minStop``/``maxStop`` as ODE applies them (§4.2), in Webots positions.

    ODE's stops are -maxStop + offset and -minStop + offset (offset = the joint's initial ``position``), each
    clamped into [-pi, pi] on ODE's angle; on Webots' position (offset - ODE angle) that is a clamp into
    [offset - pi, offset + pi]. (The caller limits a joint only when the stops differ; equal stops mean "no stop"
    in Webots.)
    """
    return max(lo, offset - math.pi), min(hi, offset + math.pi)


def set_scalar(element: Any, attr: str, value: float) -> None:
    """Set a joint's damping/stiffness: MuJoCo 4 made them arrays (polynomial terms), 3.x has scalars."""
    current = getattr(element, attr)
    if isinstance(current, np.ndarray) and current.ndim:
        current[0] = value
        setattr(element, attr, current)
    else:
        setattr(element, attr, value)


def apply_joint_dynamics(joint: Any, params: Mapping[str, Any]) -> bool:
    """Joint parameters -> MuJoCo joint dynamics; returns True when a suspension could not be converted.

    * ``dampingConstant`` -> ``damping`` (both a viscous torque -c q', per joint);
    * ``springConstant`` -> ``stiffness``, resting at MuJoCo's default ``springref`` 0: Webots' spring AMotor
      (LMotor) holds ODE's angle at the offset, i.e. the joint at its **zero position** whatever the file's
      initial ``position`` (§4.5, T = -K position - B velocity), and the converted joint's qpos is Webots'
      position (``ref`` = ``position``);
    * ``staticFriction`` -> ``frictionloss`` (a dry friction torque opposing motion in both);
    * the hinge suspension of Webots' ODE fork has no MuJoCo counterpart.
    """
    damping = float(params.get("dampingConstant", 0.0))
    spring = float(params.get("springConstant", 0.0))
    friction = float(params.get("staticFriction", 0.0))
    set_scalar(joint, "damping", damping)
    if spring:
        set_scalar(joint, "stiffness", spring)
        joint.springref = 0.0
    if friction:
        joint.frictionloss = friction
    return bool(float(params.get("suspensionSpringConstant", 0.0))
                or float(params.get("suspensionDampingConstant", 0.0)))


def motor_numeric(motor: Any) -> list[float]:
    """A RotationalMotor/LinearMotor's control semantics as ``webots_motor.<actuator>`` numeric data.

    ``[maxVelocity, Kp, Ki, Kd, acceleration]`` plus ``[minPosition, maxPosition]`` when they differ, plus
    ``multiplier`` when it is not 1 (after ``[minPosition, maxPosition]``, written then even when equal; 0 is
    Webots' 1, §5.2 and webots-devices §9): Webots scales every setPosition/setVelocity/setTorque by it. MuJoCo has
    no actuator that behaves like a Webots motor (position control through Webots' PID giving a velocity,
    clamped to maxVelocity and tracked within maxTorque), so the converter writes a ``general`` actuator whose
    force and control ranges are ±maxTorque (±maxForce) and stores the rest here for the MuJoCo twin
    (:mod:`dualtwin.twins.mujoco`) to emulate. minPosition/maxPosition are not joint stops: Webots clamps every
    position target into them while velocity and torque commands pass, so the twin needs them too.
    """
    kp, ki, kd = (float(v) for v in motor.get("controlPID", (10.0, 0.0, 0.0)))
    data = [float(motor.get("maxVelocity", 10.0)), kp, ki, kd, float(motor.get("acceleration", -1.0))]
    lo, hi = float(motor.get("minPosition", 0.0)), float(motor.get("maxPosition", 0.0))
    multiplier = float(motor.get("multiplier", 1.0)) or 1.0
    if lo != hi or multiplier != 1.0:
        data += [lo, hi]
    if multiplier != 1.0:
        data.append(multiplier)
    return data


def hinge2_second_axis(axis1: Sequence[float] | FloatArray, position1: float,
                       axis2: Sequence[float] | FloatArray) -> FloatArray:
    """A Hinge2Joint's axis 2 at the file's pose: written for hinge 1 at zero, so turned by ``position1``.

    Both hinges then live in the child body: MuJoCo applies a body's joints in order, each about its axis in
    the frame left by the previous ones, so axis 2 turns with hinge 1 exactly as ODE's hinge-2 axis 2. (A
    separate intermediate body would need a fake mass: MuJoCo rejects massless moving bodies.)
    """
    R = axis_angle_matrix((*(float(v) for v in axis1), position1))
    result: FloatArray = R @ np.asarray(axis2, dtype=float)
    return result


def kinematic_joint_notes(kind: str, end: Any, parent: Any, body_solids: Sequence[tuple[str, Any]]) -> list[str]:
    """Warnings for a joint that Webots moves kinematically (no ODE joint) where MuJoCo has a dynamic joint.

    Webots builds no ODE joint for an endPoint without Physics (on-ODE §4.1), nor for a Hinge2Joint whose parent
    has no body (§4.4: a hinge2 needs both bodies): the nearest Solid above the joint with Physics, through the
    MuJoCo bodies the converter built (``parent`` up to the world, each body's Solid in ``body_solids``).
    """
    if end.get("physics") is None:
        return [f"{kind} endPoint has no Physics: Webots moves it kinematically, MuJoCo dynamically"]
    if kind != "Hinge2Joint":
        return []
    solids = dict(body_solids)
    body = parent
    while body is not None and body.name in solids:
        if solids[body.name].get("physics") is not None:
            return []
        body = body.parent
    return ["Hinge2Joint has no Physics above it (a static parent): Webots builds no ODE joint and moves its "
            "endPoint kinematically, MuJoCo dynamically"]


#: Webots' warning for a Hinge2Joint whose axes are aligned (on-ODE §4.4), and the converter's.
HINGE2_ALIGNED = "Hinge2Joint axes are aligned: Webots falls back to the world's x and z axes, and so does the conversion"


def hinge2_axes(axis1: Sequence[float], position1: float, axis2: Sequence[float], parent: Any, frame: FloatArray,
                warn: Callable[[str], None]) -> tuple[FloatArray, FloatArray]:
    """A Hinge2Joint's two axes in its frame (``frame``: the joint's upper Pose in the MuJoCo body ``parent``).

    Axis 2 is turned by ``position1`` (:func:`hinge2_second_axis`). When the two are aligned, ODE's hinge-2 would
    have one axis twice (in MuJoCo two hinges about one axis in one body: a singular mass matrix, NaN from the
    first step), and Webots sets the world's x and z axes instead, with a warning (on-ODE §4.4; the Webots twin
    does the same): the converter does too, expressed in ``frame`` through the bodies' rotations up to the world.
    """
    a1 = np.asarray(axis1, dtype=float)
    a2 = hinge2_second_axis(a1, position1, axis2)
    n1, n2 = float(np.linalg.norm(a1)), float(np.linalg.norm(a2))
    if n1 == 0.0 or n2 == 0.0 or float(np.linalg.norm(np.cross(a1 / n1, a2 / n2))) >= 1e-6:
        return a1, a2  # a zero axis is refused by the converter with its own message
    warn(HINGE2_ALIGNED)
    rotation = np.asarray(frame, dtype=float)[:3, :3]
    body = parent
    while body is not None and body.parent is not None:  # the world body has no parent
        rotation = matrix_from_quat(np.asarray(body.quat, dtype=float)) @ rotation
        body = body.parent
    return rotation.T @ np.array([1.0, 0.0, 0.0]), rotation.T @ np.array([0.0, 0.0, 1.0])
