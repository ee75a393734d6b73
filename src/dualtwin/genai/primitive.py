"""The primitive robot description (roboGen-LLM's JSON IR) and its compilers to both twins.

A robot is a tree of rigid ``parts``, each one primitive (box, cylinder, sphere, capsule) with a mass, placed
relative to its ``parent`` part and attached by a ``joint`` (hinge, slider or fixed) that may carry a
``motor`` (and a position ``sensor``). Conventions are Webots' (R2023b, ENU, SI units, radians):

* ``position``/``orientation`` (axis-angle ``[x, y, z, angle]``) place the part's frame in its parent's frame
  (the world for the root part); the primitive is centred on the part frame;
* box ``dimensions`` = full extents ``[x, y, z]``; cylinder ``[radius, height]`` and capsule ``[radius, height
  of the cylindrical part]`` along the part's z axis; sphere ``[radius]``;
* joint ``axis`` and ``anchor`` are in the parent part's frame (anchor defaults to the part's position);
  ``limits`` are relative to the pose written in the file;
* the root part has no joint (free-floating robot) or ``{"type": "fixed"}`` (fixed base).

One description compiles to a Webots world (:func:`to_world_text`) and, through the Webots -> MuJoCo converter,
to an MJCF with the same names, explicit inertials and ``webots_motor`` numerics (:func:`compile_description`);
:func:`mjcf_to_description` goes back from an MJCF made of primitives (best effort).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import mujoco
import numpy as np
from pydantic import Field, ValidationError, model_validator

from dualtwin.errors import DualtwinError
from dualtwin.geometry import axis_angle_from_quat, axis_angle_matrix, mujoco_quat
from dualtwin.models import StrictModel
from dualtwin.webots import schema
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.writer import write_world

#: Size limits for untrusted descriptions (LLM output): a generous robot, nothing runaway.
MAX_PARTS = 64
MAX_DIMENSION_M = 50.0
MIN_DIMENSION_M = 1e-3
MAX_POSITION_M = 100.0
MAX_MASS_KG = 1e4
MIN_MASS_KG = 1e-4
NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]{0,63}$"
DEVICE_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9_ \-]{0,63}$"
SCHEMA_PATH = Path(__file__).parent / "schemas" / "primitive.schema.json"

Coordinate = Annotated[float, Field(ge=-MAX_POSITION_M, le=MAX_POSITION_M, allow_inf_nan=False)]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]
DIMENSION_COUNT = {"box": 3, "cylinder": 2, "capsule": 2, "sphere": 1}


class Joint(StrictModel):
    """How a part is attached to its parent."""

    type: Literal["hinge", "slider", "fixed"] = Field(description="hinge (rotation), slider (translation) or fixed")
    name: str | None = Field(default=None, pattern=NAME_PATTERN, description="joint name; default '<part>_joint'")
    axis: Vec3 = Field(default=(0.0, 0.0, 1.0), description="joint axis in the parent part's frame")
    anchor: Vec3 | None = Field(default=None, description="hinge: point on the axis, parent frame; default = part position")
    limits: tuple[float, float] | None = Field(default=None, description="[min, max] in rad (hinge) or m (slider)")
    damping: float = Field(default=0.0, ge=0.0, le=1e4, description="viscous damping, N*m*s/rad or N*s/m")
    stiffness: float = Field(default=0.0, ge=0.0, le=1e6,
                             description="spring constant towards the pose in the file, N*m/rad or N/m")
    sensor: str | None = Field(default=None, pattern=DEVICE_PATTERN,
                               description="PositionSensor on a joint without motor (a motor names its own)")

    @model_validator(mode="after")
    def _check(self) -> Joint:
        if math.sqrt(sum(v * v for v in self.axis)) < 1e-9:
            raise ValueError("joint axis must not be zero")
        if self.limits is not None:
            lo, hi = self.limits
            if not lo < hi:
                raise ValueError(f"joint limits must satisfy min < max (got {lo}, {hi})")
            if self.type == "hinge" and max(abs(lo), abs(hi)) > math.pi + 1e-6:
                raise ValueError(f"hinge limits are radians within [-pi, pi] (got {lo}, {hi}: degrees?)")
        return self


class Motor(StrictModel):
    """A Webots RotationalMotor (hinge) or LinearMotor (slider) on the part's joint."""

    name: str = Field(pattern=DEVICE_PATTERN, description="device name (also the MuJoCo actuator name)")
    maxVelocity: float = Field(default=10.0, gt=0.0, le=1e4, description="rad/s or m/s")
    maxTorque: float = Field(default=10.0, gt=0.0, le=1e5, description="N*m (hinge) or N (slider)")
    sensor: str | None = Field(default=None, pattern=DEVICE_PATTERN, description="name of a PositionSensor on the joint")


