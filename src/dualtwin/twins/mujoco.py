"""The MuJoCo twin.

Motors mean what a Webots motor means (see :mod:`dualtwin.twins.base`). ODE's joint motor is a velocity
constraint that reaches the commanded velocity within one step unless that needs more than the maximum
torque. MuJoCo has no such constraint, so each motor is a ``general`` actuator switched, per step, from the
torque the step needs (:func:`~dualtwin.twins.motors.servo_steps`) between:

* a stiff velocity servo (torque ``kv (u - qdot)``) while the maximum torque reaches ``u``, and
* once it does not, saturated: explicitly the torque that takes the joint to ``u`` under its load, clamped
  to ``±max_torque``.

The servo is integrated implicitly (backward Euler, so any ``kv`` is stable), but not with MuJoCo's implicit
actuator damping: ``implicitfast`` adds ``dt·kv`` to the joint's inertia only *after* the constraint solver
ran, so contacts see a free-spinning joint. A wheel then "gives" under friction that the motor actually
resists, and skid-steer turning came out 2.5x too slow against ODE, whose motor row is solved together with
the contacts. Instead the servo torque is applied explicitly from the velocity at the start of the step and
``dt·kv`` is added to the joint's ``armature`` while the servo is active: for the joint alone that is the
same backward-Euler update, and the constraint solver sees the motor's stiffness. MuJoCo's own
``forcerange`` clamp is not used: it clamps the explicit torque, not the implicit one, and a clamped stiff
servo chatters. Webots motor fields are read from
``<custom><numeric name="webots_motor.NAME" data="maxVelocity Kp Ki Kd acceleration [minPosition
maxPosition]"/>``, and the maximum torque from the actuator's ``forcerange``.

A model with ``<custom><text name="webots_contact" data="approx1"/></custom>`` gets ODE's square friction
limit (Webots' ``dContactApprox1``) from a turned MuJoCo pyramid (:mod:`dualtwin.twins.ode_friction`); others
step with plain ``mj_step``. The converter does not write it: on the Pioneer it moved no result closer to the
Webots twin and costs 40-60 % more time per step (README, Pioneer section).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.geometry import canonical_quat, matrix_from_quat
from dualtwin.twins import motor_plugin, mujoco_rays, mujoco_state, sensor_tables
from dualtwin.twins.base import (
    MAX_SUBSTEPS,
    ControlMode,
    Knob,
    MechanicalState,
    NameKind,
    StateLayout,
    SyncError,
    Twin,
    check_state_names,
    control_substeps,
    unknown_name,
)
from dualtwin.twins.knob_table import BoundKnob
from dualtwin.twins.mass_constants import MassConstants
from dualtwin.twins.mjcf_files import compile_spec, load_spec
from dualtwin.twins.motors import MotorState, assign_groups, relay_command, servo_inertia, servo_steps
from dualtwin.twins.mujoco_knobs import (
    MAX_DELAY_PERIODS,
    MUJOCO_KNOBS,
    KnobPass,
    KnobTarget,
    follow_pairs,
    nominal_values,
)
from dualtwin.twins.mujoco_state import StatePlan, scale_contact_depths
from dualtwin.twins.ode_friction import FrictionBox, contact_semantics
from dualtwin.webots.lut import discretize

if TYPE_CHECKING:
    from dualtwin.robots.binding import RobotBinding

# Servo stiffness relative to the joint's own inertia: kv·dt = SERVO_STIFFNESS·I closes 99 % of the
# velocity error of a free joint in one step, close to ODE's motor constraint (a hard row at the world CFM).
# The solver sees it as armature, so it also sets how hard a wheel resists contact friction: at 10 (91 %)
# the Pioneer turned in place 18 % slower than in ODE, at 100 3 %.
SERVO_STIFFNESS = 100.0
#: set_state refuses states whose contacts overlap deeper than this (m): that is a geometry mismatch or a
#: bad state, not the millimetres of a resting soft contact.
MAX_PENETRATION = 0.02
_AUTORESET_OFF = int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
_NAME_KINDS = {"joint": mujoco.mjtObj.mjOBJ_JOINT, "body": mujoco.mjtObj.mjOBJ_BODY, "sensor": mujoco.mjtObj.mjOBJ_SENSOR}
# plugin_state slots a command writes (literals in command and _apply_command: they run per command and motor)
assert [motor_plugin.SLOT[k] for k in ("torque_mode", "target_position", "target_velocity", "torque")] == [0, 1, 2, 3]
assert motor_plugin.SLOT["saturated"] == 15


class _Motor:
    __slots__ = ("name", "index", "qpos", "dof", "kv", "state", "saturated", "stiffness", "residual", "reaction",
                 "plugin", "group")

    def __init__(self, name: str, index: int, qpos: int, dof: int, kv: float, state: MotorState,
                 plugin: int = -1) -> None:
        self.name = name
        self.index = index
        self.qpos = qpos
        self.dof = dof
        self.kv = kv
        self.state = state
        self.saturated = 0.0  # 0 = servo; ±1 = saturated (see motors.servo_steps)
        self.stiffness = 0.0  # the servo stiffness in the joint's armature (Python law, see servo_steps)
        self.residual = 0.0  # last step's load besides the smooth forces (motors.servo_steps)
        self.reaction = 0.0  # the constraint force in it (qfrc_constraint)
        self.plugin = plugin  # with the native law: the motor's first slot in plugin_state, else -1
        self.group: tuple[_Motor, ...] | None = None  # see motors.assign_groups


class MuJoCoTwin(Twin):
    """A MuJoCo model stepped in control periods with Webots motor semantics."""

    name = "mujoco"

    def __init__(self, model: Path | mujoco.MjSpec, control_period: float,
                 aliases: dict[str, str] | None = None, native_law: bool | None = None) -> None:
        """``native_law``: run Webots' motor law in the compiled plugin (None: when it can be loaded, see
        :mod:`dualtwin.twins.motor_plugin`); False runs the Python reference law per physics step."""
        origin = str(model) if isinstance(model, Path | str) else "<MjSpec>"
        self.spec = load_spec(Path(model)) if isinstance(model, Path | str) else model
        native = motor_plugin.native_spec(self.spec, native_law, origin)
        #: True when Webots' motor law runs inside mj_step (the plugin); the Python law otherwise.
        self.native_law = native is not None
        self.model: mujoco.MjModel = compile_spec(native or self.spec, origin)
        self.data = mujoco.MjData(self.model)
        self._plugin_slots: memoryview[float] = memoryview(self.data.plugin_state)  # floats: cheaper than NumPy
        self._origin = origin
        self._aliases = aliases or {}
        dt = self.model.opt.timestep
        self._substeps = control_substeps(control_period, dt, origin, "<option timestep>")
        self._nominal_substeps: int = self._substeps
        self._nominal_timestep: float = float(dt)
        self._control_period = control_period
        self._rng = np.random.default_rng(0)
        self._noise = np.array(self.model.sensor_noise, dtype=float)
        self._nominal: dict[str, np.ndarray] = nominal_values(self.model)
        # Rotor inertia per dof as the knobs set it; the servo adds its own implicit term on top (_set_servo).
        self._armature = self._nominal["dof_armature"].copy()
        self._knob_values: dict[str, float] = {}
        self._knob_pass = KnobPass()  # what the last set_knobs collected (see mujoco_knobs)
        self._knob_index: dict[str, BoundKnob[KnobTarget]] | None = None
        self._motors = self._build_motors()
        # (the converted robot's: another robot's motors hold their place, commanded by nothing, as in the Webots twin)
        self._motor_by_name = {m.name: m for m in self._motors if mujoco_state.robot_actuator(self.model, m.index)}
        assign_groups(self._motors)
        # command()'s lookup: motor names and the aliases that resolve to one (an alias wins, as in _id).
        self._command_index = {name: self._motor_by_name[self._aliases.get(name, name)]
                               for name in {*self._motor_by_name, *self._aliases}
                               if self._aliases.get(name, name) in self._motor_by_name}
        self._nominal_kv = {m.name: m.kv for m in self._motors}
        self._nominal_motor: dict[str, tuple[float, float]] = {m.name: (m.state.params.max_torque, m.state.params.max_velocity) for m in self._motors}
        self._nominal_kp: dict[str, float] = {m.name: m.state.params.kp for m in self._motors}
        # The inertia each servo's stiffness was sized for (see _build_motors): kv follows armature knobs.
        self._servo_inertia = {m.name: m.kv * self.model.opt.timestep / SERVO_STIFFNESS for m in self._motors}
        # Knob state outside the model arrays: the control delay queues commands until they are due, and
        # the sensor models (bias, resolution, delay) apply in sensor().
        self._delay = 0
        self._pending: list[tuple[int, _Motor, ControlMode, float]] = []
        self._sensor_bias = np.zeros(self.model.nsensor)
        self._sensor_quant = np.zeros(self.model.nsensor)
        self._sensor_delay = np.zeros(self.model.nsensor, dtype=int)
        self._period_start = 0.0  # time at the start of the last step() (see _check_stable)
        self._delayed_sensors = False  # any delay above (set_knobs keeps it; step() reads it every period)
        self._history: list[np.ndarray] = []
        self._inertia_changed = False
        self._scratch = mujoco.MjData(self.model)
        self._renderer: mujoco.Renderer | None = None
        # Motors commanded since the last reset; the others hold their position (see set_state).
        self._commanded: set[str] = set()
        # False after a step until refresh() brings poses and sensors up to the stepped state.
        self._poses_current = True
        self.max_penetration = MAX_PENETRATION
        #: set_state scales the written state's contact depths by this (see :meth:`set_state`); 1 = as written.
        self.reseat_depth_ratio = 1.0
        #: "approx1" when contacts follow Webots' friction pyramid (see the module docstring), else None.
        self.contact_semantics = contact_semantics(self.model, origin)
        self._friction_box = FrictionBox() if self.contact_semantics else None
        # One physics step; every stepping path below goes through it.
        self._mj_step: Callable[[mujoco.MjModel, mujoco.MjData], None] = (
            self._friction_box.step if self._friction_box else mujoco.mj_step)
        self._opt = self.model.opt  # a live view of the model's options (each model.opt costs a lookup)
        self._ids: dict[tuple[mujoco.mjtObj, str], int] = {}  # see _id
        self._sensor_adr: list[int] = self.model.sensor_adr.tolist()
        self._resolution = mujoco_state.sensor_resolutions(self.model)  # Webots' sensor resolution (the converted model's)
        self._tables = sensor_tables.read_tables(self.model)  # Webots' lookup tables (the converted model's)
        self._rays = mujoco_rays.read_rays(self.model)  # Webots' DistanceSensor rays (the converted model's)
        # bias, delay, noise, resolution, lookup tables, rays
        self._sensor_models = bool(self._noise.any() or self._resolution.any() or self._tables or self._rays)
        self._keyframe = mujoco_state.initial_keyframe(self.model)  # Webots' initial velocities (dualtwin.convert.initial_state)
        self.reset()

    def _id(self, kind: mujoco.mjtObj, name: str, label: str) -> int:
        # Names are looked up on every read (several per period): each found one is kept (names never change).
        known_id = self._ids.get((kind, name))
        if known_id is not None:
            return known_id
        resolved = self._aliases.get(name, name)
        if not isinstance(resolved, str):
            # mj_name2id(None) dereferences a null pointer: the process dies with SIGSEGV (a task's pole_joint: null)
            raise DualtwinError(f"{self._origin}: {label} name must be a string, got {resolved!r:.80}")
        index = mujoco.mj_name2id(self.model, kind, resolved)
        if index < 0:
            count = {mujoco.mjtObj.mjOBJ_JOINT: self.model.njnt, mujoco.mjtObj.mjOBJ_BODY: self.model.nbody,
                     mujoco.mjtObj.mjOBJ_ACTUATOR: self.model.nu, mujoco.mjtObj.mjOBJ_SENSOR: self.model.nsensor,
                     mujoco.mjtObj.mjOBJ_GEOM: self.model.ngeom, mujoco.mjtObj.mjOBJ_CAMERA: self.model.ncam}[kind]
            known = [mujoco.mj_id2name(self.model, kind, i) or "" for i in range(count)]
            raise unknown_name(label, resolved, [k for k in known if k], self._origin)
        self._ids[(kind, name)] = int(index)
        return int(index)

    def _build_motors(self) -> list[_Motor]:
        m = self.model
        motors = []
        # Webots clamps torque itself; MuJoCo's clamp would disable the implicit servo derivative.
        mujoco.mj_setConst(m, self.data)
        self._masses = MassConstants(m, self._armature)
        for i in range(m.nu):
            if m.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
                continue
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}"
            joint = int(m.actuator_trnid[i, 0])
            dof = int(m.jnt_dofadr[joint])
            params = motor_plugin.motor_params(m, name, i)
            m.actuator_forcelimited[i] = 0
            m.actuator_ctrllimited[i] = 0
            inertia = float(m.dof_M0[dof])  # the joint's inertia, armature included
            kv = SERVO_STIFFNESS * inertia / m.opt.timestep
            plugin = motor_plugin.state_address(m, i)
            motors.append(_Motor(name, i, int(m.jnt_qposadr[joint]), dof, kv, MotorState(params), plugin))
        return motors

    # ---------------------------------------------------------------- Twin API
    @property
    def control_period(self) -> float:
        return self._control_period

    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(self, seed: int | None = None) -> None:
        mujoco_state.reset_data(self.model, self.data, self._keyframe)
        mujoco.mj_forward(self.model, self.data)
        self._rng = np.random.default_rng(seed)
        self._pending.clear()
        self._history.clear()
        self._commanded.clear()
        for motor in self._motors:
            motor.state.reset(float(self.data.qpos[motor.qpos]))
            motor.saturated = motor.residual = motor.reaction = 0.0
            self._set_servo(motor)
            if motor.plugin >= 0:
                self._write_plugin(motor, law=True)
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

    def _free_joint(self, body: str) -> int:
        m = self.model
        joint = m.body_jntadr[self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")]
        if joint < 0 or m.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE:
            raise DualtwinError(f"{self._origin}: body {body!r} has no free joint to teleport")
        return int(joint)

    def set_body_position(self, body: str, axis: int, value: float) -> None:
        self.data.qpos[self.model.jnt_qposadr[self._free_joint(body)] + axis] = value
        mujoco.mj_forward(self.model, self.data)

    def command(self, actuator: str, mode: ControlMode, value: float) -> None:
        motor = self._command_index.get(actuator)
        if motor is None:
            raise unknown_name("motor", actuator, list(self._motor_by_name), self._origin)
        self._commanded.add(motor.name)
        if self._delay:
            # control.delay_periods: the command reaches the motor k control periods late.
            self._pending.append((self._periods() + self._delay, motor, mode, value))
            return
        adr = motor.plugin
        if adr >= 0 and mode == "position" and motor.group is None:
            # Fast path of the commonest command, a native-law motor's position (each motor and period on the
            # arm, where six were ~7 % of a period): _apply_command and MotorState.set_position inlined, the same
            # operations in the same order, ~30 % cheaper. Keep the three in step (test_command_fast_path.py).
            st = motor.state
            p = st.params
            target = value * st.gain
            low, high = p.min_position, p.max_position
            if low != high and -math.inf < target < math.inf:
                target = low if low > target else target
                target = high if high < target else target
            st.target_position = target
            st.target_velocity = velocity = p.max_velocity
            st.torque_mode = False
            ps = self._plugin_slots
            ps[adr + 1] = target
            ps[adr + 2] = velocity
            ps[adr] = motor.saturated = ps[adr + 15] = 0.0
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
            self.refresh()
            self._history.append(mujoco_rays.sensor_snapshot(self.model, self.data, self._rays))
            del self._history[:-MAX_DELAY_PERIODS - 1]

    def _apply_command(self, motor: _Motor, mode: ControlMode, value: float) -> None:
        # command() inlines the position branch for native-law motors: a change here goes there too.
        st = motor.state
        if motor.group is not None:  # Webots' multipliers, and its relay to coupled motors
            for mo in relay_command(motor, mode, value):
                self._push_command(mo)
            return
        if mode == "position":
            st.set_position(value)
        elif mode == "velocity":
            st.set_velocity(value)
        else:
            st.set_torque(value)
        self._push_command(motor)

    def _push_command(self, motor: _Motor) -> None:  # a command's targets (torque) to the plugin or the servo
        st = motor.state
        adr = motor.plugin
        if adr >= 0:
            # The native law: only what a command changes goes to plugin_state, not the model: the torque, or the
            # targets and leaving saturation (slots 0-3 and 15, see motor_plugin).
            ps = self._plugin_slots
            if st.torque_mode:
                ps[adr + 3] = st.torque
                ps[adr] = 1.0
            else:
                ps[adr + 1] = st.target_position
                ps[adr + 2] = st.target_velocity
                ps[adr] = motor.saturated = ps[adr + 15] = 0.0
        elif st.torque_mode:
            self._set_torque(motor, st.torque)
        else:
            motor.saturated = 0.0
            self._set_servo(motor)

    def _write_plugin(self, motor: _Motor, law: bool = False) -> None:
        """The motor's targets, limits, gains and servo stiffness into its plugin_state slots, and with
        ``law`` its law state (integral, previous error, last u, saturation, residual load) too."""
        inertia = servo_inertia(motor.kv, self.model.opt.timestep, SERVO_STIFFNESS)
        values = motor_plugin.slot_values(motor.state, motor.kv, float(self._armature[motor.dof]), inertia,
                                          (motor.saturated, motor.residual, motor.reaction) if law else None)
        # The plugin adds the rotor inertia with the servo's (see native/webots_motor.c): not the model too.
        self._masses.write(self.model, motor.dof, 0.0)
        state = self.data.plugin_state
        for slot, value in values:
            state[motor.plugin + slot] = value

    def _set_servo(self, motor: _Motor) -> None:
        """Servo mode: ctrl is the explicit torque ``kv (u - qdot)``, and ``dt·kv`` of armature makes it implicit
        (the native law adds it inside the step: nothing to do)."""
        self._set_torque(motor, None)

    def _set_stiffness(self, motor: _Motor, stiffness: float) -> None:  # kv or 0, saturated (servo_steps)
        motor.stiffness = stiffness
        self._masses.write(self.model, motor.dof, self._armature[motor.dof] + stiffness * self.model.opt.timestep)

    def _set_torque(self, motor: _Motor, torque: float | None) -> None:  # None: servo mode (see _set_servo)
        m = self.model
        if motor.plugin >= 0:
            return
        m.actuator_gainprm[motor.index, 0] = 1.0
        m.actuator_biastype[motor.index] = mujoco.mjtBias.mjBIAS_NONE
        m.actuator_biasprm[motor.index, :3] = 0.0
        self._set_stiffness(motor, motor.kv if torque is None else 0.0)
        if torque is not None:
            self.data.ctrl[motor.index] = torque

    def start_period(self) -> None:
        """step() but its physics and stability check (:meth:`finish_period`), for a caller that batches."""
        # step() inlines this for the native law with plain contacts: a change here goes there too.
        self._period_start = self.data.time
        if self._pending or self._delayed_sensors:
            self._before_step()
        # mj_step computes poses and sensors before it integrates: afterwards they describe the state one
        # physics step ago (see refresh).
        self._poses_current = False

    def finish_period(self, bad_state: bool) -> None:
        self._check_stable(bad_state)

    def step(self) -> None:
        m, d = self.model, self.data
        if self.native_law and self._friction_box is None:
            # The native law and plain contacts: one mj_step call per period (nstep positional: cheaper than the
            # keyword), and start_period and _check_stable's on-time test inlined (keep the three in step). The
            # clock and options are read live as there: vector envs write the clock, and options can change.
            start = self._period_start = d.time
            if self._pending or self._delayed_sensors:
                self._before_step()
            self._poses_current = False
            mujoco.mj_step(m, d, self._substeps)
            opt = self._opt
            if not (d.time > start + (self._substeps - 0.5) * opt.timestep and not opt.disableflags & _AUTORESET_OFF):
                self._check_stable()  # not on time (or no autoreset): the full check
            return
        self.start_period()
        # The Python law: every motor, torque-controlled ones too (the law follows their joint's load).
        if self.native_law or not self._motors:
            if self._friction_box is None:
                mujoco.mj_step(m, d, self._substeps)  # no motor (the native law has its own branch above)
            else:
                for _ in range(self._substeps):
                    self._mj_step(m, d)
        else:
            self._servo_steps(self._motors, self._substeps)
        self._check_stable()

    def _servo_steps(self, servos: list[_Motor], steps: int) -> None:
        """Physics steps with the Webots PID and the bounded servo for every servo motor."""
        m, d = self.model, self.data
        step1 = self._friction_box.step1 if self._friction_box else mujoco.mj_step1
        forces = (memoryview(d.qfrc_passive), memoryview(d.qfrc_bias), memoryview(d.qfrc_applied),
                  memoryview(d.qfrc_constraint))
        servo_steps(servos, steps, m.opt.timestep, memoryview(d.qpos), memoryview(d.qvel), memoryview(d.ctrl),
                    memoryview(d.actuator_force), forces, (lambda: step1(m, d), lambda: mujoco.mj_step2(m, d)),
                    self._set_stiffness, self._constrained_dofs, SERVO_STIFFNESS, memoryview(m.dof_damping))

    def _constrained_dofs(self) -> frozenset[int]:
        """The dofs a constraint row of this step acts on (as native/webots_motor.c's constrained())."""
        m, d = self.model, self.data
        rows = d.nefc
        if not rows:
            return frozenset()
        if mujoco.mj_isSparse(m):
            colind, rowadr, rownnz = d.efc_J_colind, d.efc_J_rowadr, d.efc_J_rownnz
            return frozenset(int(c) for r in range(rows) for c in colind[rowadr[r]:rowadr[r] + rownnz[r]])
        jac = d.efc_J[:rows * m.nv].reshape(rows, m.nv)
        return frozenset(np.flatnonzero((jac != 0).any(axis=0)).tolist())

    def _bad_state_warnings(self) -> int:
        """MuJoCo resets mjData itself after bad qpos/qvel/qacc; its warning counters are the trace left."""
        counters = getattr(self, "_warning_counters", None)
        if counters is None:  # live views of the three counters, looked up once (checked every period)
            w = self.data.warning
            counters = self._warning_counters = [w[int(k)] for k in (
                mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)]
        return counters[0].number + counters[1].number + counters[2].number

    def _check_stable(self, bad_state: bool | None = None) -> None:
        d = self.data
        opt = self._opt
        # step() inlines this on-time test for the native law with plain contacts: change both together.
        if d.time > self._period_start + (self._substeps - 0.5) * opt.timestep and not (
                opt.disableflags & _AUTORESET_OFF):
            # MuJoCo resets mjData (time 0) when a step meets a bad qpos, qvel or qacc, and a step that met
            # none leaves finite values: a period that ended on time was stable (the cheap test, every period).
            return
        warnings = self._bad_state_warnings()
        if bad_state is None:
            bad_state = warnings != self._bad_state
        # One finiteness test for both vectors (a NaN or infinity anywhere makes the sum of squares non-finite).
        if bad_state or not math.isfinite(np.dot(d.qpos, d.qpos) + np.dot(d.qvel, d.qvel)):
            self._bad_state = warnings
            raise SimulationUnstable(f"MuJoCo twin became numerically unstable (MuJoCo warning: "
                                     f"bad qpos, qvel or qacc) within the period ending near t = {d.time:.3f} s")

    def check_name(self, kind: NameKind, name: str) -> None:
        if kind == "motor" and name not in self._command_index:
            raise unknown_name("motor", self._aliases.get(name, name), list(self._motor_by_name), self._origin)
        if kind == "free body":
            self._free_joint(name)
        elif kind != "motor":
            self._id(_NAME_KINDS[kind], name, kind)

    def joint_position(self, joint: str) -> float:
        j = self._id(mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
        return float(self.data.qpos[self.model.jnt_qposadr[j]])

    def joint_velocity(self, joint: str) -> float:
        j = self._id(mujoco.mjtObj.mjOBJ_JOINT, joint, "joint")
        return float(self.data.qvel[self.model.jnt_dofadr[j]])

    def refresh(self) -> None:
        """Poses, com-frame velocities and position/velocity sensors of the current qpos/qvel.

        ``mj_step`` evaluates them at the start of its last physics step and then integrates, so after a
        control period they lag qpos by one physics step, while Webots samples sensors and supervisor poses
        after its physics step: an arm's flange moving at 2.6 m/s was read 5 mm behind its joint angles.
        Recomputed once, lazily, on the first read after a step (stepping alone pays nothing); acceleration-
        stage sensors (accelerometer, touch, force) keep the last step's values. Code that reads ``data``
        directly (rendering from outside the twin) calls this first.
        """
        if self._poses_current:
            return
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        if m.nsensor:
            mujoco.mj_sensorPos(m, d)
            mujoco.mj_sensorVel(m, d)
        self._poses_current = True

    def body_position(self, body: str) -> np.ndarray:
        self.refresh()
        return self.data.xpos[self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")].copy()

    def body_orientation(self, body: str) -> np.ndarray:
        self.refresh()
        return self.data.xmat[self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")].reshape(3, 3).copy()

    def body_velocity(self, body: str) -> np.ndarray:
        self.refresh()
        b = self._id(mujoco.mjtObj.mjOBJ_BODY, body, "body")
        out = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_XBODY, b, out, 0)
        return np.concatenate([out[3:], out[:3]])

    @property
    def plain_sensor_reads(self) -> bool:
        """True when :meth:`sensor` returns MuJoCo's reading as it is (+ 0.0): no noise, bias, resolution, lookup
        table or delay applies (a batch may then read every twin's sensors at once, `dualtwin.twins.mujoco_batch`)."""
        return not self._sensor_models

    def sensor(self, name: str) -> float:
        s = self._id(mujoco.mjtObj.mjOBJ_SENSOR, name, "sensor")
        adr = self._sensor_adr[s]
        if not self._sensor_models:  # the reading as it is (+ 0.0 as a zero bias adds: -0.0 reads 0.0)
            self.refresh()
            return float(self.data.sensordata[adr]) + 0.0
        delay = int(self._sensor_delay[s])
        if delay and self._history:
            # history[-k] is the reading k periods ago; before that much time has passed, the first one.
            value = float(self._history[max(0, len(self._history) - delay)][adr])
        else:
            self.refresh()
            rays = self._rays.get(s)  # Webots' rays where the model has them, else MuJoCo's reading
            value = float(self.data.sensordata[adr]) if rays is None else rays.distance(self.model, self.data)
        if (table := self._tables.get(s)) is not None:  # Webots' lookupTable of the physical value, then the rest
            value = sensor_tables.table_value(*table, value, self._rng)
        value += float(self._sensor_bias[s])
        if self._noise[s] > 0:
            value += float(self._rng.normal(0.0, self._noise[s]))
        value = discretize(value, float(self._resolution[s]))  # Webots' resolution (0: none), after its noise
        # The quantization knob stands for a `resolution` the model does not carry, so it follows Webots' rule too:
        # int(v/r + 0.5) truncates toward zero, and a negative reading is not rounded to the nearest multiple
        # (-0.7 steps read 0, -1.5 steps -1).
        return discretize(value, float(self._sensor_quant[s]))

    # ---------------------------------------------------------------- state transfer
    def _state_plan(self) -> StatePlan:
        # The compiled model never changes its joints: resolve them once (the state is read every period).
        plan: StatePlan | None = getattr(self, "_plan", None)
        if plan is None:
            plan = self._plan = StatePlan(self.model, {v: k for k, v in self._aliases.items()})
        return plan

    def _held(self, plan: StatePlan) -> list[tuple[str, float]]:
        """(joint, hold target) of the motors that have not been commanded since reset (the state's holds)."""
        out = []
        for motor in self._motors:
            if motor.name not in self._commanded and not motor.state.torque_mode and motor.qpos in plan.by_qpos:
                target = motor.state.target_position
                if math.isfinite(target):
                    out.append((plan.by_qpos[motor.qpos], float(target)))
        return out

    def _read_state(self) -> tuple[StateLayout, list[float]]:
        """qpos/qvel by name: a free joint's qpos is its body frame's pose, its qvel the frame origin's world
        linear velocity and the body-frame angular velocity (rotated to world here); a ball joint's quaternion
        becomes its rotation vector and its qvel (child-frame angular velocity) is kept as it is."""
        plan = self._state_plan()
        held = self._held(plan)
        layout = plan.layout(tuple(name for name, _ in held))
        return layout, plan.read(self.data.qpos.tolist(), self.data.qvel.tolist(), held)

    def state_vector(self) -> tuple[StateLayout, np.ndarray]:
        layout, values = self._read_state()
        return layout, np.array(values)

    def get_state(self) -> MechanicalState:
        """See :meth:`_read_state` for how qpos/qvel map to the state."""
        layout, values = self._read_state()
        return layout.state(values, float(self.data.time), self.name)

    def set_state(self, state: MechanicalState, *, partial: bool = False) -> None:
        """Write qpos/qvel by name and recompute the derived quantities (``mj_forward``); the clock is kept.

        Raises:
            DualtwinError: A body or joint of ``state`` does not exist here (or, unless ``partial``, one of
                this twin's is missing from ``state``).
            SyncError: Non-finite values, or contacts overlapping deeper than ``max_penetration``; the twin is
                left in its previous state.
        """
        plan = self._state_plan()
        check_state_names(state, plan.body_names, plan.joint_names, self._origin, partial)
        m, d = self.model, self.data
        saved = (d.qpos.copy(), d.qvel.copy())
        for name, (qa, da) in zip(plan.body_names, plan.bodies, strict=True):
            body = state.bodies.get(name)
            if body is None:
                continue
            quat = canonical_quat(body.quaternion)
            d.qpos[qa:qa + 3] = body.position
            d.qpos[qa + 3:qa + 7] = quat
            d.qvel[da:da + 3] = body.linear_velocity
            d.qvel[da + 3:da + 6] = matrix_from_quat(quat).T @ np.asarray(body.angular_velocity, dtype=float)
        for name, qa, da in zip(plan.joint_names, plan.scalar_qpos, plan.scalar_dof, strict=False):
            if name in state.joint_positions:
                d.qpos[qa] = state.joint_positions[name]
                d.qvel[da] = state.joint_velocities[name]
        for k, (qa, da) in enumerate(zip(plan.ball_qpos, plan.ball_dof, strict=True)):
            names = plan.joint_names[plan.scalar + 3 * k:plan.scalar + 3 * k + 3]
            if names[0] in state.joint_positions:
                rotvec = np.array([state.joint_positions[c] for c in names], dtype=float)
                angle = float(np.linalg.norm(rotvec))
                quat = np.array([1.0, 0.0, 0.0, 0.0])
                if angle > 0:
                    mujoco.mju_axisAngle2Quat(quat, rotvec / angle, angle)
                d.qpos[qa:qa + 4] = quat
                d.qvel[da:da + 3] = [state.joint_velocities[c] for c in names]
        # Acceleration warm start and actuator forces belong to the old state. (Keeping the warm start
        # instead changes nothing measurable: the Newton solver converges from either start.)
        d.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(m, d)
        if self.reseat_depth_ratio != 1.0:
            scale_contact_depths(m, d, self.reseat_depth_ratio)
        depth = -min((float(d.contact[i].dist) for i in range(d.ncon)), default=0.0)
        if depth > self.max_penetration:
            pairs = [i for i in range(d.ncon) if -float(d.contact[i].dist) == depth]
            g1, g2 = (int(d.contact[pairs[0]].geom[k]) for k in (0, 1))
            names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom {g}" for g in (g1, g2)]
            d.qpos[:], d.qvel[:] = saved
            mujoco.mj_forward(m, d)
            raise SyncError(f"{self._origin}: the state puts {names[0]!r} {depth * 1000:.1f} mm into {names[1]!r} "
                            f"(more than {self.max_penetration * 1000:g} mm)", "penetration")
        self._reseat_motors({qa: state.holds[name] for qa, name in plan.by_qpos.items() if name in state.holds})
        self._bad_state = self._bad_state_warnings()

    def contact_depth(self) -> float:
        """Mean depth (m, positive) of the contacts that overlap now; 0 without any."""
        d = self.data
        depths = [-float(d.contact[i].dist) for i in range(d.ncon) if d.contact[i].dist < 0]
        return float(np.mean(depths)) if depths else 0.0

    def _reseat_motors(self, holds: dict[int, float]) -> None:
        """After a state write: held motors hold the state's hold (else the new position); every motor
        restarts from the servo."""
        for motor in self._motors:
            if motor.name not in self._commanded:
                motor.state.reset(float(self.data.qpos[motor.qpos]))
                motor.state.target_position = holds.get(motor.qpos, motor.state.target_position)
            motor.state.current_velocity = 0.0
            motor.residual = motor.reaction = 0.0
            if not motor.state.torque_mode:
                motor.saturated = 0.0
                self._set_servo(motor)
            if motor.plugin >= 0:
                self._write_plugin(motor, law=True)

    # ---------------------------------------------------------------- knobs
    # One entry per knob kind in twins.mujoco_knobs.MUJOCO_KNOBS; knobs() and set_knobs() both come from it.
    def knobs(self) -> dict[str, Knob]:
        return {name: bound.knob for name, bound in MUJOCO_KNOBS.build(self).items()}

    def set_knobs(self, values: dict[str, float]) -> None:
        # Names and handles are fixed by the model's structure: look them up once (bounds are not needed here).
        if self._knob_index is None:
            self._knob_index = MUJOCO_KNOBS.build(self)
        registry = self._knob_index
        unknown = sorted(set(values) - set(registry))
        if unknown:
            raise DualtwinError(f"{self._origin}: unknown knobs: {', '.join(unknown)}")
        m, nominal = self.model, self._nominal
        for field in ("dof_damping", "dof_frictionloss", "geom_friction", "geom_solref", "geom_size", "geom_rbound",
                      "geom_aabb", "jnt_solref", "geom_solimp", "jnt_solimp", "body_mass", "body_inertia", "body_ipos",
                      "pair_friction", "pair_solref", "pair_solimp"):
            getattr(m, field)[:] = nominal[field]
        m.opt.impratio = float(nominal["impratio"])
        self._armature[:] = nominal["dof_armature"]
        for mo in self._motors:
            mo.state.params.max_torque, mo.state.params.max_velocity = self._nominal_motor[mo.name]
            mo.state.params.kp = self._nominal_kp[mo.name]
            mo.state.gain = 1.0
        self._delay = 0
        self._set_substeps(self._nominal_substeps)
        self._noise = np.array(nominal["sensor_noise"], dtype=float)
        self._sensor_bias[:] = 0.0
        self._sensor_quant[:] = 0.0
        self._sensor_delay[:] = 0
        # Then each value given, through its table entry (mass-distribution entries mark the pass).
        self._knob_pass = knob_pass = KnobPass()
        for key, value in values.items():
            bound = registry[key]
            bound.kind.apply(self, bound.handle, float(value))
        follow_pairs(m, nominal)
        inertia_scale, changed_inertia = knob_pass.inertia_scale, knob_pass.changed_inertia
        # Inertia follows the mass (same shape, denser material), times an optional extra factor.
        for b in range(m.nbody):
            if nominal["body_mass"][b] > 0:
                factor = m.body_mass[b] / nominal["body_mass"][b] * inertia_scale.get(b, 1.0)
                m.body_inertia[b] = nominal["body_inertia"][b] * factor
        if changed_inertia or self._inertia_changed:
            # Recompute what a compiled model with these masses would derive (see mass_constants).
            self._masses.recompute(m, self._scratch)
            self._inertia_changed = changed_inertia
        # Rotor inertia everywhere, then each servo's stiffness (sized for the joint's inertia, armature
        # included) and its implicit term on top while it is active.
        self._masses.restore(m)
        self._update_servos()
        for mo in self._motors:
            mo.state.available_torque = mo.state.params.max_torque
            if mo.plugin >= 0:
                self._write_plugin(mo)
        self._delayed_sensors = bool(self._sensor_delay.any())
        self._sensor_models = bool(self._delayed_sensors or self._noise.any() or self._sensor_bias.any()
                                   or self._sensor_quant.any() or self._resolution.any() or self._tables or self._rays)
        self._knob_values = dict(values)

    def _set_substeps(self, substeps: int) -> None:
        """Integrate each control period in ``substeps`` steps; servo stiffness follows the step (kv ∝ 1/dt)."""
        if not 1 <= substeps <= MAX_SUBSTEPS:
            raise DualtwinError(f"{self._origin}: physics.substeps must be from 1 to {MAX_SUBSTEPS}, got {substeps}")
        # The nominal step exactly as compiled (the division may differ in the last bit).
        nominal = substeps == self._nominal_substeps
        self.model.opt.timestep = self._nominal_timestep if nominal else self._control_period / substeps
        self._substeps = substeps
        self._update_servos()

    def _update_servos(self) -> None:
        """Servo stiffness kv for the current step and armature (kv ∝ inertia / dt), applied to active servos."""
        ratio = self._substeps / self._nominal_substeps
        nominal_armature = self._nominal["dof_armature"]
        for mo in self._motors:
            inertia = self._servo_inertia[mo.name]
            added = float(self._armature[mo.dof] - nominal_armature[mo.dof])
            # The factor first: at nominal armature it is exactly 1, so kv is exactly the nominal kv.
            mo.kv = self._nominal_kv[mo.name] * ratio * ((inertia + added) / inertia)
            if not mo.state.torque_mode:
                self._set_servo(mo)
            if mo.plugin >= 0:
                self._write_plugin(mo)

    def render(self, camera: str, width: int, height: int) -> np.ndarray:
        cam = self._id(mujoco.mjtObj.mjOBJ_CAMERA, camera, "camera")
        if self._renderer is None or (self._renderer.width, self._renderer.height) != (width, height):
            if self._renderer is not None:
                self._renderer.close()
            self._renderer = mujoco.Renderer(self.model, height, width)
        self.refresh()
        self._renderer.update_scene(self.data, camera=cam)
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def from_binding(robot: RobotBinding, control_period: float) -> MuJoCoTwin:
    section = robot.spec.twins.get("mujoco")
    return MuJoCoTwin(robot.model_path("mujoco"), control_period, dict(section.aliases) if section else None)
