"""The Webots twin's knob table (see :mod:`dualtwin.twins.knob_table`).

Webots-twin knobs are fields of the world that Webots applies live, read and written through the supervisor's
``Field`` API (so they work the same in a real Webots installation), plus a command gain per motor applied on
the controller side. A field knob's handle is ``(node, field name, MF index or None)``; ``set_knobs`` writes
each field only when its value differs (every knob not given returns to its nominal, read when the twin was
built). Bounds always include the nominal value.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, Protocol

from dualtwin.twins.knob_table import KnobGroup, KnobKind, KnobTable
from dualtwin.twins.webots_state import JOINT_TYPES, MOTOR_TYPES, base_field


class KnobTarget(Protocol):
    """What the table's entries use on the twin: :class:`~dualtwin.twins.webots.WebotsTwin` has it.

    A Protocol rather than the twin's class, so this module does not import the twin that imports it (the
    package stays free of import cycles, type-only imports included).
    """

    #: The controller-side gain factors, by motor name (written by the gain entry).
    _gains: dict[str, float]

    @property
    def sup(self) -> Any: ...
    def _walk(self) -> Iterator[Any]: ...
    def _device_names(self, types: tuple[str, ...] | None) -> list[str]: ...

FieldHandle = tuple[Any, str, "int | None"]


def read_field(tw: KnobTarget, handle: FieldHandle) -> float:
    node, field, index = handle
    value = base_field(node, field)
    return float(value.getMFFloat(index) if index is not None else value.getSFFloat())


def write_field(tw: KnobTarget, handle: FieldHandle, value: float) -> None:
    """Write the field if it differs (an unchanged field is not touched)."""
    if read_field(tw, handle) == value:
        return
    node, field, index = handle
    target = base_field(node, field)
    if index is not None:
        target.setMFFloat(index, float(value))
    else:
        target.setSFFloat(float(value))


def _including(lower: Callable[[float], float], upper: Callable[[float], float]) -> Any:
    """Bounds from the nominal, widened to include it."""
    def limits(tw: KnobTarget, handle: Any, nominal: float) -> tuple[float, float]:
        return min(lower(nominal), nominal), max(upper(nominal), nominal)
    return limits


def _field(pattern: str, unit: str, bounds: str, sets: str, lower: Callable[[float], float],
           upper: Callable[[float], float], find: Callable[[KnobTarget, Any], tuple[str, Any] | None]
           ) -> KnobKind[KnobTarget]:
    return KnobKind(pattern, unit, bounds, sets, read_field, _including(lower, upper), write_field, find=find)


# ---------------------------------------------------------------- the robot's nodes, in walk order
def _nodes(tw: KnobTarget) -> Iterator[Any]:
    return tw._walk()


def _joint_field(field: str) -> Callable[[KnobTarget, Any], tuple[str, Any] | None]:
    def find(tw: KnobTarget, node: Any) -> tuple[str, Any] | None:
        if node.getTypeName() not in JOINT_TYPES or not node.getDef():
            return None
        params = base_field(node, "jointParameters").getSFNode()
        return (node.getDef(), (params, field, None)) if params is not None else None
    return find


def _motor_field(rotational: str, linear: str) -> Callable[[KnobTarget, Any], tuple[str, Any] | None]:
    def find(tw: KnobTarget, node: Any) -> tuple[str, Any] | None:
        kind = node.getTypeName()
        if kind not in MOTOR_TYPES:
            return None
        return base_field(node, "name").getSFString(), (node, rotational if kind == "RotationalMotor" else linear, None)
    return find


def _body_mass(tw: KnobTarget, node: Any) -> tuple[str, Any] | None:
    # Solids with a DEF and a Physics node of positive mass (a mass of -1 means "from density").
    if node.getTypeName() == "Physics":
        return None
    physics = base_field(node, "physics")
    physics_node = physics.getSFNode() if physics is not None else None
    if node.getDef() and physics_node is not None and base_field(physics_node, "mass").getSFFloat() > 0:
        return node.getDef(), (physics_node, "mass", None)
    return None


NODE_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    _field("joint.<j>.damping", "N*m*s/rad", "0 .. max(10 × nominal, 1)", "JointParameters `dampingConstant`",
           lambda n: 0.0, lambda n: max(10 * n, 1.0), _joint_field("dampingConstant")),
    _field("joint.<j>.friction", "N*m", "0 .. max(10 × nominal, 0.5)", "JointParameters `staticFriction`",
           lambda n: 0.0, lambda n: max(10 * n, 0.5), _joint_field("staticFriction")),
    _field("motor.<m>.max_torque", "N*m", "0 .. max(10 × nominal, 0.5)",
           "RotationalMotor `maxTorque` (LinearMotor `maxForce`)", lambda n: 0.0, lambda n: max(10 * n, 0.5),
           _motor_field("maxTorque", "maxForce")),
    _field("motor.<m>.max_velocity", "rad/s", "0 .. max(10 × nominal, 0.5)", "Motor `maxVelocity`",
           lambda n: 0.0, lambda n: max(10 * n, 0.5), _motor_field("maxVelocity", "maxVelocity")),
    _field("body.<b>.mass", "kg", "0.1 × nominal .. 10 × nominal", "Physics `mass` (of a Solid with a DEF)",
           lambda n: 0.1 * n, lambda n: 10 * n, _body_mass),
)


# ---------------------------------------------------------------- WorldInfo and its contact properties
def _world_info(tw: KnobTarget) -> Iterator[Any]:
    root = base_field(tw.sup.getRoot(), "children")
    info = next((n for n in (root.getMFNode(i) for i in range(root.getCount())) if n
                 and n.getTypeName() == "WorldInfo"), None)
    if info is not None:
        yield info


def _contacts(tw: KnobTarget) -> Iterator[tuple[str, Any]]:
    for info in _world_info(tw):
        contacts = base_field(info, "contactProperties")
        for i in range(contacts.getCount()):
            cp = contacts.getMFNode(i)
            yield f"{base_field(cp, 'material1').getSFString()}:{base_field(cp, 'material2').getSFString()}", cp


def _world(tw: KnobTarget) -> Iterator[tuple[str, Any]]:
    return (("", info) for info in _world_info(tw))


def _on(field: str, index: int | None = None) -> Callable[[KnobTarget, tuple[str, Any]], tuple[str, Any]]:
    """A ``find`` for a group of ``(name, node)``: the knob is the node's ``field`` (MF entry ``index``)."""
    def find(tw: KnobTarget, obj: tuple[str, Any]) -> tuple[str, Any]:
        return obj[0], (obj[1], field, index)
    return find


