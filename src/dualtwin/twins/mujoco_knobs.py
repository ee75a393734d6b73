"""The MuJoCo twin's knob table (see :mod:`dualtwin.twins.knob_table`), and the contact conversions it uses.

Every entry writes into the compiled ``MjModel`` (or the twin's motor and sensor models), always from the
nominal values :meth:`MuJoCoTwin.set_knobs <dualtwin.twins.mujoco.MuJoCoTwin.set_knobs>` restores first, so
values never compound. Entries that change the mass distribution (masses, inertia, centre of mass, armature)
mark it on the pass (:class:`KnobPass`) so ``set_knobs`` recomputes what a compiled model would derive
from it. The names are shared with the Webots twin where both have the parameter.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np

from dualtwin.twins.knob_table import KnobGroup, KnobKind, KnobTable
from dualtwin.twins.mujoco_state import robot_actuator

# Geoms whose size[0] is a radius (the geom.<g>.radius knob).
ROUND_GEOMS = frozenset({int(mujoco.mjtGeom.mjGEOM_CYLINDER), int(mujoco.mjtGeom.mjGEOM_SPHERE),
                         int(mujoco.mjtGeom.mjGEOM_CAPSULE)})
# Largest delay, in control periods, that the delay knobs accept.
MAX_DELAY_PERIODS = 10
#: Bounds of the impedance knobs (MuJoCo solimp dmax): from very soft (or the nominal, if softer) to MuJoCo's
#: hardest.
IMPEDANCE_BOUNDS = (0.5, 0.9999)


def nominal_values(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Copies of the compiled model's values that knobs write (set_knobs restores them before each pass)."""
    m = model
    return {
        "dof_damping": m.dof_damping.copy(), "dof_frictionloss": m.dof_frictionloss.copy(),
        "geom_friction": m.geom_friction.copy(), "body_mass": m.body_mass.copy(),
        "body_inertia": m.body_inertia.copy(), "body_ipos": m.body_ipos.copy(),
        "geom_solref": m.geom_solref.copy(), "jnt_stiffness": m.jnt_stiffness.copy(),
        "sensor_noise": m.sensor_noise.copy(), "body_iquat": m.body_iquat.copy(),
        "jnt_solref": m.jnt_solref.copy(), "dof_armature": m.dof_armature.copy(),
        "geom_solimp": m.geom_solimp.copy(), "jnt_solimp": m.jnt_solimp.copy(),
        "geom_size": m.geom_size.copy(), "geom_rbound": m.geom_rbound.copy(), "geom_aabb": m.geom_aabb.copy(),
        "impratio": np.array(m.opt.impratio),
        "pair_friction": m.pair_friction.copy(), "pair_solref": m.pair_solref.copy(),
        "pair_solimp": m.pair_solimp.copy(),
    }


def follow_pairs(model: mujoco.MjModel, nominal: dict[str, np.ndarray]) -> None:
    """Explicit contact pairs follow their geoms' knobs: each pair's friction, solref and solimp (dmin, dmax) change
    by the factor by which MuJoCo's mix of its two geoms (the larger friction, the mean solref and solimp) changed
    from nominal. The converter writes a ``<pair>`` where mixing cannot give a material pair its own values
    (:mod:`dualtwin.convert.contacts`), and MuJoCo then reads that pair, not the geoms: without this a geom's
    friction knob would not reach the contacts those pairs cover."""
    m = model
    for p in range(m.npair):
        a, b = int(m.pair_geom1[p]), int(m.pair_geom2[p])
        m.pair_friction[p] = nominal["pair_friction"][p] * _ratio(
            max(m.geom_friction[a, 0], m.geom_friction[b, 0]),
            max(nominal["geom_friction"][a, 0], nominal["geom_friction"][b, 0]))
        for i in range(2):
            m.pair_solref[p, i] = nominal["pair_solref"][p, i] * _ratio(
                m.geom_solref[a, i] + m.geom_solref[b, i], nominal["geom_solref"][a, i] + nominal["geom_solref"][b, i])
            m.pair_solimp[p, i] = min(IMPEDANCE_BOUNDS[1], nominal["pair_solimp"][p, i] * _ratio(
                m.geom_solimp[a, i] + m.geom_solimp[b, i], nominal["geom_solimp"][a, i] + nominal["geom_solimp"][b, i]))


