"""Build an ODE scene from a parsed Webots world and step it as Webots R2023b does.

Specification: ``docs/reference/webots-on-ode.md`` (cited as §N below). Public entry point:
:class:`Simulation` (``Simulation(world)``, ``step()``, ``reset()``, ``reset_physics()``).

What follows Webots
    One ``dWorldStep`` per ``basicTimeStep``, ENU gravity, world ERP/CFM, damping conversion, max angular
    speed, time-based auto-disable (§1); contacts from the collision pass after step *k* consumed by
    step *k+1* with per-body double-buffered joint groups, the near-callback filters of §2.3, first
    matching ContactProperties, Approx1 pyramid friction with soft ERP/CFM and bounce (§2); mass modes,
    CoM-centred bodies, Solid merging and the static basis (§3); Hinge/Slider/Hinge2/Ball joints with
    Webots' ODE sign conventions, stops, implicit springs and static friction (§4); motor control with
    the exact PID/velocity/acceleration/torque logic and the initial hold (§5).

What differs (and why)
    * Slider springs: upstream ODE's LMotor has no stops (the position-stop LMotor is a Webots fork
      feature), so the spring row is emulated with the LMotor *motor* row: velocity target
      ``∓ERP·x/h`` with CFM ``1/(hK+B)`` and unbounded force, which is algebraically the same implicit
      LCP row as a stop row with that ERP/CFM (Appendix A).
    * Asymmetric friction (2–4 ``coulombFriction`` values) and ``frictionRotation`` use the first value
      only (symmetric pyramid); fluids are not simulated. Ray devices, touch sensors and radios live in their
      own modules (``ranging``, ``touch``, ``radio``) and use the ``extensions``/``step_hooks`` slots.
    * Hinge suspension (fork-only ODE API, Appendix A.2) and BallJoint motors/springs are not modelled;
      upstream ODE never limits the second Hinge2 axis, so its stops are ignored. Brake devices are not
      modelled; coupled motors ("name::suffix") are relayed by the controller API.
    * ODE 0.16's ``dJointAddHingeTorque`` negates the torque of reversed hinges (static parent); the
      torque is pre-negated so a positive ``setTorque`` increases the position for every hinge, as
      Webots documents (whether its 0.13.1 fork negates too is UNVERIFIED).
    * All geoms go directly into one top-level simple space (no per-body child spaces); geoms of one body
      never collide anyway, so only the order in which ODE reports pairs may differ.
    * ODE's category/collide bits pre-filter pairs that §2.3 rules 4/5 discard anyway (static–static,
      same robot without selfCollision) so the Python near-callback only sees useful pairs.
    * The Debian ``libode8`` keeps ODE's assertions: a non-finite state inside ``dWorldStep`` aborts the
      process. :class:`SimulationUnstable` is therefore raised on non-finite *or diverging* state
      (|x| > 1e9 m, |v| > 1e8 m/s) right after the step, before the collision pass would see it.

UNVERIFIED choices (spec gaps, most plausible behaviour picked)
    * "Kinematic solid touches a disabled body" (§2.3 rule 9) covers every body-less geom.
    * Solids named "left wheel"/"right wheel" that are not merged are tied to their parent body with a
      fixed joint; a physics Solid under a physics-less Solid that itself has a physics ancestor is tied
      to that nearest body with a fixed joint (Webots calls this configuration undefined).
    * ``maxContactJoints`` keeps the deepest points in their original collider order.
    * Hinge2 second axis: position2 = +angle2 + offset2 (spec) with motor ``dParamVel2 = -u`` and torque
      ``(0, -τ)``, the signs for which a positive command turns the endPoint about +axis2 (checked);
      ``jointParameters2 NULL`` uses axis ``0 0 1``.
    * Joint motor commands and supervisor teleports wake the affected bodies (``dBodyEnable``).
    * Kinematic joints (endPoint without Physics) move at the commanded velocity toward the target
      without the acceleration limit.
    * Damping of merged bodies is volume-weighted; solids without boundingObject get weight 0 unless all
      weights are 0 (then a plain average).
    * Sensors sample at the end of a controller step once their sampling period has elapsed; the
      Accelerometer differentiates the CoM velocity of its body over the last basic step; Gyro and
      ``Node.getVelocity`` of a body-less Solid use its nearest body's motion (kinematic joint motion
      is not added).
"""

from __future__ import annotations

import ctypes
import math
import random
import threading
import time as _time
import warnings
from collections.abc import Callable, Iterable, Sequence
from ctypes import byref
from dataclasses import dataclass, field
from typing import Any

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.motor_law import motor_velocity
from dualtwin.webots.nodes import Node, World

__all__ = [
    "Simulation",
    "SimulationUnstable",
    "WorldBuildError",
    "SolidRec",
    "BodyRec",
    "JointRec",
    "MotorRec",
    "PositionSensorRec",
    "DeviceRec",
    "RobotRec",
    "AttachmentRec",
]

MAX_ANGULAR_SPEED = 10000.0  # §1.4: dBodySetMaxAngularSpeed for every body
DIVERGED_POSITION = 1e9  # m; beyond this the next ODE step risks a non-finite (aborting) state
DIVERGED_VELOCITY = 1e8  # m/s
DEFAULT_CONTACT_CAPACITY = 100  # §2.3 rule 8: dCollide capacity, grown ×10 when saturated
SIZEOF_CONTACT = ctypes.sizeof(ode.dContact)
GEOM_OFFSET = ode.dContact.geom.offset

SOLID_TYPES = frozenset(
    {
        "Solid", "Robot", "Accelerometer", "Altimeter", "Camera", "Charger", "Compass", "Connector",
        "Display", "DistanceSensor", "Emitter", "GPS", "Gyro", "InertialUnit", "LED", "Lidar",
        "LightSensor", "Pen", "Radar", "RangeFinder", "Receiver", "Speaker", "TouchSensor", "Track",
        "VacuumGripper",
    }
)  # fmt: skip
JOINT_TYPES = frozenset({"HingeJoint", "SliderJoint", "Hinge2Joint", "BallJoint"})
MOTOR_TYPES = frozenset({"RotationalMotor", "LinearMotor"})
# nodes that act on their parent Solid's body and are simulated by a device module (``propeller``)
ATTACHMENT_TYPES = frozenset({"Propeller"})




class WorldBuildError(DualtwinError):
    """The world cannot be turned into an ODE scene."""


def _is_solid(node: Node) -> bool:
    if node.type_name in SOLID_TYPES:
        return True
    f = node.fields
    return "boundingObject" in f and "physics" in f and "translation" in f and "children" in f


def _is_robot(node: Node) -> bool:
    return node.type_name == "Robot" or ("controller" in node.fields and "selfCollision" in node.fields)


def _f(node: Node | None, name: str, default: Any) -> Any:
    if node is None:
        return default
    value = node.fields.get(name, default)
    return default if value is None else value


def _damping_per_step(per_second: float, dt: float) -> float:
    """§1.4: fraction of speed lost per second → ODE per-step damping scale."""
    if per_second <= 0.0:
        return 0.0
    return 1.0 - (1.0 - min(per_second, 1.0)) ** dt


def _mass_zero() -> ode.dMass:
    m = ode.dMass()
    ode.load().dMassSetZero(byref(m))
    return m


def _rot_matrix(R: Sequence[float]) -> Any:
    mat = ode.dMatrix3()
    for i in range(3):
        for j in range(3):
            mat[4 * i + j] = R[3 * i + j]
    return mat


# --------------------------------------------------------------------------------------------------
# records


class _ShortRepr:
    """Records reference each other in cycles; keep reprs to the node's name."""

    def __repr__(self) -> str:
        owner = getattr(self, "root", None) or getattr(self, "solid", None)
        node = getattr(self, "node", None) or getattr(owner, "node", None)
        name = node.fields.get("name", node.def_name or node.type_name) if isinstance(node, Node) else "?"
        return f"<{type(self).__name__} {name!r}>"


@dataclass(eq=False, repr=False)
class RobotRec(_ShortRepr):
    """A Robot node and the devices found in its subtree."""

    node: Node
    solid: SolidRec
    name: str
    controller: str
    supervisor: bool
    self_collision: bool
    devices: dict[str, Any] = field(default_factory=dict)
    category: int = 0


@dataclass(eq=False, repr=False)
class GeomRec(_ShortRepr):
    """One ODE geom created from a boundingObject primitive."""

    ptr: int
    solid: SolidRec
    kind: str
    local: Pose  # geom frame in the owning Solid's frame
    body: BodyRec | None
    is_plane: bool = False
    keepalive: tuple[Any, ...] = ()


@dataclass(eq=False, repr=False)
class SolidRec(_ShortRepr):
    """A Solid-derived node and where it sits in the ODE scene."""

    node: Node
    parent: SolidRec | None
    robot: RobotRec | None
    rel: Pose  # Solid frame in the parent Solid frame (world frame for top solids); current
    pre: Pose  # frame holding the node's translation/rotation, in the parent Solid frame
    load_rel: Pose
    joint: JointRec | None = None  # joint whose endPoint this Solid is
    body: BodyRec | None = None
    in_body: Pose = field(default_factory=Pose)  # Solid frame in the body root Solid frame
    geoms: list[GeomRec] = field(default_factory=list)
    children: list[SolidRec] = field(default_factory=list)
    child_joints: list[JointRec] = field(default_factory=list)
    volume: float = 0.0
    index: int = 0

    @property
    def name(self) -> str:
        return str(_f(self.node, "name", ""))

    @property
    def material(self) -> str:
        return str(_f(self.node, "contactMaterial", "default"))

    @property
    def is_dynamic(self) -> bool:
        return self.body is not None


@dataclass(eq=False, repr=False)
class BodyRec(_ShortRepr):
    """One ODE body: a root Solid plus the Solids merged into it (§3.3)."""

    index: int
    root: SolidRec
    members: list[SolidRec]
    ptr: int = 0
    mass: float = 0.0
    com: m3.Vec3 = m3.ZERO  # CoM in the root Solid frame
    inertia: tuple[float, ...] = ()  # about the CoM, root Solid axes, row-major 3×3
    load_pos: m3.Vec3 = m3.ZERO
    load_R: m3.Mat3 = m3.IDENTITY
    load_lvel: m3.Vec3 = m3.ZERO
    load_avel: m3.Vec3 = m3.ZERO
    attached_to_world: bool = False
    pos: Any = None  # live ctypes views into ODE memory
    R: Any = None
    lvel: Any = None
    avel: Any = None
    groups: list[int] = field(default_factory=list)  # [buffer A, buffer B] contact joint groups
    joints: list[JointRec] = field(default_factory=list)
    fixed_joint: int = 0
    fixed_to: BodyRec | None = None

    def pose(self) -> Pose:
        """Pose of the root Solid frame in the world (body origin is at the CoM, §3.2)."""
        R = tuple(self.R[i] for i in (0, 1, 2, 4, 5, 6, 8, 9, 10))
        p = (self.pos[0], self.pos[1], self.pos[2])
        return Pose(R, m3.sub(p, m3.mat_vec(R, self.com)))


@dataclass(eq=False, repr=False)
class MotorRec(_ShortRepr):
    """RotationalMotor/LinearMotor state (§5)."""

    node: Node
    joint: JointRec
    axis_index: int
    rotational: bool
    name: str
    max_velocity: float
    max_force: float
    acceleration: float
    kp: float
    ki: float
    kd: float
    min_position: float
    max_position: float
    multiplier: float
    # controller-visible state
    target_position: float = 0.0
    target_velocity: float = 0.0
    available: float = 0.0
    torque_mode: bool = False
    raw_torque: float = 0.0
    integral: float = 0.0
    prev_error: float = 0.0
    current_velocity: float = 0.0  # Webots sign
    torque_params_set: bool = False
    sensor: PositionSensorRec | None = None
    brake: Node | None = None

    def reset_state(self) -> None:
        """§5.1 initial state: hold the current position at max velocity with full torque."""
        self.target_position = self.joint.positions[self.axis_index]
        self.target_velocity = self.max_velocity
        self.available = self.max_force
        self.torque_mode = False
        self.torque_params_set = False
        self.raw_torque = 0.0
        self.integral = 0.0
        self.prev_error = 0.0
        self.current_velocity = 0.0

    @property
    def position(self) -> float:
        return self.joint.positions[self.axis_index]

    def command_velocity(self, dt: float) -> float:
        """§5.3 step 2: the velocity (Webots sign) the ODE motor row will be asked for."""
        u, self.integral, self.prev_error = motor_velocity(
            target_position=self.target_position, target_velocity=self.target_velocity, available=self.available,
            position=self.joint.positions[self.axis_index], integral=self.integral, previous_error=self.prev_error,
            current_velocity=self.current_velocity, kp=self.kp, ki=self.ki, kd=self.kd,
            acceleration=self.acceleration, dt=dt)
        self.current_velocity = u
        return u


