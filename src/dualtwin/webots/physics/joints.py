"""ODE joints for Webots joints (§4): creation with Webots' sign conventions, closed loops through a
SolidReference, stops, static friction, implicit springs, fixed joints, and reading joint positions back."""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable, Sequence

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.physics.build import SceneBuilder
from dualtwin.webots.physics.records import (
    BodyRec,
    JointRec,
    SolidRec,
)
from dualtwin.webots.physics.records import (
    field_or as _f,
)

_GROUPS = (0, ode.dParamGroup2, ode.dParamGroup3)  # ODE parameter group of joint axis 0, 1, 2


class JointBuilder(SceneBuilder):
    """Joints, stops, springs and joint read-back (see the module docstring)."""

    def _joint_world_frame(self, joint: JointRec) -> Pose:
        if joint.parent is None:
            return joint.frame_rel
        return self.world_pose_at_load(joint.parent) * joint.frame_rel

    def _create_joint(self, joint: JointRec) -> None:
        lib = self._lib
        child = joint.child
        joint.parent_body = self._nearest_body(joint.parent)
        joint.child_body = child.body if child is not None and child.joint is joint else None
        if joint.child_body is None or joint.child_body.root is not child:
            joint.child_body = None
            return  # §4.1: kinematic joint (endPoint without Physics)
        if joint.kind == "hinge2" and joint.parent_body is None:
            self.warn("Hinge2Joint needs a dynamic parent and endPoint; joint handled kinematically")
            joint.child_body = None
            return
        w = self._world
        create = {
            "hinge": lib.dJointCreateHinge,
            "slider": lib.dJointCreateSlider,
            "hinge2": lib.dJointCreateHinge2,
            "ball": lib.dJointCreateBall,
        }[joint.kind]
        joint.ptr = create(w, None)
        pb = joint.parent_body.ptr if joint.parent_body is not None else None
        lib.dJointAttach(joint.ptr, pb, joint.child_body.ptr)
        joint.reverse = pb is None
        if joint.kind == "ball":
            # §4.4: the three axes' motors and stops live on an Euler AMotor (axis 1 turns with the parent,
            # axis 3 with the endPoint); with no motor, stop or friction it adds no constraint row
            joint.amotor = lib.dJointCreateAMotor(w, None)
            self._attach_euler(joint.amotor, joint)
            lib.dJointSetAMotorMode(joint.amotor, ode.dAMotorEuler)
        joint.child_body.joints.append(joint)
        if joint.parent_body is not None:
            joint.parent_body.joints.append(joint)
        else:
            joint.child_body.attached_to_world = True
        self._anchor_joint(joint)
        for i in range(len(joint.params)):
            self._set_stops(joint, i)
            self._set_static_friction(joint, i)
        self._create_spring(joint)
        if joint.kind == "hinge2":
            self._set_suspension(joint)

    def _set_suspension(self, joint: JointRec) -> None:
        """Hinge2 suspension along its first axis (ODE's own hinge2 suspension rows, §4.4): ERP = hK/(hK + B),
        CFM = 1/(hK + B) from suspensionSpringConstant K and suspensionDampingConstant B; with both 0 ODE keeps
        the world's ERP/CFM, as Webots does."""
        p = joint.params[0]
        k = float(_f(p, "suspensionSpringConstant", 0.0))
        b = float(_f(p, "suspensionDampingConstant", 0.0))
        if k == 0.0 and b == 0.0:
            return
        h = self.dt
        self._lib.dJointSetHinge2Param(joint.ptr, ode.dParamSuspensionERP, min(h * k / (h * k + b), 1.0))
        self._lib.dJointSetHinge2Param(joint.ptr, ode.dParamSuspensionCFM, 1.0 / (h * k + b))

    def _set_hinge2_suspension(self, joint: JointRec) -> None:
        """A Hinge2's suspension set again (its parameters' suspension constants edited, or the parameters node
        imported or removed at run time): ODE's default first, the world's current ERP and CFM (what Webots sets
        with both constants 0), then the parameters' own suspension, if any."""
        lib = self._lib
        lib.dJointSetHinge2Param(joint.ptr, ode.dParamSuspensionERP, lib.dWorldGetERP(self._world))
        lib.dJointSetHinge2Param(joint.ptr, ode.dParamSuspensionCFM, lib.dWorldGetCFM(self._world))
        self._set_suspension(joint)

    def _referenced_solid(self, joint: JointRec, name: str) -> SolidRec | None:
        """§10: depth-first search by name from the joint's topmost Solid ancestor, skipping its upper Solid."""
        top = joint.parent
        while top is not None and top.parent is not None:
            top = top.parent
        stack = [top] if top is not None else []
        while stack:
            solid = stack.pop()
            if solid is not joint.parent and solid.name == name:
                return solid
            stack.extend(reversed(solid.children))
        return None

    def _close_loop(self, joint: JointRec, name: str) -> None:
        """A joint whose endPoint is a SolidReference: an ODE joint from its upper body to the referenced Solid's
        body (or to the static environment), made after every body and ordinary joint, closing the loop (§10).
        The referenced Solid is not moved: ODE's zero is the configuration at load."""
        lib = self._lib
        target = None
        if name != "<static environment>":
            target = self._referenced_solid(joint, name)
            if target is None:
                self.warn(f"SolidReference '{name}' not found among the Solids of the joint's robot; joint ignored")
                return
        pb = self._nearest_body(joint.parent)
        cb = self._nearest_body(target) if target is not None else None
        if cb is None and target is not None:
            self.warn(f"SolidReference '{name}' has no Physics; closed loop ignored")
            return
        if pb is None and cb is None or pb is cb or joint.kind == "hinge2":
            self.warn(f"SolidReference '{name}': no closed loop can be built (static, same body or Hinge2)")
            return
        create = {
            "hinge": lib.dJointCreateHinge,
            "slider": lib.dJointCreateSlider,
            "ball": lib.dJointCreateBall,
        }[joint.kind]
        joint.ptr = create(self._world, None)
        joint.parent_body, joint.child_body = pb, cb
        if pb is None:
            lib.dJointAttach(joint.ptr, None, cb.ptr)  # type: ignore[union-attr]
            joint.reverse = True
        else:
            lib.dJointAttach(joint.ptr, pb.ptr, cb.ptr if cb is not None else None)
        if joint.kind == "ball":  # its axes' motors, stops and friction live on an Euler AMotor, as in _create_joint
            joint.amotor = lib.dJointCreateAMotor(self._world, None)
            self._attach_euler(joint.amotor, joint)
            lib.dJointSetAMotorMode(joint.amotor, ode.dAMotorEuler)
        for b in (pb, cb):
            if b is not None:
                b.joints.append(joint)
        if (pb is None) != (cb is None):  # §2.3 rule 6, as for any body jointed to the static environment
            (cb if pb is None else pb).attached_to_world = True  # type: ignore[union-attr]
        self._anchor_joint(joint)
        for i in range(len(joint.params)):
            self._set_stops(joint, i)
            self._set_static_friction(joint, i)
        self._create_spring(joint)

    def _anchor_joint(self, joint: JointRec) -> None:
        """Set anchor/axis from the current poses; ODE's zero is this configuration (§4.1)."""
        lib = self._lib
        frame = (
            self.solid_world_pose(joint.parent) * joint.frame_rel
            if joint.parent is not None
            else joint.frame_rel
        )
        axis = frame.rotate(joint.axis_local[0])
        anchor = frame.apply(joint.anchor_local)
        j = joint.ptr
        if joint.kind == "hinge":
            ax = m3.scale(axis, -1.0) if joint.reverse else axis
            lib.dJointSetHingeAnchor(j, *anchor)
            lib.dJointSetHingeAxis(j, *ax)
        elif joint.kind == "slider":
            lib.dJointSetSliderAxis(j, *m3.scale(m3.normalized(axis), -1.0))  # §4.3
        elif joint.kind == "hinge2":
            axis2 = frame.rotate(joint.axis_local[1])
            p1 = joint.positions[0]
            if p1 != 0.0:
                axis2 = m3.mat_vec(m3.rot_axis_angle((*axis, p1)), axis2)
            if m3.norm(m3.cross(m3.normalized(axis), m3.normalized(axis2))) < 1e-6:
                self.warn("Hinge2Joint axes are aligned; falling back to x and z")
                axis, axis2 = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
            lib.dJointSetHinge2Anchor(j, *anchor)
            lib.dJointSetHinge2Axes(j, (ctypes.c_double * 4)(*axis, 0.0), (ctypes.c_double * 4)(*axis2, 0.0))
        elif joint.kind == "ball":
            lib.dJointSetBallAnchor(j, *anchor)
            self._set_euler_axes(joint, frame)
        joint.offsets = list(joint.positions)
        joint.stop_shift = 0.0  # Webots' own offset: the stops are mapped from it
        self._read_joint(joint, predict=False)

    def _attach_euler(self, amotor: int, joint: JointRec) -> None:
        """Attach a BallJoint's Euler AMotor: parent then endPoint, or, on a static parent, the endPoint alone as
        its first body. (Attached as (none, endPoint), ODE flags the AMotor reversed, and its Euler mode does not
        follow that flag: its angles then run against its rows, so stops pushed the wrong way.) A loop closed on
        the static environment (§10) has the parent alone, its third axis then fixed in the world."""
        child = joint.child_body.ptr if joint.child_body is not None else None
        if joint.parent_body is None:
            assert child is not None
            self._lib.dJointAttach(amotor, child, None)
        else:
            self._lib.dJointAttach(amotor, joint.parent_body.ptr, child)

    def _set_euler_axes(self, joint: JointRec, frame: Pose) -> None:
        """The Euler AMotor's axes from the current poses, and the reference the positions are measured from:
        ODE's Euler angles are minus Webots' positions (checked), read here from the bodies' rotations after
        each step (ODE updates its own angles only inside the next step)."""
        lib = self._lib
        a1 = m3.normalized(frame.rotate(joint.axis_local[0]))
        a3 = frame.rotate(joint.axis_local[2])
        a3 = m3.normalized(m3.sub(a3, m3.scale(a1, m3.dot(a1, a3))))  # Euler mode needs a3 ⟂ a1
        a2 = m3.cross(a3, a1)
        if joint.parent_body is None:
            # the endPoint is the AMotor's first body (_attach_euler): ODE's first axis, relative to it, carries
            # Webots' third and ODE's third (in the world) Webots' first, both negated as the bodies are swapped;
            # ODE's middle axis (third × first) is then −a2, the same sense as the others. (Webots' a1 and a3 in
            # ODE's first and third slots made it +a2: a second-axis motor drove the joint away from its target.)
            lib.dJointSetAMotorAxis(joint.amotor, 0, 1, *m3.scale(a3, -1.0))
            lib.dJointSetAMotorAxis(joint.amotor, 2, 2, *m3.scale(a1, -1.0))
        else:
            lib.dJointSetAMotorAxis(joint.amotor, 0, 1, *a1)
            lib.dJointSetAMotorAxis(joint.amotor, 2, 2, *a3)
        parent_R = joint.parent_body.pose().R if joint.parent_body is not None else m3.IDENTITY
        child_R = joint.child_body.pose().R if joint.child_body is not None else m3.IDENTITY
        basis = (a1[0], a2[0], a3[0], a1[1], a2[1], a3[1], a1[2], a2[2], a3[2])  # columns a1, a2, a3
        joint.euler_ref = (parent_R, child_R, basis)

    def _ball_angles(self, joint: JointRec) -> tuple[float, float, float]:
        """Webots' three BallJoint angles (before offsets): the endPoint's rotation relative to its parent since
        the axes were set, decomposed as R(axis1, p1)·R(axis2, p2)·R(axis3, p3) (a chain of three hinges)."""
        parent0, child0, basis = joint.euler_ref
        parent = joint.parent_body.pose().R if joint.parent_body is not None else m3.IDENTITY
        child = joint.child_body.pose().R if joint.child_body is not None else m3.IDENTITY
        # relative rotation in the load-time world frame: Q = (P·P0ᵀ)ᵀ·(C·C0ᵀ)
        q = m3.mat_mul(m3.mat_t(m3.mat_mul(parent, m3.mat_t(parent0))), m3.mat_mul(child, m3.mat_t(child0)))
        m = m3.mat_mul(m3.mat_t(basis), m3.mat_mul(q, basis))  # = Rx(p1)·Ry(p2)·Rz(p3)
        p2 = math.asin(max(-1.0, min(1.0, m[2])))
        p1 = math.atan2(-m[5], m[8])
        p3 = math.atan2(-m[1], m[0])
        return p1, p2, p3

    def _set_stops(self, joint: JointRec, i: int) -> None:
        p = joint.params[i]
        if p is None:
            return
        lo_w, hi_w = float(_f(p, "minStop", 0.0)), float(_f(p, "maxStop", 0.0))
        if lo_w == hi_w:
            return
        shift = joint.stop_shift if joint.kind == "hinge" else 0.0
        off = joint.offsets[i] - shift  # Webots' offset (ODE's zero has moved by shift since, _rebase_hinge)
        if joint.kind == "slider":
            lo, hi = lo_w - off, hi_w - off  # §4.3
        else:
            lo = max(-math.pi, min(math.pi, -hi_w + off))  # §4.2
            hi = max(-math.pi, min(math.pi, -lo_w + off))
        if lo > hi:
            lo, hi = hi, lo
        lo, hi = lo + shift, hi + shift
        joint.rebase = joint.kind == "hinge"
        if joint.kind == "hinge2" and i == 1:
            self._set_hinge2_second_stops(joint, lo, hi)
            return
        setp = self._param_setter(joint)
        group = _GROUPS[joint.ode_axis(i)]
        setp(joint.ptr, group + ode.dParamLoStop, lo)
        setp(joint.ptr, group + ode.dParamHiStop, hi)

    def _free_stops(self, joint: JointRec, i: int) -> None:
        """No stop on axis ``i`` (before the parameters' own stops, if any, are set)."""
        if joint.kind == "hinge2" and i == 1:
            if joint.stop2:
                self._lib.dJointSetAMotorParam(joint.stop2, ode.dParamHiStop, ode.dInfinity)
                self._lib.dJointSetAMotorParam(joint.stop2, ode.dParamLoStop, -ode.dInfinity)
            return
        setp = self._param_setter(joint)
        group = _GROUPS[joint.ode_axis(i)]
        # Upstream ODE's hinge tests its limit only while a stop lies within [−π, π] and does not clear the test's
        # last result otherwise: a hinge resting on a stop whose stops become ±∞ kept its "at the limit" flag, and
        # the next step wrote a stop row it had not counted (ODE stopped inside the step on an LCP assertion). Its
        # angle is in [−π, π) (checked), so a high stop at π keeps the test running and never engages.
        setp(joint.ptr, group + ode.dParamHiStop, math.pi if joint.kind == "hinge" else ode.dInfinity)
        setp(joint.ptr, group + ode.dParamLoStop, -ode.dInfinity)
        joint.rebase = False

    def _set_stops_again(self, joint: JointRec, i: int) -> None:
        """A run-time edit of ``minStop`` or ``maxStop`` on axis ``i`` (Webots: WbJointParameters'
        minStopChanged/maxStopChanged, the joint's stops applied to ODE again): the stops are mapped as at load
        (§4.2/§4.3: sign, the current offset, clamped into [−π, π] on rotational axes) from the next step, and
        equal stops take the axis' stops away. A Hinge2's second axis may get its stop AMotor now: it joins the
        AMotors whose angle is set before every step."""
        if not joint.ptr:
            return  # a kinematic joint has no ODE stop, at load either
        self._free_stops(joint, i)
        self._set_stops(joint, i)
        self._springs = [j for j in self.joints if j.spring or j.spring2 or j.stop2]

    def _hinge_spring_rest(self, joint: JointRec) -> float:
        """The stop of a hinge's spring AMotor, whose angle is ODE's hinge angle (§4.5: normalizeAngle(offset)),
        Webots' offset taken where ODE's zero has moved since (:meth:`_rebase_hinge`)."""
        return m3.normalize_angle(joint.offsets[0] - joint.stop_shift) + joint.stop_shift

    def _rebase_hinge(self, joint: JointRec) -> None:
        """§4.2 fork difference (Appendix A.3): Webots' ODE unwraps a hinge's angle across ±π when it tests the
        stops; upstream ODE's angle wraps there, so a stop clamped to ±π never held. A hinge with stops turned
        more than π/2 from ODE's zero gets its zero here (dJointSetHingeAxis on its own axis: ODE's angle restarts
        at 0; the rows stay, the endPoint's axis re-taken along the parent's, as any re-anchoring does), its offset
        the current position, and its stops (and its spring's rest) shifted by as much: they are the stops Webots
        maps from its own offset (§4.2), and the angle ODE tests them against stays within about π/2 of 0, never
        wrapped."""
        lib = self._lib
        position = joint.positions[0]
        joint.stop_shift += position - joint.offsets[0]
        joint.offsets[0] = position
        axis = (ctypes.c_double * 4)()
        lib.dJointGetHingeAxis(joint.ptr, axis)
        lib.dJointSetHingeAxis(joint.ptr, axis[0], axis[1], axis[2])
        joint.raw_angles[0] = 0.0
        self._set_stops(joint, 0)
        if joint.spring:
            rest = self._hinge_spring_rest(joint)
            lib.dJointSetAMotorParam(joint.spring, ode.dParamLoStop, rest)
            lib.dJointSetAMotorParam(joint.spring, ode.dParamHiStop, rest)

    def _set_stop_softness(self, joint: JointRec, i: int, name: str) -> bool:
        """A run-time edit of a HingeJointParameters' ``stopERP`` or ``stopCFM`` (−1: the world's current value):
        passed to the joint's stop rows through dParamStopERP/CFM (§4.2; at creation ODE's defaults, the world's,
        apply). Hinges and a Hinge2's first axis have these fields."""
        if joint.kind not in ("hinge", "hinge2") or i != 0 or not joint.ptr:
            return False
        value = float(_f(joint.params[i], name, -1.0))
        if value == -1.0:
            value = (self._lib.dWorldGetERP if name == "stopERP" else self._lib.dWorldGetCFM)(self._world)
        param = ode.dParamStopERP if name == "stopERP" else ode.dParamStopCFM
        self._param_setter(joint)(joint.ptr, param, value)
        return True

    def _set_hinge2_second_stops(self, joint: JointRec, lo: float, hi: float) -> None:
        """Upstream ODE's hinge2 never limits its second axis (Webots' fork does, §4.4): a one-axis user AMotor
        on that axis (turning with body 2) carries the stops instead. Its angle, set before every step, is
        −(position − offset), the sense of ODE's angle rates, so the stops are −maxStop + offset and
        −minStop + offset as on the first axis; stop ERP/CFM are the world's, as for any ODE stop."""
        lib = self._lib
        if not joint.stop2:
            joint.stop2 = self._one_axis_amotor(joint)
        out = (ctypes.c_double * 4)()
        lib.dJointGetHinge2Axis2(joint.ptr, out)
        lib.dJointSetAMotorAxis(joint.stop2, 0, 2, out[0], out[1], out[2])
        lib.dJointSetAMotorParam(joint.stop2, ode.dParamLoStop, lo)
        lib.dJointSetAMotorParam(joint.stop2, ode.dParamHiStop, hi)
        lib.dJointSetAMotorAngle(joint.stop2, 0, -lib.dJointGetHinge2Angle2(joint.ptr))

    def _param_setter(self, joint: JointRec) -> Callable[..., None]:
        lib = self._lib
        if joint.kind == "ball":
            amotor = joint.amotor
            return lambda _j, param, value: lib.dJointSetAMotorParam(amotor, param, value)  # type: ignore[no-any-return]
        return {  # type: ignore[no-any-return]
            "hinge": lib.dJointSetHingeParam,
            "slider": lib.dJointSetSliderParam,
            "hinge2": lib.dJointSetHinge2Param,
        }.get(joint.kind, lambda *a: None)

    def _set_static_friction(self, joint: JointRec, i: int) -> None:
        """§4.5: without a motor, static friction is a velocity-0 motor limited to staticFriction."""
        sf = joint.static_friction[i]
        if joint.motors[i] is None and sf > 0:
            setp = self._param_setter(joint)
            group = _GROUPS[joint.ode_axis(i)]
            setp(joint.ptr, group + ode.dParamVel, 0.0)
            setp(joint.ptr, group + ode.dParamFMax, sf)

    def axis_spring_constants(self, joint: JointRec, i: int) -> tuple[float, float]:
        """(springConstant, dampingConstant + the damping of the axis' Brake) of joint axis ``i`` (§4.5)."""
        p = joint.params[i] if i < len(joint.params) else None
        k = float(_f(p, "springConstant", 0.0))
        b = float(_f(p, "dampingConstant", 0.0))
        brake = joint.brakes[i] if i < len(joint.brakes) else None
        if brake is not None:
            b += brake.damping
        return k, b

    def _create_spring(self, joint: JointRec) -> None:
        """§4.5: implicit spring/damper through an AMotor (hinge, each Hinge2 axis) or an LMotor row (slider)."""
        if joint.kind == "hinge2":
            self._create_hinge2_springs(joint)
            return
        if joint.kind == "ball":
            self._create_ball_springs(joint)
            return
        if joint.kind not in ("hinge", "slider"):
            return
        k, b = self.axis_spring_constants(joint, 0)
        if k == 0.0 and b == 0.0:
            return
        lib = self._lib
        h = self.dt
        joint.spring_cfm = 1.0 / (h * k + b)
        joint.spring_erp = min(h * k / (h * k + b), 1.0)
        pb = joint.parent_body.ptr if joint.parent_body is not None else None
        assert joint.child_body is not None
        # the parent's current pose, as for the anchor: a joint imported (or its springs rebuilt) after the
        # parent moved has its spring about the axis where it is now, not where it was at load
        frame = self.solid_world_pose(joint.parent) * joint.frame_rel if joint.parent is not None else joint.frame_rel
        axis = frame.rotate(joint.axis_local[0])
        rel = 0 if joint.reverse else 1
        if joint.kind == "hinge":
            ax = m3.scale(axis, -1.0) if joint.reverse else axis
            am = self._stop_amotor(joint, ax, rel, self._hinge_spring_rest(joint), k, b)
        else:
            am = lib.dJointCreateLMotor(self._world, None)
            lib.dJointAttach(am, pb, joint.child_body.ptr)
            lib.dJointSetLMotorNumAxes(am, 1)
            lib.dJointSetLMotorAxis(am, 0, rel, *m3.scale(m3.normalized(axis), -1.0))
            lib.dJointSetLMotorParam(am, ode.dParamCFM, joint.spring_cfm)
            lib.dJointSetLMotorParam(am, ode.dParamFMax, ode.dInfinity)
            lib.dJointSetLMotorParam(am, ode.dParamVel, 0.0)
        joint.spring = am

    def _one_axis_amotor(self, joint: JointRec) -> int:
        """A one-axis user AMotor between the joint's parent body (or the world) and its child body."""
        lib = self._lib
        am = lib.dJointCreateAMotor(self._world, None)
        pb = joint.parent_body.ptr if joint.parent_body is not None else None
        assert joint.child_body is not None
        lib.dJointAttach(am, pb, joint.child_body.ptr)
        lib.dJointSetAMotorMode(am, ode.dAMotorUser)
        lib.dJointSetAMotorNumAxes(am, 1)
        return am

    def _stop_amotor(self, joint: JointRec, axis: m3.Vec3, rel: int, stop: float, k: float, b: float) -> int:
        """A one-axis user AMotor whose stop (lo = hi, so bilateral) holds ``stop`` with ERP/CFM from K and B;
        its angle is set from the joint before every step."""
        lib = self._lib
        h = self.dt
        am = self._one_axis_amotor(joint)
        lib.dJointSetAMotorAxis(am, 0, rel, *axis)
        lib.dJointSetAMotorParam(am, ode.dParamLoStop, stop)
        lib.dJointSetAMotorParam(am, ode.dParamHiStop, stop)
        lib.dJointSetAMotorParam(am, ode.dParamStopCFM, 1.0 / (h * k + b))
        lib.dJointSetAMotorParam(am, ode.dParamStopERP, min(h * k / (h * k + b), 1.0))
        lib.dJointSetAMotorAngle(am, 0, 0.0)
        return am  # type: ignore[no-any-return]

    def _create_hinge2_springs(self, joint: JointRec) -> None:
        """Hinge2: one stop AMotor per sprung/damped axis, axis 1 turning with body 1, axis 2 with body 2. An AMotor
        row measures its angle in the sense of ODE's angle rates, (ω1 − ω2)·axis; both Webots positions run
        against those rates, so each AMotor angle is −(position − offset): ODE's angle 1 itself, and minus ODE's
        angle 2 (which runs against its rate; §4.4). The stop (spring rest) is then the offset on both axes."""
        lib = self._lib
        for i in range(2):
            k, b = self.axis_spring_constants(joint, i)
            if k == 0.0 and b == 0.0:
                continue
            out = (ctypes.c_double * 4)()
            (lib.dJointGetHinge2Axis1 if i == 0 else lib.dJointGetHinge2Axis2)(joint.ptr, out)
            axis = (out[0], out[1], out[2])
            stop = m3.normalize_angle(joint.offsets[i])
            am = self._stop_amotor(joint, axis, i + 1, stop, k, b)
            if i == 0:
                joint.spring = am
            else:
                joint.spring2 = am

    def _create_ball_springs(self, joint: JointRec) -> None:
        """BallJoint: a second Euler AMotor on the same axes whose stop rows (lo = hi: bilateral) hold each sprung
        or damped axis at its zero position with ERP/CFM from K and B (§4.5); ODE computes its Euler angles."""
        constants = [self.axis_spring_constants(joint, i) for i in range(3)]
        if all(k == 0.0 and b == 0.0 for k, b in constants):
            return
        lib = self._lib
        h = self.dt
        am = lib.dJointCreateAMotor(self._world, None)
        self._attach_euler(am, joint)
        lib.dJointSetAMotorMode(am, ode.dAMotorEuler)
        for index in (0, 2):
            axis = ctypes.cast((ctypes.c_double * 4)(), ctypes.POINTER(ctypes.c_double))
            lib.dJointGetAMotorAxis(joint.amotor, index, axis)
            lib.dJointSetAMotorAxis(am, index, index // 2 + 1, axis[0], axis[1], axis[2])
        for i, (k, b) in enumerate(constants):
            if k == 0.0 and b == 0.0:
                continue
            stop = m3.normalize_angle(joint.offsets[i])
            g = _GROUPS[joint.ode_axis(i)]
            lib.dJointSetAMotorParam(am, g + ode.dParamLoStop, stop)
            lib.dJointSetAMotorParam(am, g + ode.dParamHiStop, stop)
            lib.dJointSetAMotorParam(am, g + ode.dParamStopCFM, 1.0 / (h * k + b))
            lib.dJointSetAMotorParam(am, g + ode.dParamStopERP, min(h * k / (h * k + b), 1.0))
        joint.spring = am

    def rebuild_springs(self, joint: JointRec) -> None:
        """A run-time edit of springConstant/dampingConstant (or of a Brake's damping) reaches ODE at the next
        step: the spring rows are made again from the current values (called by the supervisor edits)."""
        lib = self._lib
        for name in ("spring", "spring2"):
            am = getattr(joint, name)
            if am:
                lib.dJointDestroy(am)
                setattr(joint, name, 0)
        if joint.ptr:
            self._create_spring(joint)
            if joint.spring or joint.spring2:
                self._apply_spring(joint)
        self._springs = [j for j in self.joints if j.spring or j.spring2 or j.stop2]

    def _create_fixed_joints(self, bodies: Sequence[BodyRec] | None = None) -> None:
        lib = self._lib
        for body in self.bodies if bodies is None else bodies:
            if body.root.joint is not None or body.root.parent is None:
                continue
            fj = lib.dJointCreateFixed(self._world, None)
            other = body.fixed_to.ptr if body.fixed_to is not None else None
            lib.dJointAttach(fj, other, body.ptr)
            lib.dJointSetFixed(fj)
            body.fixed_joint = fj

    # -- motor rows and springs during stepping

    def _set_motor_row(self, joint: JointRec, i: int, vel: float, fmax: float) -> None:
        setp = self._param_setter(joint)
        g = _GROUPS[joint.ode_axis(i)]
        setp(joint.ptr, g + ode.dParamVel, vel)
        setp(joint.ptr, g + ode.dParamFMax, fmax)

    def _apply_spring(self, joint: JointRec) -> None:
        lib = self._lib
        if joint.kind == "ball":
            return  # an Euler AMotor: ODE measures its angles itself
        if joint.kind == "hinge2":
            if joint.spring:
                lib.dJointSetAMotorAngle(joint.spring, 0, lib.dJointGetHinge2Angle1(joint.ptr))
            if joint.spring2 or joint.stop2:
                angle2 = -lib.dJointGetHinge2Angle2(joint.ptr)
                for am in (joint.spring2, joint.stop2):
                    if am:
                        lib.dJointSetAMotorAngle(am, 0, angle2)
        elif joint.kind == "hinge":
            a = lib.dJointGetHingeAngle(joint.ptr)
            lib.dJointSetAMotorAngle(joint.spring, 0, -a if joint.reverse else a)
        else:
            # LMotor motor row == stop row with ERP/CFM (module docstring); the row Jacobian sign flips
            # with the ODE body order, hence the reverse-dependent sign.
            x = joint.positions[0]
            v = joint.spring_erp * x / self.dt
            lib.dJointSetLMotorParam(joint.spring, ode.dParamVel, v if joint.reverse else -v)

    def _read_joint(self, joint: JointRec, predict: bool) -> None:
        """§4.2–4.4: Webots joint position from ODE (continuous, unwrapped for hinges)."""
        lib = self._lib
        j = joint.ptr
        kind = joint.kind
        if kind == "hinge":
            a = self._hinge_angle(j)
            joint.raw_angles[0] = a
            if predict:
                rate = self._hinge_rate(j)
                pred = joint.positions[0] + (rate if joint.reverse else -rate) * self.dt
            else:
                pred = joint.positions[0]
            pos = (a if joint.reverse else -a) + joint.offsets[0]
            joint.positions[0] = m3.normalize_angle(pos, pred)
        elif kind == "slider":
            joint.positions[0] = self._slider_pos(j) + joint.offsets[0]
        elif kind == "ball":
            # unwrapped to within ±π of the last positions, also without prediction: after a teleport (§4.1) these
            # are the positions set (a first axis teleported to 4 rad reads 4, not ODE's Euler angle 4 − 2π)
            for i, a in enumerate(self._ball_angles(joint)):
                joint.positions[i] = m3.normalize_angle(a + joint.offsets[i], joint.positions[i])
        elif kind == "hinge2":
            a1 = lib.dJointGetHinge2Angle1(j)
            a2 = lib.dJointGetHinge2Angle2(j)
            if predict:
                # ODE's angle rates are both (ω1 − ω2)·axis, the motor rows' sense; angle 1 follows its rate
                # and angle 2 runs against it, so both positions advance by −rate·dt (a +rate prediction for
                # axis 2 unwrapped a wheel turning faster than π/(2·dt) the wrong way round)
                pred1 = joint.positions[0] - lib.dJointGetHinge2Angle1Rate(j) * self.dt
                pred2 = joint.positions[1] - lib.dJointGetHinge2Angle2Rate(j) * self.dt
            else:
                pred1, pred2 = joint.positions[0], joint.positions[1]
            joint.positions[0] = m3.normalize_angle(-a1 + joint.offsets[0], pred1)
            joint.positions[1] = m3.normalize_angle(a2 + joint.offsets[1], pred2)
