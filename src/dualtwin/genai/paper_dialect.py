"""The paper's primitive robot JSON as an input dialect of our own description.

The paper's roboGen-LLM prompts (``prompts/webots_proto_to_primitive_robot.txt`` in its repository) ask the
LLM for::

    {"robot_name", "approximate_scale": [3],
     "physics": {"mass", "center_of_mass": [3], "inertia": [6], "friction", "restitution", "damping"},
     "parts": [{"name", "type": "box|cylinder|sphere",
                "dimensions": {"size": [3]} | {"radius", "height"} | {"radius"},
                "mass", "position": [3], "orientation": [3 Euler angles] | [4 quaternion],
                "material": "free text", "parent",
                "joint": {"type": "hinge|slider|fixed", "axis": [3], "limits": [2], "stiffness", "damping"}}],
     "assembly_instructions": ["..."]}

Real answers in that schema are messy (nulls and placeholders where the model did not know, keys the schema does
not name, frames it leaves open), so :func:`translate` is lenient and explicit: it returns our description as
plain data plus one note per assumption, which the caller records (``generation.json``, the LLM transcript).
What it cannot decide without guessing wrongly (masses that do not add up, a wheel whose axis does not match
its hinge, a part with no usable size) becomes a :class:`DialectProblem`: a message naming the part and the fix,
which the generate loop sends back to the LLM exactly as it sends our own schema's validation errors.

Decisions (each also written into the notes when it applies):

* **Angles** are radians; a hinge limit or Euler angle beyond 2*pi means the file is in degrees (converted).
* **Euler angles** ``[a, b, c]`` are roll, pitch, yaw about the fixed x, y, z axes (extrinsic XYZ, so
  R = Rz(c) Ry(b) Rx(a)), the ROS/URDF ``rpy`` convention.
* **Four numbers** are a unit quaternion when their norm is 1, read scalar-last ``[x, y, z, w]`` (the ROS and
  SciPy order; ``[1, 0, 0, 0]`` alone is read scalar-first, as the identity it clearly means); otherwise, when
  the first three have norm 1, a Webots axis-angle ``[x, y, z, angle]`` copied from the PROTO.
* **Positions** are in the parent part's frame, as in Webots and in our own schema. A file may say otherwise
  with a top-level ``position_frame``/``frame`` of ``"world"``; with ``approximate_scale`` given and no such key,
  the reading (parent or world) whose overall extent is closer to that scale is taken.
* **Joint axes** are in the parent part's frame (world frame under the world reading), as Webots'
  ``HingeJointParameters.axis``; the hinge passes through the part's own position unless the joint gives an
  ``anchor`` (a key the schema does not name, used because its meaning is unambiguous).
* **Missing masses**: the parts without a usable mass share what ``physics.mass`` leaves over, by volume; with
  no total, they get the density of water (1000 kg/m^3) times their volume.
* **Inertia** is always computed from geometry and mass (Webots does the same for a Physics node with a mass and
  ``density -1``); a given ``physics.inertia`` or ``center_of_mass`` is only compared and reported.
* **Motors**: the schema has none. A part may carry a ``motor``/``actuator`` object (used); otherwise every
  hinge of a part named like a wheel gets a velocity motor and every other hinge or slider a position sensor.
* **physics.damping** is the default damping of joints that give none; ``restitution`` is kept as a note (our
  description has no per-robot restitution).
* ``material`` is kept as the part's label; unknown keys are kept as notes.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from dualtwin.errors import DualtwinError
from dualtwin.genai.primitive import RobotDescription, check_tree, grounded_wheels, parse_description
from dualtwin.geometry import axis_angle_from_rotvec

Dialect = Literal["auto", "dualtwin", "paper"]

#: Keys that only the paper's schema has, at the top level and on a part.
PAPER_TOP_KEYS = frozenset({"approximate_scale", "assembly_instructions"})
PAPER_PART_KEYS = frozenset({"material"})
#: The paper's schema, as it names its keys; anything else on a part or joint is an unknown key (a note).
PART_KEYS = frozenset({"name", "type", "dimensions", "mass", "position", "orientation", "material", "parent", "joint"})
JOINT_KEYS = frozenset({"type", "axis", "limits", "stiffness", "damping"})
PHYSICS_KEYS = frozenset({"mass", "center_of_mass", "inertia", "friction", "restitution", "damping"})
#: Synonyms whose meaning is not in doubt.
JOINT_TYPES = {"hinge": "hinge", "revolute": "hinge", "continuous": "hinge", "rotational": "hinge",
               "slider": "slider", "prismatic": "slider", "linear": "slider", "fixed": "fixed", "rigid": "fixed"}
PART_TYPES = {"box": "box", "cube": "box", "cuboid": "box", "cylinder": "cylinder", "sphere": "sphere",
              "ball": "sphere", "capsule": "capsule"}
WATER_DENSITY = 1000.0  # kg/m^3, for parts with no usable mass and no total
MASS_TOLERANCE = 0.10  # parts may differ from physics.mass by 10 % before it is an inconsistency
WHEEL_AXIS_TOLERANCE_DEG = 10.0
DEFAULT_WHEEL_MAX_VELOCITY = 50.0  # rad/s, Webots' RotationalMotor default is 10; wheels need more
DEFAULT_WHEEL_MAX_TORQUE = 10.0  # N*m, Webots' RotationalMotor default
NAME_CHARS = re.compile(r"[^A-Za-z0-9_]+")
DEVICE_CHARS = re.compile(r"[^A-Za-z0-9_ \-]+")


@dataclass
class Translation:
    """Our description as plain data, the assumptions made, and the problems only the author can fix."""

    description: dict[str, Any]
    notes: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


class DialectProblem(DualtwinError):
    """The answer is ambiguous or inconsistent; the message names each part and the fix."""

    def __init__(self, problems: list[str], notes: list[str], origin: str = "the robot description") -> None:
        super().__init__(f"{origin} (paper schema) is inconsistent: " + " ".join(
            f"({i}) {p}" for i, p in enumerate(problems, 1)))
        self.problems = problems
        self.notes = notes


def detect(data: Any) -> Literal["dualtwin", "paper"]:
    """Which schema a parsed JSON object follows: the paper's has its own top-level keys, size objects,
    Euler or quaternion orientations, or materials."""
    if not isinstance(data, Mapping):
        return "dualtwin"
    if PAPER_TOP_KEYS & set(data):
        return "paper"
    physics = data.get("physics")
    if isinstance(physics, Mapping) and {"mass", "center_of_mass", "inertia"} & set(physics):
        return "paper"
    for part in data.get("parts") or []:
        if not isinstance(part, Mapping):
            continue
        if PAPER_PART_KEYS & set(part) or isinstance(part.get("dimensions"), Mapping):
            return "paper"
        orientation = part.get("orientation")
        if isinstance(orientation, list) and len(orientation) == 3:
            return "paper"
        joint = part.get("joint")
        if isinstance(joint, Mapping) and "stiffness" in joint:
            return "paper"
    return "dualtwin"


# ------------------------------------------------------------------------------------------------
# small readers: each returns None for null and placeholder values


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return None
    try:
        number = float(value)
    except ValueError:
        return None
    return number if math.isfinite(number) else None


def _vector(value: Any, length: int) -> list[float] | None:
    if not isinstance(value, list | tuple) or len(value) != length:
        return None
    numbers = [_number(v) for v in value]
    return None if any(n is None for n in numbers) else [float(n) for n in numbers]  # type: ignore[arg-type]


def _clean_name(text: Any, fallback: str) -> str:
    name = NAME_CHARS.sub("_", str(text) if text is not None else "").strip("_")
    if not name or not (name[0].isalpha() or name[0] == "_"):
        name = f"{fallback}_{name}" if name else fallback
    return name[:64]


def _volume(kind: str, dims: list[float]) -> float:
    if kind == "box":
        return dims[0] * dims[1] * dims[2]
    if kind == "sphere":
        return 4.0 / 3.0 * math.pi * dims[0] ** 3
    if kind == "cylinder":
        return math.pi * dims[0] ** 2 * dims[1]
    return math.pi * dims[0] ** 2 * dims[1] + 4.0 / 3.0 * math.pi * dims[0] ** 3


def _half_extent(kind: str, dims: list[float]) -> np.ndarray:
    if kind == "box":
        return np.asarray(dims) / 2.0
    if kind == "sphere":
        return np.full(3, dims[0])
    return np.array([dims[0], dims[0], dims[1] / 2.0 + (dims[0] if kind == "capsule" else 0.0)])


# ------------------------------------------------------------------------------------------------
# the translation


class _Translator:
    def __init__(self, data: Mapping[str, Any]) -> None:
        self.data = data
        self.notes: list[str] = []
        self.problems: list[str] = []

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    # -- per part -----------------------------------------------------------------------------

    def dimensions(self, label: str, kind: str, raw: Any) -> list[float] | None:
        """Full extents (box), [radius, height] (cylinder/capsule) or [radius] (sphere); None is a problem."""
        dims: list[float] | None = None
        if isinstance(raw, Mapping):
            unknown = set(raw) - {"size", "radius", "height", "length", "diameter"}
            if unknown:
                self.note(f"{label}: dimension keys {sorted(unknown)} are not in the schema and were ignored")
            radius = _number(raw.get("radius"))
            if radius is None and _number(raw.get("diameter")) is not None:
                radius = float(_number(raw.get("diameter")) or 0.0) / 2.0
                self.note(f"{label}: radius taken as half the given diameter")
            height = _number(raw.get("height"))
            if height is None and _number(raw.get("length")) is not None:
                height = _number(raw.get("length"))
                self.note(f"{label}: cylinder height taken from 'length'")
            if kind == "box":
                dims = _vector(raw.get("size"), 3)
            elif kind == "sphere":
                dims = [radius] if radius is not None else None
            elif radius is not None and height is not None:
                dims = [radius, height]
        elif isinstance(raw, list | tuple):
            expected = {"box": 3, "sphere": 1}.get(kind, 2)
            dims = _vector(raw, expected)
            if dims is not None:
                self.note(f"{label}: dimensions given as a list, read as our schema's "
                          f"{'[x, y, z] extents' if kind == 'box' else '[radius, height]' if expected == 2 else '[radius]'}")
        if dims is None or any(d <= 0 for d in dims):
            need = {"box": '{"size": [x, y, z]} (full extents, m)', "sphere": '{"radius": r}',
                    "cylinder": '{"radius": r, "height": h}', "capsule": '{"radius": r, "height": h}'}[kind]
            self.problems.append(f"{label}: dimensions {raw!r} are missing or not positive; give {need}")
            return None
        return dims

    def rotation(self, label: str, raw: Any, degrees: bool) -> Rotation:
        if raw is None:
            return Rotation.identity()
        values = _vector(raw, len(raw)) if isinstance(raw, list | tuple) and len(raw) in (3, 4) else None
        if values is None:
            self.note(f"{label}: orientation {raw!r} is not 3 Euler angles or 4 numbers; the identity was used")
            return Rotation.identity()
        if len(values) == 3:
            if degrees:
                return Rotation.from_euler("xyz", values, degrees=True)
            return Rotation.from_euler("xyz", values)
        norm = math.sqrt(sum(v * v for v in values))
        if abs(norm - 1.0) < 1e-3:
            if values == [1.0, 0.0, 0.0, 0.0]:
                return Rotation.identity()
            return Rotation.from_quat(values)  # scalar-last [x, y, z, w]
        axis_norm = math.sqrt(sum(v * v for v in values[:3]))
        if abs(axis_norm - 1.0) < 1e-3:
            self.note(f"{label}: orientation {values} is not a unit quaternion but a unit axis and an angle: read as "
                      "a Webots axis-angle [x, y, z, angle_rad]")
            return Rotation.from_rotvec(np.asarray(values[:3]) * values[3])
        if norm > 1e-9:
            self.note(f"{label}: quaternion {values} has norm {norm:.4g}; normalised")
            return Rotation.from_quat(np.asarray(values) / norm)
        self.note(f"{label}: orientation {values} is all zeros; the identity was used")
        return Rotation.identity()

    def motor(self, label: str, raw: Mapping[str, Any], default_name: str) -> dict[str, Any]:
        name = DEVICE_CHARS.sub("_", str(raw.get("name") or default_name)).strip()[:64] or default_name
        motor: dict[str, Any] = {"name": name, "sensor": f"{default_name} sensor"}
        for ours, keys in (("maxVelocity", ("maxVelocity", "max_velocity", "velocity_limit")),
                           ("maxTorque", ("maxTorque", "max_torque", "torque_limit", "maxForce", "max_force"))):
            for key in keys:
                value = _number(raw.get(key))
                if value is not None and value > 0:
                    motor[ours] = value
                    break
        self.note(f"{label}: motor taken from the part's motor/actuator object (not in the schema)")
        return motor


def translate(data: Any) -> Translation:
    """The paper-schema object ``data`` as our description (plain data), with notes and problems."""
    if not isinstance(data, Mapping):
        raise DualtwinError("the robot description is not a JSON object")
    t = _Translator(data)
    raw_parts = data.get("parts")
    if not isinstance(raw_parts, list) or not raw_parts:
        raise DialectProblem(["'parts' must be a non-empty list of parts"], t.notes)
    for key in sorted(set(data) - {"robot_name", "approximate_scale", "physics", "parts", "assembly_instructions",
                                    "description", "position_frame", "frame"}):
        t.note(f"top-level key {key!r} is not in the schema; kept as a note: {str(data[key])[:200]}")
    robot_name = _clean_name(data.get("robot_name"), "robot")
    if robot_name != data.get("robot_name"):
        t.note(f"robot_name {data.get('robot_name')!r} became {robot_name!r} (letters, digits and _ only)")

    raw_physics = data.get("physics")
    physics: Mapping[str, Any] = raw_physics if isinstance(raw_physics, Mapping) else {}
    if data.get("physics") is None:
        t.note("no physics object: defaults used (friction 1, no joint damping)")
    for key in sorted(set(physics) - PHYSICS_KEYS):
        t.note(f"physics key {key!r} is not in the schema; kept as a note: {physics[key]!r}")
    total_mass = _number(physics.get("mass"))
    if total_mass is not None and total_mass <= 0:
        t.note(f"physics.mass {physics.get('mass')!r} is a placeholder; ignored")
        total_mass = None
    friction = _number(physics.get("friction"))
    default_damping = _number(physics.get("damping"))
    if default_damping is not None and default_damping < 0:
        default_damping = None
    if default_damping:
        t.note(f"physics.damping {default_damping:g} is the damping of every joint that gives none")
    restitution = _number(physics.get("restitution"))
    if restitution:
        t.note(f"physics.restitution {restitution:g} kept as a note: the description has no restitution (Webots' "
               "ContactProperties bounce)")
    inertia = physics.get("inertia")
    if inertia is not None:
        values = _vector(inertia, 6)
        placeholder = values is None or all(v == 0 for v in values) or values == [1, 0, 0, 1, 0, 1]
        t.note(f"physics.inertia {inertia!r} {'is a placeholder' if placeholder else 'is not used'}: every part's "
               "inertia is computed from its geometry and mass")

    # the degree question is one for the whole file: an LLM writes all its angles in one unit
    angles: list[float] = []
    for entry in raw_parts:
        if isinstance(entry, Mapping):
            orientation = entry.get("orientation")
            if isinstance(orientation, list) and len(orientation) == 3:
                angles += [abs(v) for v in (_vector(orientation, 3) or [])]
    degrees = bool(angles) and max(angles) > 2 * math.pi + 1e-6
    if angles:
        t.note("3-value orientations are roll, pitch, yaw about the fixed x, y, z axes (R = Rz Ry Rx), in "
               + ("degrees (a value exceeds 2*pi)" if degrees else "radians"))

    names: list[str] = []
    parts: list[dict[str, Any]] = []
    rotations: list[Rotation] = []
    kinds: list[str] = []
    given_mass: list[float | None] = []
    for index, raw in enumerate(raw_parts):
        if not isinstance(raw, Mapping):
            t.problems.append(f"parts[{index}] is not an object")
            continue
        name = _clean_name(raw.get("name"), f"part{index}")
        while name in names:
            name = f"{name}_{index}"
        if name != raw.get("name"):
            t.note(f"parts[{index}]: name {raw.get('name')!r} became {name!r}")
        names.append(name)
        label = f"part {name!r}"
        kind = PART_TYPES.get(str(raw.get("type", "")).strip().lower())
        if kind is None:
            t.problems.append(f"{label}: type {raw.get('type')!r} is not box, cylinder or sphere")
            continue
        dims = t.dimensions(label, kind, raw.get("dimensions"))
        for key in sorted(set(raw) - PART_KEYS - {"motor", "actuator", "color", "colour"}):
            t.note(f"{label}: key {key!r} is not in the schema; kept as a note: {str(raw[key])[:200]}")
        position = _vector(raw.get("position"), 3)
        if position is None:
            t.note(f"{label}: position {raw.get('position')!r} unusable; [0, 0, 0] used")
            position = [0.0, 0.0, 0.0]
        part: dict[str, Any] = {"name": name, "type": kind, "dimensions": dims or [], "position": position}
        parent = raw.get("parent")
        if isinstance(parent, str) and parent.strip().lower() in ("", "none", "null", "world", "root"):
            t.note(f"{label}: parent {parent!r} read as no parent (the root)")
            parent = None
        part["parent"] = _clean_name(parent, "part") if parent is not None else None
        material = raw.get("material")
        if material not in (None, ""):
            part["material"] = str(material)[:64]
        color = _vector(raw.get("color", raw.get("colour")), 3)
        if color is not None:
            if max(color) > 1.0:
                color = [c / 255.0 for c in color]
                t.note(f"{label}: colour given in 0..255, scaled to 0..1")
            part["color"] = [min(max(c, 0.0), 1.0) for c in color]
        rotations.append(t.rotation(label, raw.get("orientation"), degrees))
        mass = _number(raw.get("mass"))
        if mass is not None and mass <= 0:
            t.note(f"{label}: mass {raw.get('mass')!r} is a placeholder")
            mass = None
        given_mass.append(mass)
        kinds.append(kind)
        joint = raw.get("joint")
        motor_raw = raw.get("motor", raw.get("actuator"))
        if isinstance(joint, Mapping):
            part["joint"] = _joint(t, label, name, kind, joint, default_damping, degrees,
                                   motor_raw if isinstance(motor_raw, Mapping) else None, part)
        elif joint is not None:
            t.note(f"{label}: joint {joint!r} is not an object; the part is attached rigidly")
        parts.append(part)
    if t.problems:
        raise DialectProblem(t.problems, t.notes)

    _masses(t, parts, kinds, given_mass, total_mass)
    _frames(t, data, parts, rotations)
    _wheel_axes(t, parts, kinds)
    _motors(t, parts)
    if t.problems:
        raise DialectProblem(t.problems, t.notes)
    scale = _vector(data.get("approximate_scale"), 3)
    description: dict[str, Any] = {
        "robot_name": robot_name,
        "description": _description_text(data),
        "physics": {"floor": True, **({"friction": min(max(friction, 0.0), 10.0)} if friction is not None else {})},
        "parts": parts,
    }
    if scale is not None:
        t.note(f"approximate_scale {scale} used only to check the position frame")
    _mobile_root(t, description)
    return Translation(description, t.notes, [])


def _description_text(data: Mapping[str, Any]) -> str:
    text = str(data.get("description") or "")
    steps = data.get("assembly_instructions")
    if isinstance(steps, list) and steps:
        text = (text + "\n" if text else "") + "Assembly: " + " ".join(str(s) for s in steps)
    return text[:4000]


def _joint(t: _Translator, label: str, name: str, kind: str, raw: Mapping[str, Any], default_damping: float | None,
           degrees: bool, motor_raw: Mapping[str, Any] | None, part: dict[str, Any]) -> dict[str, Any] | None:
    jtype = JOINT_TYPES.get(str(raw.get("type", "")).strip().lower())
    if jtype is None:
        t.problems.append(f"{label}: joint type {raw.get('type')!r} is not hinge, slider or fixed")
        return None
    if jtype != raw.get("type"):
        t.note(f"{label}: joint type {raw.get('type')!r} read as {jtype!r}")
    for key in sorted(set(raw) - JOINT_KEYS - {"anchor", "name", "motor"}):
        t.note(f"{label}: joint key {key!r} is not in the schema; kept as a note: {str(raw[key])[:200]}")
    joint: dict[str, Any] = {"type": jtype, "name": _clean_name(raw.get("name") or f"{name}_joint", "joint")}
    if jtype == "fixed":
        return joint
    axis = _vector(raw.get("axis"), 3)
    if axis is None or math.sqrt(sum(a * a for a in axis)) < 1e-9:
        t.problems.append(f"{label}: joint axis {raw.get('axis')!r} is missing or zero; give a unit vector in the "
                          "parent part's frame, e.g. [0, 1, 0]")
        return None
    joint["axis"] = axis
    anchor = _vector(raw.get("anchor"), 3)
    if anchor is not None:
        joint["anchor"] = anchor
        t.note(f"{label}: joint anchor taken from the joint's 'anchor' (not in the schema)")
    elif jtype == "hinge":
        t.note(f"{label}: the schema gives no hinge anchor; the hinge passes through the part's position")
    limits = _vector(raw.get("limits"), 2)
    if limits is not None and limits != [0.0, 0.0]:
        lo, hi = limits
        if jtype == "hinge" and (degrees or max(abs(lo), abs(hi)) > 2 * math.pi + 1e-6):
            lo, hi = math.radians(lo), math.radians(hi)
            t.note(f"{label}: hinge limits {limits} read in degrees")
        if lo > hi:
            lo, hi = hi, lo
            t.note(f"{label}: limits given as [max, min]; swapped")
        if lo < hi:
            if jtype == "hinge" and max(abs(lo), abs(hi)) > math.pi:
                t.note(f"{label}: hinge limits [{lo:.4g}, {hi:.4g}] rad reach past +-pi: the joint is left unlimited")
            else:
                joint["limits"] = [lo, hi]
    elif raw.get("limits") is not None:
        t.note(f"{label}: limits {raw.get('limits')!r} are a placeholder; the joint is unlimited")
    stiffness = _number(raw.get("stiffness"))
    if stiffness is not None and stiffness > 0:
        joint["stiffness"] = stiffness
    damping = _number(raw.get("damping"))
    if damping is not None and damping >= 0:
        joint["damping"] = damping
    elif default_damping:
        joint["damping"] = default_damping
    inner_motor = raw.get("motor")
    if isinstance(inner_motor, Mapping):
        motor_raw = inner_motor
    if motor_raw is not None:
        part["motor"] = t.motor(label, motor_raw, name)
    return joint


def _masses(t: _Translator, parts: list[dict[str, Any]], kinds: list[str], given: list[float | None],
            total: float | None) -> None:
    volumes = [_volume(k, p["dimensions"]) for k, p in zip(kinds, parts, strict=True)]
    known = sum(m for m in given if m is not None)
    missing = [i for i, m in enumerate(given) if m is None]
    if missing:
        missing_volume = sum(volumes[i] for i in missing) or 1.0
        left = (total - known) if total is not None else None
        if left is not None and left > 0:
            t.note(f"parts {[parts[i]['name'] for i in missing]} had no usable mass: they share the "
                   f"{left:.4g} kg that physics.mass leaves, by volume")
            for i in missing:
                given[i] = left * volumes[i] / missing_volume
        else:
            if left is not None:
                t.problems.append(
                    f"physics.mass is {total:g} kg but the parts that give a mass already weigh {known:.4g} kg, so "
                    f"nothing is left for {[parts[i]['name'] for i in missing]}: give those parts a mass, or raise "
                    "physics.mass")
                return
            t.note(f"parts {[parts[i]['name'] for i in missing]} had no usable mass: water density "
                   f"({WATER_DENSITY:g} kg/m^3) times their volume")
            for i in missing:
                given[i] = WATER_DENSITY * volumes[i]
    elif total is not None and abs(known - total) > MASS_TOLERANCE * total:
        heaviest = sorted(range(len(parts)), key=lambda i: -(given[i] or 0.0))[:3]
        t.problems.append(
            f"masses do not add up: the parts weigh {known:.4g} kg in all but physics.mass is {total:g} kg "
            f"({100 * (known - total) / total:+.0f} %); correct the part masses (heaviest: "
            f"{', '.join(repr(parts[i]['name']) for i in heaviest)}) or physics.mass so they agree within "
            f"{100 * MASS_TOLERANCE:.0f} %")
        return
    for part, mass in zip(parts, given, strict=True):
        part["mass"] = max(float(mass or 0.0), 1e-4)


def _world_poses(parts: list[dict[str, Any]], rotations: list[Rotation], world: bool
                 ) -> tuple[list[np.ndarray], list[Rotation]]:
    """Every part's world position and rotation when positions are read as world (or parent-relative)."""
    index = {p["name"]: i for i, p in enumerate(parts)}
    positions: list[np.ndarray | None] = [None] * len(parts)
    frames: list[Rotation | None] = [None] * len(parts)

    def resolve(i: int, depth: int = 0) -> None:
        if positions[i] is not None:
            return
        part = parts[i]
        parent = index.get(part["parent"]) if part["parent"] is not None else None
        if world or parent is None or depth > len(parts):
            positions[i], frames[i] = np.asarray(part["position"], float), rotations[i]
            return
        resolve(parent, depth + 1)
        parent_rotation = frames[parent]
        assert parent_rotation is not None
        positions[i] = positions[parent] + parent_rotation.apply(part["position"])
        frames[i] = parent_rotation * rotations[i]

    for i in range(len(parts)):
        resolve(i)
    return [p for p in positions if p is not None], [f for f in frames if f is not None]