def _ratio(now: float, before: float) -> float:
    return float(now / before) if before else 1.0


def restitution_to_dampratio(restitution: float, nominal: float) -> float:
    """Damping ratio of MuJoCo's contact spring-damper that rebounds with coefficient ``restitution``.

    A linear spring-damper with damping ratio ζ < 1 rebounds with ``e = exp(-ζπ/√(1-ζ²))``. ``e = 0`` keeps a
    nominal ratio that already does not bounce (ζ >= 1), else uses critical damping.
    """
    if restitution <= 0.0:
        return max(nominal, 1.0)
    log_e = math.log(min(restitution, 0.999))
    return -log_e / math.sqrt(math.pi ** 2 + log_e ** 2)


def impedance_pair(nominal_solimp: Sequence[float], dmax: float) -> tuple[float, float]:
    """(dmin, dmax) for a new dmax, dmin keeping its nominal ratio to dmax (the impedance curve's shape)."""
    return float(nominal_solimp[0]) * dmax / float(nominal_solimp[1]), dmax


def dampratio_to_restitution(dampratio: float) -> float:
    """Inverse of `restitution_to_dampratio` (0 for ζ >= 1)."""
    if dampratio >= 1.0:
        return 0.0
    return math.exp(-dampratio * math.pi / math.sqrt(1.0 - dampratio ** 2))


@dataclass
class KnobPass:
    """What one ``set_knobs`` call collected for the steps after the entries ran."""

    #: Extra factor on each body's rotational inertia (``body.<b>.inertia_scale``), by body id.
    inertia_scale: dict[int, float] = field(default_factory=dict)
    #: A knob moved mass, inertia, centre of mass or armature: derived quantities need recomputing.
    changed_inertia: bool = False


class KnobTarget(Protocol):
    """What the table's entries read and write on the twin: :class:`~dualtwin.twins.mujoco.MuJoCoTwin` has it.

    A Protocol rather than the twin's class, so this module does not import the twin that imports it (the
    package stays free of import cycles, type-only imports included). The members are the twin's own
    bookkeeping, private to the twins package; read-only members are properties so the twin's concrete types
    fit.
    """

    #: Written by the sensor-delay entry.
    _delay: int

    @property
    def model(self) -> mujoco.MjModel: ...
    @property
    def _nominal(self) -> dict[str, np.ndarray]: ...
    @property
    def _armature(self) -> np.ndarray: ...
    @property
    def _knob_pass(self) -> KnobPass: ...
    @property
    def _motors(self) -> Sequence[Any]: ...
    @property
    def _nominal_motor(self) -> dict[str, tuple[float, float]]: ...
    @property
    def _nominal_kp(self) -> dict[str, float]: ...
    @property
    def _nominal_substeps(self) -> int: ...
    @property
    def _nominal_timestep(self) -> float: ...
    def _set_substeps(self, substeps: int) -> None: ...


# ---------------------------------------------------------------- objects, in knob order
def _named(tw: KnobTarget, kind: mujoco.mjtObj, count: int) -> Iterator[tuple[str, int]]:
    for i in range(count):
        name = mujoco.mj_id2name(tw.model, kind, i)
        if name:
            yield name, i


def _joints(tw: KnobTarget) -> Iterator[tuple[str, int]]:
    m = tw.model
    return ((n, j) for n, j in _named(tw, mujoco.mjtObj.mjOBJ_JOINT, m.njnt)
            if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE)


def _contact_geoms(tw: KnobTarget) -> Iterator[tuple[str, int]]:
    m = tw.model
    return ((n, g) for n, g in _named(tw, mujoco.mjtObj.mjOBJ_GEOM, m.ngeom)
            if m.geom_contype[g] | m.geom_conaffinity[g])


def _bodies(tw: KnobTarget) -> Iterator[tuple[str, int]]:
    # Body 0 is the world; massless bodies have no mass to scale.
    return ((n, b) for n, b in _named(tw, mujoco.mjtObj.mjOBJ_BODY, tw.model.nbody)
            if b >= 1 and float(tw._nominal["body_mass"][b]) > 0)


