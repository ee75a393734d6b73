"""Devices and parameters a supervisor imports into (or removes from) a joint that stays in the scene, while the
simulation runs.

Devices (``device``, ``device2``, ``device3``): in Webots a motor, position sensor or brake inserted below a
Robot joins that robot's device list (its controller finds it with ``getDevice``, counts it in
``getNumberOfDevices``) and acts on its joint axis from the next step: a motor starts as at load (§5.1: it
holds the joint where it is now, at its maxVelocity, with its full torque) and then follows its controller's
commands; a position sensor reads the axis; a brake adds its damping. Removing the node takes it out of the
device list and ends its effect: a motor's ODE motor row is let go (only the axis' static friction stays,
§4.5), a brake's damping leaves the axis' damper. An axis holds one device of each kind, as at load
(:meth:`SceneBuilder._add_axis_device`). The Python API's reference only says that ``getDevice`` answers the
device object it made once and that ``Robot.devices`` is filled when the Robot is made; Webots' Robot node
announces a device inserted below it to its controller, so here ``getDevice`` finds the new device (in both
controller isolation modes), ``getDeviceByIndex`` numbers it in scene-tree order, and ``Robot.devices`` stays
as the Robot filled it.

Parameters (``jointParameters``, ``jointParameters2``, ``jointParameters3``): a (Hinge)JointParameters
imported into an empty field gives the joint its axis, anchor, stops, spring, damping, static friction (and,
Hinge2, suspension) from the next step, the joint being set again where its Solids are now: nothing moves,
and the current configuration is the new node's ``position`` (Webots takes a parameters node's position as
the joint's position and ODE's zero when the node is set). Removed, the joint goes back to the defaults (the
axis x, or z for a slider; anchor at the joint's frame; no stop, spring or friction), set where it is, its
position read on from where it was. The endPoint's load pose and the joint's load position are kept, so a
reset (which removes imported nodes) puts the joint back as it was at load.
"""

from __future__ import annotations

from collections.abc import Iterable

from dualtwin.webots.nodes import Node
from dualtwin.webots.physics.records import (
    BrakeRec,
    JointRec,
    MotorRec,
    PositionSensorRec,
    RobotRec,
    field_or,
)
from dualtwin.webots.physics.stepping import Stepper

__all__ = ["DEVICE_FIELDS", "PARAMETER_FIELDS", "JointChanges"]

DEVICE_FIELDS = ("device", "device2", "device3")
PARAMETER_FIELDS = ("jointParameters", "jointParameters2", "jointParameters3")

_AxisDevice = MotorRec | PositionSensorRec | BrakeRec