class Part(StrictModel):
    """One rigid primitive."""

    name: str = Field(pattern=NAME_PATTERN, description="unique part name (also the body name)")
    type: Literal["box", "cylinder", "sphere", "capsule"]
    dimensions: list[Annotated[float, Field(ge=MIN_DIMENSION_M, le=MAX_DIMENSION_M)]] = Field(
        min_length=1, max_length=3,
        description="box [x, y, z] full extents; cylinder/capsule [radius, height] along z; sphere [radius]")
    mass: float = Field(ge=MIN_MASS_KG, le=MAX_MASS_KG, description="kg")
    position: Vec3 = Field(default=(0.0, 0.0, 0.0), description="part frame origin in the parent's frame, m")
    orientation: tuple[float, float, float, float] = Field(
        default=(0.0, 0.0, 1.0, 0.0), description="axis-angle [x, y, z, angle_rad] in the parent's frame")
    parent: str | None = Field(default=None, description="parent part name; null for the single root part")
    joint: Joint | None = Field(default=None, description="root: null = free-floating, fixed = fixed base")
    motor: Motor | None = None
    color: tuple[float, float, float] | None = Field(default=None, description="RGB in [0, 1]")
    material: str | None = Field(default=None, max_length=64, description="free-text label; not used by physics")

    @model_validator(mode="after")
    def _check(self) -> Part:
        expected = DIMENSION_COUNT[self.type]
        if len(self.dimensions) != expected:
            raise ValueError(f"part {self.name!r}: a {self.type} needs {expected} dimensions, got {len(self.dimensions)}")
        if abs(self.orientation[3]) > 2 * math.pi + 1e-6:
            raise ValueError(f"part {self.name!r}: orientation angle {self.orientation[3]} exceeds 2*pi (degrees?)")
        if self.motor is not None and (self.joint is None or self.joint.type == "fixed"):
            raise ValueError(f"part {self.name!r}: a motor needs a hinge or slider joint")
        if self.joint is not None and self.joint.sensor and self.joint.type == "fixed":
            raise ValueError(f"part {self.name!r}: a position sensor needs a hinge or slider joint")
        return self


class PhysicsSettings(StrictModel):
    """World settings (Webots WorldInfo)."""

    timestep_ms: float = Field(default=16.0, ge=1.0, le=100.0, description="Webots basicTimeStep, ms")
    gravity: float = Field(default=9.81, ge=0.0, le=100.0, description="m/s^2, along -z")
    floor: bool = Field(default=True, description="add an infinite floor plane at z = 0")
    friction: float = Field(default=1.0, ge=0.0, le=10.0, description="Coulomb friction robot/floor")


class RobotDescription(StrictModel):
    """A robot made of primitives."""

    robot_name: str = Field(pattern=NAME_PATTERN)
    description: str = Field(default="", max_length=4000)
    physics: PhysicsSettings = Field(default_factory=PhysicsSettings)
    parts: list[Part] = Field(min_length=1, max_length=MAX_PARTS)

    @property
    def root(self) -> Part:
        return next(p for p in self.parts if p.parent is None)

    def children(self, name: str) -> list[Part]:
        return [p for p in self.parts if p.parent == name]