def _motors(tw: KnobTarget) -> Iterator[tuple[str, Any]]:
    # the converted robot's motors: another robot's (held at their initial position, dualtwin.convert.world_robots)
    # are no device of the robot in either twin, so the Webots twin has no knob for them either
    return ((mo.name, mo) for mo in tw._motors if robot_actuator(tw.model, mo.index))


def _sensors(tw: KnobTarget) -> Iterator[tuple[str, int]]:
    return _named(tw, mujoco.mjtObj.mjOBJ_SENSOR, tw.model.nsensor)


def _model(tw: KnobTarget) -> Iterator[tuple[str, None]]:
    yield "", None


def _when(test: Any) -> Any:
    """A ``find`` for the objects of a group that pass ``test(twin, handle)``."""
    def find(tw: KnobTarget, obj: tuple[str, Any]) -> tuple[str, Any] | None:
        return obj if test(tw, obj[1]) else None
    return find


# ---------------------------------------------------------------- joints
def _dof(tw: KnobTarget, j: int) -> int:
    return int(tw.model.jnt_dofadr[j])


def _set_dof(array: str) -> Any:
    def apply(tw: KnobTarget, j: int, value: float) -> None:
        getattr(tw.model, array)[tw.model.jnt_dofadr[j]] = value
    return apply


def _set_armature(tw: KnobTarget, j: int, value: float) -> None:
    tw._armature[tw.model.jnt_dofadr[j]] = value
    tw._knob_pass.changed_inertia = True


def _hinge_or_slide(tw: KnobTarget, j: int) -> bool:
    return int(tw.model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def _soft_limit(tw: KnobTarget, j: int) -> bool:
    return bool(tw.model.jnt_limited[j]) and float(tw._nominal["jnt_solref"][j, 0]) > 0


def _set_limit_timeconst(tw: KnobTarget, j: int, value: float) -> None:
    tw.model.jnt_solref[j, 0] = value


def _set_limit_impedance(tw: KnobTarget, j: int, value: float) -> None:
    tw.model.jnt_solimp[j, :2] = impedance_pair(tw._nominal["jnt_solimp"][j], value)


def _timeconst_limits(tw: KnobTarget, handle: Any, nominal: float) -> tuple[float, float]:
    # MuJoCo clamps time constants below two physics steps (refsafe).
    step = tw._nominal_timestep
    return 2 * step, max(10 * nominal, 4 * step)


def _impedance_limits(tw: KnobTarget, handle: Any, nominal: float) -> tuple[float, float]:
    return min(IMPEDANCE_BOUNDS[0], nominal), IMPEDANCE_BOUNDS[1]


JOINT_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    KnobKind("joint.<j>.damping", "N*m*s/rad", "0 .. max(10 × nominal, 1)", "`dof_damping`",
             lambda tw, j: float(tw._nominal["dof_damping"][_dof(tw, j)]), lambda tw, j, n: (0.0, max(10 * n, 1.0)),
             _set_dof("dof_damping"), "joint viscous damping (Webots dampingConstant)"),
    KnobKind("joint.<j>.friction", "N*m", "0 .. max(10 × nominal, 0.5)", "`dof_frictionloss`",
             lambda tw, j: float(tw._nominal["dof_frictionloss"][_dof(tw, j)]),
             lambda tw, j, n: (0.0, max(10 * n, 0.5)), _set_dof("dof_frictionloss"),
             "joint dry friction (MuJoCo frictionloss, Webots staticFriction)"),
    KnobKind("joint.<j>.armature", "kg*m^2", "0 .. max(10 × nominal, 0.2)", "`dof_armature` (rotor inertia; kg for "
             "a slide joint)", lambda tw, j: float(tw._nominal["dof_armature"][_dof(tw, j)]),
             lambda tw, j, n: (0.0, max(10 * n, 0.2)), _set_armature,
             "rotor inertia reflected to the joint (MuJoCo armature; Webots models none)", find=_when(_hinge_or_slide),
             unit_of=lambda tw, j: "kg" if int(tw.model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE)
             else "kg*m^2"),
    # ODE's joint stops are stiff (world ERP/CFM); MuJoCo's limits are soft by default.
    KnobKind("joint.<j>.limit_timeconst", "s", "2 steps .. max(10 × nominal, 4 steps)",
             "`jnt_solref[0]` of a limited joint", lambda tw, j: float(tw._nominal["jnt_solref"][j, 0]),
             _timeconst_limits, _set_limit_timeconst,
             "joint-limit softness: time constant of the limit's spring-damper (MuJoCo solreflimit[0])",
             find=_when(_soft_limit)),
    KnobKind("joint.<j>.limit_impedance", "", "min(0.5, nominal) .. 0.9999",
             "`jnt_solimp` dmax of a limited joint (dmin keeps its ratio)",
             lambda tw, j: float(tw._nominal["jnt_solimp"][j, 1]), _impedance_limits, _set_limit_impedance,
             "joint-limit hardness: MuJoCo solimplimit dmax (dmin keeps its ratio to it)", find=_when(_soft_limit)),
)