def _frames(t: _Translator, data: Mapping[str, Any], parts: list[dict[str, Any]], rotations: list[Rotation]) -> None:
    """Decide the position frame, then write parent-relative positions, axis-angle orientations and axes."""
    declared = str(data.get("position_frame", data.get("frame", ""))).strip().lower()
    scale = _vector(data.get("approximate_scale"), 3)
    if declared in ("world", "global", "absolute"):
        world = True
        t.note("positions, orientations and joint axes are in the world frame (the file's position_frame says so)")
    elif declared in ("parent", "local", "relative"):
        world = False
        t.note("positions are in the parent part's frame (the file's position_frame says so)")
    elif scale is not None and all(s > 0 for s in scale) and len(parts) > 1:
        errors = {}
        for reading in (False, True):
            positions, frames = _world_poses(parts, rotations, reading)
            corners = []
            for part, position, frame in zip(parts, positions, frames, strict=True):
                half = _half_extent(part["type"], part["dimensions"])
                corners.append(position + np.abs(frame.as_matrix()) @ half)
                corners.append(position - np.abs(frame.as_matrix()) @ half)
            extent = np.ptp(np.asarray(corners), axis=0)
            errors[reading] = float(np.sum(np.abs(np.log(np.maximum(extent, 1e-6) / np.asarray(scale)))))
        # a clear preference only: a tie (children near their parent's origin) keeps Webots' convention
        world = errors[True] < errors[False] - 0.05
        if abs(errors[True] - errors[False]) <= 0.05:
            t.note(f"positions are read in the parent part's frame (Webots' convention): both readings fit "
                   f"approximate_scale {scale} equally (log-error {errors[False]:.3g} and {errors[True]:.3g})")
        else:
            t.note(f"positions read in the {'world' if world else 'parent part'}'s frame: that reading's overall "
                   f"extent is closer to approximate_scale {scale} (log-error {errors[world]:.3g} against "
                   f"{errors[not world]:.3g})")
    else:
        world = False
        t.note("positions are read in the parent part's frame (Webots' convention; the schema does not say)")
    if not world:
        for part, rotation in zip(parts, rotations, strict=True):
            part["orientation"] = _axis_angle(rotation)
        return
    positions, frames = _world_poses(parts, rotations, True)
    index = {p["name"]: i for i, p in enumerate(parts)}
    for i, part in enumerate(parts):
        parent = index.get(part["parent"]) if part["parent"] is not None else None
        if parent is None:
            part["orientation"] = _axis_angle(frames[i])
            continue
        to_parent = frames[parent].inv()
        part["position"] = [float(v) for v in to_parent.apply(positions[i] - positions[parent])]
        part["orientation"] = _axis_angle(to_parent * frames[i])
        joint = part.get("joint")
        if joint and "axis" in joint:
            joint["axis"] = [float(v) for v in to_parent.apply(joint["axis"])]
            if "anchor" in joint:
                joint["anchor"] = [float(v) for v in to_parent.apply(np.asarray(joint["anchor"]) - positions[parent])]