def check_tree(desc: RobotDescription) -> None:
    """Cross-references, resolved by the compiler (like MuJoCo resolves names): unique names, one root,
    known parents, no cycles, unique joint and device names. Raises DualtwinError naming the culprit."""
    names = [p.name for p in desc.parts]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DualtwinError(f"part names must be unique: {dup}")
    roots = [p.name for p in desc.parts if p.parent is None]
    if len(roots) != 1:
        raise DualtwinError(f"exactly one part must have parent null (the root), got {roots}")
    known = set(names)
    for p in desc.parts:
        if p.parent is not None and p.parent not in known:
            raise DualtwinError(f"part {p.name!r}: unknown parent {p.parent!r} (parts: {', '.join(names)})")
    parent = {p.name: p.parent for p in desc.parts}
    for name in names:
        seen: set[str] = set()
        cur: str | None = name
        while cur is not None:
            if cur in seen:
                raise DualtwinError(f"parts form a cycle through {cur!r}")
            seen.add(cur)
            cur = parent[cur]
    devices: list[str] = []
    for p in desc.parts:
        if p.motor is not None:
            devices.append(p.motor.name)
            if p.motor.sensor:
                devices.append(p.motor.sensor)
        if p.joint is not None and p.joint.sensor and not (p.motor is not None and p.motor.sensor == p.joint.sensor):
            devices.append(p.joint.sensor)
    dup = sorted({d for d in devices if devices.count(d) > 1})
    if dup:
        raise DualtwinError(f"motor and sensor names must be unique: {dup}")
    joint_names = [p.joint.name or f"{p.name}_joint" for p in desc.parts if p.joint and p.joint.type != "fixed"]
    dup = sorted({d for d in joint_names if joint_names.count(d) > 1})
    if dup:
        raise DualtwinError(f"joint names must be unique: {dup}")


#: A driven hinge whose axis leans less than this from horizontal, on a wheel no higher than its radius plus
#: this clearance above the floor, is a wheel that rolls on the floor.
WHEEL_AXIS_HORIZONTAL_TOL = 0.3
WHEEL_FLOOR_CLEARANCE_M = 0.02


