"""Stepping (§1.6, §5): one ``dWorldStep`` per basic time step with motor control before it, the state check,
the buffer swap and the collision pass for the next step after it, and joint positions read back."""

from __future__ import annotations

import math
import threading

from dualtwin.errors import SimulationUnstable
from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.motor_law import kinematic_motion
from dualtwin.webots.physics.axis_edits import JointAxisEdits
from dualtwin.webots.physics.edit_stamps import execute_edits
from dualtwin.webots.physics.motor_edits import execute_motor_edits
from dualtwin.webots.physics.records import (
    JointRec,
    MotorRec,
    SolidRec,
)

_FMAX = ode.dParamFMax
_VEL = ode.dParamVel
_PI = math.pi
_HALF_PI = math.pi / 2


class Stepper(JointAxisEdits):
    """The per-step loop (see the module docstring)."""

    def _prepare_step_lists(self) -> None:
        self._dyn_motors = [m for m in self.motors if not m.joint.kinematic]
        self._kin_motors = [m for m in self.motors if m.joint.kinematic]
        self._springs = [j for j in self.joints if j.spring or j.spring2 or j.stop2]  # AMotor angles set per step
        self._tracked = [j for j in self.joints if not j.kinematic]
        # §4.1/§4.4: a Hinge2Joint without a parent body gets no ODE joint and is handled kinematically, so its
        # motors move the endPoint directly, also when that endPoint has a body of its own
        self._held = [
            j for j in self.joints
            if j.kind == "hinge2" and j.kinematic and j.child is not None and j.child.body is not None
            and j.child.body.root is j.child
        ]  # fmt: skip
        # kinematic geoms inside robots are re-placed from the scene graph every step (§2.4)
        self._moving_static = []
        for gr in self.geoms.values():
            if gr.body is None and gr.solid.robot is not None and self._moves(gr.solid):
                self._moving_static.append(gr)
        self._views = [(b.pos, b.lvel, b.avel) for b in self.bodies]
        self._drifting = [s for s in self.solids if self._drifts(s)]

    def _drifts(self, solid: SolidRec) -> bool:
        """A Solid without Physics, carried by no body and no joint, whose ``linearVelocity`` or
        ``angularVelocity`` is not zero: Webots moves it by that velocity every step (kinematic motion)."""
        if solid.joint is not None or self._nearest_body(solid) is not None:
            return False
        return any(float(v) != 0.0 for v in self.kinematic_velocity(solid))

    def _moves(self, solid: SolidRec) -> bool:
        s: SolidRec | None = solid
        while s is not None:
            if s.body is not None:
                return True
            if s.joint is not None and s.joint.kinematic and any(m is not None for m in s.joint.motors):
                return True
            s = s.parent
        return False

    def step(self, n: int = 1) -> None:
        """Advance ``n`` basic time steps (§1.6 order).

        Raises:
            SimulationUnstable: the state became non-finite; stepping is refused until :meth:`reset`.
        """
        if threading.get_ident() != self._thread:
            ode.ensure_thread()  # ODE needs per-thread data in every stepping thread
        for _ in range(n):
            if self._unstable:
                raise SimulationUnstable("simulation is unstable; call reset()")
            if self._pending:
                self._apply_pending()
            if self._unexecuted:
                self._unexecuted.clear()  # the supervisors' writes are executed now: every controller reads them
            execute_edits(self)  # and the devices of the nodes they wrote read their fields again
            execute_motor_edits(self)
            self._pre_physics()
            for pre_hook in self.pre_step_hooks:
                pre_hook(self.dt)
            try:
                self._step_fn(self._world, self.dt)
            except ode.OdeStepError as exc:
                self._unstable = True
                self._broken = f"ODE stopped inside the step to t={self.time + self.dt:.3f}s ({exc})"
                raise SimulationUnstable(f"{self._broken}; the world must be loaded again") from None
            for joint in self._held:
                self._hold_endpoint(joint)
            self._check_state()
            self._swap_and_collide()
            self._post_physics()
            self.step_count += 1
            for hook in self.step_hooks:
                hook()
            for hook in self.sample_hooks:  # sensors read the step's final state (contacts, flags, poses)
                hook()

    def _pre_physics(self) -> None:
        dt = self.dt
        for solid in self._drifting:
            self._drift(solid, dt)
        set_hinge = self._lib.dJointSetHingeParam
        for motor in self._dyn_motors:
            joint = motor.joint
            if joint.kind == "hinge" and not motor.torque_mode:
                # _apply_motor's most common case written out here: it runs for every motor at every step
                u = motor.command_velocity(dt)
                ptr = joint.ptr
                set_hinge(ptr, _FMAX, max(joint.static_friction[motor.axis_index], motor.available))
                set_hinge(ptr, _VEL, -u)
            else:
                self._apply_motor(motor, dt)
        for joint in self._springs:
            self._apply_spring(joint)
        if self._kin_motors:
            for motor in self._kin_motors:
                self._kinematic_motor(motor, dt)
        for gr in self._moving_static:
            self._place_static_geom(gr, self.solid_world_pose(gr.solid))

    def _apply_motor(self, motor: MotorRec, dt: float) -> None:
        """§5.3: torque mode adds a torque; otherwise set the ODE motor row (Vel, FMax)."""
        joint = motor.joint
        lib = self._lib
        kind = joint.kind
        i = motor.axis_index
        if motor.torque_mode:
            if not motor.torque_params_set:
                # §5.2: entering torque mode leaves a velocity-0 motor limited to staticFriction
                self._set_motor_row(joint, i, 0.0, joint.static_friction[i])
                motor.torque_params_set = True
            tau = motor.raw_torque
            if kind == "hinge":
                # ODE 0.16 negates the torque of reversed hinges itself; undo it so that a positive
                # torque increases the position for static-base joints too (UNVERIFIED for the fork)
                lib.dJointAddHingeTorque(joint.ptr, tau if joint.reverse else -tau)
            elif kind == "slider":
                lib.dJointAddSliderForce(joint.ptr, tau)
            elif kind == "ball":
                torques = [0.0, 0.0, 0.0]
                torques[joint.ode_axis(i)] = -tau
                lib.dJointAddAMotorTorques(joint.amotor, *torques)
            elif i == 0:
                lib.dJointAddHinge2Torques(joint.ptr, -tau, 0.0)
            else:
                lib.dJointAddHinge2Torques(joint.ptr, 0.0, -tau)
            return
        u = motor.command_velocity(dt)
        fmax = max(joint.static_friction[i], motor.available)
        if kind == "hinge":
            setp = lib.dJointSetHingeParam
            setp(joint.ptr, ode.dParamFMax, fmax)
            setp(joint.ptr, ode.dParamVel, -u)
        elif kind == "slider":
            setp = lib.dJointSetSliderParam
            setp(joint.ptr, ode.dParamFMax, fmax)
            setp(joint.ptr, ode.dParamVel, u)
        else:  # Hinge2 and BallJoint axes (physics/joints.py picks the ODE joint and parameter group)
            self._set_motor_row(joint, i, -u, fmax)

    def _drift(self, solid: SolidRec, dt: float) -> None:
        """One step of a drifting Solid's kinematic motion: its origin moves by v·dt and its frame turns by |ω|·dt
        about ω, both in world axes; its subtree, static geoms and fields follow, as in a supervisor move."""
        v = self.kinematic_velocity(solid)
        world = self.solid_world_pose(solid)
        w = v[3:]
        turn = m3.rot_axis_angle((*w, m3.norm(w) * dt)) if any(w) else m3.IDENTITY
        moved = Pose(m3.mat_mul(turn, world.R), m3.add(world.t, m3.scale(v[:3], dt)))
        frame = solid.pre if solid.parent is None else self.solid_world_pose(solid.parent) * solid.pre
        local = frame.inverse() * moved
        self._teleport_solid(solid, m3.scale(local.t, 1.0 / solid.scale), m3.axis_angle_from_mat(local.R))

    def _kinematic_motor(self, motor: MotorRec, dt: float) -> None:
        """§5.3 kinematic joints: the motor moves the joint itself, its speed ramping (motor_law.kinematic_motion)."""
        if motor.torque_mode or motor.available == 0.0:
            return
        positions = motor.joint.positions
        i = motor.axis_index
        positions[i], motor.current_velocity = kinematic_motion(
            position=positions[i], current_velocity=motor.current_velocity, target_position=motor.target_position,
            target_velocity=motor.target_velocity, available=motor.available, acceleration=motor.acceleration, dt=dt)

    def _hold_endpoint(self, joint: JointRec) -> None:
        """Places a kinematic Hinge2's endPoint body (and its subtree) where the joint's positions put it, at rest,
        after the physics step, so that collisions and sensors see the joint's pose (the body's motion under
        gravity or contacts in between is not documented for Webots; here it is dropped)."""
        child = joint.child
        assert child is not None and child.body is not None
        parent = Pose() if joint.parent is None else self.solid_world_pose(joint.parent)
        target = parent * self._endpoint_motion(joint) * child.rel
        self._move_subtree(child, target * self.solid_world_pose(child).inverse(), reset_velocity=True)

    def _swap_and_collide(self) -> None:
        auto_disable = self._auto_disable
        enabled = self._enabled
        if auto_disable:
            is_enabled = self._is_enabled
            for b in self.bodies:
                enabled[b.index] = bool(is_enabled(b.ptr))
        consumed = self._buffer
        self._buffer = consumed ^ 1
        self._collide()  # §1.6 step 4: contacts for the next step, into the other buffer
        used = self._used[consumed]
        if used:
            keep = []
            empty = self._empty_group
            done: set[int] = set()
            for body in used:
                index = body.index
                if index in done:
                    continue
                done.add(index)
                if not auto_disable or enabled[index]:
                    empty(body.groups[consumed])
                else:
                    keep.append(body)  # §1.3: contacts of disabled bodies persist
            self._used[consumed] = keep

    def _post_physics(self) -> None:
        dt = self.dt
        hinge_angle = self._hinge_angle
        hinge_rate = self._hinge_rate
        for joint in self._tracked:
            if joint.kind != "hinge":
                self._read_joint(joint, predict=True)
                continue
            # _read_joint(joint, predict=True) for a hinge, written out here (it runs for every joint at every step)
            ptr = joint.ptr
            a = hinge_angle(ptr)
            joint.raw_angles[0] = a
            rate = hinge_rate(ptr)
            positions = joint.positions
            pred = positions[0] + (rate if joint.reverse else -rate) * dt
            pos = (a if joint.reverse else -a) + joint.offsets[0]
            # already within (pred - π, pred + π]: normalize_angle would return it unchanged (both comparisons
            # are its loops' conditions; they also fail for NaN or infinite values, which take the slow path)
            positions[0] = pos if pred - _PI < pos <= pred + _PI else m3.normalize_angle(pos, pred)
            if joint.rebase and not -_HALF_PI <= a <= _HALF_PI:
                self._rebase_hinge(joint)  # its stops tested on an angle that does not wrap (physics/joints.py)
        if self._accel_cur:
            for index in self._accel_cur:
                b = self.bodies[index]
                self._accel_prev[index] = self._accel_cur[index]
                self._accel_cur[index] = (b.lvel[0], b.lvel[1], b.lvel[2])