def _axis_angle(rotation: Rotation) -> list[float]:
    return axis_angle_from_rotvec(rotation.as_rotvec())


def _looks_like_wheel(part: dict[str, Any], kind: str) -> bool:
    return kind == "cylinder" and ("wheel" in part["name"].lower()
                                   or part["dimensions"][0] > part["dimensions"][1])


def _mobile_root(t: _Translator, description: dict[str, Any]) -> None:
    """The paper's schema gives every part a joint, the root's being 'fixed': on a robot that drives wheels on
    the floor that means "the base part", not "welded to the world" (our schema's fixed base), so the root's
    joint is dropped and the reading is said."""
    try:
        desc = RobotDescription.model_validate(description)
        check_tree(desc)  # (no root, or two: desc.root below would raise StopIteration, a traceback)
    except (ValidationError, DualtwinError):
        return  # the description's own errors are reported where it is validated
    root = desc.root
    if root.joint is None or root.joint.type != "fixed":
        return
    wheels = grounded_wheels(desc)
    if not wheels:
        return
    for part in description["parts"]:
        if part["name"] == root.name:
            part.pop("joint", None)
    t.note(f"part {root.name!r}: the root's joint 'fixed' read as a free mobile base, since the robot drives "
           f"wheels on the floor ({', '.join(wheels)}); a welded base would spin them in place. Give the root "
           "no joint in our schema to say so, or mount the robot on a fixed part to weld it")


