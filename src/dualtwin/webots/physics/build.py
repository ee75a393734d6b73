"""Scene build: walk the world's node tree into records, merge Solids into ODE bodies with Webots' mass rules
(§3.2–3.3), create the collision geoms of every boundingObject (§3.4) and collect the robots' devices."""

from __future__ import annotations

import ctypes
import math
from collections.abc import Iterable, Sequence
from ctypes import byref
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.bounding_mesh import TRIMESH_TYPES, mesh_warning, trimesh_data
from dualtwin.webots.mass_rules import mass_zero, rot_matrix, solid_mass
from dualtwin.webots.mesh_files import MeshFileError
from dualtwin.webots.motor_api import MULTIPLIER_ZERO, check_maxima, coupled_groups
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics.core import SimulationCore
from dualtwin.webots.physics.records import (
    ATTACHMENT_TYPES,
    JOINT_TYPES,
    MAX_ANGULAR_SPEED,
    MOTOR_TYPES,
    SOLID_TYPES,
    AttachmentRec,
    BodyRec,
    BrakeRec,
    DeviceRec,
    GeomRec,
    JointRec,
    MotorRec,
    PositionSensorRec,
    RobotRec,
    SolidRec,
    damping_per_step,
    is_robot,
    is_solid,
)
from dualtwin.webots.physics.records import (
    field_or as _f,
)
from dualtwin.webots.solid_scale import scaled_local

#: joint parameters fields that must not be negative (webots-on-ode.md §4.5: staticFriction ≥ 0); Webots' field checks
#: reset a negative one to 0 with a warning. Negative constants also let h·K + B be 0 in the spring's and the
#: suspension's CFM = 1/(h·K + B) (a ZeroDivisionError inside the step, found by fuzzing the edits)
NON_NEGATIVE_JOINT_FIELDS = ("springConstant", "dampingConstant", "staticFriction", "suspensionSpringConstant",
                             "suspensionDampingConstant")

#: (field, low bound (excluded but for tiltAngle's −π/2), high bound, default) of the angles of a Lidar and a
#: RangeFinder (webots-devices.md §3.1; a planar projection's fieldOfView is at most π)
ANGLE_RANGES = {
    "Lidar": (("fieldOfView", 0.0, 2 * math.pi, 1.5708), ("verticalFieldOfView", 0.0, math.pi, 0.2),
              ("tiltAngle", -math.pi / 2, math.pi / 2, 0.0)),
    "RangeFinder": (("fieldOfView", 0.0, math.pi, 0.7854),),
}
#: the most rays a Lidar or RangeFinder casts per sample (2048 x 2048; a 64-layer lidar of 4500 columns is 288000)
MAX_DEPTH_RAYS = 2**22
#: |a × b| of two unit axes below which no frame spans them (ODE aborts the process normalising their cross product)
ALIGNED_AXES = 1e-6


def overflow_free(axis: Sequence[float]) -> m3.Vec3:
    """``axis`` with the same direction and a finite length: components as large as 1e308 overflow its length, and
    the slider's normalised axis (or a rotated hinge axis) came out zero or infinite, on which ODE aborted the
    process (found by fuzzing); such an axis is scaled down by its largest component."""
    if math.isfinite(m3.norm(axis)):
        return tuple(axis)  # type: ignore[return-value]
    largest = max(abs(v) for v in axis)
    return tuple(v / largest for v in axis)  # type: ignore[return-value]


def aligned(a: m3.Vec3, b: m3.Vec3) -> bool:
    """Whether two axes are too close to parallel for a frame to span them (see :data:`ALIGNED_AXES`)."""
    return m3.norm(m3.cross(m3.normalized(a), m3.normalized(b))) < ALIGNED_AXES


