"""Convert a Webots world's robot (and its static environment) into a MuJoCo model with Webots' semantics.

Built on our parser (:func:`dualtwin.webots.load_world`, PROTOs expanded) and ``mujoco.MjSpec``. Mapping
decisions (see ``docs/reference/webots-on-ode.md`` §3-5; the mapping itself is restated below):

Bodies and masses
    A Solid that is a joint endPoint (or the robot root) is a MuJoCo body whose frame is the Solid frame *at
    the file's joint positions*. Plain child Solids (no joint) are merged into their parent body, as Webots
    merges them into one ODE body; their geoms keep the Solid name as a prefix and a site marks their frame.
    Masses follow Webots (:mod:`dualtwin.convert.mass`) and are written as an explicit ``inertial``;
    ``compiler inertiafromgeom="false"`` so no geom adds mass. boundingObject geometry becomes collision
    geoms (group 3, ``mass=0``); Shapes become visual geoms (group 2, ``contype=conaffinity=0``, ``density=0``).
    IndexedFaceSet, Mesh (its file's triangles) and CadShape become MuJoCo meshes (:mod:`dualtwin.convert.surfaces`).
    A root Robot with Physics gets a freejoint, without Physics it is welded to the world (fixed base). The
    robot may sit in Group/Pose/Transform nodes; the world's other robots become bodies, joints and motors outside
    the conversion's lists (:mod:`dualtwin.convert.world_robots`).

Joints
    HingeJoint -> hinge, SliderJoint -> slide, BallJoint -> ball, Hinge2Joint -> two hinges in the child
    body (MuJoCo composes a body's joints in order, so axis 2 turns with hinge 1 as in ODE). ``axis`` and
    ``anchor`` are in the frame of the joint's parent Pose and are re-expressed in the child body frame.
    Webots stores the endPoint *at* ``position``, so ``position`` becomes ``ref`` (``qpos0``; the XML pose is the
    pose there). Positions grow with a right-handed rotation about / a translation along ``axis``, as in MuJoCo
    (§4.3). ``minStop``/``maxStop`` -> ``range`` (if they differ; a hinge's within ±pi of ``position``),
    ``dampingConstant`` -> ``damping``, ``springConstant`` -> ``stiffness`` (rest at 0), ``staticFriction`` -> ``frictionloss``.

Devices
    Motor -> ``general`` actuator on its joint, ``forcerange``/``ctrlrange`` ±maxTorque/maxForce, and a numeric
    ``webots_motor.NAME`` = maxVelocity Kp Ki Kd acceleration [minPosition maxPosition [multiplier]] for
    :mod:`dualtwin.twins.mujoco` (``a::b`` motors harmonised, :mod:`dualtwin.convert.coupled`). PositionSensor ->
    jointpos; InertialUnit -> framequat, Gyro -> gyro, Accelerometer -> accelerometer, GPS -> framepos, Compass ->
    magnetometer, DistanceSensor -> rangefinder (+ Webots' rays), TouchSensor -> touch (its site covers the boundingObject:
    :mod:`dualtwin.convert.touch_sites`), each at a site at the device pose named by the device; resolution and
    lookupTable as numerics the MuJoCo twin applies (:mod:`dualtwin.convert.sensor_models`).

Stops, contacts, cameras, world
    Stops become stiff MuJoCo limits and ContactProperties each collision geom's ``friction``, ``solref`` and
    ``solimp`` (a second pass once the model is whole, :mod:`dualtwin.convert.contacts`); FLU cameras turn into
    MuJoCo's camera frame with a vertical ``fovy``; the world gets a ``timestep`` dividing ``basicTimeStep``,
    gravity (0, 0, -g) (ENU) or (0, -g, 0) (NUE, EUN), ``implicitfast``, ``cone="pyramidal"`` (ODE's friction
    pyramid), ``angle="radian"``. Robot parts collide only with ``selfCollision``, a body jointed to the static
    environment never with it, and each material pair has its own contact (explicit pairs where MuJoCo's mixing
    differs; :mod:`dualtwin.convert.contacts`); ``bounce`` and Damping nodes have no MuJoCo equivalent (reported);
    initial velocities -> keyframe (:mod:`dualtwin.convert.initial_state`).

Every ODE -> MuJoCo equivalence, with its reasoning, is a function in :mod:`dualtwin.convert.equivalences`;
this module walks the world and writes the MjSpec; the result types are in :mod:`dualtwin.convert.conversion`.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dualtwin.convert import sensor_models, world_robots
from dualtwin.convert.ball_joint import ball_joint_notes
from dualtwin.convert.bindings import key
from dualtwin.convert.checks import Finding, lint_spec, lint_world_rotations
from dualtwin.convert.contacts import ContactGeom, Stop, apply_contacts, apply_stops
from dualtwin.convert.conversion import Conversion, ConversionError, JointInfo, MotorInfo
from dualtwin.convert.coupled import harmonise_coupled_motors
from dualtwin.convert.equivalences import (
    DAMPING_NOTE,
    IDLE_MOTOR_NOTE,
    KINEMATIC_MASS,
    apply_joint_dynamics,
    camera_fovy_degrees,
    camera_rotation,
    hinge2_axes,
    hinge_stop_range,
    kinematic_joint_notes,
    motor_numeric,
    rangefinder_rotation,
    timestep_for,
    world_erp_cfm,
    world_gravity,
    world_notes,
)
from dualtwin.convert.initial_state import add_initial_keyframe
from dualtwin.convert.mass import FloatArray, MassProps, bounding_primitives, combine, round_scale, solid_mass
from dualtwin.convert.scales import transform_scale
from dualtwin.convert.sensor_models import TABLED, RayTargets, add_sensor_model, distance_notes
from dualtwin.convert.surfaces import add_surface_mesh
from dualtwin.convert.touch_sites import touch_site_notes
from dualtwin.convert.world_robots import pose_matrix
from dualtwin.geometry import mujoco_quat
from dualtwin.twins.mujoco_state import ROBOT_TEXT, SCENERY_TEXT
from dualtwin.webots import schema
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.protos import load_world, load_world_text
from dualtwin.webots.shapes import CAD_SHAPE_RGBA, SURFACE_NODES, appearance_rgba

VISUAL_GROUP = 2
COLLISION_GROUP = 3
# Collision bits: robot geoms never touch each other (Webots selfCollision FALSE), everything else does.
ROBOT_CONTYPE, ROBOT_CONAFFINITY = 2, 1
ENV_CONTYPE, ENV_CONAFFINITY = 1, 3

#: Solid-derived devices that become a site (and a sensor where MuJoCo has one).
SITE_SENSORS = {
    "InertialUnit": mujoco.mjtSensor.mjSENS_FRAMEQUAT, "Gyro": mujoco.mjtSensor.mjSENS_GYRO,
    "Accelerometer": mujoco.mjtSensor.mjSENS_ACCELEROMETER, "GPS": mujoco.mjtSensor.mjSENS_FRAMEPOS,
    "Compass": mujoco.mjtSensor.mjSENS_MAGNETOMETER, "DistanceSensor": mujoco.mjtSensor.mjSENS_RANGEFINDER,
    "TouchSensor": mujoco.mjtSensor.mjSENS_TOUCH,
}
#: Nodes whose physics has no MuJoCo counterpart we could write by rule: conversion stops with their location.
UNSUPPORTED = frozenset({"Track", "TrackWheel", "Propeller", "Connector", "VacuumGripper", "Fluid", "Muscle",
                         "SolidReference", "Cone"})
#: Nodes without physics that are skipped silently.
IGNORED = frozenset({"PointLight", "SpotLight", "DirectionalLight", "Fog", "Background", "Viewpoint", "WorldInfo", "Billboard", "IndexedLineSet", "PointSet"})
#: The smallest WorldInfo.basicTimeStep (ms) converted: the smoke test then takes 50 000 MuJoCo steps.
MIN_BASIC_TIME_STEP_MS = 0.01

# ------------------------------------------------------------------------------------------------
# small helpers


def _where(node: Node) -> str:
    return str(node.location) if node.location is not None else "<unknown location>"


def _quat(R: FloatArray) -> list[float]:
    return [float(v) for v in mujoco_quat(R)]


def _inv(T: FloatArray) -> FloatArray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = T[:3, :3].T, -T[:3, :3].T @ T[:3, 3]
    return out


# ------------------------------------------------------------------------------------------------
# the converter


class _Converter:
    def __init__(self, world: World, world_path: str) -> None:
        self.world = world
        self.world_path = world_path
        self.spec = mujoco.MjSpec()
        self.warnings: list[str] = list(world.warnings)
        self.findings: list[Finding] = []
        self.used: dict[str, set[str]] = {}
        info = world.world_info()
        self.info = info.fields if info is not None else schema.default_fields("WorldInfo")
        self.basic_ms = self._basic_time_step(info)
        self.dt = timestep_for(self.basic_ms)
        self.erp, self.cfm = world_erp_cfm(self.info)
        version = re.search(r"R(\d{4})([ab])", world.header or "")
        self.old_cameras = version is not None and (int(version.group(1)), version.group(2)) < (2022, "a")
        self.geoms: list[ContactGeom] = []
        self.shapes: dict[str, Node] = {}  # visual geom -> the Shape it draws
        self.joints: list[JointInfo] = []
        self.motors: list[MotorInfo] = []
        self.sensors: dict[str, str] = {}
        self.body_mass: dict[str, float] = {}
        self.robot_bodies: list[str] = []
        self.body_solids: list[tuple[str, Node]] = []  # (body, the Solid it was built from): initial velocities
        self.in_robot = False
        self.self_collision = False
        self.robot_node: Node | None = None
        self.others: list[tuple[Node, FloatArray, float | FloatArray]] = []  # the other robots, in file order
        self.other: world_robots.OtherRobot | None = None  # the other robot being written
        self.missing_defs: list[str] = []
        self.stops: list[Stop] = []

    def _basic_time_step(self, info: Node | None) -> float:
        # Read as Webots and our twin read it (<= 0: reset to 32 ms). A world is untrusted: 0 or less divided by
        # zero in the contact equivalences, and 1e-300 ms made the smoke test (0.5 s / step) step forever.
        step = float(self.info.get("basicTimeStep", 32.0))
        where = str(info.field_locations.get("basicTimeStep") or info.location) if info else self.world_path
        if step <= 0:
            self.warn(f"{where}: WorldInfo.basicTimeStep {step:g} is not positive; using 32 ms (as Webots does)")
            return 32.0
        if step < MIN_BASIC_TIME_STEP_MS:
            raise ConversionError(f"{where}: WorldInfo.basicTimeStep {step:g} ms is below the "
                                  f"{MIN_BASIC_TIME_STEP_MS:g} ms the converter steps at")
        return step

    # -- names
    def unique(self, kind: str, base: str) -> str:
        used = self.used.setdefault(kind, set())
        name = base or kind
        i = 1
        while name in used:
            name = f"{base}({i})" if kind == "body" else f"{base}_{i}"
            i += 1
        used.add(name)
        return name

    def warn(self, message: str, node: Node | None = None) -> None:
        text = f"{_where(node)}: {message}" if node is not None else message
        if text not in self.warnings:
            self.warnings.append(text)

    def unsupported(self, node: Node, why: str = "") -> ConversionError:
        extra = f" ({why})" if why else ""
        return ConversionError(f"{_where(node)}: unsupported node {node.type_name}{extra}; "
                               "the converter cannot map it to MuJoCo")

    # -- world level
    def setup(self) -> None:
        spec = self.spec
        spec.compiler.degree = False
        spec.compiler.autolimits = True
        # Explicit inertials only: MuJoCo must not derive mass from (visual) geoms.
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        spec.option.timestep = self.dt
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
        spec.option.gravity = world_gravity(self.info)
        for note in world_notes(self.info):
            self.warn(note)
        self.spec.worldbody.add_light(name=self.unique("light", "sun"), pos=[0, 0, 10], dir=[0, 0, -1],
                                      type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)

    # -- geometry
    def add_geom(self, body: Any, geometry: Node, T: FloatArray, scale: float | FloatArray, name: str, *,
                 collision: bool, shape: Node | None, material: str, static: bool) -> None:
        kind, scales, uniform = geometry.type_name, scale * np.ones(3), round_scale(scale)  # see mass.Primitive
        R, t = T[:3, :3], T[:3, 3]
        kwargs: dict[str, Any] = {"pos": [float(v) for v in t], "quat": _quat(R)}
        if kind == "Box":
            size = [float(v) * s / 2.0 for v, s in zip(geometry["size"], scales, strict=True)]
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_BOX, size=size)
        elif kind == "Sphere":
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[float(geometry["radius"]) * uniform, 0, 0])
        elif kind in ("Cylinder", "Capsule"):
            # Both have their axis along local z, as MuJoCo (R2022a+); Capsule height = cylindrical part.
            gtype = mujoco.mjtGeom.mjGEOM_CYLINDER if kind == "Cylinder" else mujoco.mjtGeom.mjGEOM_CAPSULE
            kwargs.update(type=gtype, size=[float(geometry["radius"]) * uniform,
                                            float(geometry["height"]) * uniform / 2.0, 0])
        elif kind == "Plane":
            if not static:
                self.warn("a Plane cannot move with a body (Webots keeps it static): skipped", geometry)
                return
            sx, sy = (float(v) * s for v, s in zip(geometry["size"], scales[:2], strict=True))
            # Collision planes are infinite in both simulators; a visual plane keeps its drawn size.
            size = [0.0, 0.0, 1.0] if collision else [sx / 2.0, sy / 2.0, 1.0]
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_PLANE, size=size)
        elif kind in SURFACE_NODES:  # IndexedFaceSet, Mesh, CadShape: dualtwin.convert.surfaces
            mesh_name = add_surface_mesh(self.spec, geometry, scales, lambda: self.unique("mesh", f"{name}_mesh"),
                                         collision=collision, warn=self.warn)
            if mesh_name is None:
                return
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh_name)
        elif kind == "ElevationGrid":
            if not static:
                raise self.unsupported(geometry, "ElevationGrid on a moving body")
            kwargs.update(self.hfield(geometry, name, scales, T))
        elif kind == "Cone":
            if collision:
                raise self.unsupported(geometry, "as a boundingObject")
            self.warn("visual Cone skipped (no MuJoCo primitive)", geometry)
            return
        else:
            raise self.unsupported(geometry, "as a geometry")
        geom = body.add_geom(name=name, **kwargs)
        if collision:
            robot, other = self.in_robot, self.other
            geom.contype = ROBOT_CONTYPE if robot and not self.self_collision else (3 if robot else ENV_CONTYPE)
            geom.conaffinity = ROBOT_CONAFFINITY if robot and not self.self_collision else (3 if robot else ENV_CONAFFINITY)
            if other is not None:  # dualtwin.convert.world_robots
                geom.contype, geom.conaffinity = other.contype, other.conaffinity
            geom.group = COLLISION_GROUP
            geom.mass = 0.0
            geom.density = 0.0
            geom.rgba = [0.5, 0.5, 0.5, 0.3]
            self.geoms.append(ContactGeom(name, str(body.name), material, robot, other.group if other else ""))
        else:
            geom.contype = 0
            geom.conaffinity = 0
            geom.group = VISUAL_GROUP
            geom.density = 0.0
            geom.mass = 0.0
            if shape is not None:  # the Shape drawn: its colour, and (infra-red rays) its reflection
                rgba = CAD_SHAPE_RGBA if shape.type_name == "CadShape" else appearance_rgba(shape)
                if rgba is not None:
                    geom.rgba = list(rgba)
                self.shapes[name] = shape

    def hfield(self, grid: Node, name: str, scale: FloatArray, T: FloatArray) -> dict[str, Any]:
        """Spacings scaled by the scale's x and y, heights and thickness by its z (as the Webots twin does)."""
        nx, ny = int(grid["xDimension"]), int(grid["yDimension"])
        heights = np.asarray(grid["height"], dtype=float) * scale[2]
        if nx < 2 or ny < 2 or heights.size != nx * ny:
            raise ConversionError(f"{_where(grid)}: ElevationGrid needs xDimension, yDimension >= 2 and "
                                  f"xDimension*yDimension heights (got {nx}x{ny}, {heights.size} heights)")
        lx, ly = float(grid["xSpacing"]) * scale[0] * (nx - 1), float(grid["ySpacing"]) * scale[1] * (ny - 1)
        lo, hi = float(heights.min()), float(heights.max())
        span = max(hi - lo, 1e-6)
        field_name = self.unique("hfield", f"{name}_hfield")
        # Webots height[i + j*xDimension] is x index i, y index j; MuJoCo's rows run along y too.
        self.spec.add_hfield(name=field_name, nrow=ny, ncol=nx,
                             size=[lx / 2, ly / 2, span, max(float(grid["thickness"]) * scale[2], 1e-3)],
                             userdata=((heights - lo) / span).tolist())
        centre = T[:3, :3] @ np.array([lx / 2, ly / 2, lo]) + T[:3, 3]
        return {"type": mujoco.mjtGeom.mjGEOM_HFIELD, "hfieldname": field_name,
                "pos": [float(v) for v in centre]}

    # -- solids and bodies
    def solid_name(self, solid: Node) -> str:
        return solid.def_name or str(solid.get("name") or solid.type_name.lower())

    def collect_solid(self, solid: Node, T: FloatArray, scale: float | FloatArray, body: Any, label: str,
                      masses: list[MassProps], *, dynamic: bool, static: bool) -> None:
        """Add one Solid's geoms, devices, mass and child joints to ``body`` (Solid frame = T in body frame)."""
        if solid.type_name in UNSUPPORTED:
            raise self.unsupported(solid)
        material = str(solid.get("contactMaterial", "default"))
        props, mass_warnings = solid_mass(solid, scale=round_scale(scale))  # uniform (dualtwin.convert.scales)
        if (solid.get("physics") or {}).get("damping") is not None:
            self.warn(f"{label}: Physics damping {DAMPING_NOTE}", solid)
        for w in mass_warnings:
            self.warn(f"{label}: {w}", solid)
        if props is not None:
            masses.append(props.transformed(T[:3, :3], T[:3, 3]))
        for i, prim in enumerate(bounding_primitives(solid.get("boundingObject"), scale=scale)):
            if prim.geometry.type_name in UNSUPPORTED:
                raise self.unsupported(prim.geometry, "in a boundingObject")
            local = np.eye(4)
            local[:3, :3], local[:3, 3] = prim.rotation, prim.translation
            name = self.unique("geom", label if i == 0 else f"{label}_{i}")
            self.add_geom(body, prim.geometry, T @ local, prim.scale, name, collision=True, shape=None,
                          material=material, static=static)
        self.device(solid, T, body, label, round_scale(scale))
        self.children(solid.children(), T, scale, body, label, masses, dynamic=dynamic, static=static,
                      material=material)

    def device(self, solid: Node, T: FloatArray, body: Any, label: str, scale: float = 1.0) -> None:
        kind = solid.type_name
        if kind in ("Solid", "Robot") or self.other is not None:  # no controller reads another robot's devices
            return
        device_name = str(solid.get("name") or kind.lower())
        if kind == "Camera":
            w, h = int(solid["width"]), int(solid["height"])
            R = camera_rotation(T[:3, :3], old_cameras=self.old_cameras)
            cam = body.add_camera(name=self.unique("camera", device_name), pos=[float(v) for v in T[:3, 3]],
                                  quat=_quat(R))
            cam.fovy = camera_fovy_degrees(float(solid["fieldOfView"]), w, h)
            cam.resolution = [w, h]
            if str(solid.get("projection", "planar")) != "planar":
                self.warn(f"camera {device_name!r}: projection {solid['projection']!r} converted as planar", solid)
            self.sensors[device_name] = kind
            return
        site_R = T[:3, :3]
        if kind == "DistanceSensor":
            site_R = rangefinder_rotation(site_R)
            for remark in distance_notes(solid):
                self.warn(f"distance sensor {device_name!r}: {remark}", solid)
        site_name = self.unique("site", device_name)
        site = body.add_site(name=site_name, pos=[float(v) for v in T[:3, 3]], quat=_quat(site_R))
        site.group = 4
        for note in touch_site_notes(site, solid, scale) if kind == "TouchSensor" else []:
            self.warn(note, solid)
        sensor_type = SITE_SENSORS.get(kind)
        if sensor_type is None:
            self.warn(f"{kind} {device_name!r} has no MuJoCo sensor: only a site is written", solid)
            return
        if kind in ("InertialUnit", "Gyro", "Accelerometer", "Compass") and not self.in_robot:
            self.warn(f"{kind} {device_name!r} outside the robot", solid)
        sensor = self.spec.add_sensor(name=self.unique("sensor", device_name), type=sensor_type,
                                      objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name)
        for note in add_sensor_model(self.spec, sensor, solid, self.info, RayTargets(
                COLLISION_GROUP, VISUAL_GROUP, robot=self.in_robot, self_collision=self.self_collision)):
            self.warn(note, solid)
        if solid.get("lookupTable") and kind not in TABLED:
            self.warn(f"{kind} {device_name!r}: lookupTable not converted (MuJoCo reports raw values)", solid)
        if kind == "InertialUnit":
            self.warn(f"inertial unit {device_name!r}: MuJoCo framequat gives a quaternion, Webots roll/pitch/yaw",
                      solid)
        self.sensors[device_name] = kind

    def children(self, nodes: list[Node], T: FloatArray, scale: float | FloatArray, body: Any, label: str,
                 masses: list[MassProps], *, dynamic: bool, static: bool, material: str) -> None:
        shape_index = 0
        for child in nodes:
            kind = child.type_name
            if kind in IGNORED:
                continue
            if kind in UNSUPPORTED:
                raise self.unsupported(child)
            if kind in ("Shape", "CadShape"):  # a CadShape: a Shape whose geometry is its file, in a default colour
                geometry = child if kind == "CadShape" else child.get("geometry")
                if geometry is None:
                    continue
                if geometry.type_name in ("Cone", "IndexedLineSet", "PointSet"):
                    self.warn(f"visual {geometry.type_name} skipped", geometry)
                    continue
                name = self.unique("geom", f"{label}_visual" if shape_index == 0 else f"{label}_visual_{shape_index}")
                shape_index += 1
                self.add_geom(body, geometry, T, scale, name, collision=False, shape=child, material=material,
                              static=static)
            elif kind == "Group":
                self.children(child.children(), T, scale, body, label, masses, dynamic=dynamic, static=static,
                              material=material)
            elif kind in ("Pose", "Transform"):
                s = scale * transform_scale(child, self.warn) if kind == "Transform" else scale
                self.children(child.children(), T @ pose_matrix(child, scale), s, body, label, masses, dynamic=dynamic,
                              static=static, material=material)
            elif kind in schema.JOINT_TYPES:
                self.joint(child, T, round_scale(scale), body, dynamic=dynamic, static=static)
            elif kind == "Slot":
                end = child.get("endPoint")
                if end is not None:
                    self.children([end], T, scale, body, label, masses, dynamic=dynamic, static=static,
                                  material=material)
            elif schema.is_solid_type(kind):
                if kind == "Robot":
                    self.warn("nested Robot converted as a Solid", child)
                sub_label = self.solid_name(child) if child.type_name in ("Solid", "Robot") else str(
                    child.get("name") or kind.lower())
                frame_T = T @ pose_matrix(child, scale)
                # Merged Solids keep their frame as a site so their name survives the merge.
                if kind in ("Solid", "Robot"):
                    site = body.add_site(name=self.unique("site", sub_label),
                                         pos=[float(v) for v in frame_T[:3, 3]], quat=_quat(frame_T[:3, :3]))
                    site.group = 4
                self.collect_solid(child, frame_T, scale, body, sub_label, masses, dynamic=dynamic, static=static)
            elif kind in ("RotationalMotor", "LinearMotor", "PositionSensor", "Brake"):
                self.warn(f"{kind} outside a joint's device list ignored", child)
            else:
                raise self.unsupported(child)

    def make_body(self, parent: Any, solid: Node, T: FloatArray, scale: float | FloatArray, *,
                  static: bool) -> tuple[Any, str]:
        base = self.solid_name(solid)
        name = self.unique("body", base)
        body = parent.add_body(name=name, pos=[float(v) for v in T[:3, 3]], quat=_quat(T[:3, :3]))
        if self.in_robot:
            self.robot_bodies.append(name)
        return body, name

    def finish_body(self, body: Any, name: str, masses: list[MassProps], *, moving: bool, node: Node) -> None:
        total = combine(masses)
        if total is None:
            if not moving:
                return
            self.warn(f"body {name!r} moves but has no Physics (kinematic in Webots): given {KINEMATIC_MASS} kg", node)
            total = MassProps.point(KINEMATIC_MASS, (0, 0, 0), np.eye(3) * KINEMATIC_MASS * 1e-2)
        body.mass = total.mass
        body.ipos = [float(v) for v in total.com]
        body.fullinertia = total.full_inertia()
        body.explicitinertial = True
        self.body_mass[name] = total.mass

    def build_body(self, parent: Any, solid: Node, T: FloatArray, scale: float | FloatArray, *, static: bool,
                   add_joint: Any = None) -> tuple[Any, str]:
        """A MuJoCo body for ``solid`` at pose T in ``parent``; ``add_joint(body)`` adds its joint(s)."""
        body, name = self.make_body(parent, solid, T, scale, static=static)
        self.body_solids.append((name, solid))
        if add_joint is not None:
            add_joint(body, name)
        masses: list[MassProps] = []
        dynamic = solid.get("physics") is not None
        self.collect_solid(solid, np.eye(4), scale, body, name, masses, dynamic=dynamic, static=False)
        self.finish_body(body, name, masses, moving=add_joint is not None, node=solid)
        return body, name

    # -- joints
    def joint_name(self, jnode: Node, devices: list[Node], suffix: str = "") -> str:
        if jnode.def_name:
            return self.unique("joint", jnode.def_name + suffix)
        for kinds in (("RotationalMotor", "LinearMotor"), ("PositionSensor",)):
            for d in devices:
                if d.type_name in kinds:
                    return self.unique("joint", f"{d.get('name')}_joint{suffix}")
        return self.unique("joint", f"joint{len(self.joints) + 1}{suffix}")

    def joint(self, jnode: Node, T: FloatArray, scale: float, parent: Any, *, dynamic: bool, static: bool) -> None:
        kind = jnode.type_name
        end = jnode.get("endPoint")
        while end is not None and end.type_name == "Slot":
            end = end.get("endPoint")
        if end is None:
            self.warn(f"{kind} without endPoint skipped", jnode)
            return
        if end.type_name == "SolidReference":
            raise self.unsupported(end, "closed kinematic loops")
        if not schema.is_solid_type(end.type_name):
            raise self.unsupported(end, "as a joint endPoint")
        for note in kinematic_joint_notes(kind, end, parent, self.body_solids):
            self.warn(note, jnode)
        if self.in_robot:
            if not jnode.def_name:
                self.missing_defs.append(f"{kind} at {_where(jnode)}")
            if not end.def_name:
                self.missing_defs.append(f"endPoint {end.type_name} {end.get('name')!r} at {_where(end)}")
        child_T = T @ pose_matrix(end, scale)
        to_child = _inv(child_T)

        def in_child(axis: Sequence[float]) -> list[float]:
            v = to_child[:3, :3] @ (T[:3, :3] @ np.asarray(axis, dtype=float))
            n = float(np.linalg.norm(v))
            if n < 1e-12:
                raise ConversionError(f"{_where(jnode)}: {kind} axis is zero")
            return [float(x) for x in v / n]

        def point_in_child(point: Sequence[float]) -> list[float]:
            p = T @ np.array([*(np.asarray(point, dtype=float) * scale), 1.0])
            return [float(x) for x in (to_child @ p)[:3]]

        devices = [d for d in jnode.get("device", []) if d is not None]
        if kind == "Hinge2Joint":
            self.hinge2(jnode, end, child_T, T, scale, parent, in_child, point_in_child, static=static)
            return
        params_type = {"HingeJoint": "HingeJointParameters", "SliderJoint": "JointParameters",
                       "BallJoint": "BallJointParameters"}[kind]
        params_node = jnode.get("jointParameters")
        params = params_node.fields if params_node is not None else schema.default_fields(params_type)
        position = float(params.get("position", 0.0)) if params_node is not None else float(jnode.get("position", 0.0))
        where = params_node if params_node is not None else jnode

        def add(body: Any, body_name: str) -> None:
            if kind == "BallJoint":
                name = self.joint_name(jnode, devices)
                j = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_BALL,
                                   pos=point_in_child(params.get("anchor", (0.0, 0.0, 0.0))))
                self.set_dynamics(j, params, where)
                for note in ball_joint_notes(jnode):
                    self.warn(note, jnode)
                self.joints.append(JointInfo(name, "ball", body_name))
                return
            name = self.joint_name(jnode, devices)
            if kind == "HingeJoint":
                j = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=in_child(params["axis"]),
                                   pos=point_in_child(params.get("anchor", (0.0, 0.0, 0.0))))
                jkind = "hinge"
            else:
                axis = params.get("axis", (0.0, 0.0, 1.0))
                j = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=in_child(axis), pos=[0, 0, 0])
                jkind = "slide"
            j.ref = position
            limited = self.set_limits(j, params, jkind, where, position)
            self.set_dynamics(j, params, where)
            info = JointInfo(name, jkind, body_name, limited=limited)
            self.joint_devices(devices, info, linear=jkind == "slide")
            self.joints.append(info)

        self.build_body(parent, end, child_T, scale, static=False, add_joint=add)

    def set_limits(self, j: Any, params: dict[str, Any], kind: str, where: Node, position: float) -> bool:
        lo, hi = float(params.get("minStop", 0.0)), float(params.get("maxStop", 0.0))
        if lo == hi:
            return False
        if kind == "hinge":
            if max(abs(lo), abs(hi)) > 2 * math.pi + 1e-6:
                self.findings.append(Finding("error", "stop-in-degrees",
                                             f"hinge stops [{lo:g}, {hi:g}] exceed 2*pi: degrees written as radians?",
                                             _where(where)))
            lo, hi = hinge_stop_range(lo, hi, position)
        j.range = sorted([lo, hi])
        j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        if float(params.get("stopERP", -1.0)) >= 0 or float(params.get("stopCFM", -1.0)) >= 0:
            self.warn("stopERP/stopCFM reach ODE only when changed at run time (docs/reference/webots-on-ode.md "
                      "§4.2, unverified); the stops are converted with WorldInfo ERP/CFM, as ODE creates them", where)
        self.stops.append((j, self.erp, self.cfm))
        return True

    def set_dynamics(self, j: Any, params: dict[str, Any], where: Node) -> None:
        if apply_joint_dynamics(j, params):
            self.warn("hinge suspension (Webots' ODE fork) is not converted", where)

    def joint_devices(self, devices: list[Node], info: JointInfo, *, linear: bool) -> None:
        for d in devices:
            kind = d.type_name
            name = str(d.get("name"))
            if kind in ("RotationalMotor", "LinearMotor"):
                if (kind == "LinearMotor") != linear:
                    self.warn(f"{kind} {name!r} on a {'slider' if linear else 'hinge'}", d)
                limit = float(d.get("maxForce" if kind == "LinearMotor" else "maxTorque"))
                if limit == 0.0:
                    self.warn(f"motor {name!r} {IDLE_MOTOR_NOTE}", d)
                    continue
                act_name = self.unique("actuator", f"{self.other.label}/{name}" if self.other else name)
                act = self.spec.add_actuator(name=act_name, target=info.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
                act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.forcerange = [-limit, limit]
                act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.ctrlrange = [-limit, limit]
                self.spec.add_numeric(name=f"webots_motor.{act_name}", data=motor_numeric(d))
                if float(d.get("multiplier", 1.0)) == 0.0:
                    self.warn(f"motor {name!r}: multiplier 0 is not allowed; using 1 (as Webots does)", d)
                info.motors.append(act_name)
                self.motors.append(MotorInfo(act_name, info.name, kind == "LinearMotor", limit,
                                             float(d.get("maxVelocity", 10.0))))
            elif kind == "PositionSensor" and self.other is None:
                sensor_name = self.unique("sensor", name)
                sensor = self.spec.add_sensor(name=sensor_name, type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                                              objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=info.name)
                add_sensor_model(self.spec, sensor, d, self.info)
                info.sensors.append(sensor_name)
                self.sensors[sensor_name] = kind
            elif kind == "Brake":
                self.warn(f"Brake {name!r} is not converted", d)
            elif kind != "PositionSensor":
                raise self.unsupported(d, "as a joint device")

    def hinge2(self, jnode: Node, end: Node, child_T: FloatArray, T: FloatArray, scale: float, parent: Any,
               in_child: Any, point_in_child: Any, *, static: bool) -> None:
        """Hinge2Joint: two hinges (axis 1 in the parent frame, axis 2 turned by position 1)."""
        p1_node, p2_node = jnode.get("jointParameters"), jnode.get("jointParameters2")
        p1 = p1_node.fields if p1_node is not None else schema.default_fields("HingeJointParameters")
        p2 = p2_node.fields if p2_node is not None else schema.default_fields("JointParameters")
        pos1 = float(p1.get("position", 0.0)) if p1_node is not None else float(jnode.get("position", 0.0))
        pos2 = float(p2.get("position", 0.0)) if p2_node is not None else float(jnode.get("position2", 0.0))
        axis1, axis2 = hinge2_axes(p1.get("axis", (1.0, 0.0, 0.0)), pos1, p2.get("axis", (0.0, 0.0, 1.0)), parent, T,
                                   lambda message: self.warn(message, jnode))
        anchor = point_in_child(p1.get("anchor", (0.0, 0.0, 0.0)))
        devices1 = [d for d in jnode.get("device", []) if d is not None]
        devices2 = [d for d in jnode.get("device2", []) if d is not None]
        # Both hinges live in the child body (equivalences.hinge2_second_axis says why).
        def add(body: Any, body_name: str) -> None:
            name1 = self.joint_name(jnode, devices1)
            j1 = body.add_joint(name=name1, type=mujoco.mjtJoint.mjJNT_HINGE, axis=in_child(axis1), pos=anchor)
            j1.ref = pos1
            limited1 = self.set_limits(j1, p1, "hinge", p1_node or jnode, pos1)
            self.set_dynamics(j1, p1, p1_node or jnode)
            info1 = JointInfo(name1, "hinge", body_name, limited=limited1)
            self.joint_devices(devices1, info1, linear=False)
            self.joints.append(info1)
            name2 = self.joint_name(jnode, devices2, suffix="2") if jnode.def_name or devices2 else self.unique(
                "joint", f"{name1}2")
            j2 = body.add_joint(name=name2, type=mujoco.mjtJoint.mjJNT_HINGE, axis=in_child(axis2), pos=anchor)
            j2.ref = pos2
            limited2 = self.set_limits(j2, p2, "hinge", p2_node or jnode, pos2)
            self.set_dynamics(j2, p2, p2_node or jnode)
            info2 = JointInfo(name2, "hinge", body_name, limited=limited2)
            self.joint_devices(devices2, info2, linear=False)
            self.joints.append(info2)

        self.build_body(parent, end, child_T, scale, static=False, add_joint=add)

    # -- top level
    def convert(self, robot_node: Node, robot_label: str) -> Conversion:
        self.setup()
        for top in self.world.nodes:
            self.findings += lint_world_rotations(top)
        # Static environment first, so the floor comes first in the file; the other robots last, so that the
        # converted robot's names are its own (dualtwin.convert.world_robots).
        self.robot_node = robot_node
        for top in self.world.nodes:
            self.environment(top, np.eye(4), 1.0)
        self.in_robot = True
        self.self_collision = bool(robot_node.get("selfCollision", False))
        free, root_name = self.robot_body(robot_node, *world_robots.robot_frame(self.world, robot_node))
        if not free:
            self.warn("robot has no Physics: converted with a fixed base (welded to the world)", robot_node)
        self.in_robot = False
        self.other_robots(robot_label, root_name)
        scenery = world_robots.scenery_bodies(self.spec, self.body_solids, self.world, robot_node)
        if scenery:
            self.spec.add_text(name=SCENERY_TEXT, data=" ".join(scenery))
        if self.missing_defs:
            # The Webots twin addresses joints and bodies by DEF; generated names exist in MuJoCo only.
            self.warn(f"{len(self.missing_defs)} joint(s)/endPoint(s) have no DEF (first: {self.missing_defs[0]}); "
                      "the Webots twin finds joints and bodies by DEF, so give them DEFs "
                      "in the world file (e.g. DEF wheel1_hinge HingeJoint { ... endPoint DEF wheel1 Solid { ... } })")
        sensor_models.add_reflections(self.spec, self.shapes)  # (a world with infra-red sensors)
        robot_mass = sum(self.body_mass.get(b, 0.0) for b in self.robot_bodies)
        apply_contacts(self.spec, self.geoms, self.info, robot_mass, basic_ms=self.basic_ms, mujoco_step_s=self.dt,
                       warn=self.warn)
        model_name = key(str(robot_node.get("name") or robot_label))
        self.spec.modelname = model_name
        model = None
        try:
            apply_stops(self.spec, self.stops, basic_ms=self.basic_ms, mujoco_step_s=self.dt, cfm=self.cfm)
            harmonise_coupled_motors(self.spec, self.warn)
            model = self.spec.compile()
            add_initial_keyframe(self.spec, model, self.body_solids, self.world, self.warn)
        except ValueError as exc:
            raise ConversionError(f"{self.world_path}: converted model does not compile: "
                                  f"{' '.join(str(exc).split())}") from None
        findings = self.findings + lint_spec(self.spec, model)
        title = str(self.info.get("title", "") or "")
        return Conversion(
            spec=self.spec, world_path=self.world_path, robot=robot_label, model_name=model_name,
            root_body=root_name, free_base=free, control_period_ms=self.basic_ms, joints=self.joints,
            motors=self.motors, sensors=self.sensors, warnings=self.warnings, lint=findings,
            description=f"{robot_node.get('name')} converted from {os.path.basename(self.world_path)}"
                        + (f" ({title})" if title else ""))

    def robot_body(self, node: Node, T: FloatArray, scale: float | FloatArray) -> tuple[bool, str]:
        """A robot's root body at T: free with Physics, welded to the world without (whether free, its name)."""
        if node.get("physics") is None:
            return False, self.build_body(self.spec.worldbody, node, T, scale, static=False)[1]

        def add_free(body: Any, body_name: str) -> None:
            body.add_freejoint(name=self.unique("joint", f"{body_name}_free"))

        return True, self.build_body(self.spec.worldbody, node, T, scale, static=False, add_joint=add_free)[1]

    def other_robots(self, chosen: str, root: str) -> None:
        """The robots not converted, as bodies, joints and motors outside the conversion's own lists; the MuJoCo
        twin's state then holds the joints below the converted robot's ``root`` body only, as the Webots twin's."""
        if self.others or world_robots.environment_joints(self.world, self.robot_node):
            self.spec.add_text(name=ROBOT_TEXT, data=root)
        mine = self.joints, self.motors, self.sensors
        for index, (node, T, scale) in enumerate(self.others):
            blocker = next((n for n in node.walk() if n.type_name in UNSUPPORTED - {"Cone"}), None)
            if blocker is not None:  # the user's robot converts; this one's absence is said
                self.warn(f"robot {node.def_name or node.get('name')!r} is not the converted robot and holds a "
                          f"{blocker.type_name} ({_where(blocker)}), which the converter cannot map to MuJoCo: "
                          "skipped (the converted model lacks its bodies)", node)
                continue
            self.other = other = world_robots.OtherRobot.place(node, T, scale, index, len(self.others))
            self.joints, self.motors, self.sensors = [], [], {}
            self.robot_body(node, other.frame, other.scale)
            for note in world_robots.other_robot_notes(other, chosen):
                self.warn(note, node)
        self.joints, self.motors, self.sensors = mine
        self.other = None

    def environment(self, node: Node, T: FloatArray, scale: float | FloatArray) -> None:
        kind = node.type_name
        if kind in IGNORED or kind in ("DirectionalLight",):
            return
        if kind == "Robot":
            if node is not self.robot_node:
                self.others.append((node, T @ pose_matrix(node, scale), scale))
            return
        if kind in ("Pose", "Transform", "Group"):
            s = scale * transform_scale(node, self.warn) if kind == "Transform" else scale
            inner = T if kind == "Group" else T @ pose_matrix(node, scale)
            for child in node.children():
                self.environment(child, inner, s)
            return
        if kind == "Shape":
            geometry = node.get("geometry")
            if geometry is not None:
                self.add_geom(self.spec.worldbody, geometry, T, scale, self.unique("geom", "shape_visual"),
                              collision=False, shape=node, material="default", static=True)
            return
        if schema.is_solid_type(kind):
            frame = T @ pose_matrix(node, scale)
            if node.get("physics") is not None:
                # A loose physical object: a free body, like in Webots.
                def add_free(body: Any, body_name: str) -> None:
                    body.add_freejoint(name=self.unique("joint", f"{body_name}_free"))

                self.build_body(self.spec.worldbody, node, frame, scale, static=False, add_joint=add_free)
                return
            label = self.solid_name(node)
            masses: list[MassProps] = []
            self.collect_solid(node, frame, scale, self.spec.worldbody, self.unique("body", label), masses,
                               dynamic=False, static=True)
            return
        if kind in UNSUPPORTED:
            raise self.unsupported(node)
        self.warn(f"top-level {kind} ignored", node)


# ------------------------------------------------------------------------------------------------
# public API


def convert_loaded(world: World, robot: str | None = None, *, world_path: str | None = None) -> Conversion:
    """Convert an already loaded world (see :func:`convert_world`)."""
    path = world_path or world.path
    node, label = world_robots.select_robot(world, robot, path)
    return _Converter(world, path).convert(node, label)


def convert_world(world_path: str | os.PathLike[str], robot: str | None = None, *,
                  proto_paths: Sequence[str | os.PathLike[str]] = ()) -> Conversion:
    """Convert the robot of a Webots world (and its static environment) to a MuJoCo model.

    Args:
        world_path: the ``.wbt`` file.
        robot: DEF or ``name`` of the Robot; may be omitted when the world has exactly one.
        proto_paths: extra folders searched for PROTO files.

    Raises:
        ConversionError: no robot / ambiguous robot / unsupported node (message has ``file:line:col``) /
            the converted model does not compile.
        DualtwinError: the world does not parse or a PROTO is missing.
    """
    path = Path(world_path)
    if not path.is_file():
        raise ConversionError(f"{path}: world file not found")
    world = load_world(path, proto_paths)
    return convert_loaded(world, robot, world_path=str(path))


def convert_world_text(text: str, path: str, robot: str | None = None, *,
                       proto_paths: Sequence[str | os.PathLike[str]] = ()) -> Conversion:
    """Convert world text (``path`` names it in messages and anchors relative PROTO lookups)."""
    world = load_world_text(text, path, proto_paths)
    return convert_loaded(world, robot, world_path=path)