def _wheel_axes(t: _Translator, parts: list[dict[str, Any]], kinds: list[str]) -> None:
    """A wheel (a disc-shaped or wheel-named cylinder on a hinge) must spin about its own axis."""
    for part, kind in zip(parts, kinds, strict=True):
        joint = part.get("joint")
        if not joint or joint.get("type") != "hinge" or not _looks_like_wheel(part, kind):
            continue
        x, y, z, angle = part["orientation"]
        own_axis = Rotation.from_rotvec(np.asarray([x, y, z]) * angle).apply([0.0, 0.0, 1.0])
        hinge = np.asarray(joint["axis"], float) / np.linalg.norm(joint["axis"])
        cosine = abs(float(own_axis @ hinge))
        if cosine < math.cos(math.radians(WHEEL_AXIS_TOLERANCE_DEG)):
            # the rotation that takes the cylinder's z onto the hinge axis, as a Webots axis-angle
            fix = _axis_angle(Rotation.align_vectors([hinge], [[0.0, 0.0, 1.0]])[0])
            t.problems.append(
                f"part {part['name']!r}: its cylinder axis is {np.round(own_axis, 3).tolist()} in the parent's frame "
                f"but its hinge axis is {np.round(hinge, 3).tolist()} ({math.degrees(math.acos(min(cosine, 1.0))):.0f}"
                f" degrees apart), so the wheel would not roll; set its orientation to "
                f"{[round(v, 4) for v in fix]} (axis-angle) or make the hinge axis {np.round(own_axis, 3).tolist()}")