@dataclass(eq=False, repr=False)
class PositionSensorRec(_ShortRepr):
    """PositionSensor attached to a joint axis (§5.4)."""

    node: Node
    joint: JointRec
    axis_index: int
    name: str
    noise: float
    resolution: float


@dataclass(eq=False, repr=False)
class DeviceRec(_ShortRepr):
    """A Solid-derived device (GPS, InertialUnit, Gyro, Accelerometer, ...)."""

    node: Node
    solid: SolidRec
    type_name: str
    name: str


@dataclass(eq=False, repr=False)
class AttachmentRec(_ShortRepr):
    """A node of ``ATTACHMENT_TYPES`` found under a Solid: where it sits, for the module that simulates it."""

    node: Node
    frame_rel: Pose  # the closest upper Pose frame, in the parent Solid's frame
    solid: SolidRec | None
    robot: RobotRec | None


@dataclass(eq=False, repr=False)
class JointRec(_ShortRepr):
    """A Webots joint and its ODE counterpart (§4)."""

    node: Node
    kind: str  # "hinge" | "slider" | "hinge2" | "ball"
    parent: SolidRec | None
    child: SolidRec | None
    frame_rel: Pose  # joint frame (closest upper Pose) in the parent Solid frame
    params: list[Node | None]
    axis_local: list[m3.Vec3]  # Webots axes in the joint frame
    anchor_local: m3.Vec3
    initial_positions: list[float]
    positions: list[float]
    offsets: list[float]
    ptr: int = 0
    parent_body: BodyRec | None = None
    child_body: BodyRec | None = None
    reverse: bool = False
    spring: int = 0  # AMotor/LMotor implementing spring and damper
    spring_erp: float = 0.0
    spring_cfm: float = 0.0
    motors: list[MotorRec | None] = field(default_factory=lambda: [None])
    sensors: list[PositionSensorRec | None] = field(default_factory=lambda: [None])
    static_friction: list[float] = field(default_factory=lambda: [0.0])
    raw_angles: list[float] = field(default_factory=lambda: [0.0])

    @property
    def kinematic(self) -> bool:
        return self.ptr == 0


# --------------------------------------------------------------------------------------------------


@dataclass
class _Surface:
    """A ContactProperties match turned into a pre-filled ``dContact`` array (§2.2)."""

    contacts: Any
    capacity: int
    max_joints: int
    template: ode.dSurfaceParameters


@dataclass
class _PendingOp:
    kind: str
    target: Any
    value: Any