# ---------------------------------------------------------------- geoms
def _set_geom_friction(tw: KnobTarget, g: int, value: float) -> None:
    tw.model.geom_friction[g, 0] = value


def _solref_standard(tw: KnobTarget, g: int) -> bool:
    # The standard (time constant, damping ratio) form of solref.
    return float(tw._nominal["geom_solref"][g, 0]) > 0


def _set_solref_timeconst(tw: KnobTarget, g: int, value: float) -> None:
    tw.model.geom_solref[g, 0] = value


def _set_restitution(tw: KnobTarget, g: int, value: float) -> None:
    tw.model.geom_solref[g, 1] = restitution_to_dampratio(value, float(tw._nominal["geom_solref"][g, 1]))


def _set_geom_impedance(tw: KnobTarget, g: int, value: float) -> None:
    tw.model.geom_solimp[g, :2] = impedance_pair(tw._nominal["geom_solimp"][g], value)


def _set_radius(tw: KnobTarget, g: int, value: float) -> None:
    m, nominal = tw.model, tw._nominal
    m.geom_size[g, 0] = value
    # Broad-phase bounds only need to enclose the geom.
    grow = max(0.0, value - float(nominal["geom_size"][g, 0]))
    m.geom_rbound[g] = nominal["geom_rbound"][g] + grow
    m.geom_aabb[g, 3:] = nominal["geom_aabb"][g, 3:] + grow


GEOM_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    KnobKind("geom.<g>.friction", "", "0 .. 5 × max(nominal, 0.1)", "`geom_friction[0]` of a colliding geom",
             lambda tw, g: float(tw._nominal["geom_friction"][g, 0]), lambda tw, g, n: (0.0, 5.0 * max(n, 0.1)),
             _set_geom_friction, "sliding friction coefficient"),
    KnobKind("geom.<g>.solref_timeconst", "s", "2 steps .. max(10 × nominal, 4 steps)", "`geom_solref[0]`",
             lambda tw, g: float(tw._nominal["geom_solref"][g, 0]), _timeconst_limits, _set_solref_timeconst,
             "contact softness: time constant of the contact spring-damper (MuJoCo solref[0])",
             find=_when(_solref_standard)),
    KnobKind("geom.<g>.restitution", "", "0 .. 0.95",
             "`geom_solref[1]`: damping ratio ζ with e = exp(−ζπ/√(1−ζ²))",
             lambda tw, g: dampratio_to_restitution(float(tw._nominal["geom_solref"][g, 1])),
             lambda tw, g, n: (0.0, 0.95), _set_restitution,
             "contact restitution (MuJoCo: solref damping ratio below 1)", find=_when(_solref_standard)),
    KnobKind("geom.<g>.impedance", "", "min(0.5, nominal) .. 0.9999", "`geom_solimp` dmax (dmin keeps its ratio)",
             lambda tw, g: float(tw._nominal["geom_solimp"][g, 1]), _impedance_limits, _set_geom_impedance,
             "contact hardness: MuJoCo solimp dmax (dmin keeps its ratio to it; Webots softCFM)"),
    # A wheel's effective rolling radius: ODE's soft contacts let it sink (0.6 mm on the Pioneer).
    KnobKind("geom.<g>.radius", "m", "0.9 × nominal .. 1.1 × nominal",
             "`geom_size[0]` of a cylinder, sphere or capsule (broad-phase bounds grow with it)",
             lambda tw, g: float(tw._nominal["geom_size"][g, 0]), lambda tw, g, n: (0.9 * n, 1.1 * n), _set_radius,
             "radius of a cylinder, sphere or capsule geom (a wheel's rolling radius)",
             find=_when(lambda tw, g: tw.model.geom_type[g] in ROUND_GEOMS)),
)


