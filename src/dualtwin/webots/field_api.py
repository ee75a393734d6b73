"""Webots' ``Field``: a supervisor's handle on one field of a scene node (every SF/MF getter and setter, MF
insert/remove, node import from VRML text).

Values are read from and written to the scene tree (:mod:`dualtwin.webots.nodes`); a write also tells the
simulation (``Simulation.field_changed``), which applies what ODE must follow (joint damping, masses, geometry...).
A Solid's ``translation``/``rotation`` and a joint's ``position`` are read from the running physics and written as
queued teleports, applied at the next step as in Webots.

Argument checks: the SF vector setters take a list of the right length, as Webots' (a tuple or NumPy array is refused
with Webots' error line). The scalar setters are more permissive than Webots' isinstance checks: a float where an int
is expected (and the reverse) goes through :mod:`.api_args`. A value of the wrong kind or length, or an index out of
range, prints an error on stderr and changes nothing, as in Webots.

Node handles (``getSFNode``, ``getMFNode``) are built by the owner handle's own class, so this module does not
import the Node class (which imports it).
"""

from __future__ import annotations

import math
import sys
from typing import Any, Protocol

from dualtwin.webots import _math3 as m3
from dualtwin.webots import schema
from dualtwin.webots.api_args import as_float, as_floats, as_int, warn
from dualtwin.webots.nodes import Node as SceneNode
from dualtwin.webots.nodes import copy_value
from dualtwin.webots.physics import JointRec, Simulation
from dualtwin.webots.physics.edits import UNRECORDED
from dualtwin.webots.physics.records import is_robot
from dualtwin.webots.proto_links import (
    feeds_template,
    insert_linked_nodes,
    linked_fields,
    remove_linked_nodes,
)

__all__ = ["FIELD_TYPES", "Field", "FieldOwner", "field_type_name", "parse_nodes"]

#: VRML type name -> Webots' field-type number (``Field.SF_BOOL``...)
FIELD_TYPES = {
    "SFBool": 1, "SFInt32": 2, "SFFloat": 3, "SFVec2f": 4, "SFVec3f": 5, "SFRotation": 6, "SFColor": 7,
    "SFString": 8, "SFNode": 9, "MFBool": 17, "MFInt32": 18, "MFFloat": 19, "MFVec2f": 20, "MFVec3f": 21,
    "MFRotation": 22, "MFColor": 23, "MFString": 24, "MFNode": 25,
}


class FieldOwner(Protocol):
    """What a field needs of the Node handle it belongs to."""

    _node: SceneNode
    _sim: Simulation
    _sup: Any

    def _imported(self, nodes: list[SceneNode]) -> None: ...

    def _number(self, nodes: list[SceneNode]) -> None: ...

    def _handle(self, node: SceneNode) -> Any: ...

    def _removed(self, node: SceneNode) -> None: ...

    def _regenerate(self, node: SceneNode) -> bool: ...

    def _controller_changed(self) -> None: ...


def _guess_type(value: Any) -> str:
    """The VRML type of a PROTO interface value (the scene tree keeps values, not declarations)."""
    if isinstance(value, list):
        return "MF" + (_guess_type(value[0])[2:] if value else "Node")
    if isinstance(value, bool):
        return "SFBool"
    if isinstance(value, int):
        return "SFInt32"
    if isinstance(value, float):
        return "SFFloat"
    if isinstance(value, str):
        return "SFString"
    if isinstance(value, tuple):
        return {2: "SFVec2f", 3: "SFVec3f", 4: "SFRotation"}.get(len(value), "SFVec3f")
    return "SFNode"


def field_type_name(node: SceneNode, name: str, values: dict[str, Any]) -> str:
    """The VRML type of ``node``'s field ``name`` (``values`` holds it: the base fields or the PROTO's)."""
    if values is node.fields and schema.is_base_node(node.type_name):
        spec = schema.node_spec(node.type_name).fields.get(name)
        if spec is not None:
            return spec.type
    if node.type_name == "Group" and name == "children":
        return "MFNode"
    return _guess_type(values.get(name))


