"""Records of the ODE scene built from a Webots world (solids, bodies, joints, motors, devices, geoms) and the
small helpers the build, collision, stepping and edit layers share.

The records reference each other in cycles (a Solid knows its body, the body its member Solids), so they are
plain mutable dataclasses compared by identity (``eq=False``).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any

from dualtwin.errors import DualtwinError
from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.mass_rules import field_or
from dualtwin.webots.motor_law import motor_velocity
from dualtwin.webots.nodes import Node

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


def is_solid(node: Node) -> bool:
    """A Solid-derived node (by type, or for PROTO-less custom nodes by the Solid fields it carries)."""
    if node.type_name in SOLID_TYPES:
        return True
    f = node.fields
    return "boundingObject" in f and "physics" in f and "translation" in f and "children" in f


def is_robot(node: Node) -> bool:
    """A Robot node (by type, or by the Robot-only fields it carries)."""
    return node.type_name == "Robot" or ("controller" in node.fields and "selfCollision" in node.fields)


def damping_per_step(per_second: float, dt: float) -> float:
    """§1.4: fraction of speed lost per second → ODE per-step damping scale."""
    if per_second <= 0.0:
        return 0.0
    return 1.0 - (1.0 - min(per_second, 1.0)) ** dt


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
    source: Node | None = None  # the geometry node it was built from (supervisor edits resize it)
    scale: tuple[float, ...] = (1.0, 1.0, 1.0)  # Transform scale above it in the boundingObject


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
    #: the factor of the Transforms above it (dualtwin.webots.solid_scale): its translation, its children's frames
    #: and its boundingObject are that many times larger than their fields say, its mass s³ times
    scale: float = 1.0

    @property
    def name(self) -> str:
        return str(field_or(self.node, "name", ""))

    @property
    def material(self) -> str:
        return str(field_or(self.node, "contactMaterial", "default"))

    @property
    def is_dynamic(self) -> bool:
        return self.body is not None

    def subtree(self) -> list[SolidRec]:
        """This Solid and every Solid below it (depth first)."""
        out, stack = [], [self]
        while stack:
            s = stack.pop()
            out.append(s)
            stack.extend(s.children)
        return out

    def carriers(self) -> list[SolidRec]:
        """This Solid and the Solids it is mounted on, up to its top Solid."""
        out: list[SolidRec] = []
        s: SolidRec | None = self
        while s is not None:
            out.append(s)
            s = s.parent
        return out


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
    removed: bool = False  # its Solid left the scene at run time (disabled, jointless, skipped by resets)

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
    #: the ``acceleration`` field as loaded (setAcceleration replaces the field; simulationReset restores it)
    load_acceleration: float = -1.0
    sensor: PositionSensorRec | None = None
    brake: BrakeRec | None = None

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
class BrakeRec(_ShortRepr):
    """Brake of a joint axis: a damping constant added to the axis' dampingConstant (0 until set)."""

    node: Node
    joint: JointRec
    axis_index: int
    name: str
    damping: float = 0.0


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
    #: the factor of the Transforms above it (dualtwin.webots.solid_scale): a position its fields give in its frame
    #: (a Propeller's centerOfThrust) is that many times longer
    scale: float = 1.0


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
    spring2: int = 0  # Hinge2: the AMotor of the second axis
    stop2: int = 0  # Hinge2: a user AMotor holding the second axis' stops (upstream ODE's hinge2 has none there)
    # a hinge with stops: ODE's zero follows the joint (physics/joints.py _rebase_hinge); stop_shift is how far
    # it moved since Webots set it (the offset minus the offset the stops are mapped from, §4.2)
    rebase: bool = False
    stop_shift: float = 0.0
    spring_erp: float = 0.0
    spring_cfm: float = 0.0
    motors: list[MotorRec | None] = field(default_factory=lambda: [None])
    sensors: list[PositionSensorRec | None] = field(default_factory=lambda: [None])
    static_friction: list[float] = field(default_factory=lambda: [0.0])
    raw_angles: list[float] = field(default_factory=lambda: [0.0])
    brakes: list[BrakeRec | None] = field(default_factory=lambda: [None])
    amotor: int = 0  # BallJoint: the Euler AMotor carrying the three axes' motors and stops
    euler_ref: tuple[Any, ...] = ()  # BallJoint: (parent R, child R, axes basis) when the axes were set
    reference: Node | None = None  # the SolidReference endPoint of a joint closing a loop (§10)
    # the axes and anchor of the load (a reset gives them back) and those the endPoint's zero pose is taken about
    # (§4.1: its load pose undone by the load positions): the load ones, or an imported parameters node's; a
    # run-time edit of an axis or anchor keeps the zero pose (physics/axis_edits.py)
    load_axes: list[m3.Vec3] = field(default_factory=list)
    load_anchor: m3.Vec3 = m3.ZERO
    zero_axes: list[m3.Vec3] = field(default_factory=list)
    zero_anchor: m3.Vec3 = m3.ZERO
    scale: float = 1.0  # the factor of the Transforms above it: its anchor is that many times the field's

    @property
    def kinematic(self) -> bool:
        return self.ptr == 0

    def ode_axis(self, i: int) -> int:
        """The ODE axis (parameter group, AMotor axis index) carrying Webots axis ``i``. On a static parent a
        BallJoint's Euler AMotor has the endPoint as its first body, so ODE's first axis turns with the endPoint
        and its third stays in the world: there Webots' third axis is ODE's first and Webots' first is ODE's
        third (physics/joints.py ``_attach_euler`` and ``_set_euler_axes``)."""
        return 2 - i if self.kind == "ball" and self.reverse else i


# --------------------------------------------------------------------------------------------------


@dataclass
class Surface:
    """A ContactProperties match turned into a pre-filled ``dContact`` array (§2.2)."""

    contacts: Any
    capacity: int
    max_joints: int
    template: ode.dSurfaceParameters
    # asymmetric Coulomb friction: (values 2–4, material1, frictionRotation) or None
    asymmetric: tuple[tuple[float, ...], str, tuple[float, float]] | None = None


@dataclass
class PendingOp:
    kind: str
    target: Any
    value: Any
    #: the issuing supervisor's place in the scene tree (its robot's Solid index; 0 when unknown): Webots executes
    #: the queued writes of a step in scene-tree order of supervisors (§6), whoever made the call first
    order: int = 0
