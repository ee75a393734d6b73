"""A world's robots as the converter sees them: where each one is, which one is converted, and what becomes of the
others.

Where: Webots accepts a Robot inside top-level grouping nodes (Group, Pose, Transform, nested in each other), and so
does the Webots twin (it finds every Robot in the scene tree). Such a robot's world pose is the product of its
ancestors' frames (on-ODE §3.1: "World pose = product of ancestor matrices"), a Transform's uniform ``scale``
scaling what lies below it, as the converter scales the environment's Solids below a Transform. Before, only
top-level Robots were found: a world whose robot sat in a Group had "no robot".

The others: every Robot but the converted one is a Solid tree with its own controller. The Webots twin drives the
chosen robot only; the others' controllers do not run there, so their motors keep Webots' initial state, a position
servo holding the joint's initial position (on-ODE §5.1), and their bodies collide with everything else. They used
to be skipped, collision geometry included, so the converted model lacked obstacles the Webots twin has. Now each
becomes bodies as the chosen robot's do (a free root with Physics, a root welded to the world without; joints as
joints), and its motors MuJoCo actuators under the same Webots motor law (:mod:`dualtwin.twins.mujoco`), which hold
their initial position while nothing commands them. Their names start with the robot's label and ``/`` and they are
left out of the conversion's joints, motors and sensors, so the binding exposes the chosen robot's devices only.
Their sensors and other devices (cameras, lights, emitters...) are not converted: no controller reads them. The
model then names the converted robot's root body (:data:`dualtwin.twins.mujoco_state.ROBOT_TEXT`), so that the MuJoCo
twin's state holds that robot's joints only, as the Webots twin's does (its robot's joints and the world's top-level
DEF bodies): a state passes between the twins.

Contacts follow on-ODE §2.3 rule 4: the parts of one robot touch each other only with ``selfCollision``. Each other
robot gets a collision bit of its own that its geoms' ``conaffinity`` leaves out unless it has ``selfCollision``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from dualtwin.convert.conversion import ConversionError
from dualtwin.convert.mass import FloatArray
from dualtwin.convert.scales import transform_scale
from dualtwin.geometry import axis_angle_matrix
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.schema import JOINT_TYPES

__all__ = ["GROUPING", "OTHER_ROBOT_BITS", "OtherRobot", "environment_joints", "find_robots", "other_robot_notes",
           "pose_matrix", "robot_frame", "robot_label", "scenery_bodies", "select_robot"]

#: The nodes that group others without being a body: a Robot below them is still a robot of the world.
GROUPING = ("Group", "Pose", "Transform")
#: Collision bits: the environment's is 1, the converted robot's 2; each other robot one of the next ones, up to
#: MuJoCo's 32-bit ``contype`` less its sign bit.
_FIRST_OTHER_BIT = 2
OTHER_ROBOT_BITS = 31 - _FIRST_OTHER_BIT


def pose_matrix(node: Node, scale: float | FloatArray = 1.0) -> FloatArray:
    """The 4x4 frame of a Pose-derived node in its parent, its translation scaled by the ancestors' ``scale``."""
    T = np.eye(4)
    T[:3, :3] = axis_angle_matrix(node.get("rotation", (0.0, 0.0, 1.0, 0.0)))
    T[:3, 3] = np.asarray(node.get("translation", (0.0, 0.0, 0.0)), dtype=float) * scale
    return T


def _placed_robots(nodes: list[Node], ancestors: tuple[Node, ...] = ()) -> Iterator[tuple[Node, tuple[Node, ...]]]:
    """Each Robot at the top or below grouping nodes only, in file order, with its grouping ancestors."""
    for node in nodes:
        if node.type_name == "Robot":
            yield node, ancestors
        elif node.type_name in GROUPING:
            yield from _placed_robots(node.children(), (*ancestors, node))


def find_robots(world: World) -> list[Node]:
    """The world's Robot nodes (PROTO instances included, they are expanded to Robot), at the top or below Group, Pose
    and Transform nodes. A Robot inside a Solid or another Robot is part of that body (converted as a Solid)."""
    return [robot for robot, _ in _placed_robots(world.nodes)]


def robot_frame(world: World, robot: Node) -> tuple[FloatArray, float | FloatArray]:
    """``robot``'s frame in the world and the scale its ancestors' Transforms give it (1 for none; a non-uniform one
    acts as its largest factor, :func:`dualtwin.convert.scales.transform_scale`, whose warning the environment's walk
    of the same Transforms gives)."""
    for node, ancestors in _placed_robots(world.nodes):
        if node is robot:
            T: FloatArray = np.eye(4)
            scale: float | FloatArray = 1.0
            for parent in ancestors:  # as the converter's environment walk composes them
                if parent.type_name != "Group":
                    T = T @ pose_matrix(parent, scale)
                if parent.type_name == "Transform":
                    scale = scale * transform_scale(parent)
            return T @ pose_matrix(robot, scale), scale
    return pose_matrix(robot), 1.0