def _motors(t: _Translator, parts: list[dict[str, Any]]) -> None:
    if any("motor" in p for p in parts):
        return
    wheels, sensed = [], []
    for part in parts:
        joint = part.get("joint")
        if not joint or joint.get("type") not in ("hinge", "slider"):
            continue
        if joint["type"] == "hinge" and "wheel" in part["name"].lower():
            part["motor"] = {"name": part["name"], "maxVelocity": DEFAULT_WHEEL_MAX_VELOCITY,
                             "maxTorque": DEFAULT_WHEEL_MAX_TORQUE, "sensor": f"{part['name']} sensor"}
            wheels.append(part["name"])
        else:
            joint["sensor"] = f"{part['name']} sensor"
            sensed.append(part["name"])
    if wheels:
        t.note(f"the schema has no motors: the wheel hinges {wheels} got velocity motors (maxVelocity "
               f"{DEFAULT_WHEEL_MAX_VELOCITY:g} rad/s, maxTorque {DEFAULT_WHEEL_MAX_TORQUE:g} N*m) with position "
               "sensors")
    if sensed:
        t.note(f"the other joints {sensed} are passive, each with a position sensor '<part> sensor'")


# ------------------------------------------------------------------------------------------------
# reading either dialect


@dataclass
class ReadDescription:
    """A description read from either dialect, with the dialect and the assumptions its translation made."""

    description: RobotDescription
    dialect: Literal["dualtwin", "paper"]
    assumptions: list[str]


