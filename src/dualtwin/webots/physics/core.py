"""The state every layer of :class:`~dualtwin.webots.physics.Simulation` shares, and the scene-graph queries
they all need (world poses of Solids, the nearest body, the divergence check).

:class:`Simulation` is one object built from a stack of layers, each in its own module and each calling only
methods of the layers below it: ``core`` < ``build`` (traversal, bodies, mass, geoms) < ``joints`` <
``collision`` (contact pass, §2) < ``edits`` (supervisor requests, field edits, sensors) < ``stepping`` (§1.6)
< ``Simulation`` (construction, reset, close). The attributes are declared here once; they are created by
``Simulation.__init__`` and the build steps.
"""

from __future__ import annotations

import math
import random
import warnings
from collections.abc import Callable
from typing import Any

from dualtwin.errors import SimulationUnstable
from dualtwin.webots import _math3 as m3
from dualtwin.webots._math3 import Pose
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.physics.records import (
    DIVERGED_POSITION,
    DIVERGED_VELOCITY,
    AttachmentRec,
    BodyRec,
    GeomRec,
    JointRec,
    MotorRec,
    PendingOp,
    RobotRec,
    SolidRec,
    Surface,
)
from dualtwin.webots.solid_scale import transform_factor


class SimulationCore:
    """Shared state and scene-graph queries (see the module docstring)."""

    # created by Simulation.__init__ and _read_world_info
    world: World
    _lib: Any
    _thread: int
    _step_fn: Any  # cached ctypes function objects for the per-step paths
    _broken: str | None
    _is_enabled: Any
    _empty_group: Any
    _hinge_angle: Any
    _hinge_rate: Any
    _slider_pos: Any
    _warnings: list[str]
    robots: list[RobotRec]
    solids: list[SolidRec]
    bodies: list[BodyRec]
    joints: list[JointRec]
    geoms: dict[int, GeomRec]
    motors: list[MotorRec]
    devices: list[Any]
    attachments: list[AttachmentRec]
    _loops: list[tuple[JointRec, str]]  # joints whose endPoint is a SolidReference
    _solid_by_node: dict[int, SolidRec]
    _joint_by_node: dict[int, JointRec]
    #: id of a Pose/Transform among the scene's frames -> (it, the factor below it at load: solid_scale)
    _frame_factors: dict[int, tuple[Node, float]]
    _pending: list[PendingOp]
    #: (id of node, field) -> (value before, scene-tree places of the supervisors that wrote it) for the field writes
    #: of supervisors not yet executed by a step (see SupervisorEdits.note_unexecuted_write)
    _unexecuted: dict[tuple[int, str], tuple[Any, dict[int, Any]]]  # value before, writer order -> its value
    _edited: dict[tuple[int, str], Node]
    #: moves after every change of the scene tree's nodes (added, removed, restored by a reset), once it is made:
    #: what a reader caches of the tree's shape is good while it stays (Field's IS-bound base fields)
    scene_version: int = 0
    _unstable: bool
    _closed: bool
    step_count: int
    _time_base: float  # s: the time when basicTimeStep last changed (WorldInfoEdits), 0 at load and reset
    _steps_base: int  # the step_count then
    _seed_override: int | None
    _accel_prev: dict[int, tuple[float, float, float]]
    _accel_cur: dict[int, tuple[float, float, float]]
    extensions: dict[str, Any]
    step_hooks: list[Callable[[], None]]
    sample_hooks: list[Callable[[], None]]
    pre_step_hooks: list[Callable[[float], None]]
    reset_hooks: list[Callable[[], None]]
    basic_time_step: float
    dt: float
    gravity: m3.Vec3
    coordinate_system: str
    erp: float
    cfm: float
    disable_time: float
    disable_lin: float
    disable_ang: float
    world_damping: tuple[float, float]
    random_seed: int
    contact_properties: list[Node]
    _snapshot: list[tuple[Node, dict[str, Any], dict[str, Any] | None]]  # node, fields, PROTO interface
    # created by the build (_build, _categories, _init_contacts, _prepare_step_lists)
    _world: Any
    _space: Any
    _rng: random.Random
    _all_bits: int
    _surfaces: dict[int, Surface]
    _default_surface: Surface
    _plans: dict[tuple[int, int], Any]
    _run_time_links: dict[frozenset[int], int]  # pair of body indices -> how many run-time joints join them
    _contact_modifiers: dict[int, Callable[[Any, list[int], int], None]]
    _buffer: int
    _used: list[list[BodyRec]]
    _callback_error: BaseException | None
    _auto_disable: bool
    _enabled: list[bool]
    _near_cb: Any
    _dyn_motors: list[MotorRec]
    _kin_motors: list[MotorRec]
    _springs: list[JointRec]
    _tracked: list[JointRec]
    _held: list[JointRec]  # kinematic Hinge2Joints whose endPoint has a body (Stepper._hold_endpoint)
    _moving_static: list[GeomRec]
    _views: list[tuple[Any, Any, Any]]
    _drifting: list[SolidRec]  # Solids without Physics moved by their own velocity fields (Stepper._drift)

    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        return self._time_base + (self.step_count - self._steps_base) * self.basic_time_step / 1000.0

    @property
    def unstable(self) -> bool:
        return self._unstable

    def warn(self, message: str) -> None:
        self._warnings.append(message)
        warnings.warn(message, stacklevel=3)

    def warn_once(self, message: str) -> None:
        """:meth:`warn`, unless this very line was given before (a bounding Mesh that cannot be read is met by
        the mass rules and by the geom build; an edit that sums a body's mass again meets it once more)."""
        if message not in self._warnings:
            self.warn(message)

    @property
    def build_warnings(self) -> list[str]:
        return list(self._warnings)

    @staticmethod
    def _nearest_body(solid: SolidRec | None) -> BodyRec | None:
        while solid is not None:
            if solid.body is not None:
                return solid.body
            solid = solid.parent
        return None

    def factor_below(self, frame: Node, scale: float) -> float:
        """The factor of the scaled Transforms below ``frame``, a Pose or Transform among the scene's frames
        met in a frame scaled by ``scale``: the one found when it was first built (a run-time scale edit is
        not applied to the Solids below it, physics/frame_edits.py), else from its fields."""
        known = self._frame_factors.get(id(frame))
        if known is not None and known[0] is frame:
            return known[1]
        factor = scale * transform_factor(frame, self.warn_once)
        self._frame_factors[id(frame)] = (frame, factor)
        return factor

    def world_pose_at_load(self, solid: SolidRec) -> Pose:
        pose = solid.load_rel
        s = solid.parent
        while s is not None:
            pose = s.load_rel * pose
            s = s.parent
        return pose

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
        return self._endpoint_motion(joint) * solid.rel

    @staticmethod
    def _endpoint_motion(joint: JointRec) -> Pose:
        """The endPoint's motion, in the parent Solid frame, from its load pose to the joint's current positions
        (§4.1): the load pose undone by the initial positions about the axes and anchor the zero pose is taken
        about, then moved by the current positions about the current axes through the current anchor. A Hinge2's
        and a BallJoint's axes turn in chain (§4.4: axis 1 carries axis 2, which carries axis 3). While the axes
        and anchor are those of the zero pose this is the move by (position − initial position) alone."""
        if joint.axis_local == joint.zero_axes and joint.anchor_local == joint.zero_anchor:
            if joint.positions == joint.initial_positions:
                return Pose()
            if joint.kind in ("hinge", "slider"):
                return _axis_move(joint, joint.axis_local, joint.anchor_local,
                                  [joint.positions[0] - joint.initial_positions[0]])
        now = _axis_move(joint, joint.axis_local, joint.anchor_local, joint.positions)
        return now * _axis_move(joint, joint.zero_axes, joint.zero_anchor, joint.initial_positions).inverse()

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


def _axis_move(joint: JointRec, axes: list[m3.Vec3], anchor: m3.Vec3, positions: list[float]) -> Pose:
    """The move, in the parent Solid frame, by ``positions`` along a slider's axis or about ``axes`` in chain
    through ``anchor`` (axes and anchor in the joint's frame)."""
    frame = joint.frame_rel
    if joint.kind == "slider":
        return Pose(m3.IDENTITY, m3.scale(m3.normalized(frame.rotate(axes[0])), positions[0]))
    if joint.kind == "hinge":
        R = m3.rot_axis_angle((*frame.rotate(axes[0]), positions[0]))
    else:
        R = m3.IDENTITY
        for axis, p in zip(axes, positions, strict=False):
            R = m3.mat_mul(R, m3.rot_axis_angle((*m3.normalized(frame.rotate(axis)), p)))
    pivot = frame.apply(anchor)
    return Pose(R, m3.sub(pivot, m3.mat_vec(R, pivot)))
