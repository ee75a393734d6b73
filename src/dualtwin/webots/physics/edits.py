"""Supervisor-side operations (§6): physics resets of a subtree, queued teleports of Solids and joints, live
field edits, body velocities, and the readings sensors and the Supervisor API take from the scene."""

from __future__ import annotations

import random
import threading
from collections.abc import Sequence
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.lut import discretize
from dualtwin.webots.mass_rules import rot_matrix
from dualtwin.webots.motor_api import check_maxima
from dualtwin.webots.nodes import Node, copy_value
from dualtwin.webots.physics.appearance_edits import APPEARANCE_FIELDS, apply_appearance_field
from dualtwin.webots.physics.edit_stamps import execute_edits, note_edit
from dualtwin.webots.physics.geometry_edits import GEOMETRY_TYPES
from dualtwin.webots.physics.mass_edits import MASS_FIELDS
from dualtwin.webots.physics.motor_edits import (
    QUEUED_MOTOR_FIELDS,
    apply_position_sensor_field,
    execute_motor_edits,
    queue_motor_field,
    remember_load,
)
from dualtwin.webots.physics.records import (
    BodyRec,
    JointRec,
    PendingOp,
    RobotRec,
    SolidRec,
    field_or,
)
from dualtwin.webots.physics.world_edits import WorldInfoEdits
from dualtwin.webots.schema import USE_FORBIDDEN_TYPES

#: the written value of an MF item edit, which is not recorded (its author reads the stored list back)
UNRECORDED = object()