class Simulation:
    """A Webots world simulated on ODE with Webots' stepping semantics.

    Args:
        world: a parsed world (every base node with all its fields filled).
        seed: overrides ``WorldInfo.randomSeed`` for the sensor-noise RNG.

    Example:
        >>> sim = Simulation(load_world("worlds/cartpole.wbt"))  # doctest: +SKIP
        >>> sim.step(); sim.time                                  # doctest: +SKIP
        0.032
    """

    def __init__(self, world: World, *, seed: int | None = None) -> None:
        self.world = world
        self._lib = lib = ode.load()
        ode.ensure_thread()
        self._thread = threading.get_ident()
        # cached ctypes function objects for the per-step paths
        self._step_fn = lib.dWorldStep
        self._is_enabled = lib.dBodyIsEnabled
        self._empty_group = lib.dJointGroupEmpty
        self._hinge_angle = lib.dJointGetHingeAngle
        self._hinge_rate = lib.dJointGetHingeAngleRate
        self._slider_pos = lib.dJointGetSliderPosition
        self._warnings: list[str] = []
        self.robots: list[RobotRec] = []
        self.solids: list[SolidRec] = []
        self.bodies: list[BodyRec] = []
        self.joints: list[JointRec] = []
        self.geoms: dict[int, GeomRec] = {}
        self.motors: list[MotorRec] = []
        self.devices: list[Any] = []
        self.attachments: list[AttachmentRec] = []
        self._loops: list[tuple[JointRec, str]] = []  # joints whose endPoint is a SolidReference
        self._solid_by_node: dict[int, SolidRec] = {}
        self._joint_by_node: dict[int, JointRec] = {}
        self._pending: list[_PendingOp] = []
        self._edited: dict[tuple[int, str], Node] = {}
        self._unstable = False
        self._closed = False
        self.step_count = 0
        self._seed_override = seed
        self._accel_prev: dict[int, tuple[float, float, float]] = {}
        self._accel_cur: dict[int, tuple[float, float, float]] = {}
        # device modules (rays, touch, radio, ...) keep their per-simulation state here, under their own key,
        # and register callables run after each step's collision pass (post-step state, contacts of the step)
        self.extensions: dict[str, Any] = {}
        self.step_hooks: list[Callable[[], None]] = []
        self.pre_step_hooks: list[Callable[[float], None]] = []
        self.reset_hooks: list[Callable[[], None]] = []  # device state that simulationReset restores
        self._read_world_info()
        self._snapshot = self._snapshot_fields()
        self._build()

    # ------------------------------------------------------------------ world info

    def _read_world_info(self) -> None:
        info = self.world.world_info()
        step_ms = float(_f(info, "basicTimeStep", 32.0))
        if step_ms <= 0:
            step_ms = 32.0  # §1.1: reset to 32 if ≤ 0
        self.basic_time_step = step_ms
        self.dt = step_ms * 0.001
        g = float(_f(info, "gravity", 9.81))
        cs = str(_f(info, "coordinateSystem", "ENU"))
        self.gravity: m3.Vec3 = (0.0, 0.0, -g) if cs == "ENU" else (0.0, -g, 0.0)
        erp = float(_f(info, "ERP", 0.2))
        cfm = float(_f(info, "CFM", 0.00001))
        self.erp = erp if 0.0 <= erp <= 1.0 else 0.2
        self.cfm = cfm if cfm > 0.0 else 0.00001
        self.disable_time = float(_f(info, "physicsDisableTime", 1.0))
        self.disable_lin = float(_f(info, "physicsDisableLinearThreshold", 0.01))
        self.disable_ang = float(_f(info, "physicsDisableAngularThreshold", 0.01))
        damping = _f(info, "defaultDamping", None)
        self.world_damping = (
            (
                _damping_per_step(float(_f(damping, "linear", 0.2)), self.dt),
                _damping_per_step(float(_f(damping, "angular", 0.2)), self.dt),
            )
            if isinstance(damping, Node)
            else (0.0, 0.0)
        )
        self.random_seed = int(_f(info, "randomSeed", 0))
        self.contact_properties: list[Node] = [
            cp for cp in (_f(info, "contactProperties", []) or []) if isinstance(cp, Node)
        ]

    def _rng_seed(self) -> int:
        if self._seed_override is not None:
            return self._seed_override
        return self.random_seed if self.random_seed >= 0 else int(_time.time())

    # ------------------------------------------------------------------ snapshot / restore of fields

    def _snapshot_fields(self) -> list[tuple[Node, dict[str, Any]]]:
        snap = []
        for top in self.world.nodes:
            for node in top.walk():
                snap.append(
                    (node, {k: (list(v) if isinstance(v, list) else v) for k, v in node.fields.items()})
                )
        return snap

    def _restore_fields(self) -> None:
        for node, values in self._snapshot:
            node.fields.clear()
            node.fields.update({k: (list(v) if isinstance(v, list) else v) for k, v in values.items()})

    # ------------------------------------------------------------------ build

    def warn(self, message: str) -> None:
        self._warnings.append(message)
        warnings.warn(message, stacklevel=3)

    @property
    def build_warnings(self) -> list[str]:
        return list(self._warnings)

    def _build(self) -> None:
        lib = self._lib
        self._world = lib.dWorldCreate()
        lib.dWorldSetGravity(self._world, *self.gravity)
        lib.dWorldSetERP(self._world, self.erp)
        lib.dWorldSetCFM(self._world, self.cfm)
        # §1.2: damping always active; set before bodies exist since bodies copy world settings.
        lib.dWorldSetLinearDampingThreshold(self._world, 0.0)
        lib.dWorldSetAngularDampingThreshold(self._world, 0.0)
        lib.dWorldSetDamping(self._world, *self.world_damping)
        lib.dWorldSetAutoDisableTime(self._world, max(self.disable_time, 0.0))
        lib.dWorldSetAutoDisableSteps(self._world, 0)
        lib.dRandSetSeed(max(self.random_seed, 0))
        self._space = lib.dSimpleSpaceCreate(None)
        lib.dSpaceSetCleanup(self._space, 0)

        for top in self.world.nodes:
            self._walk_top(top)
        self._assign_bodies()
        for body in self.bodies:
            self._create_body(body)
        self._categories()
        for solid in self.solids:
            self._create_geoms(solid)
        for joint in self.joints:
            self._create_joint(joint)
        for joint, name in self._loops:
            self._close_loop(joint, name)
        self._create_fixed_joints()
        self._collect_devices()
        self._init_contacts()
        self._prepare_step_lists()
        self._rng = random.Random(self._rng_seed())
        for motor in self.motors:
            motor.reset_state()
        self._collide()  # §1.6: one collision pass at load, used by the first step

    # -- scene traversal

    def _walk_top(self, node: Node) -> None:
        self._walk_children([node], Pose(), None, None)

    def _walk_children(
        self,
        children: Iterable[Node | None],
        frame_rel: Pose,
        parent: SolidRec | None,
        robot: RobotRec | None,
    ) -> None:
        for child in children:
            if child is None:
                continue
            if _is_solid(child):
                self._add_solid(child, frame_rel, parent, robot, None)
            elif child.type_name in JOINT_TYPES:
                self._add_joint(child, frame_rel, parent, robot)
            elif child.type_name in ATTACHMENT_TYPES:
                self.attachments.append(AttachmentRec(child, frame_rel, parent, robot))
            elif "translation" in child.fields and "rotation" in child.fields and "children" in child.fields:
                local = Pose.from_fields(_f(child, "translation", None), _f(child, "rotation", None))
                scale = _f(child, "scale", (1.0, 1.0, 1.0))
                if tuple(scale) != (1.0, 1.0, 1.0):
                    self.warn(f"Transform scale {tuple(scale)} ignored outside boundingObjects")
                self._walk_children(child.children(), frame_rel * local, parent, robot)
            elif "children" in child.fields:
                self._walk_children(child.children(), frame_rel, parent, robot)
            elif child.type_name == "Slot" and isinstance(_f(child, "endPoint", None), Node):
                self._walk_children([child.fields["endPoint"]], frame_rel, parent, robot)

    def _add_solid(
        self,
        node: Node,
        frame_rel: Pose,
        parent: SolidRec | None,
        robot: RobotRec | None,
        joint: JointRec | None,
    ) -> SolidRec:
        local = Pose.from_fields(_f(node, "translation", None), _f(node, "rotation", None))
        rel = frame_rel * local
        solid = SolidRec(
            node=node, parent=parent, robot=robot, rel=rel, pre=frame_rel, load_rel=rel, joint=joint
        )
        solid.index = len(self.solids)
        self.solids.append(solid)
        self._solid_by_node[id(node)] = solid
        if parent is not None:
            parent.children.append(solid)
        if _is_robot(node):
            robot = RobotRec(
                node=node,
                solid=solid,
                name=str(_f(node, "name", "robot")),
                controller=str(_f(node, "controller", "")),
                supervisor=bool(_f(node, "supervisor", False)),
                self_collision=bool(_f(node, "selfCollision", False)),
            )
            solid.robot = robot
            self.robots.append(robot)
        self._walk_children(node.children(), Pose(), solid, robot)
        return solid

    def _add_joint(
        self, node: Node, frame_rel: Pose, parent: SolidRec | None, robot: RobotRec | None
    ) -> None:
        kind = {"HingeJoint": "hinge", "SliderJoint": "slider", "Hinge2Joint": "hinge2", "BallJoint": "ball"}[
            node.type_name
        ]
        p1 = _f(node, "jointParameters", None)
        params: list[Node | None] = [p1 if isinstance(p1, Node) else None]
        if kind == "hinge2":
            p2 = _f(node, "jointParameters2", None)
            params.append(p2 if isinstance(p2, Node) else None)
        default_axis = (0.0, 0.0, 1.0) if kind == "slider" else (1.0, 0.0, 0.0)
        axes = [tuple(float(v) for v in _f(params[0], "axis", default_axis))]
        if kind == "hinge2":
            axes.append(tuple(float(v) for v in _f(params[1], "axis", (0.0, 0.0, 1.0))))
        if kind == "slider":
            axes[0] = m3.normalized(axes[0])  # §4.3: Webots normalises the slider axis
        anchor = tuple(float(v) for v in _f(params[0], "anchor", (0.0, 0.0, 0.0)))
        positions = []
        for i, p in enumerate(params):
            hidden = "position" if i == 0 else "position2"
            positions.append(float(_f(p, "position", _f(node, hidden, 0.0))))
        n = len(params)
        joint = JointRec(
            node=node,
            kind=kind,
            parent=parent,
            child=None,
            frame_rel=frame_rel,
            params=params,
            axis_local=axes,  # type: ignore[arg-type]
            anchor_local=anchor,  # type: ignore[arg-type]
            initial_positions=list(positions),
            positions=list(positions),
            offsets=list(positions),
            motors=[None] * n,
            sensors=[None] * n,
            static_friction=[float(_f(p, "staticFriction", 0.0)) for p in params],
            raw_angles=[0.0] * n,
        )
        self.joints.append(joint)
        self._joint_by_node[id(node)] = joint
        for p in params:
            if p is not None:
                self._joint_by_node[id(p)] = joint
        if parent is not None:
            parent.child_joints.append(joint)
        device_fields = ["device", "device2", "device3"][:n]
        for axis_index, fname in enumerate(device_fields):
            for dev in _f(node, fname, []) or []:
                if not isinstance(dev, Node):
                    continue
                if dev.type_name in MOTOR_TYPES:
                    joint.motors[axis_index] = self._make_motor(dev, joint, axis_index)
                elif dev.type_name == "PositionSensor":
                    joint.sensors[axis_index] = PositionSensorRec(
                        node=dev,
                        joint=joint,
                        axis_index=axis_index,
                        name=str(_f(dev, "name", "position sensor")),
                        noise=float(_f(dev, "noise", 0.0)),
                        resolution=float(_f(dev, "resolution", -1.0)),
                    )
        for axis_index in range(n):
            motor, sensor = joint.motors[axis_index], joint.sensors[axis_index]
            if motor is not None and sensor is not None:
                motor.sensor = sensor
        end = _f(node, "endPoint", None)
        if isinstance(end, Node) and _is_solid(end):
            joint.child = self._add_solid(end, frame_rel, parent, robot, joint)
        elif isinstance(end, Node) and end.type_name == "SolidReference":
            self._loops.append((joint, str(_f(end, "solidName", ""))))  # closed once every body exists
        elif isinstance(end, Node):
            self.warn(f"{node.type_name} endPoint {end.type_name} is not supported; joint ignored")
        if robot is not None:
            for motor in joint.motors:
                if motor is not None:
                    robot.devices.setdefault(motor.name, motor)
            for sensor in joint.sensors:
                if sensor is not None:
                    robot.devices.setdefault(sensor.name, sensor)

    def _make_motor(self, dev: Node, joint: JointRec, axis_index: int) -> MotorRec:
        rotational = dev.type_name == "RotationalMotor"
        pid = tuple(_f(dev, "controlPID", (10.0, 0.0, 0.0)))
        motor = MotorRec(
            node=dev,
            joint=joint,
            axis_index=axis_index,
            rotational=rotational,
            name=str(_f(dev, "name", "rotational motor" if rotational else "linear motor")),
            max_velocity=float(_f(dev, "maxVelocity", 10.0)),
            max_force=float(_f(dev, "maxTorque" if rotational else "maxForce", 10.0)),
            acceleration=float(_f(dev, "acceleration", -1.0)),
            kp=float(pid[0]),
            ki=float(pid[1]),
            kd=float(pid[2]),
            min_position=float(_f(dev, "minPosition", 0.0)),
            max_position=float(_f(dev, "maxPosition", 0.0)),
            multiplier=float(_f(dev, "multiplier", 1.0)),
        )
        self.motors.append(motor)
        return motor

    # -- bodies (§3.3)

    def _assign_bodies(self) -> None:
        for solid in self.solids:
            if solid.node.fields.get("physics") is None:
                continue
            parent = solid.parent
            wheel = solid.name.lower() in ("left wheel", "right wheel")
            # a TouchSensor keeps its own body, fixed to its parent, so its joint can measure the force on it
            own = wheel or solid.node.type_name == "TouchSensor"
            if solid.joint is None and parent is not None and parent.body is not None and not own:
                body = parent.body
                body.members.append(solid)
                solid.body = body
                solid.in_body = parent.in_body * solid.rel
                continue
            body = BodyRec(index=len(self.bodies), root=solid, members=[solid])
            self.bodies.append(body)
            solid.body = body
            solid.in_body = Pose()
            if solid.joint is None and parent is not None:
                # static basis (§3.3) or unmerged wheel / undefined mid-chain: fixed to the nearest body
                body.fixed_to = self._nearest_body(parent)
                body.attached_to_world = body.fixed_to is None

    @staticmethod
    def _nearest_body(solid: SolidRec | None) -> BodyRec | None:
        while solid is not None:
            if solid.body is not None:
                return solid.body
            solid = solid.parent
        return None

    def world_pose_at_load(self, solid: SolidRec) -> Pose:
        pose = solid.load_rel
        s = solid.parent
        while s is not None:
            pose = s.load_rel * pose
            s = s.parent
        return pose

    def _solid_mass(self, solid: SolidRec) -> tuple[ode.dMass, float]:
        """§3.2: mass of one Solid in its own frame and its boundingObject volume."""
        lib = self._lib
        phys: Node = solid.node.fields["physics"]
        density = float(_f(phys, "density", 1000.0))
        mass = float(_f(phys, "mass", -1.0))
        com_list = list(_f(phys, "centerOfMass", []) or [])
        inertia = list(_f(phys, "inertiaMatrix", []) or [])
        bo = solid.node.fields.get("boundingObject")
        m = _mass_zero()
        ref = _mass_zero()
        volume = 0.0
        if isinstance(bo, Node):
            volume = self._bo_mass(bo, ref)
        com = tuple(float(v) for v in com_list[0]) if com_list else None
        if mass > 0 and density > 0 and density != 1000.0 and not inertia:
            self.warn(f"Solid '{solid.name}': both mass and density given, density ignored")
        if inertia:
            i1 = [float(v) for v in inertia[0]] if len(inertia) > 0 else []
            i2 = [float(v) for v in inertia[1]] if len(inertia) > 1 else [0.0, 0.0, 0.0]
            full = (i1 + [0.0] * 3)[:3]
            mat = (full[0], i2[0], i2[1], i2[0], full[1], i2[2], i2[1], i2[2], full[2])
            if mass > 0 and com is not None and len(inertia) == 2 and m3.is_positive_definite3(mat):
                lib.dMassSetParameters(
                    byref(m), mass, 0.0, 0.0, 0.0, full[0], full[1], full[2], i2[0], i2[1], i2[2]
                )
                lib.dMassTranslate(byref(m), *com)
                return m, volume
            self.warn(f"Solid '{solid.name}': invalid inertiaMatrix ignored")
        if mass <= 0 and density <= 0:
            self.warn(f"Solid '{solid.name}': Physics has neither mass nor density; using 1 kg")
            mass = 1.0
        if ref.mass > 0:
            ctypes.memmove(byref(m), byref(ref), ctypes.sizeof(ode.dMass))
            if mass > 0:
                lib.dMassAdjust(byref(m), mass)
            elif density != 1000.0:
                lib.dMassAdjust(byref(m), m.mass * density / 1000.0)
            if com is not None:
                lib.dMassTranslate(byref(m), com[0] - m.c[0], com[1] - m.c[1], com[2] - m.c[2])
            return m, volume
        # no boundingObject: identity inertia (§3.2, WbSolid.setDefaultMassSettings)
        total = mass if mass > 0 else density / 1000.0
        inert = 1.0 if mass > 0 else density / 1000.0
        lib.dMassSetParameters(byref(m), total, 0.0, 0.0, 0.0, inert, inert, inert, 0.0, 0.0, 0.0)
        if com is not None:
            lib.dMassTranslate(byref(m), *com)
        if not isinstance(bo, Node):
            self.warn(f"Solid '{solid.name}' has Physics but no boundingObject: default inertia")
        return m, volume

    def _bo_mass(self, node: Node, acc: ode.dMass) -> float:
        """Add the reference-density (1000) mass of a boundingObject subtree into ``acc``; return volume."""
        lib = self._lib
        t = node.type_name
        if t in ("Pose", "Transform"):
            sub = _mass_zero()
            vol = 0.0
            for c in node.children():
                vol += self._bo_mass(c, sub)
            if sub.mass > 0:
                R = m3.rot_axis_angle(_f(node, "rotation", (0, 0, 1, 0)))
                if R != m3.IDENTITY:
                    lib.dMassRotate(byref(sub), _rot_matrix(R))
                tr = _f(node, "translation", (0.0, 0.0, 0.0))
                lib.dMassTranslate(byref(sub), *tr)
                lib.dMassAdd(byref(acc), byref(sub))
            return vol
        if t == "Group":
            return sum(self._bo_mass(c, acc) for c in node.children())
        if t == "Shape":
            geom = _f(node, "geometry", None)
            return self._bo_mass(geom, acc) if isinstance(geom, Node) else 0.0
        m = _mass_zero()
        ok = True
        if t == "Box":
            sx, sy, sz = (float(v) for v in _f(node, "size", (2.0, 2.0, 2.0)))
            ok = sx > 0 and sy > 0 and sz > 0
            if ok:
                lib.dMassSetBox(byref(m), 1000.0, sx, sy, sz)
        elif t == "Sphere":
            r = float(_f(node, "radius", 1.0))
            ok = r > 0
            if ok:
                lib.dMassSetSphere(byref(m), 1000.0, r)
        elif t in ("Cylinder", "Capsule"):
            r, h = float(_f(node, "radius", 1.0)), float(_f(node, "height", 2.0))
            ok = r > 0 and h > 0
            if ok:
                fn = lib.dMassSetCylinder if t == "Cylinder" else lib.dMassSetCapsule
                fn(byref(m), 1000.0, 3, r, h)
        elif t == "IndexedFaceSet":
            built = self._trimesh_data(node)
            ok = built is not None
            if built is not None:
                tmp = lib.dCreateTriMesh(None, built[0], None, None, None)
                lib.dMassSetTrimesh(byref(m), 1000.0, tmp)
                lib.dGeomDestroy(tmp)
                lib.dGeomTriMeshDataDestroy(built[0])
                ok = m.mass > 0 and math.isfinite(m.mass)
        elif t in ("Plane", "ElevationGrid"):
            return 0.0  # §3.2: contributes nothing
        elif t == "Mesh":
            self.warn("Mesh boundingObject is not supported (no collision); mass 1 kg")
            ok = False
        else:
            return 0.0
        if not ok:
            # §3.2: invalid primitives contribute 1 kg with identity inertia
            lib.dMassSetParameters(byref(m), 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
            lib.dMassAdd(byref(acc), byref(m))
            return 0.0
        lib.dMassAdd(byref(acc), byref(m))
        return m.mass / 1000.0

    def _create_body(self, body: BodyRec) -> None:
        lib = self._lib
        total = _mass_zero()
        weights: list[tuple[float, Node | None]] = []
        for member in body.members:
            m, volume = self._solid_mass(member)
            member.volume = volume
            if member is not body.root:
                lib.dMassRotate(byref(m), _rot_matrix(member.in_body.R))
                lib.dMassTranslate(byref(m), *member.in_body.t)
            lib.dMassAdd(byref(total), byref(m))
            weights.append((volume, _f(member.node.fields["physics"], "damping", None)))
        com = (total.c[0], total.c[1], total.c[2])
        lib.dMassTranslate(byref(total), -com[0], -com[1], -com[2])
        total.c[0] = total.c[1] = total.c[2] = 0.0
        inertia = (
            total.I[0], total.I[1], total.I[2], total.I[4], total.I[5], total.I[6],
            total.I[8], total.I[9], total.I[10],
        )  # fmt: skip
        if not (total.mass > 0 and math.isfinite(total.mass) and m3.is_positive_definite3(inertia)):
            # ODE asserts on an invalid mass (Debian build): fall back to a unit mass
            self.warn(f"Solid '{body.root.name}': invalid mass/inertia, using 1 kg and identity inertia")
            lib.dMassSetParameters(byref(total), 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
            inertia = m3.IDENTITY
        body.mass = total.mass
        body.com = com
        body.inertia = inertia
        world = self.world_pose_at_load(body.root)
        body.load_R = world.R
        body.load_pos = world.apply(com)
        node = body.root.node
        body.load_lvel = tuple(float(v) for v in _f(node, "linearVelocity", (0.0, 0.0, 0.0)))  # type: ignore[assignment]
        body.load_avel = tuple(float(v) for v in _f(node, "angularVelocity", (0.0, 0.0, 0.0)))  # type: ignore[assignment]
        b = lib.dBodyCreate(self._world)
        body.ptr = b
        lib.dBodySetMass(b, byref(total))
        self._place_body_at_load(body)
        body.pos = ode.vec3(lib.dBodyGetPosition(b))
        body.R = ode.mat3(lib.dBodyGetRotation(b))
        body.lvel = ode.vec3(lib.dBodyGetLinearVel(b))
        body.avel = ode.vec3(lib.dBodyGetAngularVel(b))
        # §1.4 damping: volume-weighted average of the merged solids' Damping nodes
        wsum = sum(w for w, _ in weights)
        lin = ang = 0.0
        for w, damping in weights:
            weight = (w / wsum) if wsum > 0 else 1.0 / len(weights)
            if isinstance(damping, Node):
                lin += weight * float(_f(damping, "linear", 0.2))
                ang += weight * float(_f(damping, "angular", 0.2))
        if lin > 0 or ang > 0:
            lib.dBodySetDamping(b, _damping_per_step(lin, self.dt), _damping_per_step(ang, self.dt))
        else:
            lib.dBodySetDampingDefaults(b)
        lib.dBodySetMaxAngularSpeed(b, MAX_ANGULAR_SPEED)
        self._set_auto_disable(body)
        body.groups = [lib.dJointGroupCreate(0), lib.dJointGroupCreate(0)]

    def _set_auto_disable(self, body: BodyRec) -> None:
        lib = self._lib
        b = body.ptr
        if self.disable_time > 0:
            lib.dBodySetAutoDisableFlag(b, 1)
            lib.dBodySetAutoDisableLinearThreshold(b, self.disable_lin)
            lib.dBodySetAutoDisableAngularThreshold(b, self.disable_ang)
            lib.dBodySetAutoDisableTime(b, self.disable_time)
            lib.dBodySetAutoDisableSteps(b, 0)
        else:
            lib.dBodySetAutoDisableFlag(b, 0)

    def _place_body_at_load(self, body: BodyRec) -> None:
        """Replays the exact ODE calls used at load so a reset reproduces the state bit for bit."""
        lib = self._lib
        b = body.ptr
        lib.dBodySetPosition(b, *body.load_pos)
        lib.dBodySetRotation(b, _rot_matrix(body.load_R))
        lib.dBodySetLinearVel(b, *body.load_lvel)
        lib.dBodySetAngularVel(b, *body.load_avel)
        lib.dBodySetForce(b, 0.0, 0.0, 0.0)
        lib.dBodySetTorque(b, 0.0, 0.0, 0.0)
        lib.dBodyEnable(b)

    # -- collision categories (pre-filter for §2.3 rules 4 and 5)

    def _categories(self) -> None:
        # bit 0: body-less geoms outside robots; per robot without selfCollision: one bit for its bodies
        # and one for its body-less geoms; bit 63: everything else (filtered in Python if needed).
        next_bit = 1
        for robot in self.robots:
            if not robot.self_collision and next_bit + 1 < 63:
                robot.category = next_bit
                next_bit += 2
        self._all_bits = (1 << 64) - 1

    def _geom_bits(self, solid: SolidRec, has_body: bool) -> tuple[int, int]:
        robot = solid.robot
        all_bits = self._all_bits
        if robot is None or robot.category == 0:
            if has_body:
                return 1 << 63, all_bits
            # static environment: no static/static and no kinematic-in-robot pairs
            mask = 1
            for r in self.robots:
                if r.category:
                    mask |= 1 << (r.category + 1)
            return 1, all_bits & ~mask
        dyn, kin = 1 << robot.category, 1 << (robot.category + 1)
        if has_body:
            return dyn, all_bits & ~(dyn | kin)
        mask = 1 | dyn | kin
        for r in self.robots:
            if r.category:
                mask |= 1 << (r.category + 1)
        return kin, all_bits & ~mask

    # -- geoms (§3.4)

    def solid_world_pose(self, solid: SolidRec) -> Pose:
        """Current world pose of a Solid frame (from its body, or from the scene graph)."""
        if solid.body is not None:
            return solid.body.pose() * solid.in_body
        if solid.parent is None:
            return solid.rel
        return self.solid_world_pose(solid.parent) * self._kinematic_rel(solid)

    def _kinematic_rel(self, solid: SolidRec) -> Pose:
        joint = solid.joint
        if joint is None or not joint.kinematic:
            return solid.rel
        delta = joint.positions[0] - joint.initial_positions[0]
        if delta == 0.0:
            return solid.rel
        return self._joint_motion(joint, delta) * solid.rel

    @staticmethod
    def _joint_motion(joint: JointRec, delta: float) -> Pose:
        """Transform (in the parent Solid frame) moving an endPoint by ``delta`` along/about the axis."""
        axis = joint.frame_rel.rotate(joint.axis_local[0])
        if joint.kind == "slider":
            return Pose(m3.IDENTITY, m3.scale(m3.normalized(axis), delta))
        R = m3.rot_axis_angle((*axis, delta))
        anchor = joint.frame_rel.apply(joint.anchor_local)
        return Pose(R, m3.sub(anchor, m3.mat_vec(R, anchor)))

    def _create_geoms(self, solid: SolidRec) -> None:
        bo = solid.node.fields.get("boundingObject")
        if not isinstance(bo, Node):
            return
        world = self.world_pose_at_load(solid)
        self._bo_geoms(bo, Pose(), solid, world, (1.0, 1.0, 1.0))

    def _bo_geoms(
        self, node: Node, local: Pose, solid: SolidRec, solid_world: Pose, scale: Sequence[float]
    ) -> None:
        t = node.type_name
        if t in ("Pose", "Transform"):
            sub = local * Pose.from_fields(_f(node, "translation", None), _f(node, "rotation", None))
            sc = scale
            if t == "Transform":
                s = _f(node, "scale", (1.0, 1.0, 1.0))
                sc = (scale[0] * s[0], scale[1] * s[1], scale[2] * s[2])
            for c in node.children():
                self._bo_geoms(c, sub, solid, solid_world, sc)
            return
        if t == "Group":
            for c in node.children():
                self._bo_geoms(c, local, solid, solid_world, scale)
            return
        if t == "Shape":
            geom = _f(node, "geometry", None)
            if isinstance(geom, Node):
                self._bo_geoms(geom, local, solid, solid_world, scale)
            return
        self._make_geom(node, local, solid, solid_world, scale)

    def _make_geom(
        self, node: Node, local: Pose, solid: SolidRec, solid_world: Pose, scale: Sequence[float]
    ) -> None:
        lib = self._lib
        t = node.type_name
        keep: tuple[Any, ...] = ()
        ptr = 0
        uniform = max(scale)
        if t == "Box":
            sx, sy, sz = (float(v) * s for v, s in zip(_f(node, "size", (2.0, 2.0, 2.0)), scale, strict=True))
            if sx > 0 and sy > 0 and sz > 0:
                ptr = lib.dCreateBox(self._space, sx, sy, sz)
        elif t == "Sphere":
            r = float(_f(node, "radius", 1.0)) * uniform
            if r > 0:
                ptr = lib.dCreateSphere(self._space, r)
        elif t in ("Cylinder", "Capsule"):
            r, h = float(_f(node, "radius", 1.0)) * uniform, float(_f(node, "height", 2.0)) * uniform
            if r > 0 and h > 0:
                fn = lib.dCreateCylinder if t == "Cylinder" else lib.dCreateCapsule
                ptr = fn(self._space, r, h)
        elif t == "Plane":
            world = solid_world * local
            n = world.rotate((0.0, 0.0, 1.0))
            ptr = lib.dCreatePlane(self._space, n[0], n[1], n[2], m3.dot(n, world.t))
            if solid.body is not None:
                self.warn(f"Solid '{solid.name}': a Plane cannot be attached to a body; it stays static")
            gr = GeomRec(ptr=ptr, solid=solid, kind=t, local=local, body=None, is_plane=True)
            self._register_geom(gr)
            return
        elif t == "IndexedFaceSet":
            built = self._trimesh_data(node, scale)
            if built is not None:
                ptr = lib.dCreateTriMesh(self._space, built[0], None, None, None)
                keep = built
        elif t == "ElevationGrid":
            built_hf = self._heightfield(node)
            if built_hf is not None:
                ptr, keep, extra = built_hf
                local = local * extra
                if solid.body is not None:
                    self.warn(f"Solid '{solid.name}': ElevationGrid on a dynamic body stays static")
                gr = GeomRec(ptr=ptr, solid=solid, kind=t, local=local, body=None, keepalive=keep)
                self._register_geom(gr)
                self._place_static_geom(gr, solid_world)
                return
        elif t == "Mesh":
            self.warn("Mesh boundingObject is not supported; no collision geometry created")
            return
        else:
            self.warn(f"{t} is not a valid bounding geometry; ignored")
            return
        if not ptr:
            self.warn(f"Solid '{solid.name}': invalid {t} dimensions; no geom created")
            return
        gr = GeomRec(ptr=ptr, solid=solid, kind=t, local=local, body=solid.body, keepalive=keep)
        self._register_geom(gr)
        if solid.body is not None:
            # §3.2: geoms attached, then placed at their world pose (offset relative to the CoM)
            lib.dGeomSetBody(ptr, solid.body.ptr)
            world = solid_world * local
            lib.dGeomSetOffsetWorldPosition(ptr, *world.t)
            lib.dGeomSetOffsetWorldRotation(ptr, _rot_matrix(world.R))
        else:
            self._place_static_geom(gr, solid_world)

    def _register_geom(self, gr: GeomRec) -> None:
        cat, col = self._geom_bits(gr.solid, gr.body is not None)
        self._lib.dGeomSetCategoryBits(gr.ptr, cat)
        self._lib.dGeomSetCollideBits(gr.ptr, col)
        self.geoms[gr.ptr] = gr
        gr.solid.geoms.append(gr)

    def _place_static_geom(self, gr: GeomRec, solid_world: Pose) -> None:
        lib = self._lib
        world = solid_world * gr.local
        if gr.is_plane:
            n = world.rotate((0.0, 0.0, 1.0))
            lib.dGeomPlaneSetParams(gr.ptr, n[0], n[1], n[2], m3.dot(n, world.t))
            return
        lib.dGeomSetPosition(gr.ptr, *world.t)
        lib.dGeomSetRotation(gr.ptr, _rot_matrix(world.R))

    def _trimesh_data(self, node: Node, scale: Sequence[float] = (1.0, 1.0, 1.0)) -> tuple[Any, ...] | None:
        coord = _f(node, "coord", None)
        points = list(_f(coord, "point", []) or []) if isinstance(coord, Node) else []
        index = [int(i) for i in (_f(node, "coordIndex", []) or [])]
        tris: list[int] = []
        face: list[int] = []
        for i in [*index, -1]:
            if i < 0:
                for k in range(1, len(face) - 1):  # fan triangulation
                    tris.extend((face[0], face[k], face[k + 1]))
                face = []
            elif i < len(points):
                face.append(i)
        if not points or not tris:
            return None
        verts = (ctypes.c_double * (3 * len(points)))(
            *[float(p[k]) * scale[k] for p in points for k in range(3)]
        )
        idx = (ctypes.c_uint32 * len(tris))(*tris)
        lib = self._lib
        data = lib.dGeomTriMeshDataCreate()
        lib.dGeomTriMeshDataBuildDouble(data, verts, 3 * 8, len(points), idx, len(tris), 3 * 4)
        return (data, verts, idx)

    def _heightfield(self, node: Node) -> tuple[int, tuple[Any, ...], Pose] | None:
        nx, ny = int(_f(node, "xDimension", 0)), int(_f(node, "yDimension", 0))
        sx, sy = float(_f(node, "xSpacing", 1.0)), float(_f(node, "ySpacing", 1.0))
        heights = [float(h) for h in (_f(node, "height", []) or [])]
        if nx < 2 or ny < 2 or len(heights) < nx * ny:
            self.warn("ElevationGrid with fewer than 2×2 heights: ignored")
            return None
        lib = self._lib
        width, depth = (nx - 1) * sx, (ny - 1) * sy
        # ODE heightfield: centred, height along local +y, samples indexed [z * nx + x]. Webots grid:
        # x = i·xSpacing, y = j·ySpacing, height along +z. Local frame: Rx(+90°) maps ODE (x, y, z) to
        # Webots (x, -z, y)... so ODE z = -(y - depth/2): row k of ODE data is Webots row ny-1-k.
        data_vals = []
        for k in range(ny):
            j = ny - 1 - k
            data_vals.extend(heights[j * nx : (j + 1) * nx])
        arr = (ctypes.c_double * len(data_vals))(*data_vals)
        thickness = float(_f(node, "thickness", 1.0))
        data = lib.dGeomHeightfieldDataCreate()
        lib.dGeomHeightfieldDataBuildDouble(
            data, arr, 1, width, depth, nx, ny, 1.0, 0.0, max(thickness, 1e-6), 0
        )
        lib.dGeomHeightfieldDataSetBounds(data, min(data_vals), max(data_vals))
        ptr = lib.dCreateHeightfield(self._space, data, 1)
        extra = Pose(m3.rot_axis_angle((1.0, 0.0, 0.0, math.pi / 2)), (width / 2, depth / 2, 0.0))
        return ptr, (data, arr), extra

    # -- joints (§4)

    def _joint_world_frame(self, joint: JointRec) -> Pose:
        if joint.parent is None:
            return joint.frame_rel
        return self.world_pose_at_load(joint.parent) * joint.frame_rel

    def _create_joint(self, joint: JointRec) -> None:
        lib = self._lib
        child = joint.child
        joint.parent_body = self._nearest_body(joint.parent)
        joint.child_body = child.body if child is not None and child.joint is joint else None
        if joint.child_body is None or joint.child_body.root is not child:
            joint.child_body = None
            return  # §4.1: kinematic joint (endPoint without Physics)
        if joint.kind == "hinge2" and joint.parent_body is None:
            self.warn("Hinge2Joint needs a dynamic parent and endPoint; joint handled kinematically")
            joint.child_body = None
            return
        w = self._world
        create = {
            "hinge": lib.dJointCreateHinge,
            "slider": lib.dJointCreateSlider,
            "hinge2": lib.dJointCreateHinge2,
            "ball": lib.dJointCreateBall,
        }[joint.kind]
        joint.ptr = create(w, None)
        pb = joint.parent_body.ptr if joint.parent_body is not None else None
        lib.dJointAttach(joint.ptr, pb, joint.child_body.ptr)
        joint.reverse = pb is None
        joint.child_body.joints.append(joint)
        if joint.parent_body is not None:
            joint.parent_body.joints.append(joint)
        else:
            joint.child_body.attached_to_world = True
        self._anchor_joint(joint)
        for i in range(len(joint.params)):
            self._set_stops(joint, i)
            self._set_static_friction(joint, i)
        self._create_spring(joint)

    def _referenced_solid(self, joint: JointRec, name: str) -> SolidRec | None:
        """§10: depth-first search by name from the joint's topmost Solid ancestor, skipping its upper Solid."""
        top = joint.parent
        while top is not None and top.parent is not None:
            top = top.parent
        stack = [top] if top is not None else []
        while stack:
            solid = stack.pop()
            if solid is not joint.parent and solid.name == name:
                return solid
            stack.extend(reversed(solid.children))
        return None

    def _close_loop(self, joint: JointRec, name: str) -> None:
        """A joint whose endPoint is a SolidReference: an ODE joint from its upper body to the referenced Solid's
        body (or to the static environment), made after every body and ordinary joint, closing the loop (§10).
        The referenced Solid is not moved: ODE's zero is the configuration at load."""
        lib = self._lib
        target = None
        if name != "<static environment>":
            target = self._referenced_solid(joint, name)
            if target is None:
                self.warn(f"SolidReference '{name}' not found among the Solids of the joint's robot; joint ignored")
                return
        pb = self._nearest_body(joint.parent)
        cb = self._nearest_body(target) if target is not None else None
        if cb is None and target is not None:
            self.warn(f"SolidReference '{name}' has no Physics; closed loop ignored")
            return
        if pb is None and cb is None or pb is cb or joint.kind == "hinge2":
            self.warn(f"SolidReference '{name}': no closed loop can be built (static, same body or Hinge2)")
            return
        create = {
            "hinge": lib.dJointCreateHinge,
            "slider": lib.dJointCreateSlider,
            "ball": lib.dJointCreateBall,
        }[joint.kind]
        joint.ptr = create(self._world, None)
        joint.parent_body, joint.child_body = pb, cb
        if pb is None:
            lib.dJointAttach(joint.ptr, None, cb.ptr)  # type: ignore[union-attr]
            joint.reverse = True
        else:
            lib.dJointAttach(joint.ptr, pb.ptr, cb.ptr if cb is not None else None)
        for b in (pb, cb):
            if b is not None:
                b.joints.append(joint)
        if cb is None and pb is not None:
            pb.attached_to_world = True  # §2.3 rule 6, as for any body jointed to the static environment
        self._anchor_joint(joint)
        for i in range(len(joint.params)):
            self._set_stops(joint, i)
            self._set_static_friction(joint, i)
        self._create_spring(joint)

    def _anchor_joint(self, joint: JointRec) -> None:
        """Set anchor/axis from the current poses; ODE's zero is this configuration (§4.1)."""
        lib = self._lib
        frame = (
            self.solid_world_pose(joint.parent) * joint.frame_rel
            if joint.parent is not None
            else joint.frame_rel
        )
        axis = frame.rotate(joint.axis_local[0])
        anchor = frame.apply(joint.anchor_local)
        j = joint.ptr
        if joint.kind == "hinge":
            ax = m3.scale(axis, -1.0) if joint.reverse else axis
            lib.dJointSetHingeAnchor(j, *anchor)
            lib.dJointSetHingeAxis(j, *ax)
        elif joint.kind == "slider":
            lib.dJointSetSliderAxis(j, *m3.scale(m3.normalized(axis), -1.0))  # §4.3
        elif joint.kind == "hinge2":
            axis2 = frame.rotate(joint.axis_local[1])
            p1 = joint.positions[0]
            if p1 != 0.0:
                axis2 = m3.mat_vec(m3.rot_axis_angle((*axis, p1)), axis2)
            if m3.norm(m3.cross(m3.normalized(axis), m3.normalized(axis2))) < 1e-6:
                self.warn("Hinge2Joint axes are aligned; falling back to x and z")
                axis, axis2 = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
            lib.dJointSetHinge2Anchor(j, *anchor)
            lib.dJointSetHinge2Axes(j, (ctypes.c_double * 4)(*axis, 0.0), (ctypes.c_double * 4)(*axis2, 0.0))
        elif joint.kind == "ball":
            lib.dJointSetBallAnchor(j, *anchor)
        joint.offsets = list(joint.positions)
        self._read_joint(joint, predict=False)

    def _set_stops(self, joint: JointRec, i: int) -> None:
        p = joint.params[i]
        if p is None or joint.kind == "ball" or (joint.kind == "hinge2" and i == 1):
            return  # upstream ODE never limits the second Hinge2 axis (module docstring)
        lo_w, hi_w = float(_f(p, "minStop", 0.0)), float(_f(p, "maxStop", 0.0))
        if lo_w == hi_w:
            return
        off = joint.offsets[i]
        if joint.kind == "slider":
            lo, hi = lo_w - off, hi_w - off  # §4.3
        else:
            lo = max(-math.pi, min(math.pi, -hi_w + off))  # §4.2
            hi = max(-math.pi, min(math.pi, -lo_w + off))
        if lo > hi:
            lo, hi = hi, lo
        setp = self._param_setter(joint)
        group = ode.dParamGroup2 if i == 1 else 0
        setp(joint.ptr, group + ode.dParamLoStop, lo)
        setp(joint.ptr, group + ode.dParamHiStop, hi)

    def _param_setter(self, joint: JointRec) -> Callable[..., None]:
        lib = self._lib
        return {  # type: ignore[no-any-return]
            "hinge": lib.dJointSetHingeParam,
            "slider": lib.dJointSetSliderParam,
            "hinge2": lib.dJointSetHinge2Param,
        }.get(joint.kind, lambda *a: None)

    def _set_static_friction(self, joint: JointRec, i: int) -> None:
        """§4.5: without a motor, static friction is a velocity-0 motor limited to staticFriction."""
        sf = joint.static_friction[i]
        if joint.motors[i] is None and sf > 0 and joint.kind != "ball":
            setp = self._param_setter(joint)
            group = ode.dParamGroup2 if i == 1 else 0
            setp(joint.ptr, group + ode.dParamVel, 0.0)
            setp(joint.ptr, group + ode.dParamFMax, sf)

    def _create_spring(self, joint: JointRec) -> None:
        """§4.5: implicit spring/damper through an AMotor (hinge) or an LMotor row (slider)."""
        p = joint.params[0]
        if p is None or joint.kind not in ("hinge", "slider"):
            return
        k = float(_f(p, "springConstant", 0.0))
        b = float(_f(p, "dampingConstant", 0.0))
        if k == 0.0 and b == 0.0:
            return
        lib = self._lib
        h = self.dt
        joint.spring_cfm = 1.0 / (h * k + b)
        joint.spring_erp = min(h * k / (h * k + b), 1.0)
        pb = joint.parent_body.ptr if joint.parent_body is not None else None
        assert joint.child_body is not None
        frame = self._joint_world_frame(joint) if joint.parent is not None else joint.frame_rel
        axis = frame.rotate(joint.axis_local[0])
        rel = 0 if joint.reverse else 1
        if joint.kind == "hinge":
            am = lib.dJointCreateAMotor(self._world, None)
            lib.dJointAttach(am, pb, joint.child_body.ptr)
            lib.dJointSetAMotorMode(am, ode.dAMotorUser)
            lib.dJointSetAMotorNumAxes(am, 1)
            ax = m3.scale(axis, -1.0) if joint.reverse else axis
            lib.dJointSetAMotorAxis(am, 0, rel, *ax)
            stop = m3.normalize_angle(joint.offsets[0])
            lib.dJointSetAMotorParam(am, ode.dParamLoStop, stop)
            lib.dJointSetAMotorParam(am, ode.dParamHiStop, stop)
            lib.dJointSetAMotorParam(am, ode.dParamStopCFM, joint.spring_cfm)
            lib.dJointSetAMotorParam(am, ode.dParamStopERP, joint.spring_erp)
            lib.dJointSetAMotorAngle(am, 0, 0.0)
        else:
            am = lib.dJointCreateLMotor(self._world, None)
            lib.dJointAttach(am, pb, joint.child_body.ptr)
            lib.dJointSetLMotorNumAxes(am, 1)
            lib.dJointSetLMotorAxis(am, 0, rel, *m3.scale(m3.normalized(axis), -1.0))
            lib.dJointSetLMotorParam(am, ode.dParamCFM, joint.spring_cfm)
            lib.dJointSetLMotorParam(am, ode.dParamFMax, ode.dInfinity)
            lib.dJointSetLMotorParam(am, ode.dParamVel, 0.0)
        joint.spring = am

    def _create_fixed_joints(self) -> None:
        lib = self._lib
        for body in self.bodies:
            if body.root.joint is not None or body.root.parent is None:
                continue
            fj = lib.dJointCreateFixed(self._world, None)
            other = body.fixed_to.ptr if body.fixed_to is not None else None
            lib.dJointAttach(fj, other, body.ptr)
            lib.dJointSetFixed(fj)
            body.fixed_joint = fj

    # -- devices

    def _collect_devices(self) -> None:
        for solid in self.solids:
            robot = solid.robot
            node = solid.node
            if robot is None or node is robot.node:
                continue
            if node.type_name in SOLID_TYPES and node.type_name not in ("Solid", "Robot"):
                dev = DeviceRec(
                    node=node, solid=solid, type_name=node.type_name, name=str(_f(node, "name", ""))
                )
                robot.devices.setdefault(dev.name, dev)
                self.devices.append(dev)

    # ------------------------------------------------------------------ contacts (§2)

    def _init_contacts(self) -> None:
        self._surfaces: dict[int, _Surface] = {}
        self._default_surface = self._make_surface(None)
        self._plans: dict[tuple[int, int], Any] = {}
        self._contact_modifiers: dict[int, Callable[[Any, list[int], int], None]] = {}
        self._buffer = 0
        self._used: list[list[BodyRec]] = [[], []]
        self._callback_error: BaseException | None = None
        self._auto_disable = self.disable_time > 0
        self._enabled: list[bool] = [True] * len(self.bodies)
        self._near_cb = ode.NearCallback(self._make_near_callback())

    def _make_surface(self, cp: Node | None) -> _Surface:
        coulomb = list(_f(cp, "coulombFriction", [1.0]) or [1.0])
        slip = list(_f(cp, "forceDependentSlip", [0.0]) or [0.0])
        rolling = tuple(_f(cp, "rollingFriction", (0.0, 0.0, 0.0)))
        bounce = float(_f(cp, "bounce", 0.5))
        s = ode.dSurfaceParameters()
        mode = ode.dContactApprox1 | ode.dContactSoftCFM | ode.dContactSoftERP
        if bounce != 0.0:
            mode |= ode.dContactBounce
        mu = float(coulomb[0])
        s.mu = ode.dInfinity if mu == -1 else mu
        s.mu2 = s.mu
        if float(slip[0]) != 0.0:
            mode |= ode.dContactSlip1 | ode.dContactSlip2
            s.slip1 = s.slip2 = float(slip[0])
        rho, rho2, rho_n = (float(v) for v in rolling)
        if rho > 0 or rho2 > 0 or rho_n > 0:
            mode |= ode.dContactRolling
            if rho2 > 0 or rho_n > 0:
                mode |= ode.dContactAxisDep
        s.rho, s.rho2, s.rhoN = (ode.dInfinity if v == -1 else v for v in (rho, rho2, rho_n))
        s.bounce = bounce
        s.bounce_vel = float(_f(cp, "bounceVelocity", 0.01))
        s.soft_erp = float(_f(cp, "softERP", 0.2))
        s.soft_cfm = float(_f(cp, "softCFM", 0.001))
        s.mode = mode
        if cp is not None and len(coulomb) > 1:
            self.warn("asymmetric coulombFriction is approximated by its first value")
        capacity = DEFAULT_CONTACT_CAPACITY
        arr = self._contact_array(s, capacity)
        return _Surface(arr, capacity, int(_f(cp, "maxContactJoints", 10)), s)

    @staticmethod
    def _contact_array(s: ode.dSurfaceParameters, capacity: int) -> Any:
        arr = (ode.dContact * capacity)()
        for i in range(capacity):
            arr[i].surface = s
        return arr

    def contact_properties_for(self, material1: str, material2: str) -> Node | None:
        """§2.1: the first ContactProperties matching the two materials in either order."""
        for cp in self.contact_properties:
            m1, m2 = str(_f(cp, "material1", "default")), str(_f(cp, "material2", "default"))
            if (m1 == material1 and m2 == material2) or (m1 == material2 and m2 == material1):
                return cp
        return None

    def _surface_for(self, material1: str, material2: str) -> _Surface:
        cp = self.contact_properties_for(material1, material2)
        if cp is None:
            return self._default_surface
        surface = self._surfaces.get(id(cp))
        if surface is None:
            surface = self._surfaces[id(cp)] = self._make_surface(cp)
        return surface

    def _bodies_connected(self, b1: BodyRec, b2: BodyRec) -> bool:
        for j in b1.joints:
            if (j.parent_body is b1 and j.child_body is b2) or (j.parent_body is b2 and j.child_body is b1):
                return True
        return (b1.fixed_to is b2 and b1.fixed_joint != 0) or (b2.fixed_to is b1 and b2.fixed_joint != 0)

    def _same_anchor_chain(self, b1: BodyRec, b2: BodyRec) -> bool:
        """§2.3 rule 7: b1 and b2 linked by hinge-like joints that all share one anchor."""
        for first in b1.joints:
            if first.kind not in ("hinge", "hinge2", "ball") or first.parent_body is None:
                continue
            anchor = self._joint_world_frame(first).apply(first.anchor_local)
            seen = {b1.index}
            frontier = [b1]
            while frontier:
                b = frontier.pop()
                for j in b.joints:
                    if j.kind not in ("hinge", "hinge2", "ball") or j.parent_body is None:
                        continue
                    a = self._joint_world_frame(j).apply(j.anchor_local)
                    if m3.norm(m3.sub(a, anchor)) > 1e-9:
                        continue
                    other = j.child_body if j.parent_body is b else j.parent_body
                    if other is None or other.index in seen:
                        continue
                    if other is b2:
                        return True
                    seen.add(other.index)
                    frontier.append(other)
        return False

    def _plan_pair(self, o1: int, o2: int) -> Any:
        g1, g2 = self.geoms.get(o1), self.geoms.get(o2)
        if g1 is None or g2 is None:
            return False
        b1, b2 = g1.body, g2.body
        if b1 is None and b2 is None:
            return False  # rule 5
        r1, r2 = g1.solid.robot, g2.solid.robot
        if r1 is not None and r1 is r2 and not r1.self_collision:
            return False  # rule 4
        if b1 is not None and b2 is not None:
            if b1 is b2 or self._bodies_connected(b1, b2) or self._same_anchor_chain(b1, b2):
                return False  # rules 6 and 7
        else:
            b = b1 if b1 is not None else b2
            assert b is not None
            if b.attached_to_world:
                return False  # rule 6: a body jointed to the static environment ignores static geoms
        surface = self._surface_for(g1.solid.material, g2.solid.material)
        owner = b1 if b1 is not None else b2
        modifier = self._contact_modifiers.get(id(g1.solid)) or self._contact_modifiers.get(id(g2.solid))
        return (
            surface,
            owner,
            b1.ptr if b1 is not None else None,
            b2.ptr if b2 is not None else None,
            b1.index if b1 is not None else -1,
            b2.index if b2 is not None else -1,
            modifier,
        )

    def set_contact_modifier(self, solid: SolidRec, modifier: Callable[[Any, list[int], int], None]) -> None:
        """Let ``modifier(contacts, indices, o1)`` edit the ``dContact`` entries of every pair involving the
        Solid's geoms before their contact joints are created (Track belts set a surface velocity this way);
        the entries are restored afterwards. ``o1`` is the pair's first geom."""
        self._contact_modifiers[id(solid)] = modifier
        self._plans.clear()

    def _make_near_callback(self) -> Callable[[Any, Any, Any], None]:
        plans = self._plans
        plans_get = plans.get
        collide = self._lib.dCollide
        create = self._lib.dJointCreateContact
        attach = self._lib.dJointAttach
        world = self._world
        plan_pair = self._plan_pair
        enabled = self._enabled
        sizeof = SIZEOF_CONTACT
        geom_offset = GEOM_OFFSET
        addressof = ctypes.addressof

        def near(_data: Any, o1: int, o2: int) -> None:
            try:
                key = (o1, o2)
                plan = plans_get(key)
                if plan is None:
                    plan = plans[key] = plan_pair(o1, o2)
                if plan is False:
                    return
                surface, owner, p1, p2, i1, i2, modifier = plan
                if self._auto_disable:
                    e1 = enabled[i1] if i1 >= 0 else None
                    e2 = enabled[i2] if i2 >= 0 else None
                    if (e1 is None or not e1) and (e2 is None or not e2):
                        return  # rule 9 (both disabled, or body-less vs disabled)
                arr = surface.contacts
                base = addressof(arr)
                cap = surface.capacity
                n = collide(o1, o2, cap, base + geom_offset, sizeof)
                if n == 0:
                    return
                while n >= cap and cap < 0xFFFF:
                    cap = min(cap * 10, 0xFFFF)
                    surface.contacts = arr = self._contact_array(surface.template, cap)
                    surface.capacity = cap
                    base = addressof(arr)
                    n = collide(o1, o2, cap, base + geom_offset, sizeof)
                group = owner.groups[self._buffer]
                if n > surface.max_joints:
                    order = sorted(range(n), key=lambda i: -arr[i].geom.depth)[: surface.max_joints]
                    indices: Iterable[int] = sorted(order)
                else:
                    indices = range(n)
                if modifier is not None:
                    indices = list(indices)
                    modifier(arr, indices, o1)
                for i in indices:
                    attach(create(world, group, base + i * sizeof), p1, p2)  # ODE copies the dContact
                if modifier is not None:
                    for i in indices:
                        arr[i].surface = surface.template
                        arr[i].fdir1[0] = arr[i].fdir1[1] = arr[i].fdir1[2] = 0.0
                self._used[self._buffer].append(owner)
            except BaseException as exc:  # a ctypes callback cannot raise: re-raised after dSpaceCollide
                self._callback_error = exc

        return near

    def _collide(self) -> None:
        self._lib.dSpaceCollide(self._space, None, self._near_cb)
        if self._callback_error is not None:
            exc, self._callback_error = self._callback_error, None
            raise exc

    # ------------------------------------------------------------------ stepping

    def _prepare_step_lists(self) -> None:
        self._dyn_motors = [m for m in self.motors if not m.joint.kinematic and m.joint.kind != "ball"]
        self._kin_motors = [m for m in self.motors if m.joint.kinematic]
        self._springs = [j for j in self.joints if j.spring]
        self._tracked = [j for j in self.joints if not j.kinematic and j.kind != "ball"]
        # kinematic geoms inside robots are re-placed from the scene graph every step (§2.4)
        self._moving_static: list[GeomRec] = []
        for gr in self.geoms.values():
            if gr.body is None and gr.solid.robot is not None and self._moves(gr.solid):
                self._moving_static.append(gr)
        self._views = [(b.pos, b.lvel, b.avel) for b in self.bodies]

    def _moves(self, solid: SolidRec) -> bool:
        s: SolidRec | None = solid
        while s is not None:
            if s.body is not None:
                return True
            if s.joint is not None and s.joint.kinematic and s.joint.motors[0] is not None:
                return True
            s = s.parent
        return False

    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        return self.step_count * self.basic_time_step / 1000.0

    @property
    def unstable(self) -> bool:
        return self._unstable

    def step(self, n: int = 1) -> None:
        """Advance ``n`` basic time steps (§1.6 order).

        Raises:
            SimulationUnstable: the state became non-finite; stepping is refused until :meth:`reset`.
        """
        if threading.get_ident() != self._thread:
            ode.ensure_thread()  # ODE needs per-thread data in every stepping thread
        for _ in range(n):
            if self._unstable:
                raise SimulationUnstable("simulation is unstable; call reset()")
            if self._pending:
                self._apply_pending()
            self._pre_physics()
            for pre_hook in self.pre_step_hooks:
                pre_hook(self.dt)
            self._step_fn(self._world, self.dt)
            self._check_state()
            self._swap_and_collide()
            self._post_physics()
            self.step_count += 1
            for hook in self.step_hooks:
                hook()

    def _pre_physics(self) -> None:
        dt = self.dt
        for motor in self._dyn_motors:
            self._apply_motor(motor, dt)
        for joint in self._springs:
            self._apply_spring(joint)
        if self._kin_motors:
            for motor in self._kin_motors:
                self._kinematic_motor(motor, dt)
        for gr in self._moving_static:
            self._place_static_geom(gr, self.solid_world_pose(gr.solid))

    def _apply_motor(self, motor: MotorRec, dt: float) -> None:
        """§5.3: torque mode adds a torque; otherwise set the ODE motor row (Vel, FMax)."""
        joint = motor.joint
        lib = self._lib
        kind = joint.kind
        i = motor.axis_index
        if motor.torque_mode:
            if not motor.torque_params_set:
                # §5.2: entering torque mode leaves a velocity-0 motor limited to staticFriction
                self._set_motor_row(joint, i, 0.0, joint.static_friction[i])
                motor.torque_params_set = True
            tau = motor.raw_torque
            if kind == "hinge":
                # ODE 0.16 negates the torque of reversed hinges itself; undo it so that a positive
                # torque increases the position for static-base joints too (UNVERIFIED for the fork)
                lib.dJointAddHingeTorque(joint.ptr, tau if joint.reverse else -tau)
            elif kind == "slider":
                lib.dJointAddSliderForce(joint.ptr, tau)
            elif i == 0:
                lib.dJointAddHinge2Torques(joint.ptr, -tau, 0.0)
            else:
                lib.dJointAddHinge2Torques(joint.ptr, 0.0, -tau)
            return
        u = motor.command_velocity(dt)
        fmax = max(joint.static_friction[i], motor.available)
        if kind == "hinge":
            setp = lib.dJointSetHingeParam
            setp(joint.ptr, ode.dParamFMax, fmax)
            setp(joint.ptr, ode.dParamVel, -u)
        elif kind == "slider":
            setp = lib.dJointSetSliderParam
            setp(joint.ptr, ode.dParamFMax, fmax)
            setp(joint.ptr, ode.dParamVel, u)
        else:
            setp = lib.dJointSetHinge2Param
            g = ode.dParamGroup2 if i == 1 else 0
            setp(joint.ptr, g + ode.dParamFMax, fmax)
            setp(joint.ptr, g + ode.dParamVel, -u)

    def _set_motor_row(self, joint: JointRec, i: int, vel: float, fmax: float) -> None:
        setp = self._param_setter(joint)
        g = ode.dParamGroup2 if i == 1 else 0
        setp(joint.ptr, g + ode.dParamVel, vel)
        setp(joint.ptr, g + ode.dParamFMax, fmax)

    def _apply_spring(self, joint: JointRec) -> None:
        lib = self._lib
        if joint.kind == "hinge":
            a = lib.dJointGetHingeAngle(joint.ptr)
            lib.dJointSetAMotorAngle(joint.spring, 0, -a if joint.reverse else a)
        else:
            # LMotor motor row == stop row with ERP/CFM (module docstring); the row Jacobian sign flips
            # with the ODE body order, hence the reverse-dependent sign.
            x = joint.positions[0]
            v = joint.spring_erp * x / self.dt
            lib.dJointSetLMotorParam(joint.spring, ode.dParamVel, v if joint.reverse else -v)

    def _kinematic_motor(self, motor: MotorRec, dt: float) -> None:
        """§5.3 (kinematic joints): move toward the target at the commanded velocity."""
        joint = motor.joint
        i = motor.axis_index
        pos = joint.positions[i]
        if motor.torque_mode or motor.available == 0.0:
            return
        if math.isinf(motor.target_position):
            pos += motor.target_velocity * dt
        else:
            step = abs(motor.target_velocity) * dt
            err = motor.target_position - pos
            pos = motor.target_position if abs(err) <= max(step, 1e-6) else pos + math.copysign(step, err)
        joint.positions[i] = pos

    def _check_state(self) -> None:
        isfinite = math.isfinite
        for pos, lvel, avel in self._views:
            p0, p1, p2 = pos[0], pos[1], pos[2]
            v0, v1, v2 = lvel[0], lvel[1], lvel[2]
            s = p0 * p0 + p1 * p1 + p2 * p2 + v0 * v0 + v1 * v1 + v2 * v2 + avel[0] + avel[1] + avel[2]
            if (
                not isfinite(s)
                or abs(p0) + abs(p1) + abs(p2) > DIVERGED_POSITION
                or (abs(v0) + abs(v1) + abs(v2) > DIVERGED_VELOCITY)
            ):
                self._unstable = True
                raise SimulationUnstable(
                    f"non-finite or diverging body state at t={self.time + self.dt:.3f}s; reset() to recover"
                )

    def _swap_and_collide(self) -> None:
        if self._auto_disable:
            is_enabled = self._is_enabled
            enabled = self._enabled
            for b in self.bodies:
                enabled[b.index] = bool(is_enabled(b.ptr))
        consumed = self._buffer
        self._buffer ^= 1
        self._collide()  # §1.6 step 4: contacts for the next step, into the other buffer
        used = self._used[consumed]
        if used:
            keep = []
            empty = self._empty_group
            enabled = self._enabled
            done: set[int] = set()
            for body in used:
                if body.index in done:
                    continue
                done.add(body.index)
                if enabled[body.index] or not self._auto_disable:
                    empty(body.groups[consumed])
                else:
                    keep.append(body)  # §1.3: contacts of disabled bodies persist
            self._used[consumed] = keep

    def _post_physics(self) -> None:
        for joint in self._tracked:
            self._read_joint(joint, predict=True)
        if self._accel_cur:
            for index in self._accel_cur:
                b = self.bodies[index]
                self._accel_prev[index] = self._accel_cur[index]
                self._accel_cur[index] = (b.lvel[0], b.lvel[1], b.lvel[2])

    def _read_joint(self, joint: JointRec, predict: bool) -> None:
        """§4.2–4.4: Webots joint position from ODE (continuous, unwrapped for hinges)."""
        lib = self._lib
        j = joint.ptr
        kind = joint.kind
        if kind == "hinge":
            a = self._hinge_angle(j)
            joint.raw_angles[0] = a
            if predict:
                rate = self._hinge_rate(j)
                pred = joint.positions[0] + (rate if joint.reverse else -rate) * self.dt
            else:
                pred = joint.positions[0]
            pos = (a if joint.reverse else -a) + joint.offsets[0]
            joint.positions[0] = m3.normalize_angle(pos, pred)
        elif kind == "slider":
            joint.positions[0] = self._slider_pos(j) + joint.offsets[0]
        elif kind == "hinge2":
            a1 = lib.dJointGetHinge2Angle1(j)
            a2 = lib.dJointGetHinge2Angle2(j)
            if predict:
                pred1 = joint.positions[0] - lib.dJointGetHinge2Angle1Rate(j) * self.dt
                pred2 = joint.positions[1] + lib.dJointGetHinge2Angle2Rate(j) * self.dt
            else:
                pred1, pred2 = joint.positions[0], joint.positions[1]
            joint.positions[0] = m3.normalize_angle(-a1 + joint.offsets[0], pred1)
            joint.positions[1] = m3.normalize_angle(a2 + joint.offsets[1], pred2)

    # ------------------------------------------------------------------ reset (§6)

    def reset(self) -> None:
        """``simulationReset``: restore the load state exactly (fields, poses, joints, motors, contacts, RNG)."""
        lib = self._lib
        self._pending.clear()
        self._restore_fields()
        for body in self.bodies:
            for g in body.groups:
                lib.dJointGroupEmpty(g)
        self._used = [[], []]
        self._buffer = 0
        for solid in self.solids:
            solid.rel = solid.load_rel
        for body in self.bodies:
            self._place_body_at_load(body)
            self._set_auto_disable(body)
        for joint in self.joints:
            joint.positions = list(joint.initial_positions)
            if joint.ptr:
                self._anchor_joint(joint)
                for i in range(len(joint.params)):
                    self._set_stops(joint, i)
                if joint.spring and joint.kind == "hinge":
                    stop = m3.normalize_angle(joint.offsets[0])
                    lib.dJointSetAMotorParam(joint.spring, ode.dParamLoStop, stop)
                    lib.dJointSetAMotorParam(joint.spring, ode.dParamHiStop, stop)
                    lib.dJointSetAMotorAngle(joint.spring, 0, 0.0)
                for i, m in enumerate(joint.motors):
                    if m is not None or joint.static_friction[i] > 0:
                        self._set_motor_row(joint, i, 0.0, joint.static_friction[i] if m is None else 0.0)
        for gr in self.geoms.values():
            if gr.body is None:
                self._place_static_geom(gr, self.solid_world_pose(gr.solid))
        for (_, name), node in list(self._edited.items()):
            self._apply_field(node, name)
        self._edited.clear()
        for motor in self.motors:
            motor.reset_state()
        self._enabled[:] = [True] * len(self.bodies)
        self._accel_prev.clear()
        for index in self._accel_cur:
            b = self.bodies[index]
            self._accel_cur[index] = (b.lvel[0], b.lvel[1], b.lvel[2])
        lib.dRandSetSeed(max(self.random_seed, 0))
        self._rng = random.Random(self._rng_seed())
        self._unstable = False
        self.step_count = 0
        for hook in self.reset_hooks:
            hook()
        self._collide()

    def reset_physics(self, solid: SolidRec | None = None) -> None:
        """``simulationResetPhysics`` (or ``Node.resetPhysics`` for a subtree): zero velocities and forces,
        wake bodies, zero motors' current velocity (§6). Poses and time are kept."""
        lib = self._lib
        bodies = self.bodies if solid is None else self._bodies_in_subtree(solid)
        for body in bodies:
            lib.dBodySetLinearVel(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetAngularVel(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetForce(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetTorque(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodyEnable(body.ptr)
        ids = {b.index for b in bodies}
        for motor in self.motors:
            if solid is None or (motor.joint.child_body is not None and motor.joint.child_body.index in ids):
                motor.current_velocity = 0.0

    def _bodies_in_subtree(self, solid: SolidRec) -> list[BodyRec]:
        out: list[BodyRec] = []
        stack = [solid]
        while stack:
            s = stack.pop()
            if s.body is not None and s.body.root is s:
                out.append(s.body)
            stack.extend(s.children)
        if solid.body is not None and solid.body not in out:
            out.append(solid.body)
        return out

    # ------------------------------------------------------------------ supervisor-side operations (§6)

    def solid_for(self, node: Node) -> SolidRec | None:
        return self._solid_by_node.get(id(node))

    def joint_for(self, node: Node) -> JointRec | None:
        """The joint of a joint node or of one of its (Hinge)JointParameters nodes."""
        return self._joint_by_node.get(id(node))

    def has_pending(self, target: Any) -> bool:
        """Whether a queued teleport (pose or joint position) targets ``target`` (a SolidRec or JointRec)."""
        return any(op.target is target and op.kind != "velocity" for op in self._pending)

    def _teleport_pending_for(self, body: BodyRec) -> bool:
        """Whether a queued teleport will move (and maybe reset) ``body``."""
        for op in self._pending:
            if op.kind == "pose":
                root = op.target
            elif op.kind == "joint" and op.target.child is not None:
                root = op.target.child
            else:
                continue
            if any(b is body for b in self._bodies_in_subtree(root)):
                return True
        return False

    def queue_set_pose(
        self, solid: SolidRec, translation: Sequence[float] | None, rotation: Sequence[float] | None
    ) -> None:
        """Queue a teleport (translation/rotation field set), applied before the next physics step."""
        self._pending.append(_PendingOp("pose", solid, (translation, rotation)))

    def queue_set_joint_position(self, joint: JointRec, axis_index: int, position: float) -> None:
        """Queue a joint ``position`` field set (§4.1), applied before the next physics step."""
        self._pending.append(_PendingOp("joint", joint, (axis_index, position)))

    def apply_pending(self) -> None:
        """Execute the queued supervisor requests now, without a physics step (dualtwin extension, no Webots
        equivalent: Webots runs them only as part of the next step). Tests use it to inspect a write."""
        if threading.get_ident() != self._thread:
            ode.ensure_thread()
        self._apply_pending()

    def _apply_pending(self) -> None:
        ops, self._pending = self._pending, []
        for op in ops:
            if op.kind == "pose":
                translation, rotation = op.value
                self._teleport_solid(op.target, translation, rotation)
            elif op.kind == "joint":
                axis_index, position = op.value
                self._teleport_joint(op.target, axis_index, position)
            elif op.kind == "velocity":
                self._set_body_velocity_now(op.target, op.value)
        self._check_state()

    def _teleport_solid(
        self, solid: SolidRec, translation: Sequence[float] | None, rotation: Sequence[float] | None
    ) -> None:
        if solid.body is not None and solid.body.root is not solid:
            self.warn(f"moving merged Solid '{solid.name}' is not supported; ignored")
            return
        node = solid.node
        current = self.solid_local_pose(solid)  # fields of moving solids are only refreshed lazily
        t = tuple(float(v) for v in translation) if translation is not None else current.t
        R = m3.rot_axis_angle(rotation) if rotation is not None else current.R
        node.fields["translation"] = t
        node.fields["rotation"] = tuple(rotation) if rotation is not None else m3.axis_angle_from_mat(R)
        local = Pose(R, t)
        old_world = self.solid_world_pose(solid)
        if solid.parent is None:
            new_world = solid.pre * local
        else:
            parent_world = self.solid_world_pose(solid.parent)
            if solid.joint is not None and not solid.joint.kinematic:
                new_world = parent_world * solid.pre * local
            else:
                new_world = parent_world * self._kinematic_extra(solid) * solid.pre * local
        solid.rel = solid.pre * local
        self._move_subtree(solid, new_world * old_world.inverse(), reset_velocity=False)
        self._reanchor_boundary(solid)

    def _kinematic_extra(self, solid: SolidRec) -> Pose:
        joint = solid.joint
        if joint is None or not joint.kinematic:
            return Pose()
        delta = joint.positions[0] - joint.initial_positions[0]
        return self._joint_motion(joint, delta) if delta else Pose()

    def _move_subtree(self, solid: SolidRec, T: Pose, reset_velocity: bool) -> None:
        """Apply a rigid world transform ``T`` to every body and static geom in a Solid subtree."""
        lib = self._lib
        for body in self._bodies_in_subtree(solid):
            pose = body.pose()
            new_root = T * pose
            lib.dBodySetPosition(body.ptr, *new_root.apply(body.com))
            lib.dBodySetRotation(body.ptr, _rot_matrix(new_root.R))
            if reset_velocity:
                lib.dBodySetLinearVel(body.ptr, 0.0, 0.0, 0.0)
                lib.dBodySetAngularVel(body.ptr, 0.0, 0.0, 0.0)
                lib.dBodySetForce(body.ptr, 0.0, 0.0, 0.0)
                lib.dBodySetTorque(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodyEnable(body.ptr)
        stack = [solid]
        while stack:
            s = stack.pop()
            for gr in s.geoms:
                if gr.body is None:
                    self._place_static_geom(gr, self.solid_world_pose(s))
            stack.extend(s.children)

    def _reanchor_boundary(self, solid: SolidRec) -> None:
        """Re-set joints crossing the moved subtree's boundary (ODE zero re-based, §6)."""
        inside = {id(s) for s in self._subtree(solid)}
        for joint in self.joints:
            if not joint.ptr:
                continue
            child_in = joint.child is not None and id(joint.child) in inside
            parent_in = joint.parent is not None and id(joint.parent) in inside
            if child_in != parent_in or (child_in and joint.reverse):
                self._anchor_joint(joint)
                for i in range(len(joint.params)):
                    self._set_stops(joint, i)
                self._respring(joint)

    def _respring(self, joint: JointRec) -> None:
        if joint.spring and joint.kind == "hinge":
            lib = self._lib
            stop = m3.normalize_angle(joint.offsets[0])
            lib.dJointSetAMotorParam(joint.spring, ode.dParamLoStop, stop)
            lib.dJointSetAMotorParam(joint.spring, ode.dParamHiStop, stop)

    def _subtree(self, solid: SolidRec) -> list[SolidRec]:
        out = []
        stack = [solid]
        while stack:
            s = stack.pop()
            out.append(s)
            stack.extend(s.children)
        return out

    def _teleport_joint(self, joint: JointRec, axis_index: int, position: float) -> None:
        """§4.1: move the endPoint to zero-pose ⊕ position, reset its subtree's physics."""
        p = joint.params[axis_index]
        if p is not None:
            p.fields["position"] = float(position)
        child = joint.child
        if child is None or joint.kind in ("ball",) or (joint.kind == "hinge2" and axis_index == 1):
            joint.positions[axis_index] = float(position)
            return
        if joint.kinematic:
            joint.positions[axis_index] = float(position)
            return
        old_world = self.solid_world_pose(child)
        parent_world = self.solid_world_pose(joint.parent) if joint.parent is not None else Pose()
        delta = float(position) - joint.initial_positions[axis_index]
        new_rel = self._joint_motion(joint, delta) * child.load_rel if delta else child.load_rel
        new_world = parent_world * new_rel
        self._move_subtree(child, new_world * old_world.inverse(), reset_velocity=True)
        moved = {id(s) for s in self._subtree(child)}
        for motor in self.motors:
            if motor.joint.child is not None and id(motor.joint.child) in moved:
                motor.current_velocity = 0.0
        joint.positions[axis_index] = float(position)
        self._read_joint(joint, predict=False)

    # ------------------------------------------------------------------ live field edits

    def field_changed(self, node: Node, name: str) -> bool:
        """Apply a supervisor's edit of ``node.fields[name]`` to the running ODE scene, as Webots does.

        Webots reacts to field edits at run time (WbJoint/WbMotor/WbPhysics/WbContactProperties update
        their ODE objects). Supported: joint ``dampingConstant``/``springConstant``/``staticFriction``,
        motor ``maxVelocity``/``maxTorque``/``maxForce``, ``Physics.mass`` (inertia scaled with it, CoM
        unchanged), ``ContactProperties`` friction/bounce/soft ERP/CFM, and ``WorldInfo`` ERP/CFM.
        Returns False for fields whose edit has no physics effect here.
        """
        applied = self._apply_field(node, name)
        if applied:
            # simulationReset restores the field; reset() then re-applies it so ODE follows.
            self._edited[(id(node), name)] = node
        return applied

    def _apply_field(self, node: Node, name: str) -> bool:
        lib = self._lib
        value: Any = node.fields.get(name)
        joint = next((j for j in self.joints if node in j.params), None)
        if joint is not None:
            i = joint.params.index(node)
            if name == "staticFriction":
                joint.static_friction[i] = float(value)
                self._set_static_friction(joint, i)
                return True
            if name in ("dampingConstant", "springConstant") and i == 0:
                if joint.spring:
                    lib.dJointDestroy(joint.spring)
                    joint.spring = 0
                self._create_spring(joint)
                if joint.spring and joint.kind == "hinge":
                    self._apply_spring(joint)
                return True
            return False
        motor = next((m for m in self.motors if m.node is node), None)
        if motor is not None:
            if name == "maxVelocity":
                motor.max_velocity = float(value)
                motor.target_velocity = max(-motor.max_velocity, min(motor.max_velocity, motor.target_velocity))
                return True
            if name in ("maxTorque", "maxForce"):
                motor.max_force = float(value)
                motor.available = motor.max_force
                return True
            return False
        if node.type_name == "Physics" and name == "mass":
            body = next((b for b in self.bodies if any(m.node.fields.get("physics") is node for m in b.members)), None)
            if body is None or float(value) <= 0:
                return False
            # The merged members' masses, re-read from their (edited) Physics nodes; the inertia scales
            # with the total and the CoM stays put (exact for single-solid bodies).
            total = sum(self._solid_mass(member)[0].mass for member in body.members)
            mass = ode.dMass()
            lib.dBodyGetMass(body.ptr, byref(mass))
            lib.dMassAdjust(byref(mass), total)
            lib.dBodySetMass(body.ptr, byref(mass))
            body.mass = mass.mass
            return True
        if node.type_name == "ContactProperties":
            self._surfaces.pop(id(node), None)
            return True
        if node.type_name == "WorldInfo" and name in ("ERP", "CFM"):
            if name == "ERP":
                lib.dWorldSetERP(self._world, float(value))
            else:
                lib.dWorldSetCFM(self._world, float(value))
            return True
        return False

    def joint_velocity(self, joint: JointRec, axis_index: int = 0) -> float:
        """Current joint rate in the Webots sign convention (rad/s or m/s)."""
        lib = self._lib
        if joint.kinematic or joint.kind == "ball":
            motor = joint.motors[axis_index] if axis_index < len(joint.motors) else None
            return motor.current_velocity if motor is not None else 0.0
        if joint.kind == "hinge":
            rate = lib.dJointGetHingeAngleRate(joint.ptr)
            return float(rate if joint.reverse else -rate)
        if joint.kind == "slider":
            return float(lib.dJointGetSliderPositionRate(joint.ptr))
        if axis_index == 0:
            return float(-lib.dJointGetHinge2Angle1Rate(joint.ptr))
        return float(lib.dJointGetHinge2Angle2Rate(joint.ptr))

    def set_body_velocity(self, solid: SolidRec, velocity: Sequence[float]) -> None:
        """``Node.setVelocity``: set the ODE body's linear (CoM) and angular velocity (world frame).

        Webots executes a supervisor's requests in the order they were made, just before the next physics
        step. A velocity set after a teleport of the same body (a ``translation``/``rotation`` or joint
        ``position`` write, which may reset the subtree's velocities, spec §4.1) must therefore survive it:
        while such a teleport is queued, the velocity is queued behind it. Otherwise it applies at once, as
        before (the two orders cannot be told apart then).
        """
        body = solid.body
        if body is None:
            return
        if self._pending and self._teleport_pending_for(body):
            self._pending.append(_PendingOp("velocity", solid, tuple(float(v) for v in velocity)))
            return
        self._set_body_velocity_now(solid, velocity)

    def _set_body_velocity_now(self, solid: SolidRec, velocity: Sequence[float]) -> None:
        body = solid.body
        if body is None:
            return
        lib = self._lib
        lib.dBodySetLinearVel(body.ptr, *velocity[:3])
        lib.dBodySetAngularVel(body.ptr, *velocity[3:6])
        lib.dBodyEnable(body.ptr)

    def solid_velocity(self, solid: SolidRec) -> tuple[float, ...]:
        """``Node.getVelocity``: 6 values, body CoM linear velocity and angular velocity (world)."""
        if solid.body is not None:
            b = solid.body
            return (b.lvel[0], b.lvel[1], b.lvel[2], b.avel[0], b.avel[1], b.avel[2])
        anc = solid.parent
        while anc is not None and anc.body is None:
            anc = anc.parent
        if anc is None or anc.body is None:
            return (0.0,) * 6
        b = anc.body
        w = (b.avel[0], b.avel[1], b.avel[2])
        r = m3.sub(self.solid_world_pose(solid).t, (b.pos[0], b.pos[1], b.pos[2]))
        v = m3.add((b.lvel[0], b.lvel[1], b.lvel[2]), m3.cross(w, r))
        return (*v, *w)

    def center_of_mass(self, solid: SolidRec) -> m3.Vec3:
        """World position of the body CoM holding ``solid`` (its own origin if it has no body)."""
        if solid.body is not None:
            b = solid.body
            return (b.pos[0], b.pos[1], b.pos[2])
        return self.solid_world_pose(solid).t

    def solid_local_pose(self, solid: SolidRec) -> Pose:
        """The Solid's current pose in the frame its ``translation``/``rotation`` fields refer to."""
        if solid.body is None and (solid.joint is None or not solid.joint.kinematic):
            return solid.pre.inverse() * solid.rel
        world = self.solid_world_pose(solid)
        parent = self.solid_world_pose(solid.parent) if solid.parent is not None else Pose()
        return solid.pre.inverse() * parent.inverse() * world

    def wake(self, joint: JointRec) -> None:
        """Re-enable a joint's sleeping bodies (a motor command changed, UNVERIFIED)."""
        if not self._auto_disable:
            return
        enabled = self._enabled
        for b in (joint.parent_body, joint.child_body):
            if b is not None and not enabled[b.index]:
                self._lib.dBodyEnable(b.ptr)
                enabled[b.index] = True

    # ------------------------------------------------------------------ sensors

    def track_acceleration(self, solid: SolidRec) -> None:
        body = solid.body or (self._nearest_body(solid.parent) if solid.parent is not None else None)
        if body is not None and body.index not in self._accel_cur:
            v = (body.lvel[0], body.lvel[1], body.lvel[2])
            self._accel_cur[body.index] = v
            self._accel_prev[body.index] = v

    def acceleration(self, solid: SolidRec) -> m3.Vec3:
        """Accelerometer reading in the device frame: R^T·(a − g)."""
        body = solid.body or (self._nearest_body(solid.parent) if solid.parent is not None else None)
        a = (0.0, 0.0, 0.0)
        if body is not None and body.index in self._accel_cur:
            cur, prev = self._accel_cur[body.index], self._accel_prev[body.index]
            a = m3.scale(m3.sub(cur, prev), 1.0 / self.dt)
        R = self.solid_world_pose(solid).R
        return m3.mat_t_vec(R, m3.sub(a, self.gravity))

    @property
    def rng(self) -> random.Random:
        """The sensor-noise generator (seeded from ``WorldInfo.randomSeed`` or the ``seed`` argument)."""
        return self._rng

    def sensor_noise(self, value: float, noise: float, resolution: float) -> float:
        if noise > 0:
            value += self._rng.gauss(0.0, noise)
        if resolution > 0:
            value = round(value / resolution) * resolution
        return value

    def close(self) -> None:
        """Destroy the ODE world (idempotent)."""
        if self._closed:
            return
        self._closed = True
        lib = self._lib
        for gr in self.geoms.values():
            lib.dGeomDestroy(gr.ptr)
        for body in self.bodies:
            for g in body.groups:
                lib.dJointGroupDestroy(g)
        lib.dSpaceDestroy(self._space)
        lib.dWorldDestroy(self._world)

    def __del__(self) -> None:
        try:
            if not self._closed and hasattr(self, "_world"):
                self.close()
        except Exception:
            pass