def _world_frames(desc: RobotDescription) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every part's (position, rotation matrix) in the world, composing the parent-relative frames."""
    by_name = {p.name: p for p in desc.parts}
    frames: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def frame(name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in frames:
            part = by_name[name]
            local_R = axis_angle_matrix(part.orientation)
            local_t = np.asarray(part.position, float)
            if part.parent is None:
                frames[name] = (local_t, local_R)
            else:
                pt, pR = frame(part.parent)
                frames[name] = (pt + pR @ local_t, pR @ local_R)
        return frames[name]

    for part in desc.parts:
        frame(part.name)
    return frames


def grounded_wheels(desc: RobotDescription) -> list[str]:
    """Parts that are wheels rolling on the floor: a motor-driven hinge about the part's own (horizontal) axis,
    a cylinder or sphere whose centre is no higher than its radius (plus a small clearance) above z = 0.

    A turntable (vertical axis) or a driven drum held in the air is not one; a wheel on a robot whose root is
    welded to the world is the mistake :func:`check_mobile_base` names.
    """
    if not desc.physics.floor:
        return []
    frames = _world_frames(desc)
    wheels = []
    for part in desc.parts:
        joint = part.joint
        if part.motor is None or joint is None or joint.type != "hinge" or part.type not in ("cylinder", "sphere"):
            continue
        t, R = frames[part.name]
        parent_R = frames[part.parent][1] if part.parent is not None else np.eye(3)
        axis = parent_R @ (np.asarray(joint.axis, float) / max(float(np.linalg.norm(joint.axis)), 1e-12))
        if abs(float(axis[2])) > WHEEL_AXIS_HORIZONTAL_TOL:
            continue
        radius = float(part.dimensions[0])
        if part.type == "cylinder" and abs(float(axis @ (R @ np.array([0.0, 0.0, 1.0])))) < 0.9:
            continue  # the hinge does not spin the cylinder about its own axis: not a rolling wheel
        if float(t[2]) <= radius + WHEEL_FLOOR_CLEARANCE_M:
            wheels.append(part.name)
    return wheels


def check_mobile_base(desc: RobotDescription) -> None:
    """Refuse a robot welded to the world that drives wheels on the floor (a fixed root is for mounted robots).

    Raises:
        DualtwinError: naming the root, the wheels and the fix.
    """
    root = desc.root
    if root.joint is None or root.joint.type != "fixed":
        return
    wheels = grounded_wheels(desc)
    if wheels:
        raise DualtwinError(
            f"root part {root.name!r} has joint type 'fixed', which welds the robot to the world, but it drives "
            f"wheels on the floor ({', '.join(wheels)}): the wheels would spin in place and the two twins disagree "
            "on how they touch the floor; a mobile robot's root has no joint (remove the root's \"joint\"), a "
            "fixed base is for arms and other mounted robots")


def json_schema() -> dict[str, Any]:
    """The JSON Schema of :class:`RobotDescription` (also shipped as ``schemas/primitive.schema.json``)."""
    data = RobotDescription.model_json_schema()
    data["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    data["$id"] = "https://dualtwin.dev/schemas/primitive.schema.json"
    return data


def write_json_schema(path: Path = SCHEMA_PATH) -> Path:
    path.write_text(json.dumps(json_schema(), indent=2) + "\n", encoding="utf-8")
    return path


def validation_errors(exc: ValidationError) -> str:
    """Compact, LLM-readable list of validation errors (``parts.2.dimensions: ...``)."""
    lines = []
    for err in exc.errors()[:20]:
        loc = ".".join(str(x) for x in err["loc"])
        lines.append(f"{loc or '<root>'}: {err['msg']}")
    return "\n".join(lines)


def parse_description(data: Any, origin: str = "<description>") -> RobotDescription:
    """Validate a dict (or JSON text) as a robot description; errors name the field."""
    if isinstance(data, str | bytes):
        try:
            data = json.loads(data)
        except json.JSONDecodeError as exc:
            raise DualtwinError(f"{origin}: invalid JSON: {exc}") from None
    try:
        return RobotDescription.model_validate(data)
    except ValidationError as exc:
        raise DualtwinError(f"{origin}: invalid robot description:\n{validation_errors(exc)}") from None


def load_description(path: Path) -> RobotDescription:
    path = Path(path)
    if not path.is_file():
        raise DualtwinError(f"{path}: file not found")
    return parse_description(path.read_text(encoding="utf-8"), str(path))


# ------------------------------------------------------------------------------------------------
# JSON -> Webots world


def _node(type_name: str, def_name: str | None = None, **values: Any) -> Node:
    fields = schema.default_fields(type_name)
    unknown = set(values) - set(fields)
    if unknown:
        raise ValueError(f"{type_name} has no fields {sorted(unknown)}")
    fields.update(values)
    return Node(type_name, fields, def_name=def_name)


def _geometry(part: Part) -> Node:
    d = [float(v) for v in part.dimensions]
    if part.type == "box":
        return _node("Box", size=(d[0], d[1], d[2]))
    if part.type == "sphere":
        return _node("Sphere", radius=d[0])
    if part.type == "cylinder":
        return _node("Cylinder", radius=d[0], height=d[1])
    return _node("Capsule", radius=d[0], height=d[1])


def _f3(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _solid(desc: RobotDescription, part: Part, *, robot: bool) -> Node:
    color = _f3(part.color) if part.color is not None else (0.6, 0.6, 0.65)
    shape = _node("Shape", appearance=_node("PBRAppearance", baseColor=color, roughness=1.0, metalness=0.0),
                  geometry=_geometry(part))
    children: list[Node] = [shape]
    for child in desc.children(part.name):
        children.append(_attachment(desc, child))
    fixed_base = robot and part.joint is not None and part.joint.type == "fixed"
    values: dict[str, Any] = {
        "translation": _f3(part.position),
        "rotation": tuple(float(v) for v in part.orientation),
        "children": children,
        "name": part.name,
        "boundingObject": _geometry(part),
        "physics": None if fixed_base else _node("Physics", density=-1.0, mass=float(part.mass)),
    }
    if robot:
        # DEF = root part name (the MuJoCo body name); the Robot's name is the robot's.
        values.update(name=desc.robot_name, controller="<extern>", supervisor=True)
        return _node("Robot", def_name=part.name, **values)
    return _node("Solid", def_name=part.name, **values)


def _attachment(desc: RobotDescription, part: Part) -> Node:
    solid = _solid(desc, part, robot=False)
    joint = part.joint
    if joint is None or joint.type == "fixed":
        return solid  # merged into the parent body, as Webots merges jointless physical Solids
    devices: list[Node] = []
    if part.motor is not None:
        m = part.motor
        if joint.type == "hinge":
            devices.append(_node("RotationalMotor", name=m.name, maxVelocity=m.maxVelocity, maxTorque=m.maxTorque))
        else:
            devices.append(_node("LinearMotor", name=m.name, maxVelocity=m.maxVelocity, maxForce=m.maxTorque))
        if m.sensor:
            devices.append(_node("PositionSensor", name=m.sensor))
    if joint.sensor and not (part.motor is not None and part.motor.sensor == joint.sensor):
        devices.append(_node("PositionSensor", name=joint.sensor))
    params: dict[str, Any] = {"axis": _f3(joint.axis), "dampingConstant": float(joint.damping)}
    if joint.stiffness:
        params["springConstant"] = float(joint.stiffness)
    if joint.limits is not None:
        params.update(minStop=float(joint.limits[0]), maxStop=float(joint.limits[1]))
    if joint.type == "hinge":
        params["anchor"] = _f3(joint.anchor if joint.anchor is not None else part.position)
        jp = _node("HingeJointParameters", **params)
        kind = "HingeJoint"
    else:
        jp = _node("JointParameters", **params)
        kind = "SliderJoint"
    return _node(kind, def_name=joint.name or f"{part.name}_joint", jointParameters=jp, device=devices,
                 endPoint=solid)


def to_world(desc: RobotDescription, path: str = "robot.wbt") -> World:
    """The description as a Webots world tree: WorldInfo, optional floor, the Robot."""
    contact = _node("ContactProperties", coulombFriction=[float(desc.physics.friction)])
    info = _node("WorldInfo", title=desc.robot_name, info=[desc.description[:200]] if desc.description else [],
                 basicTimeStep=float(desc.physics.timestep_ms), gravity=float(desc.physics.gravity),
                 contactProperties=[contact])
    nodes = [info, _node("Viewpoint", orientation=(-0.2, 0.1, 0.97, 2.5), position=(2.5, 2.5, 1.5))]
    if desc.physics.floor:
        plane = _node("Plane", size=(20.0, 20.0))
        nodes.append(_node("Solid", def_name="FLOOR", name="floor",
                           children=[_node("Shape", appearance=_node("PBRAppearance", baseColor=(0.8, 0.8, 0.8),
                                                                     roughness=1.0, metalness=0.0),
                                           geometry=plane)],
                           boundingObject=_node("Plane", size=(20.0, 20.0)), locked=True))
    nodes.append(_solid(desc, desc.root, robot=True))
    return World(path=path, header="#VRML_SIM R2023b utf8", nodes=nodes)


def to_world_text(desc: RobotDescription) -> str:
    header = f"# {desc.robot_name}: generated by dualtwin from a primitive description.\n"
    text = write_world(to_world(desc), externprotos=False)
    first, _, rest = text.partition("\n")
    return f"{first}\n{header}{rest}"


@dataclass
class CompiledRobot:
    """Both twins of a description: world text, MJCF (spec) and binding data."""

    description: RobotDescription
    wbt_text: str
    conversion: Any  # dualtwin.convert.Conversion

    @property
    def spec(self) -> mujoco.MjSpec:
        return self.conversion.spec

    @property
    def xml(self) -> str:
        return str(self.conversion.xml)

    def write(self, out_dir: Path) -> dict[str, Path]:
        """Write ``<name>.wbt``, ``<name>.xml``, ``robot.json`` and (if it has sensors) ``binding.yaml``."""
        from dualtwin.artifacts import write_text
        from dualtwin.convert.bindings import validate_binding

        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        name = self.description.robot_name
        paths = {"wbt": out_dir / f"{name}.wbt", "xml": out_dir / f"{name}.xml", "json": out_dir / "robot.json"}
        write_text(paths["wbt"], self.wbt_text)
        write_text(paths["xml"], self.xml)
        write_text(paths["json"], self.description.model_dump_json(indent=2, exclude_none=True) + "\n")
        binding = self.conversion.binding_dict(paths["xml"].name, paths["wbt"].name)
        if binding.get("onboard"):
            validate_binding(binding, out_dir / "binding.yaml")
            paths["binding"] = out_dir / "binding.yaml"
            write_text(paths["binding"], self.conversion.binding_yaml(paths["xml"].name, paths["wbt"].name))
        return paths


def compile_description(desc: RobotDescription, wbt_path: str | None = None) -> CompiledRobot:
    """Description -> Webots world text -> (our converter, MjSpec) MJCF. Raises DualtwinError on failure."""
    from dualtwin.convert.webots_to_mjcf import convert_world_text

    check_tree(desc)
    check_mobile_base(desc)
    text = to_world_text(desc)
    conversion = convert_world_text(text, wbt_path or f"{desc.robot_name}.wbt", desc.robot_name)
    return CompiledRobot(desc, text, conversion)


# ------------------------------------------------------------------------------------------------
# MJCF -> JSON (best effort)

_PRIMITIVES = {
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
}


def _clean(name: str, fallback: str) -> str:
    text = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")
    if not text or not re.match(r"[A-Za-z_]", text[0]):
        text = f"{fallback}_{text}" if text else fallback
    return text[:64]


def _dims(gtype: str, size: np.ndarray) -> list[float]:
    if gtype == "box":
        return [float(2 * size[0]), float(2 * size[1]), float(2 * size[2])]
    if gtype == "sphere":
        return [float(size[0])]
    return [float(size[0]), float(2 * size[1])]


def _volume(gtype: str, size: np.ndarray) -> float:
    if gtype == "box":
        return float(8 * size[0] * size[1] * size[2])
    if gtype == "sphere":
        return float(4 / 3 * math.pi * size[0] ** 3)
    if gtype == "cylinder":
        return float(math.pi * size[0] ** 2 * 2 * size[1])
    return float(math.pi * size[0] ** 2 * 2 * size[1] + 4 / 3 * math.pi * size[0] ** 3)


def mjcf_to_description(source: Path | str | mujoco.MjSpec, robot_name: str | None = None) -> RobotDescription:
    """Best-effort inverse for MJCFs made of primitives: one part per primitive geom, joints/motors/sensors kept.

    Bodies with several primitive geoms become several parts rigidly attached (mass split by volume);
    mesh/plane/hfield geoms of the robot are not representable and raise DualtwinError.
    """
    if isinstance(source, mujoco.MjSpec):
        spec, origin = source, "<MjSpec>"
    else:
        origin = str(source)
        try:
            spec = mujoco.MjSpec.from_file(str(source))
        except ValueError as exc:
            raise DualtwinError(f"{origin}: MJCF does not parse: {' '.join(str(exc).split())}") from None
    try:
        model = spec.compile()
    except ValueError as exc:
        raise DualtwinError(f"{origin}: MJCF does not compile: {' '.join(str(exc).split())}") from None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)

    def name_of(kind: mujoco.mjtObj, i: int) -> str:
        return mujoco.mj_id2name(model, kind, i) or ""

    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    moving = [b for b in roots if model.body_dofnum[b] or any(
        model.body_rootid[c] == b and model.body_dofnum[c] for c in range(1, model.nbody))]
    if not moving:
        raise DualtwinError(f"{origin}: no robot (no body with joints under the world body)")
    root = moving[0]
    floor = any(int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE) and model.geom_bodyid[g] == 0
                for g in range(model.ngeom))
    # part frames (world) per body: the first primitive geom's frame
    parts: list[dict[str, Any]] = []
    frame_of: dict[int, tuple[str, np.ndarray, np.ndarray]] = {}  # body -> (part name, R, p)
    used: set[str] = set()

    def unique(base: str) -> str:
        name, i = base, 1
        while name in used:
            name, i = f"{base}_{i}", i + 1
        used.add(name)
        return name

    bodies = [b for b in range(1, model.nbody) if model.body_rootid[b] == root]
    motors = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)
              if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)}
    sensors = {int(model.sensor_objid[s]): s for s in range(model.nsensor)
               if int(model.sensor_type[s]) == int(mujoco.mjtSensor.mjSENS_JOINTPOS)}
    for b in bodies:
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == b]
        collision = [g for g in geoms if model.geom_contype[g] or model.geom_conaffinity[g]]
        candidates = [g for g in (collision or geoms) if int(model.geom_type[g]) in _PRIMITIVES]
        bname = name_of(mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
        if not candidates:
            raise DualtwinError(f"{origin}: body {bname!r} has no primitive geom (box/sphere/cylinder/capsule)")
        volumes = [_volume(_PRIMITIVES[int(model.geom_type[g])], model.geom_size[g]) for g in candidates]
        total_volume = sum(volumes) or 1.0
        parent_body = int(model.body_parentid[b])
        for k, g in enumerate(candidates):
            gtype = _PRIMITIVES[int(model.geom_type[g])]
            R = data.geom_xmat[g].reshape(3, 3).copy()
            p = data.geom_xpos[g].copy()
            pname = unique(_clean(bname if k == 0 else name_of(mujoco.mjtObj.mjOBJ_GEOM, g) or f"{bname}_{k}", "part"))
            if k == 0:
                frame_of[b] = (pname, R, p)
                parent_info = frame_of.get(parent_body) if b != root else None
            else:
                parent_info = frame_of[b]
            if parent_info is None:
                rel_R, rel_p, parent_name = R, p, None
            else:
                parent_name, PR, pp = parent_info
                rel_R, rel_p = PR.T @ R, PR.T @ (p - pp)
            part: dict[str, Any] = {
                "name": pname, "type": gtype, "dimensions": _dims(gtype, model.geom_size[g]),
                "mass": max(float(model.body_mass[b]) * volumes[k] / total_volume, MIN_MASS_KG),
                "position": [float(v) for v in rel_p], "orientation": list(axis_angle_from_quat(mujoco_quat(rel_R))),
                "parent": parent_name,
            }
            rgba = model.geom_rgba[g]
            part["color"] = [float(min(max(v, 0.0), 1.0)) for v in rgba[:3]]
            if k == 0:
                jnts = [j for j in range(model.njnt) if model.jnt_bodyid[j] == b]
                if b == root:
                    if not any(int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE) for j in jnts):
                        part["joint"] = {"type": "fixed"}
                elif jnts:
                    j = jnts[0]
                    jtype = int(model.jnt_type[j])
                    if jtype in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)) and parent_info is not None:
                        _, PR, pp = parent_info
                        joint: dict[str, Any] = {
                            "type": "hinge" if jtype == int(mujoco.mjtJoint.mjJNT_HINGE) else "slider",
                            "name": _clean(name_of(mujoco.mjtObj.mjOBJ_JOINT, j) or f"{pname}_joint", "joint"),
                            "axis": [float(v) for v in PR.T @ data.xaxis[j]],
                            "damping": float(model.dof_damping[model.jnt_dofadr[j]]),
                        }
                        if jtype == int(mujoco.mjtJoint.mjJNT_HINGE):
                            joint["anchor"] = [float(v) for v in PR.T @ (data.xanchor[j] - pp)]
                        if model.jnt_limited[j]:
                            joint["limits"] = [float(v) for v in model.jnt_range[j]]
                        part["joint"] = joint
                        if j in motors:
                            a = motors[j]
                            motor: dict[str, Any] = {"name": name_of(mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"{pname}_motor"}
                            if model.actuator_forcelimited[a]:
                                motor["maxTorque"] = float(abs(model.actuator_forcerange[a, 1])) or 10.0
                            numeric = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, f"webots_motor.{motor['name']}")
                            if numeric >= 0:
                                motor["maxVelocity"] = float(model.numeric_data[model.numeric_adr[numeric]])
                            if j in sensors:
                                motor["sensor"] = name_of(mujoco.mjtObj.mjOBJ_SENSOR, sensors[j])
                            part["motor"] = motor
                        elif j in sensors:
                            joint["sensor"] = name_of(mujoco.mjtObj.mjOBJ_SENSOR, sensors[j])
                    # ball/free joints below the root cannot be expressed: the part stays rigidly attached
            parts.append(part)
    name = robot_name or _clean(str(spec.modelname or "robot"), "robot")
    description = {
        "robot_name": _clean(name, "robot"),
        "description": f"imported from {Path(origin).name}",
        "physics": {"timestep_ms": 8.0, "gravity": float(-model.opt.gravity[2]), "floor": floor},
        "parts": parts,
    }
    return parse_description(description, origin)