def parse_nodes(sim: Simulation, text: str) -> list[SceneNode]:
    """Scene nodes from VRML text, expanded like the world's own (its EXTERNPROTOs and folder apply)."""
    from dualtwin.webots.protos import load_world_text

    world = sim.world
    header = [f'EXTERNPROTO "{url}"' for url in world.externprotos]
    header += [f'EXTERNPROTO "{url}"' for url in world.importable_externprotos]
    source = "\n".join(["#VRML_SIM R2023b utf8", *header, text, ""])
    return load_world_text(source, world.path if world.path else "<string>").nodes


def undeclared_protos(sim: Simulation, text: str) -> list[str]:
    """The PROTOs ``text`` names (a node type that is not a base node: a word followed by ``{``) that the world
    does not declare ``IMPORTABLE EXTERNPROTO``. Webots imports a PROTO only when so declared: a plain EXTERNPROTO,
    even of a PROTO the world already uses, is not enough (PROTOs used inside the imported PROTO's own body come
    from its declarations and are not named here)."""
    from dualtwin.webots.lexer import tokenize

    importable = {url.replace("\\", "/").rsplit("/", 1)[-1].removesuffix(".proto")
                  for url in sim.world.importable_externprotos}
    tokens = tokenize(text)
    named = [word.text for word, after in zip(tokens, tokens[1:], strict=False)
             if word.kind == "ident" and after.kind == "{"]
    return [name for name in dict.fromkeys(named) if not schema.is_base_node(name) and name not in importable]


