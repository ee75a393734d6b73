"""Supervisor handles on scene nodes (``Node``, ``ContactPoint``; ``Field`` is in :mod:`.field_api`).

Split from :mod:`dualtwin.webots.controller` (which re-exports these names) to keep each module to one
concept: the controller module owns stepping and devices, this one the scene tree a supervisor reads and
edits. Timing and edit semantics are described in :mod:`dualtwin.webots.controller`.
"""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Sequence
from typing import Any, Protocol

from dualtwin.webots import _math3 as m3
from dualtwin.webots.api_args import as_float, as_floats, as_int, as_text, finite, warn
from dualtwin.webots.contacts import contact_points, solids_of, static_balance
from dualtwin.webots.field_api import Field, parse_nodes
from dualtwin.webots.node_states import load_state, save_state
from dualtwin.webots.node_types import node_type_of
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.nodes import World, copy_value, path_to_node
from dualtwin.webots.physics import Simulation, SolidRec
from dualtwin.webots.physics.records import RobotRec, is_robot
from dualtwin.webots.proto_links import linked_fields
from dualtwin.webots.proto_regeneration import join_physics, regenerate
from dualtwin.webots.protos import saved_hidden
from dualtwin.webots.solid_scale import scaled_local
from dualtwin.webots.step_hints import step_value
from dualtwin.webots.writer import write_node


class NodeIndex(Protocol):
    """The runtime's numbering of scene nodes (Webots' unique node ids), and the controllers of the robots a
    supervisor imports or removes."""

    def node_ids(self) -> tuple[dict[int, int], dict[int, SceneNode]]: ...

    def start_controllers(self, robots: list[SceneNode]) -> None: ...

    def end_controllers(self, top: SceneNode, *, advance: bool = True) -> None: ...

    def restart_controller(self, robot_node: SceneNode) -> None: ...


class SceneHost(Protocol):
    """What a node or field handle needs of the ``Supervisor`` that made it. A Protocol, so this module never
    imports :mod:`.controller` (which imports it)."""

    @property
    def _sim(self) -> Simulation: ...

    @property
    def _runtime(self) -> NodeIndex: ...

    @property
    def _rec(self) -> RobotRec: ...

    def getFromId(self, id: Any) -> Node | None: ...  # noqa: A002, N802 - Webots' names

__all__ = ["ContactPoint", "Field", "Node", "NodeIndex", "SceneHost", "descendants", "find_def", "path_to",
           "world_as_saved"]

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


def _forget_imported(sim: Simulation) -> None:
    """simulationReset removes the nodes a supervisor added, from the tree and from the physics (fields inside
    nodes are restored by the reset); nodes a supervisor removed stay removed, as the reset does not reload."""
    imported = sim.extensions.get("imported_nodes", [])
    for node in imported:
        sim.remove_nodes(node)
    sim.world.nodes[:] = [n for n in sim.world.nodes if not any(n is i for i in imported)]
    imported.clear()
    removed = sim.extensions.get("removed_nodes", [])
    for node in removed:
        _detach(sim, node)


def _detach(sim: Simulation, node: SceneNode) -> None:
    """Take ``node`` out of the scene tree (wherever it is)."""
    chain = path_to(sim, node)
    if chain is None:
        return
    if len(chain) == 1:
        sim.world.nodes[:] = [n for n in sim.world.nodes if n is not node]
        return
    parent = chain[-2]
    for key, value in parent.fields.items():
        if value is node:
            parent.fields[key] = None
            _unbind_parameter(chain[:-1], parent, key, None)
        elif isinstance(value, list) and any(v is node for v in value):
            at = next(i for i, v in enumerate(value) if v is node)
            value[:] = [v for v in value if v is not node]
            _unbind_parameter(chain[:-1], parent, key, at)


def _unbind_parameter(ancestors: list[SceneNode], parent: SceneNode, key: str, at: int | None) -> None:
    """A node removed from a field that a PROTO instance's node-valued interface field feeds through ``IS`` is a
    copy of one of its parameters (§7.1): the parameter goes too, so the interface field counts what the scene
    holds."""
    for root in ancestors:
        for name in list(root.proto_fields or {}):
            base, _ = linked_fields(root, name)
            if any(node is parent and field == key for node, field in base):
                assert root.proto_fields is not None
                items = root.proto_fields[name]
                if at is None:
                    root.proto_fields[name] = None
                elif isinstance(items, list) and 0 <= at < len(items):
                    items.pop(at)


