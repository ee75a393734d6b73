"""The MuJoCo twin.

Motors mean what a Webots motor means (see :mod:`dualtwin.twins.base`). ODE's joint motor is a velocity
constraint that reaches the commanded velocity within one step unless that needs more than the maximum
torque. MuJoCo has no such constraint, so each motor is a ``general`` actuator switched between:

* a stiff velocity servo (force ``kv (u - qdot)``, integrated implicitly by ``implicitfast``, so any ``kv``
  is stable) while the torque it needs stays within the limit, and
* a saturated torque of ``±max_torque`` once it does not, until the velocity reaches ``u`` again.

MuJoCo's own ``forcerange`` clamp is not used for this: when it clamps, ``implicitfast`` drops the servo's
derivative and a stiff servo chatters. Webots motor fields are read from
``<custom><numeric name="webots_motor.NAME" data="maxVelocity Kp Ki Kd acceleration"/>``, and the maximum
torque from the actuator's ``forcerange``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.twins.base import (
    BodyState,
    ControlMode,
    Knob,
    MechanicalState,
    SyncError,
    Twin,
    canonical_quat,
    check_state_names,
    matrix_from_quat,
    unknown_name,
)
from dualtwin.twins.motors import MotorParams, MotorState

if TYPE_CHECKING:
    from dualtwin.robots.binding import RobotBinding

# Servo stiffness relative to the joint's own inertia: kv·dt = SERVO_STIFFNESS·I closes 91 % of the
# velocity error of a free joint in one step, like ODE's motor constraint.
SERVO_STIFFNESS = 10.0
# Largest delay, in control periods, that the delay knobs accept.
MAX_DELAY_PERIODS = 10
#: set_state refuses states whose contacts overlap deeper than this (m): that is a geometry mismatch or a
#: bad state, not the millimetres of a resting soft contact.
MAX_PENETRATION = 0.02


def restitution_to_dampratio(restitution: float, nominal: float) -> float:
    """Damping ratio of MuJoCo's contact spring-damper that rebounds with coefficient ``restitution``.

    A linear spring-damper with damping ratio ζ < 1 rebounds with ``e = exp(-ζπ/√(1-ζ²))``. ``e = 0`` keeps a
    nominal ratio that already does not bounce (ζ >= 1), else uses critical damping.
    """
    if restitution <= 0.0:
        return max(nominal, 1.0)
    log_e = math.log(min(restitution, 0.999))
    return -log_e / math.sqrt(math.pi ** 2 + log_e ** 2)


def dampratio_to_restitution(dampratio: float) -> float:
    """Inverse of `restitution_to_dampratio` (0 for ζ >= 1)."""
    if dampratio >= 1.0:
        return 0.0
    return math.exp(-dampratio * math.pi / math.sqrt(1.0 - dampratio ** 2))


class _Motor:
    __slots__ = ("name", "index", "qpos", "dof", "kv", "state", "saturated")

    def __init__(self, name: str, index: int, qpos: int, dof: int, kv: float, state: MotorState) -> None:
        self.name = name
        self.index = index
        self.qpos = qpos
        self.dof = dof
        self.kv = kv
        self.state = state
        self.saturated = 0.0  # 0 = servo; ±1 = applying ±max torque


def compile_spec(spec: mujoco.MjSpec, origin: str) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as exc:
        message = " ".join(str(exc).split())
        raise DualtwinError(f"{origin}: MJCF does not compile: {message}") from None


def load_spec(path: Path) -> mujoco.MjSpec:
    if not Path(path).is_file():
        raise DualtwinError(f"{path}: model file not found")
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        message = " ".join(str(exc).split())
        raise DualtwinError(f"{path}: MJCF does not parse: {message}") from None


class MuJoCoTwin(Twin):
    """A MuJoCo model stepped in control periods with Webots motor semantics."""

    name = "mujoco"

    def __init__(self, model: Path | mujoco.MjSpec, control_period: float,
                 aliases: dict[str, str] | None = None) -> None:
        origin = str(model) if isinstance(model, Path | str) else "<MjSpec>"
        self.spec = load_spec(Path(model)) if isinstance(model, Path | str) else model
        self.model = compile_spec(self.spec, origin)
        self.data = mujoco.MjData(self.model)
        self._origin = origin
        self._aliases = aliases or {}
        dt = self.model.opt.timestep
        substeps = control_period / dt
        if abs(substeps - round(substeps)) > 1e-6 or round(substeps) < 1:
            raise DualtwinError(f"{origin}: control period {control_period} s is not a whole number of "
                                f"physics steps of {dt} s")
        self._substeps = int(round(substeps))
        self._control_period = control_period
        self._rng = np.random.default_rng(0)
        self._noise = np.array(self.model.sensor_noise, dtype=float)
        self._nominal = self._snapshot_nominal()
        self._knob_values: dict[str, float] = {}
        self._motors = self._build_motors()
        self._motor_by_name = {m.name: m for m in self._motors}
        self._nominal_motor = {m.name: (m.state.params.max_torque, m.state.params.max_velocity) for m in self._motors}
        # Knob state outside the model arrays: the control delay queues commands until they are due, and
        # the sensor models (bias, resolution, delay) apply in sensor().
        self._delay = 0
        self._pending: list[tuple[int, _Motor, ControlMode, float]] = []
        self._sensor_bias = np.zeros(self.model.nsensor)
        self._sensor_quant = np.zeros(self.model.nsensor)
        self._sensor_delay = np.zeros(self.model.nsensor, dtype=int)
        self._history: list[np.ndarray] = []
        self._inertia_changed = False
        self._scratch = mujoco.MjData(self.model)
        self._renderer: mujoco.Renderer | None = None
        # Motors commanded since the last reset; the others hold their position (see set_state).
        self._commanded: set[str] = set()
        self.max_penetration = MAX_PENETRATION
        self.reset()

    # ---------------------------------------------------------------- set-up
    def _id(self, kind: mujoco.mjtObj, name: str, label: str) -> int:
        resolved = self._aliases.get(name, name)
        index = mujoco.mj_name2id(self.model, kind, resolved)
        if index < 0:
            count = {mujoco.mjtObj.mjOBJ_JOINT: self.model.njnt, mujoco.mjtObj.mjOBJ_BODY: self.model.nbody,
                     mujoco.mjtObj.mjOBJ_ACTUATOR: self.model.nu, mujoco.mjtObj.mjOBJ_SENSOR: self.model.nsensor,
                     mujoco.mjtObj.mjOBJ_GEOM: self.model.ngeom, mujoco.mjtObj.mjOBJ_CAMERA: self.model.ncam}[kind]
            known = [mujoco.mj_id2name(self.model, kind, i) or "" for i in range(count)]
            raise unknown_name(label, resolved, [k for k in known if k], self._origin)
        return int(index)

    def _motor_params(self, name: str, actuator: int) -> MotorParams:
        params = MotorParams()
        numeric = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_NUMERIC, f"webots_motor.{name}")
        if numeric >= 0:
            adr, size = self.model.numeric_adr[numeric], self.model.numeric_size[numeric]
            values = list(self.model.numeric_data[adr:adr + size]) + [math.nan] * 5
            for attr, value in zip(("max_velocity", "kp", "ki", "kd", "acceleration"), values[:5], strict=True):
                if not math.isnan(value):
                    setattr(params, attr, float(value))
        if self.model.actuator_forcelimited[actuator]:
            params.max_torque = float(abs(self.model.actuator_forcerange[actuator, 1]))
        return params

    def _build_motors(self) -> list[_Motor]:
        m = self.model
        motors = []
        # Webots clamps torque itself; MuJoCo's clamp would disable the implicit servo derivative.
        mujoco.mj_setConst(m, self.data)
        for i in range(m.nu):
            if m.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
                continue
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}"
            joint = int(m.actuator_trnid[i, 0])
            dof = int(m.jnt_dofadr[joint])
            params = self._motor_params(name, i)
            m.actuator_forcelimited[i] = 0
            m.actuator_ctrllimited[i] = 0
            inertia = float(m.dof_M0[dof]) + float(m.dof_armature[dof])
            kv = SERVO_STIFFNESS * inertia / m.opt.timestep
            motors.append(_Motor(name, i, int(m.jnt_qposadr[joint]), dof, kv, MotorState(params)))
        return motors

    def _snapshot_nominal(self) -> dict[str, np.ndarray]:
        m = self.model
        return {
            "dof_damping": m.dof_damping.copy(), "dof_frictionloss": m.dof_frictionloss.copy(),
            "geom_friction": m.geom_friction.copy(), "body_mass": m.body_mass.copy(),
            "body_inertia": m.body_inertia.copy(), "body_ipos": m.body_ipos.copy(),
            "geom_solref": m.geom_solref.copy(), "jnt_stiffness": m.jnt_stiffness.copy(),
            "sensor_noise": m.sensor_noise.copy(), "body_iquat": m.body_iquat.copy(),
            "jnt_solref": m.jnt_solref.copy(),
        }

    # ---------------------------------------------------------------- Twin API
    @property
    def control_period(self) -> float:
        return self._control_period

    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(self, seed: int | None = None) -> None:
        mujoco.mj_resetData(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)
        self._rng = np.random.default_rng(seed)
        self._pending.clear()
        self._history.clear()
        self._commanded.clear()
        for motor in self._motors:
            motor.state.reset(float(self.data.qpos[motor.qpos]))
            motor.saturated = 0.0
            self._set_servo(motor)
        self._bad_state = self._bad_state_warnings()

    def set_joint_state(self, joint: str, position: float | None = None, velocity: float | None = None) -> None:
        j = self._id(mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
        m, d = self.model, self.data
        if position is not None:
            d.qpos[m.jnt_qposadr[j]] = position
            # Webots resets the physics of the teleported subtree (spec §4.1).
            body = m.jnt_bodyid[j]
            for b in range(m.nbody):
                if self._in_subtree(b, body):
                    start, count = m.body_dofadr[b], m.body_dofnum[b]
                    if count:
                        d.qvel[start:start + count] = 0.0
        if velocity is not None:
            d.qvel[m.jnt_dofadr[j]] = velocity
        mujoco.mj_forward(m, d)

    def _in_subtree(self, body: int, root: int) -> bool:
        while body > 0:
            if body == root:
                return True
            body = int(self.model.body_parentid[body])
        return root == 0

    def set_body_position(self, body: str, axis: int, value: float) -> None:
        b = self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")
        m = self.model
        joint = m.body_jntadr[b]
        if joint < 0 or m.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE:
            raise DualtwinError(f"{self._origin}: body {body!r} has no free joint to teleport")
        self.data.qpos[m.jnt_qposadr[joint] + axis] = value
        mujoco.mj_forward(m, self.data)

    def command(self, actuator: str, mode: ControlMode, value: float) -> None:
        motor = self._motor_by_name.get(self._aliases.get(actuator, actuator))
        if motor is None:
            raise unknown_name("motor", actuator, list(self._motor_by_name), self._origin)
        self._commanded.add(motor.name)
        if self._delay:
            # control.delay_periods: the command reaches the motor k control periods late.
            self._pending.append((self._periods() + self._delay, motor, mode, value))
            return
        self._apply_command(motor, mode, value)

    def _periods(self) -> int:
        """Control periods since reset (teleports do not advance time)."""
        return int(round(self.data.time / self._control_period))

    def _before_step(self) -> None:
        """Deliver delayed commands that are due and remember sensor readings for delayed sensors."""
        if self._pending:
            now = self._periods()
            due = [p for p in self._pending if p[0] <= now]
            self._pending = [p for p in self._pending if p[0] > now]
            for _, motor, mode, value in due:
                self._apply_command(motor, mode, value)
        if self._sensor_delay.any():
            self._history.append(self.data.sensordata.copy())
            del self._history[:-MAX_DELAY_PERIODS - 1]

    def _apply_command(self, motor: _Motor, mode: ControlMode, value: float) -> None:
        if mode == "velocity":
            motor.state.set_velocity(value)
        elif mode == "position":
            motor.state.set_position(value)
        else:
            motor.state.set_torque(value)
        if motor.state.torque_mode:
            self._set_torque(motor, motor.state.torque)
        else:
            motor.saturated = 0.0
            self._set_servo(motor)

    def _set_servo(self, motor: _Motor) -> None:
        m = self.model
        m.actuator_gainprm[motor.index, 0] = motor.kv
        m.actuator_biastype[motor.index] = mujoco.mjtBias.mjBIAS_AFFINE
        m.actuator_biasprm[motor.index, :3] = (0.0, 0.0, -motor.kv)

    def _set_torque(self, motor: _Motor, torque: float) -> None:
        m = self.model
        m.actuator_gainprm[motor.index, 0] = 1.0
        m.actuator_biastype[motor.index] = mujoco.mjtBias.mjBIAS_NONE
        m.actuator_biasprm[motor.index, :3] = 0.0
        self.data.ctrl[motor.index] = torque

    def step(self) -> None:
        m, d = self.model, self.data
        if self._pending or self._sensor_delay.any():
            self._before_step()
        servos = [mo for mo in self._motors if not mo.state.torque_mode]
        if not servos:
            mujoco.mj_step(m, d, nstep=self._substeps)
        elif any(mo.saturated or mo.state.needs_feedback for mo in servos):
            for _ in range(self._substeps):
                self._servo_substep(servos)
        else:
            # Plain velocity control: u is constant over the period, so only saturation needs watching.
            # A memoryview reads plain floats: cheaper than NumPy scalars in this per-sub-step check.
            qvel = memoryview(d.qvel)
            dt = m.opt.timestep
            checks = []
            for mo in servos:
                u = mo.state.velocity_command(0.0, dt)
                d.ctrl[mo.index] = u
                checks.append((mo, u, mo.dof, mo.kv, mo.state.available_torque))
            for k in range(self._substeps):
                mujoco.mj_step(m, d)
                for mo, u, dof, kv, limit in checks:
                    torque = kv * (u - qvel[dof])
                    if torque > limit or -torque > limit:
                        self._saturate(mo, torque)
                        for _ in range(self._substeps - k - 1):
                            self._servo_substep(servos)
                        self._check_stable()
                        return
        self._check_stable()

    def _saturate(self, mo: _Motor, torque: float) -> None:
        mo.saturated = math.copysign(1.0, torque)
        self._set_torque(mo, mo.saturated * mo.state.available_torque)

    def _servo_substep(self, servos: list[_Motor]) -> None:
        """One physics step with the Webots PID and the saturation state machine for every servo motor."""
        m, d = self.model, self.data
        dt = m.opt.timestep
        qpos, qvel, ctrl = d.qpos, d.qvel, d.ctrl
        for mo in servos:
            u = mo.state.velocity_command(float(qpos[mo.qpos]), dt)
            limit = mo.state.available_torque
            if mo.saturated:
                # Leave saturation once full torque would carry the joint past u this step.
                if (u - float(qvel[mo.dof])) * mo.saturated <= 0.0 or limit <= 0.0:
                    mo.saturated = 0.0
                    self._set_servo(mo)
                    ctrl[mo.index] = u
                else:
                    ctrl[mo.index] = mo.saturated * limit
            else:
                ctrl[mo.index] = u
        mujoco.mj_step(m, d)
        for mo in servos:
            if not mo.saturated:
                # The backward-Euler servo torque actually applied this step.
                torque = mo.kv * (float(ctrl[mo.index]) - float(qvel[mo.dof]))
                if abs(torque) > mo.state.available_torque:
                    self._saturate(mo, torque)

    def _bad_state_warnings(self) -> int:
        """MuJoCo resets mjData itself after bad qpos/qvel/qacc; its warning counters are the trace left."""
        w = self.data.warning
        return sum(w[k].number for k in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                                         mujoco.mjtWarning.mjWARN_BADQACC))

    def _check_stable(self) -> None:
        d = self.data
        warnings = self._bad_state_warnings()
        if warnings != self._bad_state or not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            self._bad_state = warnings
            raise SimulationUnstable(f"MuJoCo twin became numerically unstable (MuJoCo warning: "
                                     f"bad qpos, qvel or qacc) within the period ending near t = {d.time:.3f} s")

    def joint_position(self, joint: str) -> float:
        j = self._id(mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
        return float(self.data.qpos[self.model.jnt_qposadr[j]])

    def joint_velocity(self, joint: str) -> float:
        j = self._id(mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
        return float(self.data.qvel[self.model.jnt_dofadr[j]])

    def body_position(self, body: str) -> np.ndarray:
        return self.data.xpos[self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")].copy()

    def body_orientation(self, body: str) -> np.ndarray:
        return self.data.xmat[self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")].reshape(3, 3).copy()

    def body_velocity(self, body: str) -> np.ndarray:
        b = self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")
        out = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_XBODY, b, out, 0)
        return np.concatenate([out[3:], out[:3]])

    def sensor(self, name: str) -> float:
        s = self._id(mujoco.mjtObj.mjOBJ_SENSOR, name, "sensor")
        adr = self.model.sensor_adr[s]
        delay = int(self._sensor_delay[s])
        if delay and self._history:
            # history[-k] is the reading k periods ago; before that much time has passed, the first one.
            value = float(self._history[max(0, len(self._history) - delay)][adr])
        else:
            value = float(self.data.sensordata[adr])
        value += float(self._sensor_bias[s])
        if self._noise[s] > 0:
            value += float(self._rng.normal(0.0, self._noise[s]))
        if self._sensor_quant[s] > 0:
            # Webots' sensor `resolution`: readings are rounded to a multiple of it.
            value = float(np.round(value / self._sensor_quant[s]) * self._sensor_quant[s])
        return value

    # ---------------------------------------------------------------- state transfer
    def _state_entities(self) -> tuple[list[tuple[str, int, int]], list[tuple[str, int, int]]]:
        """(canonical name, qpos address, dof address) of the free bodies and of the hinge/slide joints."""
        # The compiled model never changes its joints: resolve them once (the state is read every period).
        cached: tuple[list[tuple[str, int, int]], list[tuple[str, int, int]]] | None = getattr(self, "_entities", None)
        if cached is None:
            cached = self._entities = self._find_state_entities()
            self._qpos_joint = {qa: name for name, qa, _ in cached[1]}
        return cached

    def _find_state_entities(self) -> tuple[list[tuple[str, int, int]], list[tuple[str, int, int]]]:
        m = self.model
        inverse = {v: k for k, v in self._aliases.items()}
        bodies, joints = [], []
        free, hinge, slide = (int(k) for k in (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_HINGE,
                                                mujoco.mjtJoint.mjJNT_SLIDE))
        for j in range(m.njnt):
            kind = int(m.jnt_type[j])
            if kind == free:
                name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.jnt_bodyid[j]))
                if name:
                    bodies.append((inverse.get(name, name), int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])))
            elif kind in (hinge, slide):
                name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
                if name:
                    joints.append((inverse.get(name, name), int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])))
        return bodies, joints

    def get_state(self) -> MechanicalState:
        """qpos/qvel by name: a free joint's qpos is its body frame's pose, its qvel the frame origin's world
        linear velocity and the body-frame angular velocity (rotated to world here)."""
        bodies, joints = self._state_entities()
        qpos, qvel = self.data.qpos, self.data.qvel
        out = MechanicalState(float(self.data.time), source=self.name)
        for name, qa, da in bodies:
            quat = qpos[qa + 3:qa + 7].copy()
            angular = np.zeros(3)
            mujoco.mju_rotVecQuat(angular, qvel[da + 3:da + 6], quat)
            if quat[0] < 0:
                quat = -quat
            out.bodies[name] = BodyState(qpos[qa:qa + 3].copy(), quat / math.sqrt(float(quat @ quat)),
                                         qvel[da:da + 3].copy(), angular)
        positions, velocities = qpos.tolist(), qvel.tolist()
        out.joint_positions = {name: positions[qa] for name, qa, _ in joints}
        out.joint_velocities = {name: velocities[da] for name, _, da in joints}
        by_qpos = self._qpos_joint
        for motor in self._motors:
            held = motor.name not in self._commanded and not motor.state.torque_mode
            if held and motor.qpos in by_qpos and math.isfinite(motor.state.target_position):
                out.holds[by_qpos[motor.qpos]] = float(motor.state.target_position)
        return out

    def set_state(self, state: MechanicalState, *, partial: bool = False) -> None:
        """Write qpos/qvel by name and recompute the derived quantities (``mj_forward``); the clock is kept.

        Raises:
            DualtwinError: A body or joint of ``state`` does not exist here (or, unless ``partial``, one of
                this twin's is missing from ``state``).
            SyncError: Non-finite values, or contacts overlapping deeper than ``max_penetration``; the twin is
                left in its previous state.
        """
        bodies, joints = self._state_entities()
        check_state_names(state, [b[0] for b in bodies], [j[0] for j in joints], self._origin, partial)
        m, d = self.model, self.data
        saved = (d.qpos.copy(), d.qvel.copy())
        for name, qa, da in bodies:
            body = state.bodies.get(name)
            if body is None:
                continue
            quat = canonical_quat(body.quaternion)
            d.qpos[qa:qa + 3] = body.position
            d.qpos[qa + 3:qa + 7] = quat
            d.qvel[da:da + 3] = body.linear_velocity
            d.qvel[da + 3:da + 6] = matrix_from_quat(quat).T @ np.asarray(body.angular_velocity, dtype=float)
        for name, qa, da in joints:
            if name in state.joint_positions:
                d.qpos[qa] = state.joint_positions[name]
                d.qvel[da] = state.joint_velocities[name]
        # Acceleration warm start and actuator forces belong to the old state.
        d.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(m, d)
        depth = -min((float(d.contact[i].dist) for i in range(d.ncon)), default=0.0)
        if depth > self.max_penetration:
            pairs = [i for i in range(d.ncon) if -float(d.contact[i].dist) == depth]
            g1, g2 = (int(d.contact[pairs[0]].geom[k]) for k in (0, 1))
            names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom {g}" for g in (g1, g2)]
            d.qpos[:], d.qvel[:] = saved
            mujoco.mj_forward(m, d)
            raise SyncError(f"{self._origin}: the state puts {names[0]!r} {depth * 1000:.1f} mm into {names[1]!r} "
                            f"(more than {self.max_penetration * 1000:g} mm)", "penetration")
        self._reseat_motors({qa: state.holds[name] for name, qa, _ in joints if name in state.holds})
        self._bad_state = self._bad_state_warnings()

    def _reseat_motors(self, holds: dict[int, float]) -> None:
        """After a state write: held motors hold the state's hold (else the new position); every motor
        restarts from the servo."""
        for motor in self._motors:
            if motor.name not in self._commanded:
                motor.state.reset(float(self.data.qpos[motor.qpos]))
                motor.state.target_position = holds.get(motor.qpos, motor.state.target_position)
            motor.state.current_velocity = 0.0
            if not motor.state.torque_mode:
                motor.saturated = 0.0
                self._set_servo(motor)

    # ---------------------------------------------------------------- knobs
    # The knob table (names shared with the Webots twin) is documented in dualtwin.align.knobs.
    def knobs(self) -> dict[str, Knob]:
        m = self.model
        nominal = self._nominal
        out: dict[str, Knob] = {}

        def add(name: str, value: float, lower: float, upper: float, unit: str, description: str) -> None:
            out[name] = Knob(name, float(value), float(lower), float(upper), unit, description)

        for j in range(m.njnt):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if not name or m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                continue
            dof = m.jnt_dofadr[j]
            damping = float(nominal["dof_damping"][dof])
            friction = float(nominal["dof_frictionloss"][dof])
            add(f"joint.{name}.damping", damping, 0.0, max(10 * damping, 1.0),
                "N*m*s/rad", "joint viscous damping (Webots dampingConstant)")
            add(f"joint.{name}.friction", friction, 0.0, max(10 * friction, 0.5),
                "N*m", "joint dry friction (MuJoCo frictionloss, Webots staticFriction)")
            limit_timeconst = float(nominal["jnt_solref"][j, 0])
            if m.jnt_limited[j] and limit_timeconst > 0:
                # ODE's joint stops are stiff (world ERP/CFM); MuJoCo's limits are soft by default.
                add(f"joint.{name}.limit_timeconst", limit_timeconst, 2 * m.opt.timestep,
                    max(10 * limit_timeconst, 4 * m.opt.timestep), "s",
                    "joint-limit softness: time constant of the limit's spring-damper (MuJoCo solreflimit[0])")
        for g in range(m.ngeom):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
            if name and m.geom_contype[g] | m.geom_conaffinity[g]:
                mu = float(nominal["geom_friction"][g, 0])
                add(f"geom.{name}.friction", mu, 0.0, 5.0 * max(mu, 0.1), "", "sliding friction coefficient")
                timeconst, dampratio = (float(v) for v in nominal["geom_solref"][g])
                if timeconst > 0:  # the standard (time constant, damping ratio) form of solref
                    # MuJoCo clamps time constants below two physics steps (refsafe).
                    add(f"geom.{name}.solref_timeconst", timeconst, 2 * m.opt.timestep,
                        max(10 * timeconst, 4 * m.opt.timestep), "s",
                        "contact softness: time constant of the contact spring-damper (MuJoCo solref[0])")
                    add(f"geom.{name}.restitution", dampratio_to_restitution(dampratio), 0.0, 0.95, "",
                        "contact restitution (MuJoCo: solref damping ratio below 1)")
        for b in range(1, m.nbody):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
            mass = float(nominal["body_mass"][b])
            if not name or mass <= 0:
                continue
            add(f"body.{name}.mass", mass, 0.1 * mass, 10 * mass, "kg", "body mass (inertia scaled with it)")
            add(f"body.{name}.inertia_scale", 1.0, 0.1, 10.0, "", "factor on the body's rotational inertia")
            geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == b]
            reach = max([float(m.geom_rbound[g]) for g in geoms] + [0.0])
            span = max(0.05, 0.25 * reach)
            for axis in "xyz":
                add(f"body.{name}.com_offset_{axis}", 0.0, -span, span, "m",
                    f"shift of the centre of mass along the body's {axis} axis")
        for mo in self._motors:
            max_torque, max_velocity = self._nominal_motor[mo.name]
            add(f"motor.{mo.name}.max_torque", max_torque, 0.0, 10 * max_torque, "N*m", "maximum motor torque")
            add(f"motor.{mo.name}.max_velocity", max_velocity, 0.1 * max_velocity, 10 * max_velocity, "rad/s",
                "maximum motor velocity")
            add(f"motor.{mo.name}.gain", 1.0, -2.0, 2.0, "", "command gain (sign included)")
        add("control.delay_periods", 0.0, 0.0, MAX_DELAY_PERIODS, "periods",
            "commands take effect this many control periods late (integer)")
        for s in range(m.nsensor):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SENSOR, s)
            if not name:
                continue
            noise = float(nominal["sensor_noise"][s])
            add(f"sensor.{name}.noise", noise, 0.0, max(10 * noise, 0.05), "",
                "standard deviation of Gaussian reading noise (Webots noise)")
            add(f"sensor.{name}.bias", 0.0, -0.1, 0.1, "", "constant offset added to readings")
            add(f"sensor.{name}.delay", 0.0, 0.0, MAX_DELAY_PERIODS, "periods",
                "readings are this many control periods old (integer)")
            add(f"sensor.{name}.quantization", 0.0, 0.0, 0.1, "",
                "readings are rounded to a multiple of this (Webots resolution; 0 = off)")
        return out

    def set_knobs(self, values: dict[str, float]) -> None:
        registry = self.knobs()
        unknown = sorted(set(values) - set(registry))
        if unknown:
            raise DualtwinError(f"{self._origin}: unknown knobs: {', '.join(unknown)}")
        m, nominal = self.model, self._nominal
        m.dof_damping[:] = nominal["dof_damping"]
        m.dof_frictionloss[:] = nominal["dof_frictionloss"]
        m.geom_friction[:] = nominal["geom_friction"]
        m.geom_solref[:] = nominal["geom_solref"]
        m.jnt_solref[:] = nominal["jnt_solref"]
        m.body_mass[:] = nominal["body_mass"]
        m.body_inertia[:] = nominal["body_inertia"]
        m.body_ipos[:] = nominal["body_ipos"]
        for mo in self._motors:
            mo.state.params.max_torque, mo.state.params.max_velocity = self._nominal_motor[mo.name]
            mo.state.gain = 1.0
        self._delay = 0
        self._noise = np.array(nominal["sensor_noise"], dtype=float)
        self._sensor_bias[:] = 0.0
        self._sensor_quant[:] = 0.0
        self._sensor_delay[:] = 0
        inertia_scale: dict[int, float] = {}
        changed_inertia = False
        for key, value in values.items():
            value = float(value)
            if key == "control.delay_periods":
                self._delay = int(round(value))
                continue
            # Names may contain dots or spaces ("pole sensor"): the kind is first, the property last.
            kind, rest = key.split(".", 1)
            name, prop = rest.rsplit(".", 1)
            if kind == "joint":
                j = self._id(mujoco.mjtObj.mjOBJ_JOINT, name, "joint")
                if prop == "limit_timeconst":
                    m.jnt_solref[j, 0] = value
                else:
                    (m.dof_damping if prop == "damping" else m.dof_frictionloss)[m.jnt_dofadr[j]] = value
            elif kind == "geom":
                g = self._id(mujoco.mjtObj.mjOBJ_GEOM, name, "geom")
                if prop == "friction":
                    m.geom_friction[g, 0] = value
                elif prop == "solref_timeconst":
                    m.geom_solref[g, 0] = value
                else:
                    m.geom_solref[g, 1] = restitution_to_dampratio(value, float(nominal["geom_solref"][g, 1]))
            elif kind == "body":
                b = self._id(mujoco.mjtObj.mjOBJ_BODY, name, "body")
                changed_inertia = True
                if prop == "mass":
                    m.body_mass[b] = value
                elif prop == "inertia_scale":
                    inertia_scale[b] = value
                else:
                    m.body_ipos[b, "xyz".index(prop[-1])] += value
            elif kind == "motor":
                mo = self._motor_by_name[name]
                if prop == "max_torque":
                    mo.state.params.max_torque = value
                elif prop == "max_velocity":
                    mo.state.params.max_velocity = value
                else:
                    mo.state.gain = value
            elif kind == "sensor":
                s = self._id(mujoco.mjtObj.mjOBJ_SENSOR, name, "sensor")
                if prop == "noise":
                    self._noise[s] = value
                elif prop == "bias":
                    self._sensor_bias[s] = value
                elif prop == "delay":
                    self._sensor_delay[s] = int(round(value))
                else:
                    self._sensor_quant[s] = value
        # Inertia follows the mass (same shape, denser material), times an optional extra factor.
        for b in range(m.nbody):
            if nominal["body_mass"][b] > 0:
                factor = m.body_mass[b] / nominal["body_mass"][b] * inertia_scale.get(b, 1.0)
                m.body_inertia[b] = nominal["body_inertia"][b] * factor
        if changed_inertia or self._inertia_changed:
            # Constraint regularisation and derived masses depend on the mass distribution; recompute them as
            # a compiled model with these values would (so a patched MJCF reproduces the knobs exactly).
            mujoco.mj_setConst(m, self._scratch)
            # The compiler's statistics (they scale solver tolerances), which mj_setConst leaves alone.
            scratch = self._scratch
            scratch.qpos[:] = m.qpos0
            mujoco.mj_forward(m, scratch)
            full = np.zeros((m.nv, m.nv))
            mujoco.mj_fullM(m, scratch, full)
            m.stat.meaninertia = float(np.trace(full)) / max(m.nv, 1)
            m.stat.meanmass = float(np.mean(m.body_mass[1:])) if m.nbody > 1 else 0.0
            self._inertia_changed = changed_inertia
        for mo in self._motors:
            mo.state.available_torque = mo.state.params.max_torque
        self._knob_values = dict(values)

    def render(self, camera: str, width: int, height: int) -> np.ndarray:
        cam = self._id(mujoco.mjtObj.mjOBJ_CAMERA, camera, "camera")
        if self._renderer is None or (self._renderer.width, self._renderer.height) != (width, height):
            if self._renderer is not None:
                self._renderer.close()
            self._renderer = mujoco.Renderer(self.model, height, width)
        self._renderer.update_scene(self.data, camera=cam)
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def from_binding(robot: RobotBinding, control_period: float) -> MuJoCoTwin:
    section = robot.spec.twins.get("mujoco")
    return MuJoCoTwin(robot.model_path("mujoco"), control_period, dict(section.aliases) if section else None)
