"""Supervisor handles on scene nodes and fields (``Node``, ``Field``, ``ContactPoint``).

Split from :mod:`dualtwin.webots.controller` (which re-exports these names) to keep each module to one
concept: the controller module owns stepping and devices, this one the scene tree a supervisor reads and
edits. Timing and edit semantics are described in :mod:`dualtwin.webots.controller`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

from dualtwin.webots import _math3 as m3
from dualtwin.webots.api_args import as_float, as_floats, as_int, finite, warn
from dualtwin.webots.contacts import contact_points, solids_of, static_balance
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.physics import JointRec, Simulation, SolidRec


class NodeIndex(Protocol):
    """The runtime's numbering of scene nodes (Webots' unique node ids)."""

    def node_ids(self) -> tuple[dict[int, int], dict[int, SceneNode]]: ...


class SceneHost(Protocol):
    """What a node or field handle needs of the ``Supervisor`` that made it. A Protocol, so this module never
    imports :mod:`.controller` (which imports it)."""

    @property
    def _sim(self) -> Simulation: ...

    @property
    def _runtime(self) -> NodeIndex: ...

    def getFromId(self, id: Any) -> Node | None: ...  # noqa: A002, N802 - Webots' names

__all__ = ["ContactPoint", "Field", "Node", "NodeIndex", "SceneHost", "descendants", "find_def", "path_to"]

_warn = warn
_finite = finite


def descendants(node: SceneNode) -> list[SceneNode]:
    out: list[SceneNode] = []
    for value in node.fields.values():
        if isinstance(value, SceneNode):
            out.append(value)
        elif isinstance(value, list):
            out.extend(v for v in value if isinstance(v, SceneNode))
    return out


def find_def(node: SceneNode, name: str) -> SceneNode | None:
    # PROTO-internal DEFs live in ``proto_def_name`` and are not visible (getFromProtoDef in Webots)
    if node.def_name == name:
        return node
    for child in descendants(node):
        found = find_def(child, name)
        if found is not None:
            return found
    return None


class Node:
    """Supervisor handle on a scene node."""

    def __init__(self, supervisor: SceneHost, node: SceneNode) -> None:
        self._sup = supervisor
        self._sim: Simulation = supervisor._sim
        self._node = node
        self._is_root = False

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Node) and other._node is self._node

    def __hash__(self) -> int:
        return id(self._node)

    @property
    def scene_node(self) -> SceneNode:
        return self._node

    def getDef(self) -> str:
        return self._node.def_name or ""

    def getTypeName(self) -> str:
        return self._node.proto_name or self._node.type_name

    def getBaseTypeName(self) -> str:
        return self._node.type_name

    def _solid(self) -> SolidRec | None:
        return self._sim.solid_for(self._node)

    def _world_pose(self) -> m3.Pose:
        solid = self._solid()
        if solid is not None:
            return self._sim.solid_world_pose(solid)
        chain = path_to(self._sim, self._node)
        if chain is None:
            return m3.Pose()
        pose = m3.Pose()
        for n in chain:
            s = self._sim.solid_for(n)
            if s is not None:
                pose = self._sim.solid_world_pose(s)
            elif "translation" in n.fields and "rotation" in n.fields:
                pose = pose * m3.Pose.from_fields(n.fields.get("translation"), n.fields.get("rotation"))
        return pose

    def getPosition(self) -> list[float]:
        return list(self._world_pose().t)

    def getOrientation(self) -> list[float]:
        return list(self._world_pose().R)

    def getPose(self, fromNode: Node | None = None) -> list[float]:
        pose = self._world_pose()
        if fromNode is not None:
            pose = fromNode._world_pose().inverse() * pose
        R, t = pose.R, pose.t
        return [R[0], R[1], R[2], t[0], R[3], R[4], R[5], t[1], R[6], R[7], R[8], t[2], 0.0, 0.0, 0.0, 1.0]

    def getVelocity(self) -> list[float]:
        solid = self._solid()
        return list(self._sim.solid_velocity(solid)) if solid is not None else [0.0] * 6

    def setVelocity(self, velocity: Sequence[float]) -> None:
        solid = self._solid()
        values = as_floats(velocity, "Node.setVelocity")
        if len(values) != 6 or not _finite(*values):
            _warn("Node.setVelocity() needs 6 finite values")
            return
        if solid is not None:
            self._sim.set_body_velocity(solid, values)

    def getCenterOfMass(self) -> list[float]:
        solid = self._solid()
        return list(self._sim.center_of_mass(solid)) if solid is not None else self.getPosition()

    def resetPhysics(self) -> None:
        solid = self._solid()
        if solid is not None:
            self._sim.reset_physics(solid)

    def _push(self, method: str, vector: Any, relative: Any, torque: bool) -> None:
        """Add a force or torque to the Solid's body for the next basic step only (ODE clears it after)."""
        values = as_floats(vector, method)
        if len(values) != 3 or not _finite(*values):
            _warn(f"{method}() needs 3 finite values")
            return
        solid = self._solid()
        if solid is None or solid.body is None:
            _warn(f"{method}() called on a node without physics: ignored")
            return
        if relative:
            values = list(m3.mat_vec(self._sim.solid_world_pose(solid).R, values))
        lib = self._sim._lib
        (lib.dBodyAddTorque if torque else lib.dBodyAddForce)(solid.body.ptr, *values)
        lib.dBodyEnable(solid.body.ptr)

    def addForce(self, force: Sequence[float], relative: bool) -> None:
        """A force at the centre of mass, in world axes (or the Solid's with ``relative``), for one step."""
        self._push("Node.addForce", force, relative, torque=False)

    def addTorque(self, torque: Sequence[float], relative: bool) -> None:
        """A torque on the body, in world axes (or the Solid's with ``relative``), for one step."""
        self._push("Node.addTorque", torque, relative, torque=True)

    def getField(self, fieldName: str) -> Field | None:
        if fieldName not in self._node.fields:
            return None
        return Field(self, fieldName)

    def getParentNode(self) -> Node | None:
        chain = path_to(self._sim, self._node)
        if not chain or len(chain) < 2:
            return None
        return Node(self._sup, chain[-2])

    def getId(self) -> int:
        """Unique id: 0 for the root, then the scene tree's nodes in pre-order (stable for a world)."""
        if self._is_root:
            return 0
        return self._sup._runtime.node_ids()[0].get(id(self._node), -1)

    # -- contacts (computed on demand, see dualtwin.webots.contacts)

    def _contact_solids(self, include_descendants: bool) -> list[SolidRec]:
        solid = self._solid()
        return solids_of(self._sim, solid, bool(include_descendants)) if solid is not None else []

    def getContactPoints(self, includeDescendants: bool = False) -> list[ContactPoint]:
        """Contact points of this Solid (and its descendants) from the last step, in world coordinates."""
        ids = self._sup._runtime.node_ids()[0]
        return [
            ContactPoint(list(c.point), ids.get(id(c.solid.node), -1))
            for c in contact_points(self._sim, self._contact_solids(includeDescendants))
        ]

    def getNumberOfContactPoints(self, includeDescendants: bool = False) -> int:
        return len(contact_points(self._sim, self._contact_solids(includeDescendants)))

    def getContactPoint(self, index: Any) -> list[float]:
        points = self.getContactPoints(True)
        i = as_int(index, "Node.getContactPoint")
        return list(points[i].point) if 0 <= i < len(points) else [math.nan] * 3

    def getContactPointNode(self, index: Any) -> Node | None:
        points = self.getContactPoints(True)
        i = as_int(index, "Node.getContactPointNode")
        return self._sup.getFromId(points[i].node_id) if 0 <= i < len(points) else None

    def enableContactPointsTracking(self, samplingPeriod: Any, includeDescendants: bool = False) -> None:
        as_int(samplingPeriod, "Node.enableContactPointsTracking")  # queries always read the last step

    def disableContactPointsTracking(self) -> None:
        pass

    def getStaticBalance(self) -> bool:
        """Whether the centre of mass projects (along gravity) inside the support polygon of the contacts."""
        solids = self._contact_solids(True)
        return static_balance(self._sim, solids, contact_points(self._sim, solids)) if solids else False