class JointChanges(Stepper):
    """Run-time addition and removal of joint devices and parameters (see the module docstring)."""

    def _joint_part_added(self, joint_node: Node, top: Node) -> bool:
        """``top`` was imported into a device or parameters field of the joint ``joint_node``: it acts from the
        next step (True). False for its endPoint, which :meth:`SceneChanges.add_nodes` builds."""
        joint = self._joint_by_node.get(id(joint_node))
        if joint is None:
            return False
        for axis, name in enumerate(PARAMETER_FIELDS):
            if joint_node.fields.get(name) is top:
                if axis < len(joint.params) and joint.params[axis] is None:
                    self._set_parameters(joint, axis, top)
                return True
        for axis, name in enumerate(DEVICE_FIELDS):
            if any(d is top for d in joint_node.fields.get(name) or []):
                if axis < len(joint.params):  # (a field the joint does not have is read by nothing, as at load)
                    self._device_added(joint, axis, top)
                return True
        return False

    def _joint_parts_removed(self, ids: Iterable[int]) -> None:
        """The devices and parameters among the removed nodes ``ids`` that belong to a joint that stays leave it;
        the joint's bodies are woken (a motor or a stop may have held them still)."""
        removed = set(ids)
        for joint in self.joints:
            if id(joint.node) in removed:
                continue  # the joint itself goes, with its devices (SceneChanges.remove_nodes)
            changed = False
            for axis, p in enumerate(joint.params):
                if p is not None and id(p) in removed:
                    self._set_parameters(joint, axis, None)
                    changed = True
            gone: list[_AxisDevice] = [rec for group in (joint.motors, joint.sensors, joint.brakes)
                                       for rec in group if rec is not None and id(rec.node) in removed]  # fmt: skip
            for rec in gone:
                self._drop_axis_device(joint, rec)
            robot = self._joint_robot(joint)
            if gone and robot is not None:
                for name in [name for name, rec in robot.devices.items() if any(rec is g for g in gone)]:
                    del robot.devices[name]
            if gone or changed:
                self._prepare_step_lists()
                self.wake(joint)

    # -- devices

    @staticmethod
    def _joint_robot(joint: JointRec) -> RobotRec | None:
        """The robot whose device list holds ``joint``'s devices (its upper Solid's robot)."""
        return joint.parent.robot if joint.parent is not None else None

    def _device_added(self, joint: JointRec, axis: int, node: Node) -> None:
        rec = self._add_axis_device(joint, axis, node)
        if rec is None:
            return
        if isinstance(rec, MotorRec):
            rec.reset_state()  # §5.1: it holds the joint where it is now
        elif isinstance(rec, BrakeRec):
            self.rebuild_springs(joint)
        robot = self._joint_robot(joint)
        if robot is not None:
            robot.devices.setdefault(rec.name, rec)
            self._order_devices(robot)
            self._harmonise_coupled_motors(robot)
        self._prepare_step_lists()
        self.wake(joint)

    def _drop_axis_device(self, joint: JointRec, rec: _AxisDevice) -> None:
        i = rec.axis_index
        motor = joint.motors[i]
        if isinstance(rec, MotorRec):
            joint.motors[i] = None
            self.motors[:] = [m for m in self.motors if m is not rec]
            if joint.ptr:  # its motor row let go: no force, or the axis' static friction alone (§4.5)
                self._set_motor_row(joint, i, 0.0, 0.0)
                self._set_static_friction(joint, i)
        elif isinstance(rec, PositionSensorRec):
            joint.sensors[i] = None
            if motor is not None:
                motor.sensor = None
        else:
            joint.brakes[i] = None
            if motor is not None:
                motor.brake = None
            self.rebuild_springs(joint)

    # -- parameters

    def _set_parameters(self, joint: JointRec, axis: int, node: Node | None) -> None:
        """``node`` (None: removed) becomes ``joint``'s parameters of ``axis``; the joint is set again where its
        Solids are now (the module docstring)."""
        old = joint.params[axis]
        if old is not None:
            self._joint_by_node.pop(id(old), None)
        child = joint.child
        kinematic_pose = self._kinematic_rel(child) if child is not None and joint.kinematic else None
        joint.params[axis] = node
        if node is not None:
            self.check_joint_parameters(node)
            self._joint_by_node[id(node)] = joint
            joint.positions[axis] = float(field_or(node, "position", joint.positions[axis]))
        axes, anchor = self._joint_axes(joint.kind, joint.params, joint.scale)
        joint.axis_local[:] = axes
        joint.anchor_local = anchor
        joint.zero_axes[:] = axes  # a later position teleport moves the endPoint about these
        joint.zero_anchor = anchor
        joint.static_friction[axis] = float(field_or(node, "staticFriction", 0.0))
        if kinematic_pose is not None and child is not None:
            # no ODE joint: the endPoint stays where it is, its frame re-based on the new axes and position
            motion = self._kinematic_rel(child) * child.rel.inverse()
            child.rel = motion.inverse() * kinematic_pose
        if not joint.ptr:
            return
        self._set_joint_again(joint)
        for i, motor in enumerate(joint.motors):
            if motor is None:
                self._set_motor_row(joint, i, 0.0, 0.0)
                self._set_static_friction(joint, i)
        if joint.kind == "hinge2":
            self._set_hinge2_suspension(joint)