def robot_label(node: Node) -> str:
    """How the binding and the messages name a robot: its DEF, else its ``name``."""
    return node.def_name or str(node.get("name"))


def select_robot(world: World, robot: str | None, origin: str) -> tuple[Node, str]:
    """The Robot node chosen by DEF or ``name`` (or the only one), and the label the binding uses for it."""
    robots = find_robots(world)
    if not robots:
        raise ConversionError(f"{origin}: world has no robot (no Robot node at the top or in a Group, Pose or "
                              "Transform)")
    if robot is None:
        if len(robots) > 1:
            names = ", ".join(robot_label(r) for r in robots)
            raise ConversionError(f"{origin}: world has {len(robots)} robots ({names}); choose one with --robot")
        return robots[0], robot_label(robots[0])
    for node in robots:
        if node.def_name == robot or node.proto_name == robot:
            return node, robot_label(node)
    for node in robots:
        if str(node.get("name")) == robot:
            return node, robot_label(node)
    names = ", ".join(robot_label(r) for r in robots)
    raise ConversionError(f"{origin}: no robot with DEF or name {robot!r} (robots: {names})")


@dataclass(frozen=True)
class OtherRobot:
    """A robot of the world that is not the converted one, as the converter writes it."""

    node: Node
    frame: FloatArray  # in the world
    scale: float | FloatArray
    label: str
    contype: int
    conaffinity: int
    #: The name its geoms share so that contact pairs are never written between them ("" with selfCollision).
    group: str

    @staticmethod
    def place(node: Node, frame: FloatArray, scale: float | FloatArray, index: int, count: int) -> OtherRobot:
        """The ``index``-th of ``count`` other robots: its own collision bit (the last one shared by those past
        :data:`OTHER_ROBOT_BITS`, whose parts then touch each other)."""
        label = robot_label(node) or f"robot{index + 1}"
        bit = 1 << (_FIRST_OTHER_BIT + min(index, OTHER_ROBOT_BITS - 1))
        every = 3 | sum(1 << (_FIRST_OTHER_BIT + k) for k in range(min(count, OTHER_ROBOT_BITS)))
        shared = count > OTHER_ROBOT_BITS and index >= OTHER_ROBOT_BITS - 1
        apart = not bool(node.get("selfCollision", False)) and not shared
        return OtherRobot(node, frame, scale, label, bit, every & ~bit if apart else every, label if apart else "")


def other_robot_notes(other: OtherRobot, chosen: str) -> list[str]:
    """What the conversion of a robot that is not the converted one leaves out (the module docstring)."""
    notes = [f"robot {other.label!r} is not the converted robot: its bodies, joints and motors are converted (named "
             f"'{other.label}/<motor>'; its motors hold their initial positions, as Webots' do while no controller "
             "moves them: on-ODE §5.1), not its controller, sensors or other devices; the binding exposes robot "
             f"{chosen!r} only"]
    if not other.group and not other.node.get("selfCollision", False):
        notes.append(f"robot {other.label!r}: more robots than MuJoCo's {OTHER_ROBOT_BITS + 2} collision bits; its "
                     "parts touch each other as with selfCollision")
    return notes


def scenery_bodies(spec: Any, bodies: list[tuple[str, Node]], world: World, robot: Node) -> list[str]:
    """The free bodies built from ``bodies`` ((body, Solid)) that the Webots twin's state leaves out: it holds the
    converted ``robot`` and the world's top-level Solids with a DEF (and a body) only, so a loose Solid without a
    DEF, or one below a top-level Group or Pose (another robot too), is scenery; the MuJoCo twin's state leaves the
    bodies :data:`dualtwin.twins.mujoco_state.SCENERY_TEXT` lists out as well, and a state passes between the twins
    (before, such a body was state in MuJoCo only, and the Webots twin refused the MuJoCo twin's state)."""
    free = {b.name for b in spec.bodies if any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in b.joints)}
    named_top = {id(n) for n in world.nodes if n.def_name}
    return [name for name, solid in bodies if name in free and solid is not robot and id(solid) not in named_top]


def environment_joints(world: World, robot: Node | None) -> bool:
    """Whether the world has joints outside the converted ``robot`` (another robot's, a door hinged to a wall...): the
    Webots twin's state holds the robot's joints only, so the model then names the robot's root body
    (:data:`dualtwin.twins.mujoco_state.ROBOT_TEXT`) and the MuJoCo twin's state leaves the others out as well."""
    mine = {id(n) for n in robot.walk()} if robot is not None else set()
    return any(n.type_name in JOINT_TYPES and id(n) not in mine for top in world.nodes for n in top.walk())