# ---------------------------------------------------------------- bodies
def _set_mass(tw: KnobTarget, b: int, value: float) -> None:
    tw.model.body_mass[b] = value
    tw._knob_pass.changed_inertia = True


def _set_inertia_scale(tw: KnobTarget, b: int, value: float) -> None:
    tw._knob_pass.inertia_scale[b] = value
    tw._knob_pass.changed_inertia = True


def _com_span(tw: KnobTarget, b: int, nominal: float) -> tuple[float, float]:
    m = tw.model
    reach = max([float(m.geom_rbound[g]) for g in range(m.ngeom) if m.geom_bodyid[g] == b] + [0.0])
    span = max(0.05, 0.25 * reach)
    return -span, span


def _com_offset(axis: str) -> KnobKind[KnobTarget]:
    index = "xyz".index(axis)

    def apply(tw: KnobTarget, b: int, value: float) -> None:
        tw.model.body_ipos[b, index] += value
        tw._knob_pass.changed_inertia = True

    return KnobKind(f"body.<b>.com_offset_{axis}", "m", "± max(0.05, ¼ of the body's largest geom bounding radius)",
                    f"shift of `body_ipos[{index}]`", lambda tw, b: 0.0, _com_span, apply,
                    f"shift of the centre of mass along the body's {axis} axis")


BODY_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    KnobKind("body.<b>.mass", "kg", "0.1 × nominal .. 10 × nominal", "`body_mass`, `body_inertia` scaled with it",
             lambda tw, b: float(tw._nominal["body_mass"][b]), lambda tw, b, n: (0.1 * n, 10 * n), _set_mass,
             "body mass (inertia scaled with it)"),
    KnobKind("body.<b>.inertia_scale", "", "0.1 .. 10", "factor on `body_inertia`", lambda tw, b: 1.0,
             lambda tw, b, n: (0.1, 10.0), _set_inertia_scale, "factor on the body's rotational inertia"),
    *(_com_offset(axis) for axis in "xyz"),
)


# ---------------------------------------------------------------- motors (the Webots-motor emulation)
def _set_param(attr: str) -> Any:
    def apply(tw: KnobTarget, mo: Any, value: float) -> None:
        setattr(mo.state.params, attr, value)
    return apply


def _set_gain(tw: KnobTarget, mo: Any, value: float) -> None:
    mo.state.gain = value


MOTOR_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    KnobKind("motor.<m>.max_torque", "N*m", "0 .. 10 × nominal", "the emulated Webots motor's torque limit",
             lambda tw, mo: tw._nominal_motor[mo.name][0], lambda tw, mo, n: (0.0, 10 * n), _set_param("max_torque"),
             "maximum motor torque"),
    KnobKind("motor.<m>.max_velocity", "rad/s", "0.1 × nominal .. 10 × nominal",
             "the emulated Webots motor's velocity limit", lambda tw, mo: tw._nominal_motor[mo.name][1],
             lambda tw, mo, n: (0.1 * n, 10 * n), _set_param("max_velocity"), "maximum motor velocity"),
    KnobKind("motor.<m>.gain", "", "-2 .. 2", "command × gain", lambda tw, mo: 1.0, lambda tw, mo, n: (-2.0, 2.0),
             _set_gain, "command gain (sign included)"),
    KnobKind("motor.<m>.kp", "1/s", "0.1 × nominal .. 10 × nominal", "P of the emulated Webots position PID",
             lambda tw, mo: tw._nominal_kp[mo.name], lambda tw, mo, n: (0.1 * n, 10 * n), _set_param("kp"),
             "proportional gain of Webots' position PID (velocity command per unit position error)"),
)