def _cfm_upper(nominal: float) -> float:
    return max(nominal * 100, 1e-2)


WORLD_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    _field("world.erp", "", "0.01 .. 1", "WorldInfo `ERP`", lambda n: 0.01, lambda n: 1.0, _on("ERP")),
    _field("world.cfm", "", "1e-9 .. max(100 × nominal, 0.01)", "WorldInfo `CFM`", lambda n: 1e-9, _cfm_upper,
           _on("CFM")),
)

# Coulomb friction is a coefficient (tangential over normal force): dimensionless, like MuJoCo's
# geom.<g>.friction. (It read "N*m" until the knob tables, from a unit table keyed by the name's last part.)
CONTACT_KINDS: tuple[KnobKind[KnobTarget], ...] = (
    _field("contact.<p>.friction", "", "0 .. 5 × max(nominal, 0.1)", "ContactProperties `coulombFriction[0]`",
           lambda n: 0.0, lambda n: 5 * max(n, 0.1), _on("coulombFriction", 0)),
    _field("contact.<p>.bounce", "", "0 .. 1", "ContactProperties `bounce`", lambda n: 0.0, lambda n: 1.0,
           _on("bounce")),
    _field("contact.<p>.soft_erp", "", "0.01 .. 1", "ContactProperties `softERP`", lambda n: 0.01, lambda n: 1.0,
           _on("softERP")),
    _field("contact.<p>.soft_cfm", "", "1e-9 .. max(100 × nominal, 0.01)", "ContactProperties `softCFM`",
           lambda n: 1e-9, _cfm_upper, _on("softCFM")),
)


# ---------------------------------------------------------------- controller side
def _motor_names(tw: KnobTarget) -> Iterator[tuple[str, str]]:
    return ((name, name) for name in tw._device_names(MOTOR_TYPES))


def _set_gain(tw: KnobTarget, motor: str, value: float) -> None:
    tw._gains[motor] = value


GAIN = KnobKind("motor.<m>.gain", "", "-2 .. 2", "command × gain (controller side)", lambda tw, motor: 1.0,
                lambda tw, motor, n: (-2.0, 2.0), _set_gain, "command gain (sign included)")

#: The Webots twin's knobs, in ``knobs()`` order.
WEBOTS_KNOBS: KnobTable[KnobTarget] = KnobTable((
    KnobGroup(_nodes, NODE_KINDS),
    KnobGroup(_world, WORLD_KINDS),
    KnobGroup(_contacts, CONTACT_KINDS),
    KnobGroup(_motor_names, (GAIN,)),
))