def _scene_edits(sim: Simulation) -> list[Any]:
    """The per-simulation lists of imported and removed nodes, with the reset hook that acts on them."""
    if "imported_nodes" not in sim.extensions:
        sim.extensions["imported_nodes"] = []
        sim.extensions["removed_nodes"] = []
        sim.reset_hooks.append(functools.partial(_forget_imported, sim))
    return [sim.extensions["imported_nodes"], sim.extensions["removed_nodes"]]


class Node:
    """Webots ``Node``: a supervisor's handle on a scene node (from ``getFromDef``, ``getRoot``, fields...).

    PROTO instances are expanded in the scene tree: ``getField`` answers the PROTO's interface fields (kept on the
    expanded root) and ``getProtoField`` the fields of its base node, as Webots' R2023b does. Headless answers:
    ``moveViewpoint`` and ``setVisibility`` have no 3D view to act on (no effect); pose and contact tracking are not
    needed (every read is current). ``addTorque`` and ``addForceWithOffset`` do what Webots documents (a torque; a
    force at the offset), not what its 2023-24 Python wrapper does (both call the C force function).
    """

    # Webots' node-type numbers (dualtwin.webots.node_types.NODE_TYPE_CONSTANTS; a test holds them equal)
    NO_NODE, APPEARANCE, BACKGROUND, BILLBOARD, BOX, CAD_SHAPE = 0, 1, 2, 3, 4, 5
    CAPSULE, COLOR, CONE, COORDINATE, CYLINDER, DIRECTIONAL_LIGHT = 6, 7, 8, 9, 10, 11
    ELEVATION_GRID, FOG, GROUP, IMAGE_TEXTURE, INDEXED_FACE_SET, INDEXED_LINE_SET = 12, 13, 14, 15, 16, 17
    MATERIAL, MESH, MUSCLE, NORMAL, PBR_APPEARANCE, PLANE = 18, 19, 20, 21, 22, 23
    POINT_LIGHT, POINT_SET, SHAPE, SPHERE, SPOT_LIGHT, TEXTURE_COORDINATE = 24, 25, 27, 28, 29, 30
    TEXTURE_TRANSFORM, TRANSFORM, VIEWPOINT, ROBOT, ACCELEROMETER, ALTIMETER = 31, 32, 33, 34, 35, 36
    BRAKE, CAMERA, COMPASS, CONNECTOR, DISPLAY, DISTANCE_SENSOR = 37, 38, 39, 40, 41, 42
    EMITTER, GPS, GYRO, INERTIAL_UNIT, LED, LIDAR = 43, 44, 45, 46, 47, 48
    LIGHT_SENSOR, LINEAR_MOTOR, PEN, POSITION_SENSOR, RADAR, RANGE_FINDER = 49, 50, 51, 52, 54, 55
    RECEIVER, ROTATIONAL_MOTOR, SKIN, SPEAKER, TOUCH_SENSOR, VACUUM_GRIPPER = 56, 57, 58, 59, 60, 61
    BALL_JOINT, BALL_JOINT_PARAMETERS, CHARGER, CONTACT_PROPERTIES, DAMPING, FLUID = 62, 63, 64, 65, 66, 67
    FOCUS, HINGE_JOINT, HINGE_JOINT_PARAMETERS, HINGE_2_JOINT, IMMERSION_PROPERTIES, JOINT_PARAMETERS = 68, 69, 70, 71, 72, 73
    LENS, LENS_FLARE, PHYSICS, RECOGNITION, SLIDER_JOINT, SLOT = 74, 75, 76, 77, 78, 79
    SOLID, SOLID_REFERENCE, TRACK, TRACK_WHEEL, WORLD_INFO, ZOOM = 80, 81, 82, 83, 84, 85
    MICROPHONE, RADIO = 86, 87

    def __init__(self, supervisor: SceneHost, node: SceneNode) -> None:
        self._sup = supervisor
        self._sim: Simulation = supervisor._sim
        self._node = node
        self._is_root = False

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Node) and other._node is self._node

    def __hash__(self) -> int:
        return id(self._node)

    def __repr__(self) -> str:
        return f"<Node {self.getTypeName()} {self.getDef()!r}>"

    @property
    def scene_node(self) -> SceneNode:
        """The scene-tree node behind this handle (a dualtwin extension)."""
        return self._node

    # -- identity

    def getDef(self) -> str:
        return self._node.def_name or ""

    def getTypeName(self) -> str:
        return self._node.proto_name or self._node.type_name

    def getBaseTypeName(self) -> str:
        return self._node.type_name

    def getType(self) -> int:
        return node_type_of(self._node.type_name)

    def isProto(self) -> bool:
        return self._node.proto_name is not None

    def getId(self) -> int:
        """Unique id: 0 for the root, then the scene tree's nodes in pre-order, then imported nodes."""
        if self._is_root:
            return 0
        return self._sup._runtime.node_ids()[0].get(id(self._node), -1)

    def getParentNode(self) -> Node | None:
        if self._is_root:
            return None
        chain = path_to(self._sim, self._node)
        if chain is None:
            return None
        if len(chain) < 2:
            return self._sup.getFromId(0)  # a top-level node's parent is the root
        return Node(self._sup, chain[-2])

    def getFromProtoDef(self, DEF: str) -> Node | None:  # noqa: N803 - Webots' parameter name
        """The node DEF'd ``DEF`` inside this PROTO instance's own body."""
        as_text(DEF, "Node.getFromProtoDef")
        if not self.isProto():
            return None
        found = next((n for n in self._node.walk() if n.proto_def_name == DEF), None)
        return Node(self._sup, found) if found is not None else None

    def exportString(self) -> str:
        """The node as Webots writes it (a PROTO instance as its name and interface fields), with its current
        pose: text that ``importMFNodeFromString`` turns into a copy."""
        return write_node(node_as_saved(self._sim, self._node), protos=True)

    DEF = property(lambda self: self.getDef())
    id = property(lambda self: self.getId())
    type = property(lambda self: self.getType())
    type_name = property(lambda self: self.getTypeName())
    base_type_name = property(lambda self: self.getBaseTypeName())
    number_of_fields = property(lambda self: self.getNumberOfFields())

    # -- fields

    def _interface(self) -> dict[str, Any]:
        """The visible fields: a PROTO instance's interface, else the base node's fields."""
        return self._node.proto_fields if self._node.proto_fields is not None else self._node.fields

    def getField(self, name: str) -> Field | None:
        as_text(name, "Node.getField")
        values = self._interface()
        if name not in values:
            return None
        return Field(self, name, None if values is self._node.fields else values)

    def getFieldByIndex(self, index: Any) -> Field | None:
        names = list(self._interface())
        i = as_int(index, "Node.getFieldByIndex")
        return self.getField(names[i]) if 0 <= i < len(names) else None

    def getNumberOfFields(self) -> int:
        return len(self._interface())

    def getProtoField(self, name: str) -> Field | None:
        """A field of the base node a PROTO instance expands to (None for a non-PROTO node)."""
        as_text(name, "Node.getProtoField")
        if not self.isProto() or name not in self._node.fields:
            return None
        return Field(self, name)

    def getProtoFieldByIndex(self, index: Any) -> Field | None:
        names = list(self._node.fields)
        i = as_int(index, "Node.getProtoFieldByIndex")
        return self.getProtoField(names[i]) if self.isProto() and 0 <= i < len(names) else None

    # -- tree edits (called by Field)

    def _handle(self, node: SceneNode) -> Node:
        return Node(self._sup, node)

    def _imported(self, nodes: list[SceneNode]) -> None:
        """Number the new nodes and build their physics (Solids fall, collide, are seen by rays from the next
        step), as Webots does for an imported node."""
        self._number(nodes)
        imported, _ = _scene_edits(self._sim)
        imported.extend(nodes)
        outside = [where for top in nodes if (where := join_physics(self._sim, top)) is not None]
        robots = [n for top in nodes for n in top.walk() if is_robot(n)]
        if robots:
            self._sup._runtime.start_controllers(robots)
        if outside:
            # (a joint's endPoint joins the physics; a Slot with no joint, or a parent Solid outside the physics,
            # has no body to join)
            warn(f"a Solid imported under {outside[0]} is in the scene tree (read, saved) but takes no part in the "
                 "physics: nothing there for it to join")

    def _number(self, nodes: list[SceneNode]) -> None:
        """Give the nodes of these subtrees that have none a unique id (after the existing ones)."""
        ids, by_id = self._sup._runtime.node_ids()
        for top in nodes:
            for node in top.walk():
                if id(node) not in ids:
                    ids[id(node)] = max(by_id, default=0) + 1
                    by_id[ids[id(node)]] = node

    def _regenerate(self, node: SceneNode) -> bool:
        """Expand a procedural PROTO instance again after a field its template reads changed
        (:mod:`.proto_regeneration`); False when it is not done (an instance in or holding a Robot)."""
        text = write_node(node_as_saved(self._sim, node, state=False), protos=True)
        try:
            return regenerate(self._sim, node, text, lambda t: parse_nodes(self._sim, t), self._number)
        except Exception as exc:  # noqa: BLE001 - the template failed on the new value: Webots keeps the node
            warn(f"PROTO {node.proto_name} could not be regenerated: {exc}")
            return True

    def _removed(self, node: SceneNode, advance: bool = True) -> None:
        """Take the Solids of a removed subtree out of the physics (no collision, no ray hit, no joint)."""
        _, removed = _scene_edits(self._sim)
        imported = self._sim.extensions["imported_nodes"]
        if not any(node is n for n in imported):
            removed.append(node)
        self._sim.remove_nodes(node)
        self._sup._runtime.end_controllers(node, advance=advance)

    def remove(self) -> None:
        """Delete this node from the scene tree (and its Solids from the physics). A supervisor removing its own
        Robot (or a node holding it) removes it at the end of the step, as Webots does (api.md: self-removal)."""
        if self._is_root:
            warn("Node.remove(): the root node cannot be removed")
            return
        if path_to(self._sim, self._node) is None:
            return
        own = self._sup._rec.node
        if any(n is own for n in self._node.walk()):
            pending = self._sim.extensions.get("self_removals")
            if pending is None:  # one hook per simulation, registered between steps
                pending = self._sim.extensions["self_removals"] = []
                self._sim.step_hooks.append(functools.partial(self._remove_pending, pending))
            if not any(n is self._node for n in pending):
                pending.append(self._node)
            return
        _detach(self._sim, self._node)
        self._removed(self._node)

    def _remove_pending(self, pending: list[SceneNode]) -> None:
        """The step hook of a self-removal: at the end of the step, the nodes leave the tree and the physics and
        their controllers' step returns -1 (the simulation is advancing: nothing more is stepped from here)."""
        while pending:
            node = pending.pop(0)
            if path_to(self._sim, node) is not None:
                _detach(self._sim, node)
                self._removed(node, advance=False)

    # -- pose and physics

    def _solid(self) -> SolidRec | None:
        return self._sim.solid_for(self._node)

    def _world_pose(self) -> m3.Pose:
        solid = self._solid()
        if solid is not None:
            return self._sim.solid_world_pose(solid)
        chain = path_to(self._sim, self._node)
        if chain is None:  # removed from the scene: Webots answers NaNs for a handle on a deleted node
            warn("Node: this node is no longer in the scene (removed); its pose reads NaN")
            nan = math.nan
            return m3.Pose((nan,) * 9, (nan, nan, nan))
        pose, scale = m3.Pose(), 1.0
        for n in chain:
            s = self._sim.solid_for(n)
            if s is not None:
                pose, scale = self._sim.solid_world_pose(s), s.scale
            elif "translation" in n.fields and "rotation" in n.fields:
                # a frame below a scaled Transform: its translation scaled (solid_scale), its own scale applies below
                pose, scale = pose * scaled_local(n, scale), self._sim.factor_below(n, scale)
        return pose

    @step_value
    def getPosition(self) -> list[float]:
        return list(self._world_pose().t)

    @step_value
    def getOrientation(self) -> list[float]:
        return list(self._world_pose().R)

    def getPose(self, fromNode: Node | None = None) -> list[float]:
        pose = self._world_pose()
        if fromNode is not None:
            pose = fromNode._world_pose().inverse() * pose
        R, t = pose.R, pose.t
        return [R[0], R[1], R[2], t[0], R[3], R[4], R[5], t[1], R[6], R[7], R[8], t[2], 0.0, 0.0, 0.0, 1.0]

    def enablePoseTracking(self, samplingPeriod: Any, fromNode: Node | None = None) -> None:
        """Webots streams the pose every period; here every ``getPose`` is current, so nothing is needed."""
        as_int(samplingPeriod, "Node.enablePoseTracking")

    def disablePoseTracking(self, fromNode: Node | None = None) -> None:
        pass

    @step_value
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

    def setJointPosition(self, position: Any, index: Any = 1) -> None:
        """Teleport a joint node (axis ``index`` 1..3) to ``position``, as writing its parameters' position does."""
        joint = self._sim.joint_for(self._node)
        value = as_float(position, "Node.setJointPosition")
        axis = as_int(index, "Node.setJointPosition") - 1
        if joint is None or not 0 <= axis < len(joint.params) or not _finite(value):
            _warn("Node.setJointPosition() needs a joint node, a valid axis index and a finite position")
            return
        param = joint.params[axis]
        if param is not None:
            param.fields["position"] = value
        self._sim.queue_set_joint_position(joint, axis, value)

    def saveState(self, stateName: str) -> None:
        """Remember this subtree's fields and its Solids' poses and velocities under ``stateName`` (:mod:`.node_states`)."""
        save_state(self._sim, self._node, str(stateName))

    def loadState(self, stateName: str) -> None:
        """Restore a ``saveState`` snapshot (``'__init__'``: the state at load), its restored fields acting as written
        ones, poses and joints at the next step (:mod:`.node_states`)."""
        restored = load_state(self._sim, self._node, str(stateName))
        if restored is None:
            warn(f"Node.loadState(): no state named {stateName!r} was saved for this node")
        elif restored == "load":
            self.resetPhysics()

    def restartController(self) -> None:
        """End this Robot's controller and start the one its ``controller`` field names, at the next step (as
        Webots: time goes on, the new controller's devices start disabled). On another node: an error line."""
        if not is_robot(self._node):
            print("Error: wb_supervisor_node_restart_controller() can only be called on a Robot node.",
                  file=sys.stderr)
            return
        if path_to(self._sim, self._node) is None:
            return  # removed: it has no controller any more
        self._sup._runtime.restart_controller(self._node)

    def _controller_changed(self) -> None:
        """A supervisor gave this Robot another ``controller``: Webots restarts it with the new one."""
        self._sup._runtime.restart_controller(self._node)

    def moveViewpoint(self) -> None:
        """There is no 3D view headless: nothing to move."""

    def setVisibility(self, fromNode: Node, visible: bool) -> None:
        """Only cameras and viewpoints see visibility; headless cameras draw no nodes, so nothing changes."""
        if not isinstance(fromNode, Node):  # Webots' wrapper passes its node reference on (fromNode._ref)
            raise TypeError(f"Node.setVisibility() expects a Node, got {type(fromNode).__name__}")

    # -- forces

    def _push(self, method: str, vector: Any, relative: Any, torque: bool, offset: Any = None) -> None:
        """Add a force or torque to the Solid's body for the next basic step only (ODE clears it after)."""
        values = as_floats(vector, method)
        if len(values) != 3 or not _finite(*values):
            _warn(f"{method}() needs 3 finite values")
            return
        solid = self._solid()
        if solid is None or solid.body is None:
            _warn(f"{method}() called on a node without physics: ignored")
            return
        pose = self._sim.solid_world_pose(solid)
        if relative:
            values = list(m3.mat_vec(pose.R, values))
        lib = self._sim._lib
        if offset is not None:
            point = pose.apply(as_floats(offset, method))
            lib.dBodyAddForceAtPos(solid.body.ptr, *values, *point)
        else:
            (lib.dBodyAddTorque if torque else lib.dBodyAddForce)(solid.body.ptr, *values)
        lib.dBodyEnable(solid.body.ptr)

    def addForce(self, force: Sequence[float], relative: bool) -> None:
        """A force at the centre of mass, in world axes (or the Solid's with ``relative``), for one step."""
        self._push("Node.addForce", force, relative, torque=False)

    def addForceWithOffset(self, force: Sequence[float], offset: Sequence[float], relative: bool) -> None:
        """A force applied at ``offset`` (in the Solid's frame), world or Solid axes, for one step."""
        self._push("Node.addForceWithOffset", force, relative, torque=False, offset=offset)

    def addTorque(self, torque: Sequence[float], relative: bool) -> None:
        """A torque on the body, in world axes (or the Solid's with ``relative``), for one step."""
        self._push("Node.addTorque", torque, relative, torque=True)

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

    def disableContactPointsTracking(self, includeDescendants: bool = False) -> None:
        pass

    def getStaticBalance(self) -> bool:
        """Whether the centre of mass projects (along gravity) inside the support polygon of the contacts."""
        solids = self._contact_solids(True)
        return static_balance(self._sim, solids, contact_points(self._sim, solids)) if solids else False