# ---------------------------------------------------------------- sensors
def _set_sensor(array: str, integer: bool = False) -> Any:
    def apply(tw: KnobTarget, s: int, value: float) -> None:
        getattr(tw, array)[s] = int(round(value)) if integer else value
    return apply


SENSOR_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    KnobKind("sensor.<s>.noise", "", "0 .. max(10 × nominal, 0.05)", "Gaussian σ added in `sensor()`",
             lambda tw, s: float(tw._nominal["sensor_noise"][s]), lambda tw, s, n: (0.0, max(10 * n, 0.05)),
             _set_sensor("_noise"), "standard deviation of Gaussian reading noise (Webots noise)"),
    KnobKind("sensor.<s>.bias", "", "-0.1 .. 0.1", "offset added in `sensor()`", lambda tw, s: 0.0,
             lambda tw, s, n: (-0.1, 0.1), _set_sensor("_sensor_bias"), "constant offset added to readings"),
    KnobKind("sensor.<s>.delay", "periods", f"0 .. {MAX_DELAY_PERIODS}", "readings k control periods old",
             lambda tw, s: 0.0, lambda tw, s, n: (0.0, MAX_DELAY_PERIODS), _set_sensor("_sensor_delay", integer=True),
             "readings are this many control periods old (integer)"),
    KnobKind("sensor.<s>.quantization", "", "0 .. 0.1", "readings discretised as Webots' resolution (0 = off)",
             lambda tw, s: 0.0, lambda tw, s, n: (0.0, 0.1), _set_sensor("_sensor_quant"),
             "readings are discretised to this step by Webots' resolution rule, int(v/r + 0.5)·r (0 = off)"),
)


# ---------------------------------------------------------------- the model as a whole
def _set_impratio(tw: KnobTarget, handle: None, value: float) -> None:
    tw.model.opt.impratio = value


def _set_delay(tw: KnobTarget, handle: None, value: float) -> None:
    tw._delay = int(round(value))


def _set_substeps(tw: KnobTarget, handle: None, value: float) -> None:
    tw._set_substeps(int(round(value)))


# How hard friction is against the normal force: the slip of MuJoCo's soft friction (Webots: the contact's
# forceDependentSlip has a similar role, with no common scale).
IMPRATIO = KnobKind("option.impratio", "", "0.1 .. 100", "`opt.impratio` (friction/normal impedance ratio)",
                    lambda tw, _: float(tw._nominal["impratio"]), lambda tw, _, n: (0.1, 100.0), _set_impratio,
                    "ratio of frictional to normal constraint impedance (MuJoCo option impratio)")
DELAY = KnobKind("control.delay_periods", "periods", f"0 .. {MAX_DELAY_PERIODS}",
                 "commands act k control periods late", lambda tw, _: 0.0, lambda tw, _, n: (0.0, MAX_DELAY_PERIODS),
                 _set_delay, "commands take effect this many control periods late (integer)")
# The integration step is part of a twin's behaviour: ODE's symplectic Euler at Webots' basicTimeStep leads a
# 2 ms MuJoCo model on unstable motion and resolves stop and contact impacts within one coarse step. Down to
# a quarter of the nominal steps (8 ms for 2 ms models), up to twice as many.
SUBSTEPS = KnobKind("physics.substeps", "steps", "max(1, nominal // 4) .. 2 × nominal",
                    "physics steps per control period (timestep = period / k)",
                    lambda tw, _: tw._nominal_substeps,
                    lambda tw, _, n: (max(1, tw._nominal_substeps // 4), 2 * tw._nominal_substeps), _set_substeps,
                    "physics steps per control period (MuJoCo timestep = control period / steps; integer)")

#: The MuJoCo twin's knobs, in ``knobs()`` order.
MUJOCO_KNOBS: KnobTable[KnobTarget] = KnobTable((
    KnobGroup(_joints, JOINT_KINDS),
    KnobGroup(_contact_geoms, GEOM_KINDS),
    KnobGroup(_model, (IMPRATIO,)),
    KnobGroup(_bodies, BODY_KINDS),
    KnobGroup(_motors, MOTOR_KINDS),
    KnobGroup(_model, (DELAY, SUBSTEPS)),
    KnobGroup(_sensors, SENSOR_KINDS),
))