class Field:
    """Webots ``Field`` (from ``Node.getField``/``getProtoField``): never built by controllers."""

    SF_BOOL, SF_INT32, SF_FLOAT, SF_VEC2F, SF_VEC3F, SF_ROTATION, SF_COLOR, SF_STRING, SF_NODE = range(1, 10)
    MF_BOOL, MF_INT32, MF_FLOAT, MF_VEC2F, MF_VEC3F, MF_ROTATION, MF_COLOR, MF_STRING, MF_NODE = range(17, 26)

    #: Webots' field-type number (a plain attribute in Webots, set when the handle is made)
    type: int | None

    def __init__(self, owner: FieldOwner, name: str, values: dict[str, Any] | None = None) -> None:
        self._owner = owner
        self._sim = owner._sim
        self._name = name
        # a PROTO's interface fields live in proto_fields; its base node's fields in fields
        self._values = owner._node.fields if values is None else values
        self._vrml = field_type_name(owner._node, name, self._values)
        self.type = FIELD_TYPES.get(self._vrml)

    # -- identity

    @property
    def _node(self) -> SceneNode:
        return self._owner._node

    def _raw(self) -> Any:
        """The value this handle's node stores (what a write of this handle edits)."""
        return self._values.get(self._name)

    def _current(self) -> Any:
        """The value a read gives. An interface field IS-bound to a base field is one value with it (§7.1): the
        base field holds what changed inside the instance too (the robot's own setCustomData, an Emitter's
        setChannel), which Webots passes up to the PROTO's field; a supervisor's write of the interface field
        came down to it. A write of another supervisor is read once a step executed it, and its author reads its own
        write back until then, even one that a supervisor later in the scene tree overrode (§6). (Node-valued
        fields: see _in_scene.)"""
        if self._vrml.endswith("Node"):
            return self._raw()
        decided, value = self._sim.unexecuted_before(self._node, self._name)
        if decided:  # a write no step executed yet: the value before it for the others, its own for the writer
            return value
        if not self._is_base():
            for node, name in self._bound_base():
                if name in node.fields:
                    return node.fields[name]
        return self._raw()

    def _bound_base(self) -> list[tuple[SceneNode, str]]:
        """The base-node fields ``IS`` bound to this interface field (:func:`linked_fields`), walked once for the
        scene tree as it is: a read of such a field walked the whole PROTO body every time (hundreds of
        microseconds for a robot PROTO, and supervisors read their robots' customData every step)."""
        key = (id(self._node), self._name)
        memo: dict[tuple[int, str], tuple[int, SceneNode, list[tuple[SceneNode, str]]]]
        memo = self._sim.extensions.setdefault("is_bound_base", {})
        version = self._sim.scene_version  # read first: a change meanwhile leaves a stale version, walked again
        held = memo.get(key)
        if held is not None and held[0] == version and held[1] is self._node:
            return held[2]
        base = linked_fields(self._node, self._name)[0]
        memo[key] = (version, self._node, base)
        return base

    def _is_base(self) -> bool:
        return self._values is self._node.fields

    def _joint(self) -> JointRec | None:
        return self._sim.joint_for(self._node) if self._name == "position" and self._is_base() else None

    def _live(self) -> Field | None:
        """For a PROTO interface field, the base field it is ``IS``-bound to whose value follows the physics (a
        Solid's ``translation``/``rotation``, a joint's ``position``), read through its own getter: the binding
        makes them one value (§7.1), and Webots' base field follows the physics, so ``translation IS
        translation`` of a PROTO robot reads where the robot is now. None for a base field or no such link."""
        if self._is_base():
            return None
        for node, name in self._bound_base():
            bound = Field(self._owner._handle(node), name)
            if (name in ("translation", "rotation") and self._sim.solid_for(node) is not None) or bound._joint():
                return bound
        return None

    def getName(self) -> str:
        return self._name

    def getType(self) -> int:
        return int(self.type or 0)

    def getTypeName(self) -> str:
        return self._vrml

    def getCount(self) -> int:
        value = self._current()
        return len(value) if isinstance(value, list) else -1

    name = property(lambda self: self.getName())
    type_name = property(lambda self: self.getTypeName())
    count = property(lambda self: self.getCount())

    def enableSFTracking(self, samplingPeriod: Any) -> None:
        """Webots streams the value every period; here every read is current, so nothing is needed."""
        as_int(samplingPeriod, "Field.enableSFTracking")

    def disableSFTracking(self) -> None:
        pass

    def _check(self, method: str, kind: str) -> bool:
        if self._vrml != kind:
            warn(f"Field.{method}() called on a {self._vrml} field ('{self._name}'): ignored")
            return False
        return True

    # -- SF getters

    def getSFBool(self) -> int:
        return int(bool(self._current())) if self._check("getSFBool", "SFBool") else 0

    def getSFInt32(self) -> int:
        return int(self._current()) if self._check("getSFInt32", "SFInt32") else 0

    def getSFFloat(self) -> float:
        if not self._check("getSFFloat", "SFFloat"):
            return math.nan
        live = self._live()
        if live is not None and live._vrml == "SFFloat":
            return live.getSFFloat()
        joint = self._joint()
        if joint is not None:
            params = joint.params
            index = params.index(self._node) if self._node in params else 0
            return float(joint.positions[index])
        return float(self._current())

    def getSFVec2f(self) -> list[float]:
        return [float(v) for v in self._current()] if self._check("getSFVec2f", "SFVec2f") else [math.nan] * 2

    def getSFVec3f(self) -> list[float]:
        if not self._check("getSFVec3f", "SFVec3f"):
            return [math.nan] * 3
        live = self._live()
        if live is not None and live._vrml == "SFVec3f":
            return live.getSFVec3f()
        solid = self._sim.solid_for(self._node)
        if solid is not None and self._name == "translation":
            # the field follows the physics; this supervisor's own write not yet executed reads back
            own = self._sim.pending_pose(solid)[0]
            return [float(v) for v in own] if own is not None else list(self._sim.solid_local_pose(solid).t)
        return [float(v) for v in self._current()]

    def getSFRotation(self) -> list[float]:
        if not self._check("getSFRotation", "SFRotation"):
            return [math.nan] * 4
        live = self._live()
        if live is not None and live._vrml == "SFRotation":
            return live.getSFRotation()
        solid = self._sim.solid_for(self._node)
        if solid is not None and self._name == "rotation":
            own = self._sim.pending_pose(solid)[1]  # (as for translation)
            if own is not None:
                return [float(v) for v in own]
            return list(m3.axis_angle_from_mat(self._sim.solid_local_pose(solid).R))
        return [float(v) for v in self._current()]

    def getSFColor(self) -> list[float]:
        return [float(v) for v in self._current()] if self._check("getSFColor", "SFColor") else [math.nan] * 3

    def getSFString(self) -> str:
        return str(self._current()) if self._check("getSFString", "SFString") else ""

    def getSFNode(self) -> Any:
        value = self._raw()
        return self._owner._handle(self._in_scene(value, None)) if isinstance(value, SceneNode) else None

    def _in_scene(self, item: SceneNode, at: int | None) -> SceneNode:
        """The node the scene holds for ``item``, at ``at`` of this node field (None: SFNode). A PROTO interface
        field's node is a parameter: the body's field ``IS`` bound to it holds the copy that is in the scene tree
        and the physics (its pose, its field edits), which a handle must name; else ``item`` itself."""
        if self._is_base():
            return item
        for node, name in linked_fields(self._node, self._name)[0]:
            value = node.fields.get(name)
            if at is None and isinstance(value, SceneNode):
                return value
            if at is not None and isinstance(value, list) and 0 <= at < len(value) and isinstance(value[at], SceneNode):
                return value[at]
        return item

    @property
    def value(self) -> Any:
        """The SF value (None for an MF field); assigning sets it like the matching ``setSF*``."""
        getter = {"SFBool": self.getSFBool, "SFInt32": self.getSFInt32, "SFFloat": self.getSFFloat,
                  "SFVec2f": self.getSFVec2f, "SFVec3f": self.getSFVec3f, "SFRotation": self.getSFRotation,
                  "SFColor": self.getSFColor, "SFString": self.getSFString, "SFNode": self.getSFNode}.get(self._vrml)
        return getter() if getter is not None else None

    @value.setter
    def value(self, value: Any) -> None:
        setter = {"SFBool": self.setSFBool, "SFInt32": self.setSFInt32, "SFFloat": self.setSFFloat,
                  "SFVec2f": self.setSFVec2f, "SFVec3f": self.setSFVec3f, "SFRotation": self.setSFRotation,
                  "SFColor": self.setSFColor, "SFString": self.setSFString}.get(self._vrml)
        if setter is None:
            warn(f"Field.value cannot be set on a {self._vrml} field ('{self._name}')")
            return
        setter(value)

    # -- MF getters

    def _item(self, method: str, kind: str, index: Any) -> tuple[bool, Any]:
        if not self._check(method, kind):
            return False, None
        items = self._current() or []
        i = as_int(index, f"Field.{method}")
        if not -len(items) <= i < len(items):
            warn(f"Field.{method}(): index {i} out of range for '{self._name}' ({len(items)} items)")
            return False, None
        return True, items[i]

    def getMFBool(self, index: Any) -> bool:
        ok, item = self._item("getMFBool", "MFBool", index)
        return bool(item) if ok else False

    def getMFInt32(self, index: Any) -> int:
        ok, item = self._item("getMFInt32", "MFInt32", index)
        return int(item) if ok else 0

    def getMFFloat(self, index: Any) -> float:
        ok, item = self._item("getMFFloat", "MFFloat", index)
        return float(item) if ok else math.nan

    def _vector(self, method: str, kind: str, index: Any, size: int) -> list[float]:
        ok, item = self._item(method, kind, index)
        return [float(v) for v in item] if ok else [math.nan] * size

    def getMFVec2f(self, index: Any) -> list[float]:
        return self._vector("getMFVec2f", "MFVec2f", index, 2)

    def getMFVec3f(self, index: Any) -> list[float]:
        return self._vector("getMFVec3f", "MFVec3f", index, 3)

    def getMFRotation(self, index: Any) -> list[float]:
        return self._vector("getMFRotation", "MFRotation", index, 4)

    def getMFColor(self, index: Any) -> list[float]:
        return self._vector("getMFColor", "MFColor", index, 3)

    def getMFString(self, index: Any) -> str:
        ok, item = self._item("getMFString", "MFString", index)
        return str(item) if ok else ""

    def getMFNode(self, index: Any) -> Any:
        ok, item = self._item("getMFNode", "MFNode", index)
        if not ok or not isinstance(item, SceneNode):
            return None
        i = as_int(index, "Field.getMFNode")
        return self._owner._handle(self._in_scene(item, i if i >= 0 else len(self._raw()) + i))

    # -- SF setters

    def _changed(self) -> None:
        if self._is_base():
            self._sim.field_changed(self._node, self._name)
            return
        # a PROTO interface field: Webots propagates the value through the IS links of the PROTO body
        value = self._raw()
        # a template reads it (this PROTO's, or a procedural one's in its body): the instance is expanded again
        # with the new value, and its whole body follows from it
        if feeds_template(self._node, self._name) and self._regenerate(self._node):
            return
        base, interfaces = linked_fields(self._node, self._name)
        for node, name in interfaces:
            assert node.proto_fields is not None
            node.proto_fields[name] = copy_value(value)
        for node, name in base:
            Field(self._owner._handle(node), name)._store(copy_value(value))

    def _regenerate(self, node: SceneNode) -> bool:
        if self._owner._regenerate(node):
            return True
        warn(f"Field: '{self._name}' is read by the template of a procedural PROTO in {node.proto_name}; Webots "
             "regenerates the node, dualtwin only follows the IS links here (the node holds a Robot or is part of one)")
        return False

    def _convert(self, method: str, kind: str, value: Any) -> tuple[bool, Any]:
        """``value`` as a stored SF value of ``kind`` (stderr error and False when it does not fit)."""
        try:
            if kind == "SFBool":
                return True, bool(value)
            if kind == "SFInt32":
                return True, as_int(value, f"Field.{method}")
            # a float must be finite (±inf refused like NaN): no Webots field holds one (a world's inf keeps the
            # field's default, see protos.py), and ODE aborts the whole process on an infinite rotation axis
            # (dxOrthogonalizeR) while an infinite angle or translation breaks the next step
            if kind == "SFFloat":
                v = as_float(value, f"Field.{method}")
                return (True, v) if math.isfinite(v) else (False, None)
            if kind == "SFString":
                return (True, value) if isinstance(value, str) else (False, None)
            size = schema.VECTOR_SIZES[kind]
            values = as_floats(value, f"Field.{method}")
            if len(values) != size or not all(math.isfinite(v) for v in values):
                return False, None
            # an axis whose length overflows (1e308 components) normalises to zero, as bad as a zero axis
            if kind == "SFRotation" and not 0.0 < m3.norm(values[:3]) < math.inf:
                return False, None
            return True, tuple(float(v) for v in values)
        except TypeError:
            return False, None

    def _set(self, method: str, kind: str, value: Any) -> None:
        if not self._check(method, kind):
            return
        if kind in schema.VECTOR_SIZES and not isinstance(value, list):
            # Webots' Python Field checks ``isinstance(value, list)``: a tuple or NumPy array is refused with
            # this line on stderr and the field keeps its value (no exception)
            print("Error: new field value has wrong type or length.", file=sys.stderr)
            return
        ok, converted = self._convert(method, kind, value)
        if not ok:
            warn(f"Field.{method}(): new field value has wrong type or length ('{self._name}'): ignored")
            return
        self._store(converted)

    def _store(self, converted: Any) -> None:
        """Write an already checked value and send it to the physics (joint position, pose, other fields)."""
        kind = self._vrml
        if kind == "SFFloat":
            joint = self._joint()
            if joint is not None:
                params = joint.params
                index = params.index(self._node) if self._node in params else 0
                self._values["position"] = converted
                self._sim.queue_set_joint_position(joint, index, converted)
                return
        solid = self._sim.solid_for(self._node) if self._is_base() else None
        if solid is not None and (self._name, kind) in (("translation", "SFVec3f"), ("rotation", "SFRotation")):
            if self._name == "translation":
                self._sim.queue_set_pose(solid, converted, None)
            else:
                self._sim.queue_set_pose(solid, None, converted)
            self._values[self._name] = converted
            return
        changed = converted != self._values.get(self._name)
        if not self._note_write(converted):
            return  # a supervisor later in the scene tree wrote it in this step: its value is the one executed last
        self._values[self._name] = converted
        self._changed()
        if changed and self._name == "controller" and kind == "SFString" and self._is_base() and is_robot(self._node):
            self._owner._controller_changed()  # Webots restarts the robot's controller with the new one

    def _note_write(self, written: Any = UNRECORDED) -> bool:
        """Before this supervisor's write of a (non-node) value, ``written`` (an SF value; an MF item edit records
        none): the others read the value before it until a step executes the write (see _current). False when a
        supervisor later in the scene tree already wrote the field in this step, whose write is executed after this
        one (§6: scene-tree order): this one is not stored, its author reads it back until the step."""
        return self._sim.note_unexecuted_write(self._node, self._name, self._raw(), copy_value(written))

    def setSFBool(self, value: Any) -> None:
        self._set("setSFBool", "SFBool", value)

    def setSFInt32(self, value: Any) -> None:
        self._set("setSFInt32", "SFInt32", value)

    def setSFFloat(self, value: Any) -> None:
        self._set("setSFFloat", "SFFloat", value)

    def setSFVec2f(self, value: Any) -> None:
        self._set("setSFVec2f", "SFVec2f", value)

    def setSFVec3f(self, value: Any) -> None:
        self._set("setSFVec3f", "SFVec3f", value)

    def setSFRotation(self, value: Any) -> None:
        self._set("setSFRotation", "SFRotation", value)

    def setSFColor(self, value: Any) -> None:
        self._set("setSFColor", "SFColor", value)

    def setSFString(self, value: Any) -> None:
        self._set("setSFString", "SFString", value)

    # -- MF setters, insertion and removal (the list is edited in place: the root's list is the world's)

    def _mf_write(self, method: str, kind: str, index: Any, value: Any, insert: bool) -> None:
        if not self._check(method, kind):
            return
        ok, converted = self._convert(method, schema.mf_element_type(kind), value)
        if not ok:
            warn(f"Field.{method}(): new field value has wrong type or length ('{self._name}'): ignored")
            return
        items = self._raw()
        if not isinstance(items, list):
            items = []
            self._values[self._name] = items
        i = as_int(index, f"Field.{method}")
        n = len(items)
        if not (-(n + 1) <= i <= n if insert else -n <= i < n):
            warn(f"Field.{method}(): index {i} out of range for '{self._name}' ({n} items)")
            return
        self._note_write()
        if insert:
            items.insert(i if i >= 0 else n + 1 + i, converted)
        else:
            items[i] = converted
        self._changed()

    def setMFBool(self, index: Any, value: Any) -> None:
        self._mf_write("setMFBool", "MFBool", index, value, False)

    def setMFInt32(self, index: Any, value: Any) -> None:
        self._mf_write("setMFInt32", "MFInt32", index, value, False)

    def setMFFloat(self, index: Any, value: Any) -> None:
        self._mf_write("setMFFloat", "MFFloat", index, value, False)

    def setMFVec2f(self, index: Any, value: Any) -> None:
        self._mf_write("setMFVec2f", "MFVec2f", index, value, False)

    def setMFVec3f(self, index: Any, value: Any) -> None:
        self._mf_write("setMFVec3f", "MFVec3f", index, value, False)

    def setMFRotation(self, index: Any, value: Any) -> None:
        self._mf_write("setMFRotation", "MFRotation", index, value, False)

    def setMFColor(self, index: Any, value: Any) -> None:
        self._mf_write("setMFColor", "MFColor", index, value, False)

    def setMFString(self, index: Any, value: Any) -> None:
        self._mf_write("setMFString", "MFString", index, value, False)

    def insertMFBool(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFBool", "MFBool", index, value, True)

    def insertMFInt32(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFInt32", "MFInt32", index, value, True)

    def insertMFFloat(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFFloat", "MFFloat", index, value, True)

    def insertMFVec2f(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFVec2f", "MFVec2f", index, value, True)

    def insertMFVec3f(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFVec3f", "MFVec3f", index, value, True)

    def insertMFRotation(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFRotation", "MFRotation", index, value, True)

    def insertMFColor(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFColor", "MFColor", index, value, True)

    def insertMFString(self, index: Any, value: Any) -> None:
        self._mf_write("insertMFString", "MFString", index, value, True)

    def removeMF(self, index: Any) -> None:
        items = self._raw()
        if not self._vrml.startswith("MF") or not isinstance(items, list):
            warn(f"Field.removeMF() called on a {self._vrml} field ('{self._name}'): ignored")
            return
        i = as_int(index, "Field.removeMF")
        if not -len(items) <= i < len(items):
            warn(f"Field.removeMF(): index {i} out of range for '{self._name}' ({len(items)} items)")
            return
        at = i if i >= 0 else len(items) + i
        if not isinstance(items[at], SceneNode):
            self._note_write()
        item = items.pop(at)
        if isinstance(item, SceneNode):
            self._nodes_removed(item, at)
        else:
            self._changed()

    def removeSF(self) -> None:
        """Empty an SFNode field."""
        item = self._raw()
        if self._vrml != "SFNode":
            warn(f"Field.removeSF() called on a {self._vrml} field ('{self._name}'): ignored")
            return
        if isinstance(item, SceneNode):
            self._values[self._name] = None
            self._nodes_removed(item, None)

    def _nodes_added(self, nodes: list[SceneNode], at: int | None) -> None:
        """Nodes just put at ``at`` of this node field (None: SFNode) join the scene. A PROTO interface field's
        nodes are the instance's parameters: the scene tree holds the copies its ``IS`` links give the body (a
        Solid added to an extension slot moves with, and is merged into or jointed to, the PROTO's Solids), so
        those copies join the physics, as the nodes of a base field do."""
        if self._is_base():
            self._owner._imported(nodes)
            self._changed()
            return
        self._owner._number(nodes)  # the parameter nodes have ids too (getMFNode handles)
        placed = insert_linked_nodes(self._node, self._name, at, nodes)  # (a regeneration writes the body's)
        if feeds_template(self._node, self._name) and self._regenerate(self._node):
            return  # the instance is expanded again from its fields, the new nodes with them
        self._owner._imported(placed)

    def _nodes_removed(self, item: SceneNode, at: int | None) -> None:
        """A node just taken from ``at`` of this node field (None: SFNode) leaves the scene; for a PROTO interface
        field, the copies its ``IS`` links gave the body leave the scene tree and the physics with it."""
        if self._is_base():
            self._owner._removed(item)
            self._changed()
            return
        for copy in remove_linked_nodes(self._node, self._name, at):
            self._owner._removed(copy)
        if feeds_template(self._node, self._name):
            self._regenerate(self._node)  # expanded again without it (else the IS links were followed above)

    def _not_importable(self, method: str, text: str) -> bool:
        """Webots' refusal of a PROTO the world does not declare IMPORTABLE (its error line; nothing imported)."""
        try:
            missing = undeclared_protos(self._sim, text)
        except Exception:  # noqa: BLE001 - a string that does not tokenize is parse_nodes' error to report
            return False
        for name in missing[:1]:
            print(f"Error: Field.{method}(): In order to import the PROTO '{name}', first it must be declared in "
                  "the IMPORTABLE EXTERNPROTO list.", file=sys.stderr)
        return bool(missing)

    def importMFNodeFromString(self, position: Any, nodeString: str) -> None:
        """Parse VRML text into nodes inserted at ``position`` (-1 = append) of this MFNode field."""
        if not self._check("importMFNodeFromString", "MFNode"):
            return
        items = self._raw()
        if not isinstance(items, list):
            items = []
            self._values[self._name] = items
        i = as_int(position, "Field.importMFNodeFromString")
        n = len(items)
        if not -(n + 1) <= i <= n:
            warn(f"Field.importMFNodeFromString(): position {i} out of range for '{self._name}' ({n} items)")
            return
        if self._not_importable("importMFNodeFromString", str(nodeString)):
            return
        try:
            nodes = parse_nodes(self._sim, str(nodeString))
        except Exception as exc:  # noqa: BLE001 - Webots reports a bad string on stderr and imports nothing
            warn(f"Field.importMFNodeFromString(): {exc}")
            return
        at = i if i >= 0 else n + 1 + i
        items[at:at] = nodes
        self._nodes_added(nodes, at)

    def importSFNodeFromString(self, nodeString: str) -> None:
        """Parse VRML text into the node of this (empty) SFNode field."""
        if not self._check("importSFNodeFromString", "SFNode"):
            return
        if self._raw() is not None:
            warn(f"Field.importSFNodeFromString(): '{self._name}' is not empty; remove its node first")
            return
        if self._not_importable("importSFNodeFromString", str(nodeString)):
            return
        try:
            nodes = parse_nodes(self._sim, str(nodeString))
        except Exception as exc:  # noqa: BLE001
            warn(f"Field.importSFNodeFromString(): {exc}")
            return
        if nodes:
            self._values[self._name] = nodes[0]
            self._nodes_added(nodes[:1], None)