class SceneBuilder(SimulationCore):
    """Records, bodies, masses and geoms (see the module docstring)."""

    # -- scene traversal

    def _walk_top(self, node: Node) -> None:
        self._walk_children([node], Pose(), None, None)

    def _walk_children(self, children: Iterable[Node | None], frame_rel: Pose, parent: SolidRec | None,
                       robot: RobotRec | None, scale: float | None = None) -> None:
        """``scale``: the factor of the Transforms above ``frame_rel`` (solid_scale; by default the parent's)."""
        scale = (parent.scale if parent is not None else 1.0) if scale is None else scale
        for child in children:
            if child is None:
                continue
            if is_solid(child):
                self._add_solid(child, frame_rel, parent, robot, None, scale)
            elif child.type_name in JOINT_TYPES:
                self._add_joint(child, frame_rel, parent, robot, scale)
            elif child.type_name in ATTACHMENT_TYPES:
                self.attachments.append(AttachmentRec(child, frame_rel, parent, robot, scale))
            elif "translation" in child.fields and "rotation" in child.fields and "children" in child.fields:
                if child.type_name == "TrackWheel":
                    # webots-devices.md §7.1: Webots places a TrackWheel's children at (position.x, 0, position.y)
                    # in the Track's frame (its hidden translation)
                    x, z = (float(v) for v in _f(child, "position", (0.0, 0.0)))
                    child.fields["translation"] = (x, 0.0, z)
                inner = self.factor_below(child, scale)
                self._walk_children(child.children(), frame_rel * scaled_local(child, scale), parent, robot, inner)
            elif "children" in child.fields:
                self._walk_children(child.children(), frame_rel, parent, robot, scale)
            elif child.type_name == "Slot" and isinstance(_f(child, "endPoint", None), Node):
                self._walk_children([child.fields["endPoint"]], frame_rel, parent, robot, scale)

    def _add_solid(
        self,
        node: Node,
        frame_rel: Pose,
        parent: SolidRec | None,
        robot: RobotRec | None,
        joint: JointRec | None,
        scale: float = 1.0,
    ) -> SolidRec:
        rel = frame_rel * scaled_local(node, scale)
        solid = SolidRec(
            node=node, parent=parent, robot=robot, rel=rel, pre=frame_rel, load_rel=rel, joint=joint, scale=scale
        )
        solid.index = len(self.solids)
        self.solids.append(solid)
        self._solid_by_node[id(node)] = solid
        if parent is not None:
            parent.children.append(solid)
        if is_robot(node):
            robot = RobotRec(
                node=node,
                solid=solid,
                name=str(_f(node, "name", "robot")),
                controller=str(_f(node, "controller", "")),
                supervisor=bool(_f(node, "supervisor", False)),
                self_collision=bool(_f(node, "selfCollision", False)),
            )
            solid.robot = robot
            self.robots.append(robot)
        self._walk_children(node.children(), Pose(), solid, robot)
        if node.type_name == "Lidar":
            # webots-devices.md §3.1: a Lidar's rotatingHead Solid sits in the lidar's frame; a rotating lidar turns
            # it at run time (dualtwin.webots.lidar_head), and it is drawn and seen as any Solid below the lidar
            self._walk_children([_f(node, "rotatingHead", None)], Pose(), solid, robot)
        return solid

    def check_joint_parameters(self, node: Node, names: Iterable[str] = NON_NEGATIVE_JOINT_FIELDS) -> None:
        """A negative spring, damping, static friction or suspension constant among ``names`` of a joint
        parameters node is reset to 0 in the node, with a warning (at load, on import and on a run-time edit)."""
        for name in names:
            value = node.fields.get(name)
            if name in NON_NEGATIVE_JOINT_FIELDS and isinstance(value, int | float) and value < 0:
                self.warn(f"{node.type_name}.{name} {value:g} is negative; reset to 0")
                node.fields[name] = 0.0

    def _add_joint(
        self, node: Node, frame_rel: Pose, parent: SolidRec | None, robot: RobotRec | None, scale: float = 1.0
    ) -> None:
        kind = {"HingeJoint": "hinge", "SliderJoint": "slider", "Hinge2Joint": "hinge2", "BallJoint": "ball"}[
            node.type_name
        ]
        n_axes = {"hinge2": 2, "ball": 3}.get(kind, 1)
        param_fields = ["jointParameters", "jointParameters2", "jointParameters3"][:n_axes]
        params: list[Node | None] = []
        for fname in param_fields:
            p = _f(node, fname, None)
            params.append(p if isinstance(p, Node) else None)
            if isinstance(p, Node):
                self.check_joint_parameters(p)
        axes, anchor = self._joint_axes(kind, params, scale)
        positions = []
        for i, p in enumerate(params):
            hidden = ["position", "position2", "position3"][i]
            positions.append(float(_f(p, "position", _f(node, hidden, 0.0))))
        n = len(params)
        joint = JointRec(
            node=node,
            kind=kind,
            parent=parent,
            child=None,
            frame_rel=frame_rel,
            params=params,
            axis_local=axes,  # type: ignore[arg-type]
            anchor_local=anchor,  # type: ignore[arg-type]
            load_axes=list(axes),
            load_anchor=anchor,
            zero_axes=list(axes),
            zero_anchor=anchor,
            initial_positions=list(positions),
            positions=list(positions),
            offsets=list(positions),
            motors=[None] * n,
            sensors=[None] * n,
            static_friction=[float(_f(p, "staticFriction", 0.0)) for p in params],
            raw_angles=[0.0] * n,
            brakes=[None] * n,
            scale=scale,
        )
        self.joints.append(joint)
        self._joint_by_node[id(node)] = joint
        for p in params:
            if p is not None:
                self._joint_by_node[id(p)] = joint
        if parent is not None:
            parent.child_joints.append(joint)
        for axis_index, fname in enumerate(["device", "device2", "device3"][:n]):
            for dev in _f(node, fname, []) or []:
                if isinstance(dev, Node):
                    self._add_axis_device(joint, axis_index, dev)
        end = _f(node, "endPoint", None)
        while isinstance(end, Node) and end.type_name == "Slot":
            end = _f(end, "endPoint", None)  # a Slot pair is a pass-through: no frame of its own
        if isinstance(end, Node) and is_solid(end):
            joint.child = self._add_solid(end, frame_rel, parent, robot, joint, scale)
        elif isinstance(end, Node) and end.type_name == "SolidReference":
            joint.reference = end
            self._loops.append((joint, str(_f(end, "solidName", ""))))  # closed once every body exists
        elif isinstance(end, Node):
            self.warn(f"{node.type_name} endPoint {end.type_name} is not supported; joint ignored")
        if robot is not None:
            for group in (joint.motors, joint.sensors, joint.brakes):
                for dev_rec in group:
                    if dev_rec is not None:
                        robot.devices.setdefault(dev_rec.name, dev_rec)

    def _joint_axes(self, kind: str, params: Sequence[Node | None],
                    scale: float = 1.0) -> tuple[list[m3.Vec3], m3.Vec3]:
        """A joint's axes and anchor in its frame, from its (Hinge)JointParameters nodes (defaults where a
        jointParameters field is empty); the anchor times the ``scale`` of the Transforms above the joint."""
        default_axis = (0.0, 0.0, 1.0) if kind == "slider" else (1.0, 0.0, 0.0)
        axes = [self._axis(params[0], default_axis)]
        if kind == "hinge2":
            axes.append(self._axis(params[1], (0.0, 0.0, 1.0)))
        elif kind == "ball":
            # §4.4: BallJointParameters has no axis; the first axis is jointParameters2's, the third
            # jointParameters3's, the second their cross product (axis3 × axis1), as in a chain of three hinges
            a1 = self._axis(params[1], (1.0, 0.0, 0.0))
            a3 = self._axis(params[2], (0.0, 0.0, 1.0))
            if aligned(a1, a3):  # no Euler frame spans them
                self.warn("BallJoint first and third axes are aligned or zero; falling back to x and z")
                a1, a3 = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
            axes = [a1, m3.cross(a3, a1), a3]
        if kind == "slider":
            axes[0] = m3.normalized(axes[0])  # §4.3: Webots normalises the slider axis
        anchor = tuple(float(v) * scale for v in _f(params[0], "anchor", (0.0, 0.0, 0.0)))
        return axes, anchor  # type: ignore[return-value]

    def _axis(self, params: Node | None, default: m3.Vec3) -> m3.Vec3:
        """A joint parameters node's ``axis``, or ``default`` (with a warning) where it has no direction: ODE
        normalises the axes it is given and aborts the process on a zero or non-finite one (Webots, too, will
        not take a null axis)."""
        axis = tuple(float(v) for v in _f(params, "axis", default))
        if not all(math.isfinite(v) for v in axis) or m3.norm(axis) < 1e-12:
            where = f"{params.location}: " if params is not None and params.location is not None else ""
            self.warn(f"{where}joint axis {' '.join(f'{v:g}' for v in axis)} has no direction; using the default "
                      f"{' '.join(f'{v:g}' for v in default)}")
            return default
        return overflow_free(axis)

    def _add_axis_device(
        self, joint: JointRec, axis_index: int, dev: Node
    ) -> MotorRec | PositionSensorRec | BrakeRec | None:
        """The record of a motor, position sensor or brake in one of ``joint``'s device fields, set on the joint's
        axis and linked to the axis' other devices (a motor reads its axis' sensor and brake). An axis holds one
        device of each kind: a second one is left out, with a warning, and None returned (as for a node of
        another type)."""
        kind = "Brake" if dev.type_name == "Brake" else "Motor" if dev.type_name in MOTOR_TYPES else dev.type_name
        groups: dict[str, Sequence[object]] = {"Brake": joint.brakes, "Motor": joint.motors,
                                               "PositionSensor": joint.sensors}
        slots = groups.get(kind)
        if slots is None:
            return None
        if slots[axis_index] is not None:  # (Webots' joint takes the first of each kind in the field)
            self.warn(f"{joint.node.type_name} axis {axis_index + 1}: a second {kind} in its device field is ignored")
            return None
        rec: MotorRec | PositionSensorRec | BrakeRec
        if kind == "Brake":
            rec = joint.brakes[axis_index] = BrakeRec(
                node=dev, joint=joint, axis_index=axis_index, name=str(_f(dev, "name", "brake")))
        elif kind == "Motor":
            rec = joint.motors[axis_index] = self._make_motor(dev, joint, axis_index)
        else:
            rec = joint.sensors[axis_index] = PositionSensorRec(
                node=dev,
                joint=joint,
                axis_index=axis_index,
                name=str(_f(dev, "name", "position sensor")),
                noise=float(_f(dev, "noise", 0.0)),
                resolution=float(_f(dev, "resolution", -1.0)),
            )
        motor = joint.motors[axis_index]
        if motor is not None:
            motor.sensor, motor.brake = joint.sensors[axis_index], joint.brakes[axis_index]
        return rec

    def _make_motor(self, dev: Node, joint: JointRec, axis_index: int) -> MotorRec:
        rotational = dev.type_name == "RotationalMotor"
        check_maxima(dev, self.warn)
        pid = tuple(_f(dev, "controlPID", (10.0, 0.0, 0.0)))
        motor = MotorRec(
            node=dev,
            joint=joint,
            axis_index=axis_index,
            rotational=rotational,
            name=str(_f(dev, "name", "rotational motor" if rotational else "linear motor")),
            max_velocity=float(_f(dev, "maxVelocity", 10.0)),
            max_force=float(_f(dev, "maxTorque" if rotational else "maxForce", 10.0)),
            acceleration=float(_f(dev, "acceleration", -1.0)),
            kp=float(pid[0]),
            ki=float(pid[1]),
            kd=float(pid[2]),
            min_position=float(_f(dev, "minPosition", 0.0)),
            max_position=float(_f(dev, "maxPosition", 0.0)),
            multiplier=float(_f(dev, "multiplier", 1.0)),
        )
        motor.load_acceleration = motor.acceleration
        if motor.multiplier == 0.0:
            self.warn(MULTIPLIER_ZERO.format(name=motor.name))
            motor.multiplier = 1.0
        # a joint that starts outside its motor's position limits widens them to its position, as Webots does
        position = joint.positions[axis_index]
        if motor.min_position != motor.max_position:
            if position < motor.min_position:
                self.warn(f"motor '{motor.name}': the joint starts at {position:g}, below minPosition; "
                          "minPosition set to it")
                motor.min_position = position
            elif position > motor.max_position:
                self.warn(f"motor '{motor.name}': the joint starts at {position:g}, above maxPosition; "
                          "maxPosition set to it")
                motor.max_position = position
        self.motors.append(motor)
        return motor

    # -- bodies (§3.3)

    def _assign_bodies(self, solids: Sequence[SolidRec] | None = None) -> None:
        for solid in self.solids if solids is None else solids:
            if solid.node.fields.get("physics") is None:
                continue
            parent = solid.parent
            wheel = solid.name.lower() in ("left wheel", "right wheel")
            # a TouchSensor keeps its own body, fixed to its parent, so its joint can measure the force on it
            own = wheel or solid.node.type_name == "TouchSensor"
            if solid.joint is None and parent is not None and parent.body is not None and not own:
                body = parent.body
                body.members.append(solid)
                solid.body = body
                solid.in_body = parent.in_body * solid.rel
                continue
            body = BodyRec(index=len(self.bodies), root=solid, members=[solid])
            self.bodies.append(body)
            solid.body = body
            solid.in_body = Pose()
            if solid.joint is None and parent is not None:
                # static basis (§3.3) or unmerged wheel / undefined mid-chain: fixed to the nearest body
                body.fixed_to = self._nearest_body(parent)
                body.attached_to_world = body.fixed_to is None


    def _solid_mass(self, solid: SolidRec) -> tuple[ode.dMass, float]:
        """§3.2: mass of one Solid in its own frame and its boundingObject volume (:mod:`..mass_rules`)."""
        return solid_mass(solid.node, solid.name, self.warn_once, solid.scale)

    def _merged_mass(self, body: BodyRec) -> tuple[ode.dMass, list[tuple[float, Node | None]]]:
        """§3.3: the masses of the body's Solids summed in its root Solid's frame (CoM not yet moved to the
        origin), with each Solid's boundingObject volume and Damping node (the damping weights, §1.4)."""
        lib = self._lib
        total = mass_zero()
        weights: list[tuple[float, Node | None]] = []
        for member in body.members:
            m, volume = self._solid_mass(member)
            member.volume = volume
            if member is not body.root:
                lib.dMassRotate(byref(m), rot_matrix(member.in_body.R))
                lib.dMassTranslate(byref(m), *member.in_body.t)
            lib.dMassAdd(byref(total), byref(m))
            weights.append((volume, _f(member.node.fields["physics"], "damping", None)))
        return total, weights

    def _centred_mass(self, body: BodyRec) -> tuple[ode.dMass, list[tuple[float, Node | None]]]:
        """The merged mass moved to its CoM (§3.2: the body origin sits there); ``body.mass``, ``com`` and
        ``inertia`` are set from it."""
        lib = self._lib
        total, weights = self._merged_mass(body)
        com = (total.c[0], total.c[1], total.c[2])
        lib.dMassTranslate(byref(total), -com[0], -com[1], -com[2])
        total.c[0] = total.c[1] = total.c[2] = 0.0
        inertia = (
            total.I[0], total.I[1], total.I[2], total.I[4], total.I[5], total.I[6],
            total.I[8], total.I[9], total.I[10],
        )  # fmt: skip
        if not (total.mass > 0 and math.isfinite(total.mass) and m3.is_positive_definite3(inertia)):
            # ODE asserts on an invalid mass (Debian build): fall back to a unit mass
            self.warn(f"Solid '{body.root.name}': invalid mass/inertia, using 1 kg and identity inertia")
            lib.dMassSetParameters(byref(total), 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
            inertia = m3.IDENTITY
        body.mass = total.mass
        body.com = com
        body.inertia = inertia
        return total, weights

    def _create_body(self, body: BodyRec) -> None:
        lib = self._lib
        total, weights = self._centred_mass(body)
        world = self.world_pose_at_load(body.root)
        body.load_R = world.R
        body.load_pos = world.apply(body.com)
        node = body.root.node
        body.load_lvel = tuple(float(v) for v in _f(node, "linearVelocity", (0.0, 0.0, 0.0)))  # type: ignore[assignment]
        body.load_avel = tuple(float(v) for v in _f(node, "angularVelocity", (0.0, 0.0, 0.0)))  # type: ignore[assignment]
        b = lib.dBodyCreate(self._world)
        body.ptr = b
        lib.dBodySetMass(b, byref(total))
        self._place_body_at_load(body)
        body.pos = ode.vec3(lib.dBodyGetPosition(b))
        body.R = ode.mat3(lib.dBodyGetRotation(b))
        body.lvel = ode.vec3(lib.dBodyGetLinearVel(b))
        body.avel = ode.vec3(lib.dBodyGetAngularVel(b))
        self._set_damping(body, weights)
        lib.dBodySetMaxAngularSpeed(b, MAX_ANGULAR_SPEED)
        self._set_auto_disable(body)
        body.groups = [lib.dJointGroupCreate(0), lib.dJointGroupCreate(0)]

    def _set_damping(self, body: BodyRec, weights: list[tuple[float, Node | None]]) -> None:
        """§1.4 damping: volume-weighted average of the merged solids' Damping nodes."""
        lib = self._lib
        wsum = sum(w for w, _ in weights)
        lin = ang = 0.0
        for w, damping in weights:
            weight = (w / wsum) if wsum > 0 else 1.0 / len(weights)
            if isinstance(damping, Node):
                lin += weight * float(_f(damping, "linear", 0.2))
                ang += weight * float(_f(damping, "angular", 0.2))
        if lin > 0 or ang > 0:
            lib.dBodySetDamping(body.ptr, damping_per_step(lin, self.dt), damping_per_step(ang, self.dt))
        else:
            lib.dBodySetDampingDefaults(body.ptr)

    def _set_auto_disable(self, body: BodyRec) -> None:
        lib = self._lib
        b = body.ptr
        if self.disable_time > 0:
            lib.dBodySetAutoDisableFlag(b, 1)
            lib.dBodySetAutoDisableLinearThreshold(b, self.disable_lin)
            lib.dBodySetAutoDisableAngularThreshold(b, self.disable_ang)
            lib.dBodySetAutoDisableTime(b, self.disable_time)
            lib.dBodySetAutoDisableSteps(b, 0)
        else:
            lib.dBodySetAutoDisableFlag(b, 0)

    def _place_body_at_load(self, body: BodyRec) -> None:
        """Replays the exact ODE calls used at load so a reset reproduces the state bit for bit."""
        lib = self._lib
        b = body.ptr
        lib.dBodySetPosition(b, *body.load_pos)
        lib.dBodySetRotation(b, rot_matrix(body.load_R))
        lib.dBodySetLinearVel(b, *body.load_lvel)
        lib.dBodySetAngularVel(b, *body.load_avel)
        lib.dBodySetForce(b, 0.0, 0.0, 0.0)
        lib.dBodySetTorque(b, 0.0, 0.0, 0.0)
        lib.dBodyEnable(b)

    # -- collision categories (pre-filter for §2.3 rules 4 and 5)

    def _categories(self) -> None:
        # bit 0: body-less geoms outside robots; per robot without selfCollision: one bit for its bodies
        # and one for its body-less geoms; bit 63: everything else (filtered in Python if needed).
        next_bit = 1
        for robot in self.robots:
            if not robot.self_collision and next_bit + 1 < 63:
                robot.category = next_bit
                next_bit += 2
        self._all_bits = (1 << 64) - 1

    def _geom_bits(self, solid: SolidRec, has_body: bool) -> tuple[int, int]:
        robot = solid.robot
        all_bits = self._all_bits
        if robot is None or robot.category == 0:
            if has_body:
                return 1 << 63, all_bits
            # static environment: no static/static and no kinematic-in-robot pairs
            mask = 1
            for r in self.robots:
                if r.category:
                    mask |= 1 << (r.category + 1)
            return 1, all_bits & ~mask
        dyn, kin = 1 << robot.category, 1 << (robot.category + 1)
        if has_body:
            return dyn, all_bits & ~(dyn | kin)
        mask = 1 | dyn | kin
        for r in self.robots:
            if r.category:
                mask |= 1 << (r.category + 1)
        return kin, all_bits & ~mask

    # -- geoms (§3.4)


    def _create_geoms(self, solid: SolidRec, world: Pose | None = None) -> None:
        """The geoms of ``solid``'s boundingObject, placed with the Solid frame at ``world`` (default: its
        load pose; at run time its current pose, so geoms on a moving body sit where the Solid is now)."""
        bo = solid.node.fields.get("boundingObject")
        if not isinstance(bo, Node):
            return
        if world is None:
            world = self.world_pose_at_load(solid)
        self._bo_geoms(bo, Pose(), solid, world, (solid.scale,) * 3)

    def _bo_geoms(
        self, node: Node, local: Pose, solid: SolidRec, solid_world: Pose, scale: Sequence[float]
    ) -> None:
        t = node.type_name
        if t in ("Pose", "Transform"):
            translation = _f(node, "translation", None)
            if translation is not None and tuple(scale) != (1.0, 1.0, 1.0):
                # a scaled frame above scales this frame's translation too (as mass_rules does for the mass)
                translation = tuple(float(v) * k for v, k in zip(translation, scale, strict=True))
            sub = local * Pose.from_fields(translation, _f(node, "rotation", None))
            sc = scale
            if t == "Transform":
                s = _f(node, "scale", (1.0, 1.0, 1.0))
                sc = (scale[0] * s[0], scale[1] * s[1], scale[2] * s[2])
            for c in node.children():
                self._bo_geoms(c, sub, solid, solid_world, sc)
            return
        if t == "Group":
            for c in node.children():
                self._bo_geoms(c, local, solid, solid_world, scale)
            return
        if t == "Shape":
            geom = _f(node, "geometry", None)
            if isinstance(geom, Node):
                self._bo_geoms(geom, local, solid, solid_world, scale)
            return
        self._make_geom(node, local, solid, solid_world, scale)

    def _make_geom(
        self, node: Node, local: Pose, solid: SolidRec, solid_world: Pose, scale: Sequence[float]
    ) -> None:
        lib = self._lib
        t = node.type_name
        keep: tuple[Any, ...] = ()
        ptr = 0
        uniform = max(scale)
        if t == "Box":
            sx, sy, sz = (float(v) * s for v, s in zip(_f(node, "size", (2.0, 2.0, 2.0)), scale, strict=True))
            if sx > 0 and sy > 0 and sz > 0:
                ptr = lib.dCreateBox(self._space, sx, sy, sz)
        elif t == "Sphere":
            r = float(_f(node, "radius", 1.0)) * uniform
            if r > 0:
                ptr = lib.dCreateSphere(self._space, r)
        elif t in ("Cylinder", "Capsule"):
            r, h = float(_f(node, "radius", 1.0)) * uniform, float(_f(node, "height", 2.0)) * uniform
            if r > 0 and h > 0:
                fn = lib.dCreateCylinder if t == "Cylinder" else lib.dCreateCapsule
                ptr = fn(self._space, r, h)
        elif t == "Plane":
            world = solid_world * local
            n = world.rotate((0.0, 0.0, 1.0))
            ptr = lib.dCreatePlane(self._space, n[0], n[1], n[2], m3.dot(n, world.t))
            if solid.body is not None:
                self.warn(f"Solid '{solid.name}': a Plane cannot be attached to a body; it stays static")
            gr = GeomRec(ptr=ptr, solid=solid, kind=t, local=local, body=None, is_plane=True, source=node)
            self._register_geom(gr)
            return
        elif t in TRIMESH_TYPES:
            try:
                built = trimesh_data(node, scale)
            except MeshFileError as exc:
                self.warn_once(mesh_warning(exc))  # the mass rules may have given this line already
                return
            if built is not None:
                ptr = lib.dCreateTriMesh(self._space, built[0], None, None, None)
                keep = built
        elif t == "ElevationGrid":
            built_hf = self._heightfield(node, scale)
            if built_hf is not None:
                ptr, keep, extra = built_hf
                local = local * extra
                if solid.body is not None:
                    self.warn(f"Solid '{solid.name}': ElevationGrid on a dynamic body stays static")
                gr = GeomRec(ptr=ptr, solid=solid, kind=t, local=local, body=None, keepalive=keep, source=node,
                             scale=tuple(float(v) for v in scale))
                self._register_geom(gr)
                self._place_static_geom(gr, solid_world)
                return
        else:
            self.warn(f"{t} is not a valid bounding geometry; ignored")
            return
        if not ptr:
            self.warn(f"Solid '{solid.name}': invalid {t} dimensions; no geom created")
            return
        gr = GeomRec(
            ptr=ptr, solid=solid, kind=t, local=local, body=solid.body, keepalive=keep, source=node,
            scale=tuple(float(v) for v in scale),
        )
        self._register_geom(gr)
        if solid.body is not None:
            # §3.2: geoms attached, then placed at their world pose (offset relative to the CoM)
            lib.dGeomSetBody(ptr, solid.body.ptr)
            world = solid_world * local
            lib.dGeomSetOffsetWorldPosition(ptr, *world.t)
            lib.dGeomSetOffsetWorldRotation(ptr, rot_matrix(world.R))
        else:
            self._place_static_geom(gr, solid_world)

    def _destroy_geom(self, gr: GeomRec) -> None:
        """Destroy a geom and the triangle-mesh or height-field data it was made of (ODE does not own it)."""
        lib = self._lib
        lib.dGeomDestroy(gr.ptr)
        if gr.keepalive and gr.kind in TRIMESH_TYPES:
            lib.dGeomTriMeshDataDestroy(gr.keepalive[0])
        elif gr.keepalive and gr.kind == "ElevationGrid":
            lib.dGeomHeightfieldDataDestroy(gr.keepalive[0])
        gr.keepalive = ()

    def _register_geom(self, gr: GeomRec) -> None:
        cat, col = self._geom_bits(gr.solid, gr.body is not None)
        self._lib.dGeomSetCategoryBits(gr.ptr, cat)
        self._lib.dGeomSetCollideBits(gr.ptr, col)
        self.geoms[gr.ptr] = gr
        gr.solid.geoms.append(gr)

    def _place_static_geom(self, gr: GeomRec, solid_world: Pose) -> None:
        lib = self._lib
        world = solid_world * gr.local
        if gr.is_plane:
            n = world.rotate((0.0, 0.0, 1.0))
            lib.dGeomPlaneSetParams(gr.ptr, n[0], n[1], n[2], m3.dot(n, world.t))
            return
        lib.dGeomSetPosition(gr.ptr, *world.t)
        lib.dGeomSetRotation(gr.ptr, rot_matrix(world.R))

    def _heightfield(
        self, node: Node, scale: Sequence[float] = (1.0, 1.0, 1.0)
    ) -> tuple[int, tuple[Any, ...], Pose] | None:
        """An ODE heightfield geom for an ElevationGrid (:meth:`_heightfield_data`): (geom, what it is made of,
        the grid's frame in the geom's)."""
        built = self._heightfield_data(node, scale)
        if built is None:
            return None
        data, arr, extra = built
        return self._lib.dCreateHeightfield(self._space, data, 1), (data, arr, extra), extra

    def _heightfield_data(self, node: Node, scale: Sequence[float] = (1.0, 1.0, 1.0)) -> tuple[Any, Any, Pose] | None:
        """ODE heightfield data for an ElevationGrid, in a Transform ``scale``d frame (§3.4): spacings scaled by the
        scale's x and y, heights and thickness by its z (per axis, as a Box's sizes); with the grid's frame in the
        heightfield geom's (ODE centres the field)."""
        nx, ny = int(_f(node, "xDimension", 0)), int(_f(node, "yDimension", 0))
        sx, sy = float(_f(node, "xSpacing", 1.0)) * scale[0], float(_f(node, "ySpacing", 1.0)) * scale[1]
        heights = [float(h) * scale[2] for h in (_f(node, "height", []) or [])]
        if nx < 2 or ny < 2 or len(heights) < nx * ny:
            self.warn("ElevationGrid with fewer than 2×2 heights: ignored")
            return None
        lib = self._lib
        width, depth = (nx - 1) * sx, (ny - 1) * sy
        # ODE heightfield: centred, height along local +y, samples indexed [z * nx + x]. Webots grid:
        # x = i·xSpacing, y = j·ySpacing, height along +z. Local frame: Rx(+90°) maps ODE (x, y, z) to
        # Webots (x, -z, y)... so ODE z = -(y - depth/2): row k of ODE data is Webots row ny-1-k.
        data_vals = []
        for k in range(ny):
            j = ny - 1 - k
            data_vals.extend(heights[j * nx : (j + 1) * nx])
        arr = (ctypes.c_double * len(data_vals))(*data_vals)
        thickness = float(_f(node, "thickness", 1.0)) * scale[2]
        data = lib.dGeomHeightfieldDataCreate()
        lib.dGeomHeightfieldDataBuildDouble(
            data, arr, 1, width, depth, nx, ny, 1.0, 0.0, max(thickness, 1e-6), 0
        )
        lib.dGeomHeightfieldDataSetBounds(data, min(data_vals), max(data_vals))
        extra = Pose(m3.rot_axis_angle((1.0, 0.0, 0.0, math.pi / 2)), (width / 2, depth / 2, 0.0))
        return data, arr, extra

    # -- devices

    def _collect_devices(self, solids: Sequence[SolidRec] | None = None, robots: Sequence[RobotRec] | None = None) -> None:
        for solid in self.solids if solids is None else solids:
            robot = solid.robot
            node = solid.node
            if robot is None or node is robot.node:
                continue
            if node.type_name in SOLID_TYPES and node.type_name not in ("Solid", "Robot"):
                dev = DeviceRec(
                    node=node, solid=solid, type_name=node.type_name, name=str(_f(node, "name", ""))
                )
                robot.devices.setdefault(dev.name, dev)
                self.devices.append(dev)
                if node.type_name in ANGLE_RANGES:
                    self._check_angles(node, dev.name)
                if node.type_name == "Lidar":
                    self._check_lidar_layers(node, dev.name)
                if node.type_name in ("Lidar", "RangeFinder"):
                    self._check_ray_count(node, dev.name)
        for robot in self.robots if robots is None else robots:
            self._order_devices(robot)
            self._harmonise_coupled_motors(robot)

    def _check_angles(self, node: Node, name: str) -> None:
        """A Lidar's or RangeFinder's angles out of their range (webots-devices.md §3.1: fieldOfView ≤ π if planar,
        verticalFieldOfView in (0, π], tiltAngle in [−π/2, π/2]) take their default, with a warning: a
        verticalFieldOfView of 1e308 raised OverflowError out of the load, a fieldOfView of 1e308 gave NaN ray
        directions and a point cloud that raised ValueError (found by fuzzing)."""
        planar = str(_f(node, "projection", "planar" if node.type_name == "RangeFinder" else "")) == "planar"
        for field, low, high, default in ANGLE_RANGES[node.type_name]:
            if field == "fieldOfView" and planar:
                high = math.pi
            value = node.fields.get(field)
            if isinstance(value, int | float) and not (low < value <= high or value == low == -math.pi / 2):
                self.warn(f"{node.type_name} '{name}': {field} {value:g} is out of range; using {default:g}")
                node.fields[field] = default

    def _check_lidar_layers(self, node: Node, name: str) -> None:
        """Webots' load-time check of a Lidar (webots-devices.md §3.1): ``numberOfLayers ≤ verticalFieldOfView ·
        horizontalResolution / fieldOfView`` (2π instead of the field of view for a rotating lidar), else the field
        is rewritten, here to the largest whole number of layers that fits (at least 1), with a warning."""
        layers = int(_f(node, "numberOfLayers", 4))
        rotating = str(_f(node, "type", "fixed")) == "rotating"
        fov = 2 * math.pi if rotating else float(_f(node, "fieldOfView", 1.5708))
        if fov <= 0:
            return
        bound = float(_f(node, "verticalFieldOfView", 0.2)) * int(_f(node, "horizontalResolution", 512)) / fov
        fitted = max(1, int(bound))
        if layers > bound and fitted != layers:
            self.warn(f"Lidar '{name}': numberOfLayers {layers} is more than verticalFieldOfView * "
                      f"horizontalResolution / {'2π' if rotating else 'fieldOfView'} = {bound:g}; numberOfLayers "
                      f"set to {fitted}")
            node.fields["numberOfLayers"] = fitted

    def _check_ray_count(self, node: Node, name: str) -> None:
        """A Lidar or RangeFinder casts one ray per pixel of its image: beyond ``MAX_DEPTH_RAYS`` (each side is
        at most 16384, protos.MAX_IMAGE_SIDE, but 16384 x 16384 rays took tens of GB before the first sample,
        found by fuzzing) its numberOfLayers (Lidar) or height (RangeFinder) is cut to the most that fit, with a
        warning."""
        lidar = node.type_name == "Lidar"
        width_field, rows_field = ("horizontalResolution", "numberOfLayers") if lidar else ("width", "height")
        width = max(1, int(_f(node, width_field, 512 if lidar else 64)))
        rows = int(_f(node, rows_field, 4 if lidar else 64))
        if width * rows <= MAX_DEPTH_RAYS:
            return
        fitted = max(1, MAX_DEPTH_RAYS // width)
        self.warn(f"{node.type_name} '{name}': {width_field} * {rows_field} = {width} * {rows} rays is more than "
                  f"dualtwin casts ({MAX_DEPTH_RAYS}); {rows_field} set to {fitted}")
        node.fields[rows_field] = fitted

    def _harmonise_coupled_motors(self, robot: RobotRec) -> None:
        """Coupled motors (``prefix::suffix``, same robot) take their limits from the group's first motor in
        device order, scaled by the multiplier ratio r = multiplier / first multiplier: maxVelocity = |r|·first's,
        [minPosition, maxPosition] = r·first's (swapped when r < 0; unlimited stays unlimited), as Webots
        adjusts them at load."""
        recs = [rec for rec in robot.devices.values() if isinstance(rec, MotorRec)]
        for motors in coupled_groups(recs, lambda rec: rec.name).values():
            first = motors[0]
            for motor in motors[1:]:
                if first.multiplier == 0.0:
                    continue
                r = motor.multiplier / first.multiplier
                before = (motor.max_velocity, motor.min_position, motor.max_position)
                motor.max_velocity = abs(r) * first.max_velocity
                lo, hi = r * first.min_position, r * first.max_position
                motor.min_position, motor.max_position = (lo, hi) if lo <= hi else (hi, lo)
                if before != (motor.max_velocity, motor.min_position, motor.max_position):
                    self.warn(f"coupled motor '{motor.name}': maxVelocity and position limits set from "
                              f"'{first.name}' scaled by the multiplier ratio {r:g}")

    @staticmethod
    def _order_devices(robot: RobotRec) -> None:
        """Device indices follow the scene tree (pre-order, each joint's device lists in the order written, then
        its endPoint), as Webots numbers them for getDeviceByIndex."""
        rank = {id(n): i for i, n in enumerate(robot.node.walk())}
        last = len(rank)
        items = sorted(robot.devices.items(), key=lambda kv: rank.get(id(getattr(kv[1], "node", None)), last))
        robot.devices.clear()
        robot.devices.update(items)