class ContactPoint:
    """One contact: ``point`` (world coordinates) and ``node_id`` (the touching Solid of the queried tree)."""

    point: list[float]
    node_id: int

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
    return path_to_node(sim.world.nodes, target)


def world_as_saved(sim: Simulation) -> World:
    """A copy of the scene tree with every Solid's ``translation``/``rotation`` and every joint's ``position`` at
    their current values, as Webots writes them in ``worldSave`` (its fields follow the physics). A PROTO
    instance's own pose goes to the interface field it is ``IS``-linked to."""
    tops = [node_as_saved(sim, node) for node in sim.world.nodes]
    return World(sim.world.path, sim.world.header, tops, list(sim.world.externprotos),
                 list(sim.world.importable_externprotos))


def node_as_saved(sim: Simulation, top: SceneNode, state: bool = True) -> SceneNode:
    """A copy of ``top``'s subtree with its poses, velocities and joint positions as :func:`world_as_saved`
    writes them; a PROTO instance's internal state goes to its ``hidden`` fields, as Webots saves it. Without
    ``state``, only the poses that fields carry (a regenerated instance's geometry comes from its template)."""
    copy_top = top.copy()
    for original, copy in zip(top.walk(), copy_top.walk(), strict=True):
        solid = sim.solid_for(original)
        if solid is not None:
            pose = sim.solid_local_pose(solid)
            _save_field(copy, "translation", tuple(pose.t))
            _save_field(copy, "rotation", tuple(m3.axis_angle_from_mat(pose.R)))
            body = solid.body
            if state and body is not None and body.root is solid and not body.removed:
                velocity = sim.solid_velocity(solid)
                for name, value in (("linearVelocity", velocity[:3]), ("angularVelocity", velocity[3:])):
                    if any(v != 0.0 for v in value):  # a body at rest keeps the default (nothing written)
                        copy.fields[name] = tuple(float(v) for v in value)
        joint = sim.joint_for(original)
        if joint is not None and original.type_name.endswith("Parameters") and original in joint.params:
            _save_field(copy, "position", float(joint.positions[joint.params.index(original)]))
    for node in copy_top.walk():
        if node.proto_fields is not None:
            _bind_interface(node)
        if state and node.proto_name is not None and node.proto_fields is not None:
            node.hidden = {**node.hidden, **saved_hidden(node)}
    return copy_top


def _save_field(node: SceneNode, name: str, value: Any) -> None:
    if name in node.fields:
        node.fields[name] = value


def _bind_interface(root: SceneNode) -> None:
    """A PROTO instance's interface fields take the values of the fields ``IS`` binds them to (§7.1: one value),
    through nested and derived PROTOs: the values just saved from the physics (a derived PROTO's position is its
    outer field's) and what changed inside the instance (a robot's own setCustomData). A node-valued field takes
    the nodes the scene holds for its parameters (:meth:`Field._in_scene`: the ones the physics moves and
    supervisors edit), as saved."""
    assert root.proto_fields is not None
    for name in root.proto_fields:
        base, _ = linked_fields(root, name)
        bound = next((node.fields[field] for node, field in base if field in node.fields), None)
        if bound is not None:
            root.proto_fields[name] = copy_value(bound)