class SupervisorEdits(WorldInfoEdits):
    """Teleports, field edits, velocities and sensor readings (see the module docstring)."""

    def reset_physics(self, solid: SolidRec | None = None) -> None:
        """``simulationResetPhysics`` (or ``Node.resetPhysics`` for a subtree): zero velocities and forces,
        wake bodies, zero motors' current velocity (§6). Poses and time are kept."""
        lib = self._lib
        bodies = [b for b in self.bodies if not b.removed] if solid is None else self._bodies_in_subtree(solid)
        for body in bodies:
            lib.dBodySetLinearVel(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetAngularVel(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetForce(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodySetTorque(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodyEnable(body.ptr)
        ids = {b.index for b in bodies}
        for motor in self.motors:
            if solid is None or (motor.joint.child_body is not None and motor.joint.child_body.index in ids):
                motor.current_velocity = 0.0
        if solid is not None:
            self._rest_motors(solid)

    def _rest_motors(self, solid: SolidRec) -> None:
        """Zero the current velocity of the motors of the joints whose endPoint is ``solid`` or below it: Webots
        resets each Solid of a subtree with the motor of the joint it is the endPoint of (§6,
        WbSolid.resetSingleSolidPhysics; §4.1, WbJoint.resetPhysics), a kinematic joint's (no body) too, whose
        motor then ramps up from rest again (§5.3)."""
        endpoints = {id(s) for s in solid.subtree()}
        for motor in self.motors:
            if motor.joint.child is not None and id(motor.joint.child) in endpoints:
                motor.current_velocity = 0.0

    def _bodies_in_subtree(self, solid: SolidRec) -> list[BodyRec]:
        out = [s.body for s in solid.subtree() if s.body is not None and s.body.root is s]
        if solid.body is not None and solid.body not in out:
            out.append(solid.body)
        return out

    # ------------------------------------------------------------------ supervisor-side operations (§6)

    def solid_for(self, node: Node) -> SolidRec | None:
        return self._solid_by_node.get(id(node))

    def joint_for(self, node: Node) -> JointRec | None:
        """The joint of a joint node or of one of its (Hinge)JointParameters nodes."""
        return self._joint_by_node.get(id(node))

    def note_unexecuted_write(self, node: Node, name: str, current: Any, written: Any = UNRECORDED) -> bool:
        """The supervisor making the current request writes ``node``'s field ``name``, which holds ``current``, with
        ``written`` (UNRECORDED for an MF item edit). The value is stored at once (the physics steps only once every
        controller waits in its step), but the write is executed at the beginning of the next step (§6): until then
        the other supervisors read the value before the step's first write (a copy of ``current`` made then, not at
        every write: a supervisor writing the points of a long MF field one by one copied the whole field at each)
        and the writer its own value. The writes of one step are executed in the supervisors' scene-tree order, so
        the last one in the tree wins whichever came first: False when a supervisor later in the tree already wrote
        the field in this step (this write must not be stored; its author still reads it back until the step)."""
        requester = self._request_order()
        key = (id(node), name)
        entry = self._unexecuted.get(key)
        if entry is None:
            entry = self._unexecuted[key] = (copy_value(current), {})
        writers = entry[1]
        writers[requester] = written
        return written is UNRECORDED or all(order <= requester for order in writers)

    def unexecuted_before(self, node: Node, name: str) -> tuple[bool, Any]:
        """``(True, value)`` when a supervisor's write of ``node``'s field ``name`` that no step executed yet decides
        what the one making the current request reads (see :meth:`note_unexecuted_write`): the value before the
        write for another supervisor, its own value for a writer whose value a supervisor later in the scene tree
        replaced. ``(False, None)``: the stored value is read (by the writer whose value it is: as the field's checks
        left it, a basicTimeStep of 0 read back as 32)."""
        entry = self._unexecuted.get((id(node), name))
        if entry is None:
            return False, None
        before, writers = entry
        requester = self._request_order()
        if requester not in writers:
            return True, before
        own = writers[requester]
        if own is UNRECORDED or all(order <= requester for order in writers):
            return False, None
        return True, own

    def executed_value(self, node: Node, name: str, default: Any = None) -> Any:
        """``node``'s field ``name`` as the steps executed it: the value before any supervisor's write that no step
        executed yet (see :meth:`note_unexecuted_write`). What an image of the step just done shows: Webots draws
        it during its step, before the writes sent after it."""
        entry = self._unexecuted.get((id(node), name))
        return node.fields.get(name, default) if entry is None else entry[0]

    def executed_fields(self, node: Node) -> dict[str, Any]:
        """``node``'s fields as the steps executed them (see :meth:`executed_value`): ``node.fields`` itself when no
        write of it waits for its step, else a copy with the values before the waiting writes."""
        if not self._unexecuted:
            return node.fields
        key = id(node)
        # (a copy of the items: another controller's thread may write meanwhile)
        waiting = {name: before for (owner, name), (before, _) in list(self._unexecuted.items()) if owner == key}
        return {**node.fields, **waiting} if waiting else node.fields

    def pending_pose(self, solid: SolidRec) -> tuple[Sequence[float] | None, Sequence[float] | None]:
        """The translation and the rotation that the supervisor making the current request queued for ``solid``
        (each None when it queued none). What it reads back of its own writes before the step executes them: the
        other supervisors still read the pose, as a write reaches Webots with its author's step and is executed at
        the beginning of the next step (§6)."""
        requester = self._request_order()
        translation = rotation = None
        for op in self._pending:
            if op.kind == "pose" and op.target is solid and op.order == requester:
                translation = op.value[0] if op.value[0] is not None else translation
                rotation = op.value[1] if op.value[1] is not None else rotation
        return translation, rotation

    def _teleport_pending_for(self, body: BodyRec) -> bool:
        """Whether a queued teleport will move (and maybe reset) ``body``."""
        for op in self._pending:
            if op.kind == "pose":
                root = op.target
            elif op.kind == "joint" and op.target.child is not None:
                root = op.target.child
            else:
                continue
            if any(b is body for b in self._bodies_in_subtree(root)):
                return True
        return False

    def queue_set_pose(
        self, solid: SolidRec, translation: Sequence[float] | None, rotation: Sequence[float] | None
    ) -> None:
        """Queue a teleport (translation/rotation field set), applied before the next physics step."""
        self._pending.append(PendingOp("pose", solid, (translation, rotation), self._request_order()))

    def queue_set_joint_position(self, joint: JointRec, axis_index: int, position: float) -> None:
        """Queue a joint ``position`` field set (§4.1), applied before the next physics step."""
        self._pending.append(PendingOp("joint", joint, (axis_index, position), self._request_order()))

    def apply_pending(self) -> None:
        """Execute the queued supervisor requests now, without a physics step (dualtwin extension, no Webots
        equivalent: Webots runs them only as part of the next step). Tests use it to inspect a write."""
        if threading.get_ident() != self._thread:
            ode.ensure_thread()
        self._apply_pending()
        execute_edits(self)
        execute_motor_edits(self)

    def _request_order(self) -> int:
        """The scene-tree place of the supervisor making the current request: the ``request_order`` extension (set
        by the runtime that runs the controllers, which knows the calling thread's robot), else 0."""
        order_of = self.extensions.get("request_order")
        return int(order_of()) if order_of is not None else 0

    def _apply_pending(self) -> None:
        ops, self._pending = self._pending, []
        # §6: in scene-tree order of supervisors, each one's requests in the order it made them
        ops.sort(key=lambda op: op.order)
        for op in ops:
            if op.kind == "pose":
                translation, rotation = op.value
                # the body-less shapes it carries wake the bodies asleep where they were and where they land, as
                # when a Pose carries them (FrameEdits._carry); a sleeping body takes no contact from them (§2.3)
                static = [g for s in op.target.subtree() for g in s.geoms if g.body is None]
                reach = self._static_reach(static)
                self._teleport_solid(op.target, translation, rotation)
                if static:
                    self._wake_reaching(reach + self._static_reach(static))
            elif op.kind == "joint":
                axis_index, position = op.value
                self._teleport_joint(op.target, axis_index, position)
            elif op.kind == "velocity":
                self._set_body_velocity_now(op.target, op.value)
        self._check_state()

    def _teleport_solid(
        self, solid: SolidRec, translation: Sequence[float] | None, rotation: Sequence[float] | None
    ) -> None:
        if solid.body is not None and solid.body.root is not solid:
            self.warn(f"moving merged Solid '{solid.name}' is not supported; ignored")
            return
        node = solid.node
        current = self.solid_local_pose(solid)  # fields of moving solids are only refreshed lazily
        t = tuple(float(v) for v in translation) if translation is not None else current.t
        R = m3.rot_axis_angle(rotation) if rotation is not None else current.R
        node.fields["translation"] = t
        node.fields["rotation"] = tuple(rotation) if rotation is not None else m3.axis_angle_from_mat(R)
        local = Pose(R, m3.scale(t, solid.scale))  # the field's translation in its scaled frame (solid_scale)
        old_world = self.solid_world_pose(solid)
        if solid.parent is None:
            new_world = solid.pre * local
        else:
            parent_world = self.solid_world_pose(solid.parent)
            if solid.joint is not None and not solid.joint.kinematic:
                new_world = parent_world * solid.pre * local
            else:
                new_world = parent_world * self._kinematic_extra(solid) * solid.pre * local
        solid.rel = solid.pre * local
        self._move_subtree(solid, new_world * old_world.inverse(), reset_velocity=False)
        self._reanchor_boundary(solid)

    def turn_solid(self, solid: SolidRec, rotation: Sequence[float]) -> None:
        """Set the ``rotation`` field of a Solid without a body of its own and move it with its subtree *now*,
        within the current step (a supervisor edit waits for the next one): a rotating Lidar's head, turned
        after each step's physics so that the step's rays and readings see it turned."""
        self._teleport_solid(solid, None, rotation)

    def _kinematic_extra(self, solid: SolidRec) -> Pose:
        joint = solid.joint
        if joint is None or not joint.kinematic:
            return Pose()
        return self._endpoint_motion(joint)

    def _move_subtree(self, solid: SolidRec, T: Pose, reset_velocity: bool) -> None:
        """Apply a rigid world transform ``T`` to every body and static geom in a Solid subtree."""
        lib = self._lib
        for body in self._bodies_in_subtree(solid):
            pose = body.pose()
            new_root = T * pose
            lib.dBodySetPosition(body.ptr, *new_root.apply(body.com))
            lib.dBodySetRotation(body.ptr, rot_matrix(new_root.R))
            if reset_velocity:
                lib.dBodySetLinearVel(body.ptr, 0.0, 0.0, 0.0)
                lib.dBodySetAngularVel(body.ptr, 0.0, 0.0, 0.0)
                lib.dBodySetForce(body.ptr, 0.0, 0.0, 0.0)
                lib.dBodySetTorque(body.ptr, 0.0, 0.0, 0.0)
            lib.dBodyEnable(body.ptr)
        for s in solid.subtree():
            for gr in s.geoms:
                if gr.body is None:
                    self._place_static_geom(gr, self.solid_world_pose(s))

    def _reanchor_boundary(self, solid: SolidRec) -> None:
        """Re-set joints crossing the moved subtree's boundary (ODE zero re-based, §6)."""
        inside = {id(s) for s in solid.subtree()}
        for joint in self.joints:
            if not joint.ptr:
                continue
            child_in = joint.child is not None and id(joint.child) in inside
            parent_in = joint.parent is not None and id(joint.parent) in inside
            if child_in != parent_in or (child_in and joint.reverse):
                self._reanchor(joint)

    def _reanchor(self, joint: JointRec) -> None:
        """Set a joint again from where its Solids are now: anchor and axes, stops and the hinge spring's rest
        position, all about its new ODE zero (§6)."""
        self._anchor_joint(joint)
        for i in range(len(joint.params)):
            self._set_stops(joint, i)
        self._respring(joint)

    def _set_joint_again(self, joint: JointRec) -> None:
        """Set the ODE joint again on its current parameters (edited axes or anchor, an imported or removed
        parameters node): every axis' stops freed before :meth:`_reanchor` sets the parameters' own, and the spring
        and damper rows rebuilt about the current axes."""
        for i in range(len(joint.params)):
            self._free_stops(joint, i)
        self._reanchor(joint)  # anchor, axes, ODE's zero here, offsets = positions, stops, spring rest
        self.rebuild_springs(joint)

    def _respring(self, joint: JointRec) -> None:
        if joint.spring and joint.kind == "hinge":
            lib = self._lib
            stop = m3.normalize_angle(joint.offsets[0])
            lib.dJointSetAMotorParam(joint.spring, ode.dParamLoStop, stop)
            lib.dJointSetAMotorParam(joint.spring, ode.dParamHiStop, stop)

    def _teleport_joint(self, joint: JointRec, axis_index: int, position: float) -> None:
        """§4.1: move the endPoint to zero-pose ⊕ position, reset its subtree's physics. On a Hinge2Joint or a
        BallJoint the other axes keep their current positions and the rotations compose as in a chain of hinges
        (§4.4: the first axis carries the second, which carries the third): zero-pose ⊕ R(axis1, p1)·R(axis2,
        p2)(·R(axis3, p3)), the zero pose being the load pose undone by the load positions in the same chain.
        ODE's zero and the offsets stay (but for a hinge with stops, which takes its zero at the new pose): the
        positions are read on from ODE."""
        p = joint.params[axis_index]
        if p is not None:
            p.fields["position"] = float(position)
        child = joint.child
        if child is None or joint.kinematic:
            joint.positions[axis_index] = float(position)
            if child is not None:
                self._rest_motors(child)  # §4.1: its subtree's physics reset, as a dynamic endPoint's
            return
        joint.positions[axis_index] = float(position)
        self._place_endpoint(joint)
        self._read_joint(joint, predict=False)
        if joint.rebase:
            # a hinge with stops: ODE tests them on its wrapped angle, which after a jump of more than π from ODE's
            # zero reads the joint beyond a stop (it was thrown onto the other one); its zero is taken here, as
            # while it turns (physics/joints.py _rebase_hinge), so the stops hold where Webots puts them (§4.2)
            self._rebase_hinge(joint)

    def _place_endpoint(self, joint: JointRec) -> None:
        """Teleport a dynamic joint's endPoint to its zero pose moved by the joint's current positions about its
        current axes (§4.1, :meth:`_endpoint_motion`), its subtree's physics reset (velocities and the motors'
        current velocity zeroed)."""
        child = joint.child
        assert child is not None
        old_world = self.solid_world_pose(child)
        parent_world = self.solid_world_pose(joint.parent) if joint.parent is not None else Pose()
        new_world = parent_world * self._endpoint_motion(joint) * child.load_rel
        self._move_subtree(child, new_world * old_world.inverse(), reset_velocity=True)
        self._rest_motors(child)

    # ------------------------------------------------------------------ live field edits

    def field_changed(self, node: Node, name: str) -> bool:
        """Apply a supervisor's edit of ``node.fields[name]`` to the running ODE scene, as Webots does.

        Webots reacts to field edits at run time (WbJoint/WbMotor/WbPhysics/WbContactProperties update
        their ODE objects). Supported: joint ``dampingConstant``/``springConstant``/``staticFriction``/``stopERP``/
        ``stopCFM``/``minStop``/``maxStop`` and a Hinge2's ``suspensionSpringConstant``/``suspensionDampingConstant``,
        motor ``maxVelocity``/``maxTorque``/``maxForce``/``acceleration`` and (:mod:`.motor_edits`)
        ``controlPID``/``minPosition``/``maxPosition``/``multiplier``, a joint's PositionSensor ``noise``/``resolution``,
        ``Physics``
        ``mass``/``density``/``centerOfMass``/``inertiaMatrix`` (the body's mass properties summed again as at
        load, :mod:`.mass_edits`), a
        ``Damping`` node's ``linear``/``angular`` (bodies and, for ``WorldInfo.defaultDamping``, the world),
        ``ContactProperties`` friction/bounce/soft ERP/CFM, a Solid's ``contactMaterial``, a Robot's
        ``selfCollision``, ``WorldInfo`` ``ERP``/``CFM``/``gravity``/``basicTimeStep`` and the sleep fields
        ``physicsDisableTime``/``physicsDisableLinearThreshold``/``physicsDisableAngularThreshold``
        (:mod:`.world_edits`), and the dimensions of bounding geometries
        (:mod:`.geometry_edits`; the mass properties of a body they bound follow), a PBRAppearance's or Material's
        colour, transparency and roughness (:mod:`.appearance_edits`: Camera images, infra-red rays). The layers
        above add joint
        ``axis``/``anchor`` (:mod:`.axis_edits`), Solid and frame
        poses (:mod:`.frame_edits`), bounding Meshes (:mod:`.scene_changes`) and a Solid's ``linearVelocity``/
        ``angularVelocity`` (:mod:`.velocity_edits`).
        Every write is counted (:mod:`.edit_stamps`): the devices of the node read their fields again.
        Returns False for fields whose edit has no physics effect here.
        """
        note_edit(self, node, name)
        self._copy_to_uses(node, name)
        applied = self._apply_field(node, name)
        if applied:
            # simulationReset restores the field; reset() then re-applies it so ODE follows.
            self._edited[(id(node), name)] = node
        return applied

    def _copy_to_uses(self, node: Node, name: str) -> None:
        """A DEF'd node and its USEs are one node (the twin's DEF/USE rule): the value goes to every copy, whose write
        is counted too, before anything reads it, so what reads a copy where it sits (a USE'd light, an
        ImmersionProperties, a Material) follows. Node-valued fields are imports and removals (scene_api); Solids,
        joints and joint parameters have no USEs (S §7.1)."""
        if not (node.def_name or node.use_name or node.proto_def_name) or node.type_name in USE_FORBIDDEN_TYPES:
            return
        value = node.fields.get(name)
        if isinstance(value, Node) or (isinstance(value, list) and any(isinstance(v, Node) for v in value)):
            return
        for other in self.linked_nodes(node)[1:]:
            other.fields[name] = copy_value(value)
            note_edit(self, other, name)

    def _apply_field(self, node: Node, name: str) -> bool:
        if node.type_name in GEOMETRY_TYPES:
            return self._apply_geometry(node, name)
        value: Any = node.fields.get(name)
        joint = next((j for j in self.joints if node in j.params), None)
        if joint is not None:
            i = joint.params.index(node)
            return self._apply_joint_field(joint, i, name)
        motor = next((m for m in self.motors if m.node is node), None)
        if motor is not None:
            remember_load(self, motor)  # (what simulationReset puts back)
            check_maxima(node, self.warn)  # a negative maximum, as at load
            if name not in QUEUED_MOTOR_FIELDS:
                return False
            queue_motor_field(self, motor, name)  # (the motor takes it at the beginning of the next step)
            return True
        if node.type_name == "PositionSensor":
            sensor = next((s for j in self.joints for s in j.sensors if s is not None and s.node is node), None)
            if sensor is not None:
                return apply_position_sensor_field(sensor, name)
        if node.type_name == "Physics" and name in MASS_FIELDS:
            return self._apply_physics_mass(node, name)
        if node.type_name == "Damping" and name in ("linear", "angular"):
            return self._apply_damping(node, name)
        if node.type_name == "ContactProperties":
            # §2.3 step 10: each collision pass fills its contacts from the properties of that moment; the pairs'
            # cached plans hold the surface they were made with, and which node matches may have changed
            self._surfaces.pop(id(node), None)
            self._plans.clear()
            return True
        if name == "contactMaterial" and self.solid_for(node) is not None:
            self._plans.clear()  # §2.1: the Solid's pairs match their ContactProperties again, by the new material
            return True
        if name == "selfCollision":
            robot = next((r for r in self.robots if r.node is node), None)
            if robot is not None:
                self._set_self_collision(robot, bool(value))
                return True
        if node.type_name == "WorldInfo":
            return self._apply_world_info(node, name)
        if node.type_name in APPEARANCE_FIELDS:
            return apply_appearance_field(self, node, name)
        return False

    def _set_self_collision(self, robot: RobotRec, self_collision: bool) -> None:
        """§2.3 rule 4 is a test of the near callback on the robot's ``selfCollision`` at each collision pass: the
        robot leaves the category bits that pre-filter its pairs (build._categories) for the callback's own test,
        which reads the new value, and the pairs are planned again."""
        robot.self_collision = self_collision
        robot.category = 0
        lib = self._lib
        for gr in self.geoms.values():
            if gr.solid.robot is robot:
                category, collide = self._geom_bits(gr.solid, gr.body is not None)
                lib.dGeomSetCategoryBits(gr.ptr, category)
                lib.dGeomSetCollideBits(gr.ptr, collide)
        self._plans.clear()

    def _apply_joint_field(self, joint: JointRec, i: int, name: str) -> bool:
        """An edit of a field of ``joint``'s parameters of axis ``i`` (``position`` is a teleport, queued by the
        Field API). A kinematic joint (no ODE joint) has nothing in ODE to change."""
        params = joint.params[i]
        if params is not None:
            self.check_joint_parameters(params, (name,))
        if name == "staticFriction":
            joint.static_friction[i] = float(field_or(joint.params[i], name, 0.0))
            if joint.ptr and joint.motors[i] is None:
                # §4.5: without a motor the axis' motor row is velocity 0 limited to staticFriction; set even
                # when it is 0 now, which lets the axis go (a friction edited to 0 held the joint as before)
                self._set_motor_row(joint, i, 0.0, joint.static_friction[i])
                self.wake(joint)
            return True
        if name in ("dampingConstant", "springConstant"):
            self.rebuild_springs(joint)  # physics/joints.py: every axis, stepping lists refreshed
            return True
        if name in ("stopERP", "stopCFM"):
            return self._set_stop_softness(joint, i, name)
        if name in ("minStop", "maxStop"):
            self._set_stops_again(joint, i)
            self.wake(joint)
            return True
        if name in ("suspensionSpringConstant", "suspensionDampingConstant") and joint.kind == "hinge2" and i == 0:
            # §4.4: ODE's own hinge2 suspension, set as at load (a HingeJoint's suspension is fork-only, §4.2)
            if joint.ptr:
                self._set_hinge2_suspension(joint)
                self.wake(joint)
            return True
        return False

    def joint_velocity(self, joint: JointRec, axis_index: int = 0) -> float:
        """Current joint rate in the Webots sign convention (rad/s or m/s)."""
        lib = self._lib
        if joint.kinematic or joint.kind == "ball":
            motor = joint.motors[axis_index] if axis_index < len(joint.motors) else None
            return motor.current_velocity if motor is not None else 0.0
        if joint.kind == "hinge":
            rate = lib.dJointGetHingeAngleRate(joint.ptr)
            return float(rate if joint.reverse else -rate)
        if joint.kind == "slider":
            return float(lib.dJointGetSliderPositionRate(joint.ptr))
        # both Hinge2 positions advance against ODE's angle rates (physics/joints.py _read_joint)
        if axis_index == 0:
            return float(-lib.dJointGetHinge2Angle1Rate(joint.ptr))
        return float(-lib.dJointGetHinge2Angle2Rate(joint.ptr))

    def set_body_velocity(self, solid: SolidRec, velocity: Sequence[float]) -> None:
        """``Node.setVelocity``: set the ODE body's linear (CoM) and angular velocity (world frame).

        Webots executes a supervisor's requests in the order they were made, just before the next physics
        step. A velocity set after a teleport of the same body (a ``translation``/``rotation`` or joint
        ``position`` write, which may reset the subtree's velocities, spec §4.1) must therefore survive it:
        while such a teleport is queued, the velocity is queued behind it. Otherwise it applies at once, as
        before (the two orders cannot be told apart then).
        """
        body = solid.body
        if body is None:
            return
        if self._pending and self._teleport_pending_for(body):
            self._pending.append(PendingOp("velocity", solid, tuple(float(v) for v in velocity), self._request_order()))
            return
        self._set_body_velocity_now(solid, velocity)

    def _set_body_velocity_now(self, solid: SolidRec, velocity: Sequence[float]) -> None:
        body = solid.body
        if body is None:
            return
        lib = self._lib
        lib.dBodySetLinearVel(body.ptr, *velocity[:3])
        lib.dBodySetAngularVel(body.ptr, *velocity[3:6])
        lib.dBodyEnable(body.ptr)

    def solid_velocity(self, solid: SolidRec) -> tuple[float, ...]:
        """``Node.getVelocity``: 6 values, body CoM linear velocity and angular velocity (world)."""
        if solid.body is not None:
            b = solid.body
            return (b.lvel[0], b.lvel[1], b.lvel[2], b.avel[0], b.avel[1], b.avel[2])
        anc = solid.parent
        while anc is not None and anc.body is None:
            anc = anc.parent
        if anc is None or anc.body is None:
            return self._drift_velocity(solid)
        b = anc.body
        w = (b.avel[0], b.avel[1], b.avel[2])
        r = m3.sub(self.solid_world_pose(solid).t, (b.pos[0], b.pos[1], b.pos[2]))
        v = m3.add((b.lvel[0], b.lvel[1], b.lvel[2]), m3.cross(w, r))
        return (*v, *w)

    def kinematic_velocity(self, solid: SolidRec) -> tuple[float, ...]:
        """The six world velocities of a Solid without Physics: its ``linearVelocity`` and ``angularVelocity``."""
        fields = solid.node.fields
        lin = fields.get("linearVelocity", (0.0, 0.0, 0.0))
        ang = fields.get("angularVelocity", (0.0, 0.0, 0.0))
        return tuple(float(v) for v in (*lin, *ang))

    def _drift_velocity(self, solid: SolidRec) -> tuple[float, ...]:
        """A Solid that no body carries moves only with a drifting Solid (itself or an ancestor, Stepper._drift):
        that Solid's velocity, plus ω × lever arm for a Solid inside it; zero otherwise."""
        s: SolidRec | None = solid
        while s is not None and s not in self._drifting:
            s = s.parent
        if s is None:
            return (0.0,) * 6
        v = self.kinematic_velocity(s)
        w = (v[3], v[4], v[5])
        r = m3.sub(self.solid_world_pose(solid).t, self.solid_world_pose(s).t)
        return (*m3.add((v[0], v[1], v[2]), m3.cross(w, r)), *w)

    def point_velocity(self, solid: SolidRec) -> m3.Vec3:
        """World velocity of the Solid's frame origin as a point of the body carrying it (``dBodyGetPointVel``:
        the CoM velocity plus ω × lever arm); without a body, that of the drifting Solid moving it, if any."""
        body = self._nearest_body(solid)
        if body is None:
            v = self._drift_velocity(solid)
            return (v[0], v[1], v[2])
        r = m3.sub(self.solid_world_pose(solid).t, (body.pos[0], body.pos[1], body.pos[2]))
        w = (body.avel[0], body.avel[1], body.avel[2])
        return m3.add((body.lvel[0], body.lvel[1], body.lvel[2]), m3.cross(w, r))

    def angular_velocity(self, solid: SolidRec) -> m3.Vec3:
        """World angular velocity of the body carrying the Solid (without one: of the drifting Solid moving it)."""
        body = self._nearest_body(solid)
        if body is None:
            v = self._drift_velocity(solid)
            return (v[3], v[4], v[5])
        return (body.avel[0], body.avel[1], body.avel[2])

    def center_of_mass(self, solid: SolidRec) -> m3.Vec3:
        """World position of the body CoM holding ``solid`` (its own origin if it has no body)."""
        if solid.body is not None:
            b = solid.body
            return (b.pos[0], b.pos[1], b.pos[2])
        return self.solid_world_pose(solid).t

    def solid_local_pose(self, solid: SolidRec) -> Pose:
        """The Solid's current pose in the frame its ``translation``/``rotation`` fields refer to, in the fields'
        units: below a scaled Transform the translation is the field's, the frame's length divided by the scale."""
        if solid.body is None and (solid.joint is None or not solid.joint.kinematic):
            local = solid.pre.inverse() * solid.rel
        else:
            world = self.solid_world_pose(solid)
            parent = self.solid_world_pose(solid.parent) if solid.parent is not None else Pose()
            local = solid.pre.inverse() * parent.inverse() * world
        return local if solid.scale == 1.0 else Pose(local.R, m3.scale(local.t, 1.0 / solid.scale))

    def wake(self, joint: JointRec) -> None:
        """Re-enable a joint's sleeping bodies (a motor command changed, UNVERIFIED)."""
        if not self._auto_disable:
            return
        enabled = self._enabled
        for b in (joint.parent_body, joint.child_body):
            if b is not None and not enabled[b.index]:
                self._lib.dBodyEnable(b.ptr)
                enabled[b.index] = True

    # ------------------------------------------------------------------ sensors

    def track_acceleration(self, solid: SolidRec) -> None:
        body = solid.body or (self._nearest_body(solid.parent) if solid.parent is not None else None)
        if body is not None and body.index not in self._accel_cur:
            v = (body.lvel[0], body.lvel[1], body.lvel[2])
            self._accel_cur[body.index] = v
            self._accel_prev[body.index] = v

    def acceleration(self, solid: SolidRec) -> m3.Vec3:
        """Accelerometer reading in the device frame: R^T·(a − g)."""
        body = solid.body or (self._nearest_body(solid.parent) if solid.parent is not None else None)
        a = (0.0, 0.0, 0.0)
        if body is not None and body.index in self._accel_cur:
            cur, prev = self._accel_cur[body.index], self._accel_prev[body.index]
            a = m3.scale(m3.sub(cur, prev), 1.0 / self.dt)
        R = self.solid_world_pose(solid).R
        return m3.mat_t_vec(R, m3.sub(a, self.gravity))

    @property
    def rng(self) -> random.Random:
        """The sensor-noise generator (seeded from ``WorldInfo.randomSeed`` or the ``seed`` argument)."""
        return self._rng

    def sensor_noise(self, value: float, noise: float, resolution: float) -> float:
        """A position reading (PositionSensor, Track): + N(0, noise²), then Webots' ``resolution``
        (``WbMathsUtilities::discretize``, :func:`dualtwin.webots.lut.discretize`: int(v/r + 0.5)·r, truncated
        toward zero, so -0.26 at 0.1 reads -0.2 where ``round`` gave -0.3)."""
        if noise > 0:
            value += self._rng.gauss(0.0, noise)
        return discretize(value, resolution)