def read_description(data: Any, origin: str = "<description>", dialect: Dialect = "auto") -> ReadDescription:
    """Validate ``data`` (parsed JSON or JSON text) in ``dialect`` (``auto``: :func:`detect`)."""
    if isinstance(data, str | bytes):
        try:
            data = json.loads(data)
        except json.JSONDecodeError as exc:
            raise DualtwinError(f"{origin}: invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    chosen = detect(data) if dialect == "auto" else dialect
    if chosen == "dualtwin":
        return ReadDescription(parse_description(data, origin), "dualtwin", [])
    try:
        translation = translate(data)
    except DialectProblem as exc:
        raise DialectProblem(exc.problems, exc.notes, origin) from None
    except DualtwinError as exc:
        raise DualtwinError(f"{origin}: {exc}") from None
    return ReadDescription(parse_description(translation.description, origin), "paper", translation.notes)


def load_any_description(path: Path, dialect: Dialect = "auto") -> ReadDescription:
    """:func:`read_description` of a file; unreadable files are one DualtwinError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise DualtwinError(f"{path}: not a file" if path.exists() else f"{path}: file not found")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DualtwinError(f"{path}: not UTF-8 text (byte {exc.start}); a robot description is JSON") from None
    return read_description(text, str(path), dialect)