class ContactPoint:
    """One contact: ``point`` (world coordinates) and ``node_id`` (the touching Solid of the queried tree)."""

    def __init__(self, point: list[float], node_id: int) -> None:
        self.point = point
        self.node_id = node_id

    def getPoint(self) -> list[float]:
        return list(self.point)

    def getNodeId(self) -> int:
        return self.node_id

    def __repr__(self) -> str:
        return f"ContactPoint(point={self.point}, node_id={self.node_id})"


def path_to(sim: Simulation, target: SceneNode) -> list[SceneNode] | None:
    """Nodes from a top-level node down to ``target`` (inclusive)."""

    def search(node: SceneNode, path: list[SceneNode]) -> list[SceneNode] | None:
        path.append(node)
        if node is target:
            return path
        for child in descendants(node):
            found = search(child, path)
            if found is not None:
                return found
        path.pop()
        return None

    for top in sim.world.nodes:
        found = search(top, [])
        if found is not None:
            return found
    return None


class Field:
    """Supervisor handle on one field of a scene node."""

    def __init__(self, owner: Node, name: str) -> None:
        self._owner = owner
        self._sim = owner._sim
        self._name = name

    def getName(self) -> str:
        return self._name

    @property
    def _node(self) -> SceneNode:
        return self._owner._node

    def _raw(self) -> Any:
        return self._node.fields.get(self._name)

    def _joint(self) -> JointRec | None:
        return self._sim.joint_for(self._node) if self._name == "position" else None

    def getCount(self) -> int:
        value = self._raw()
        return len(value) if isinstance(value, list) else -1

    # -- SF getters

    def getSFFloat(self) -> float:
        joint = self._joint()
        if joint is not None:
            params = joint.params
            index = params.index(self._node) if self._node in params else 0
            return float(joint.positions[index])
        return float(self._raw())

    def getSFInt32(self) -> int:
        return int(self._raw())

    def getSFBool(self) -> bool:
        return bool(self._raw())

    def getSFString(self) -> str:
        return str(self._raw())

    def getSFVec2f(self) -> list[float]:
        return [float(v) for v in self._raw()]

    def getSFColor(self) -> list[float]:
        return [float(v) for v in self._raw()]

    def getSFVec3f(self) -> list[float]:
        solid = self._sim.solid_for(self._node)
        if solid is not None and self._name == "translation" and not self._sim.has_pending(solid):
            return list(self._sim.solid_local_pose(solid).t)
        return [float(v) for v in self._raw()]

    def getSFRotation(self) -> list[float]:
        solid = self._sim.solid_for(self._node)
        if solid is not None and self._name == "rotation" and not self._sim.has_pending(solid):
            return list(m3.axis_angle_from_mat(self._sim.solid_local_pose(solid).R))
        return [float(v) for v in self._raw()]

    def getSFNode(self) -> Node | None:
        value = self._raw()
        return Node(self._owner._sup, value) if isinstance(value, SceneNode) else None

    def getMFNode(self, index: int) -> Node | None:
        value = self._raw()
        if not isinstance(value, list) or not -len(value) <= index < len(value):
            return None
        item = value[index]
        return Node(self._owner._sup, item) if isinstance(item, SceneNode) else None

    def getMFFloat(self, index: int) -> float:
        return float(self._raw()[index])

    def getMFString(self, index: int) -> str:
        return str(self._raw()[index])

    # -- SF setters

    def setSFFloat(self, value: Any) -> None:
        value = as_float(value, "Field.setSFFloat")
        if not _finite(value):
            _warn(f"Field.setSFFloat() called with NaN on '{self._name}'")
            return
        joint = self._joint()
        if joint is not None:
            params = joint.params
            index = params.index(self._node) if self._node in params else 0
            self._node.fields["position"] = float(value)
            self._sim.queue_set_joint_position(joint, index, float(value))
            return
        self._node.fields[self._name] = float(value)
        self._sim.field_changed(self._node, self._name)

    def setSFInt32(self, value: Any) -> None:
        self._node.fields[self._name] = as_int(value, "Field.setSFInt32")

    def setSFBool(self, value: bool) -> None:
        self._node.fields[self._name] = bool(value)

    def setSFString(self, value: str) -> None:
        self._node.fields[self._name] = str(value)

    def setMFFloat(self, index: Any, value: Any) -> None:
        index = as_int(index, "Field.setMFFloat")
        value = as_float(value, "Field.setMFFloat")
        if not _finite(value):
            _warn(f"Field.setMFFloat() called with NaN on '{self._name}'")
            return
        values = list(self._raw() or [])
        values[index] = float(value)
        self._node.fields[self._name] = values
        self._sim.field_changed(self._node, self._name)

    def setSFVec3f(self, values: Sequence[float]) -> None:
        values = as_floats(values, "Field.setSFVec3f")
        if len(values) != 3 or not _finite(*values):
            _warn(f"Field.setSFVec3f() needs 3 finite values on '{self._name}'")
            return
        vec = tuple(float(v) for v in values)
        solid = self._sim.solid_for(self._node)
        if solid is not None and self._name == "translation":
            self._sim.queue_set_pose(solid, vec, None)
            self._node.fields[self._name] = vec
            return
        self._node.fields[self._name] = vec
        self._sim.field_changed(self._node, self._name)

    def setMFVec3f(self, index: Any, values: Sequence[float]) -> None:
        index = as_int(index, "Field.setMFVec3f")
        values = as_floats(values, "Field.setMFVec3f")
        items = list(self._raw() or [])
        if len(values) != 3 or not _finite(*values) or not -len(items) <= index < len(items):
            _warn(f"Field.setMFVec3f() needs 3 finite values and a valid index on '{self._name}'")
            return
        items[index] = tuple(float(v) for v in values)
        self._node.fields[self._name] = items
        self._sim.field_changed(self._node, self._name)

    def setSFRotation(self, values: Sequence[float]) -> None:
        values = as_floats(values, "Field.setSFRotation")
        if len(values) != 4 or not _finite(*values) or m3.norm(values[:3]) == 0.0:
            _warn(f"Field.setSFRotation() needs a non-zero axis and finite values on '{self._name}'")
            return
        rot = tuple(float(v) for v in values)
        solid = self._sim.solid_for(self._node)
        if solid is not None and self._name == "rotation":
            self._sim.queue_set_pose(solid, None, rot)
        self._node.fields[self._name] = rot
