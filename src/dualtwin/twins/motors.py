"""Webots motor semantics, shared by every twin that has to emulate them (spec §5 of docs/reference/webots-on-ode.md).

Webots turns every controller command into a target velocity ``u`` for the ODE joint motor once per physics
step: velocity control uses the target velocity, position control runs Webots' PID on the position error
and clamps it to the target velocity, and an acceleration limit slews the result.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from dualtwin.webots.motor_api import coupled_groups
from dualtwin.webots.motor_law import motor_velocity


@dataclass(slots=True)
class MotorParams:
    """A Webots RotationalMotor/LinearMotor's fields."""

    max_velocity: float = 10.0
    max_torque: float = 10.0
    kp: float = 10.0
    ki: float = 0.0
    kd: float = 0.0
    acceleration: float = -1.0
    #: Webots' minPosition/maxPosition: position targets are clamped into them when they differ.
    min_position: float = 0.0
    max_position: float = 0.0
    #: Webots' multiplier: every setPosition/setVelocity/setTorque is scaled by it (webots-devices §9).
    multiplier: float = 1.0


@dataclass(slots=True)
class MotorState:
    """The controller-side state of one motor, as Webots keeps it (WbMotor)."""

    params: MotorParams
    target_position: float = 0.0
    target_velocity: float = 0.0
    torque: float = 0.0
    available_torque: float = 0.0
    torque_mode: bool = False
    integral: float = 0.0
    previous_error: float = 0.0
    current_velocity: float = 0.0
    gain: float = 1.0
    extra: dict[str, float] = field(default_factory=dict)

    def reset(self, position: float) -> None:
        """Webots' initial state: hold the current position at up to max velocity (spec §5.1)."""
        self.target_position = position
        self.target_velocity = self.params.max_velocity
        self.available_torque = self.params.max_torque
        self.torque = 0.0
        self.torque_mode = False
        self.integral = 0.0
        self.previous_error = 0.0
        self.current_velocity = 0.0

    def set_velocity(self, velocity: float) -> None:
        """Velocity control: ``setPosition(inf)`` + ``setVelocity(v)``, clamped to max velocity (then, with a
        multiplier, times it and clamped again, as the Webots twin's command and Webots' motor do)."""
        v = velocity * self.gain
        limit = self.params.max_velocity
        if self.params.multiplier != 1.0:
            self.relay("velocity", max(-limit, min(limit, v)), limit)
            return
        # max(-limit, min(limit, v)) without the calls (a command per motor and period): the comparisons pick
        # exactly what min and max pick, NaN and signed zeros included (min keeps its first argument unless the
        # second is smaller, max unless it is larger).
        v = v if v < limit else limit
        self.target_position = math.inf
        self.target_velocity = v if v > -limit else -limit
        self.torque_mode = False

    def set_position(self, position: float) -> None:
        # MuJoCoTwin.command inlines this for native-law motors (twins/mujoco.py): a change here goes there too.
        p = self.params
        if p.multiplier != 1.0:
            self.relay("position", position * self.gain, p.max_velocity)
            return
        target = position * self.gain
        low, high = p.min_position, p.max_position
        # min(max(target, low), high) for finite targets, without the calls (a command per motor and period).
        if low != high and -math.inf < target < math.inf:
            target = low if low > target else target
            target = high if high < target else target
        self.target_position = target
        self.target_velocity = p.max_velocity
        self.torque_mode = False

    def set_torque(self, torque: float) -> None:
        available, most = self.available_torque, self.params.max_torque
        if self.params.multiplier != 1.0:
            self.relay("torque", max(-most, min(most, torque * self.gain)), 0.0)
            return
        limit = most if most < available else available  # min(available, most), as in set_velocity
        t = torque * self.gain
        t = t if t < limit else limit
        self.torque = t if t > -limit else -limit  # max(-limit, min(limit, t))
        self.torque_mode = True

    def relay(self, mode: str, value: float, max_velocity: float) -> None:
        """A command as Webots' coupled motors relay it (webots-devices §9), in the Webots twin's order: ``value``
        is what the commanded motor was given (its gain applied; a velocity clamped to its max velocity, a
        torque to its max torque), ``max_velocity`` its max velocity (the target velocity a position command
        sets first). This motor applies its own multiplier and limits."""
        p = self.params
        m = p.multiplier
        if mode == "torque":
            limit = min(self.available_torque, p.max_torque)
            self.torque = max(-limit, min(limit, value * m))
            self.torque_mode = True
            return
        if mode == "velocity":
            self.target_position = math.copysign(math.inf, m)  # setPosition(inf), multiplied
            velocity = value * m
        else:
            velocity = max_velocity * m  # setVelocity(max velocity), multiplied
            target = value * m
            if p.min_position != p.max_position and math.isfinite(target):
                target = min(max(target, p.min_position), p.max_position)
            self.target_position = target
        self.target_velocity = math.copysign(p.max_velocity, velocity) if abs(velocity) > p.max_velocity else velocity
        self.torque_mode = False

    @property
    def needs_feedback(self) -> bool:
        """Position control and acceleration limits change ``u`` every physics step."""
        return not math.isinf(self.target_position) or self.params.acceleration > 0 or self.available_torque == 0.0

    def velocity_command(self, position: float, dt: float) -> float:
        """The velocity ``u`` the joint motor tracks this physics step (WbMotor.computeCurrentDynamicVelocity)."""
        p = self.params
        u, self.integral, self.previous_error = motor_velocity(
            target_position=self.target_position, target_velocity=self.target_velocity,
            available=self.available_torque, position=position, integral=self.integral,
            previous_error=self.previous_error, current_velocity=self.current_velocity, kp=p.kp, ki=p.ki, kd=p.kd,
            acceleration=p.acceleration, dt=dt)
        self.current_velocity = u
        return u


class ServoMotor(Protocol):
    """What :func:`servo_steps` needs of a twin's motor: its state, where its joint is, and its servo."""

    state: MotorState
    index: int  # actuator (ctrl) index
    qpos: int
    dof: int
    kv: float  # servo stiffness: torque = kv (w - qdot)
    saturated: float  # 0 = servo; ±1 = saturated: u lies beyond what ±available torque reaches
    stiffness: float  # the servo stiffness its joint's inertia holds now (dt x it, see servo_steps)
    residual: float  # last step's force on the joint besides the motor and the smooth forces (see servo_steps)
    reaction: float  # the constraint force in it (qfrc_constraint)


def servo_steps(servos: Sequence[ServoMotor], steps: int, dt: float, qpos: memoryview[float],
                qvel: memoryview[float], ctrl: memoryview[float], force: memoryview[float],
                forces: tuple[memoryview[Any], memoryview[Any], memoryview[Any], memoryview[Any]],
                physics_step: tuple[Callable[[], None], Callable[[], None]], servo: Callable[[Any, float], None],
                constrained: Callable[[], Container[int]], stiffness: float, damping: memoryview[float]) -> None:
    """``steps`` physics steps of Webots' motor law (:func:`~dualtwin.webots.motor_law.motor_velocity`) for
    every motor (``servos``: those in torque control apply their torque), each bounded like ODE's motor row.

    ODE enforces Webots' ``u`` with a bounded velocity row (webots-on-ode §5: ``dParamVel = u``, ``dParamFMax``
    = the available torque ``A``, solved with the other constraints): the joint reaches ``u`` when ``A``
    allows, else the motor applies exactly ``A`` and the joint stays short of ``u``; the motor never carries it
    past ``u``. MuJoCo has no such row. Here a motor is, per step, either a stiff velocity servo towards ``u``
    (torque ``kv (u - qdot')`` at the step's end velocity, made implicit by ``dt·kv`` of inertia that the
    constraint solver sees, like ODE's row) or, saturated, an explicit torque within ``±A`` without that
    inertia; ``servo(motor, k)`` puts ``dt·k`` of inertia on the joint (``k`` = ``kv`` or 0).

    ``physics_step`` is the step in two halves (``mj_step1``, ``mj_step2``); between them ``forces``
    (qfrc_passive, qfrc_bias, qfrc_applied) hold this step's smooth force ``S`` on each joint. The load ``L``
    is ``S`` plus what else moved the joint last step (contacts, coupled joints: the residual ``m (qdot' - qdot)
    / dt + b (qdot' - qdot) - torque - S``, ``m`` the inertia the servo is sized for, ``dt·kv = stiffness·m``,
    ``b`` the joint's ``damping`` (dof_damping): ``implicitfast`` integrates it at the step's end velocity, so
    ``S``, which has it at the start velocity, is off by ``b (qdot' - qdot)``; left in the residual, that
    difference flipped with each velocity change and a damped joint's motor chattered between servo and
    saturation). The servo applies
    ``±A`` at ``u = qdot + (L ± A)·dt/m ± A/kv``:

    * within that reach, the servo: it reaches ``u`` (to its ``1 / (1 + stiffness)`` lag) with at most ``A``;
    * beyond it, saturated: explicitly the torque that takes the joint to ``u`` under its load, clamped to
      ``±A``: exactly ``A`` while the load holds the joint back. The load counts the residual only while a
      constraint row of this step still acts on the joint (``constrained()``, the dofs of this step's
      contacts, equalities, limits and friction loss, known after ``mj_step1``): a wheel in the air, a
      released coupling, is driven to ``u`` under ``S`` alone and no further, where the full torque threw it
      far past ``u`` (and past maxVelocity). A motor saturates when ``u`` lies beyond the reach under ``S``
      (before the step), or after a step whose servo applied more than ``A`` (a load it did not foresee); it
      leaves once ``u`` is within the reach under ``L``. While saturated, the constraint force in the residual
      (last step's qfrc_constraint) does not count when it pushed the joint the way the motor pushes: a stop or
      contact the joint was driven into (an impact's impulse above all) holds it only as hard as needed, since
      ODE solves it with the motor row, and does none of the motor's work; counted, it took the motor out of
      saturation and its servo lifted the joint off its stop. The rest of the residual, the other joints' pull
      through the chain, does help and still counts (dropping the whole residual moved the arm's fast lift 6x
      further from the Webots twin; dropping it wherever a constraint acted, a joint with static friction
      included, made a held arm joint chatter).

    What this cannot do is ODE's simultaneous solve: a constraint's load is known only from the last step. A
    servo step whose load grew applies more than ``A``; a saturated step whose constraint lets go within the
    step (a contact separating) can still carry the joint past ``u``, by what that residual would have held.
    A step whose inertia changes runs ``mj_step1`` again. Decision: entering saturation reads only ``S``
    (exact for the step), leaving it the whole load: coupled joints' residuals swing with each other's
    switches, and a rule that both entered and left on them chattered on the arm. After each step ``force``
    (actuator_force) holds the torque the motor applied over it. The native law (native/webots_motor.c)
    computes the same, bit for bit.

    Decision: this is the law inlined, not a call to ``motor_velocity`` per motor and step. On the arm that
    call (keyword arguments, a tuple back, MotorState attributes) cost more than MuJoCo's physics step itself.
    The arithmetic is the law's, operation for operation in the same order (so results are bit-identical);
    what a period cannot change (which branch of the law, targets, gains, limits) is read once per call, and
    the law's state (integral, previous error, last ``u``) lives in locals and is written back at the end.
    """
    passive, bias, applied, constraint = forces
    step1, step2 = physics_step
    # Per motor: what the period cannot change (a tuple), and the state that steps change (a list: the law's
    # integral, previous error and last u, the residual, the step's qdot and servo stiffness, the saturation
    # sign, the stiffness in the joint's inertia, the step's smooth force and explicit torque, the constraint
    # force in the residual). kind: 0 no control (no available torque), 1 velocity control (infinite target
    # position), 2 position control (the PID), 3 torque control.
    rows = []
    for mo in servos:
        st = mo.state
        p = st.params
        kind = 3 if st.torque_mode else 0 if st.available_torque == 0.0 else 1 if math.isinf(st.target_position) else 2
        inertia = servo_inertia(mo.kv, dt, stiffness)
        limit = st.available_torque
        reach = dt / inertia
        margin = limit / mo.kv
        const = (mo, kind, st.target_position, st.target_velocity, abs(st.target_velocity), p.kp, p.ki, p.kd,
                 p.acceleration >= 0, p.acceleration * dt, mo.qpos, mo.dof, mo.index, mo.kv, limit, reach, margin,
                 inertia, st.torque)
        rows.append((const, [st.integral, st.previous_error, st.current_velocity, mo.residual, 0.0, 0.0,
                             mo.saturated, mo.stiffness, 0.0, 0.0, mo.reaction]))
    try:
        for _ in range(steps):
            step1()
            held: Container[int] | None = None  # the constrained dofs, asked for only by a saturated motor (as the C law)
            switched = False
            for const, state in rows:
                mo, kind, target, target_velocity, vlimit, kp, ki, kd, slew, slew_step, iq, iv, ic, kv, limit, reach, margin, inertia, _ = const
                qdot = state[4] = qvel[iv]
                smooth = state[8] = passive[iv] - bias[iv] + applied[iv]
                if kind == 3:
                    continue  # ctrl holds the commanded torque
                # Webots' law (motor_law.motor_velocity), inlined.
                if kind == 2:
                    error = target - qpos[iq]
                    integral = state[0] + error * dt
                    out = kp * error + ki * integral + kd * (error - state[1]) / dt
                    state[0] = integral
                    state[1] = error
                    u = out if abs(out) < vlimit else math.copysign(vlimit, out)
                elif kind == 1:
                    u = target_velocity
                else:
                    u = 0.0
                if slew:
                    current = state[2]
                    u = max(current - slew_step, min(current + slew_step, u))
                state[2] = u
                # The bounded row (the native law's arithmetic): a servo to u, stiff or saturated.
                sign = state[6]
                if not sign:
                    # Beyond what the torque reaches under the smooth force: saturated before the step.
                    if u > qdot + ((smooth + limit) * reach + margin):
                        sign = 1.0
                    elif u < qdot + ((smooth - limit) * reach - margin):
                        sign = -1.0
                residual, reaction = state[3], state[10]
                if reaction > 0.0 if sign > 0.0 else (sign < 0.0 and reaction < 0.0):
                    # A constraint's reaction pushing the joint the way the saturated motor pushes (a stop or
                    # contact it was driven into, an impact's impulse) holds the joint only as hard as needed:
                    # ODE solves it with the motor row, so more motor torque would relieve it, not move the
                    # joint. It does none of the motor's work: only what holds the joint back counts.
                    residual = residual - reaction
                load = smooth + residual
                if sign and not (u > qdot + ((load + limit) * reach + margin) if sign > 0.0
                                 else u < qdot + ((load - limit) * reach - margin)):
                    sign = 0.0  # within reach under the whole load: the servo reaches u
                state[6] = sign
                stiffness, torque = kv, 0.0
                if sign:
                    # Saturated: no servo, explicitly the torque that takes the joint to u under its load,
                    # within ±limit: the smooth force, and last step's residual while a constraint still acts
                    # on the joint (a contact that is gone, a released coupling no longer hold it back).
                    stiffness = 0.0
                    if held is None:
                        held = constrained()
                    torque = inertia * (u - qdot) / dt - (load if iv in held else smooth)
                    torque = torque if torque < limit else limit
                    torque = torque if torque > -limit else -limit
                state[5] = stiffness
                state[9] = torque
                if stiffness != state[7]:
                    servo(mo, stiffness)
                    state[7] = stiffness
                    switched = True
                ctrl[ic] = stiffness * (u - qdot) + torque
            if switched:
                step1()  # the inertia matrix again, with the servo inertia the switches changed
            step2()
            for const, state in rows:
                # The torque the motor applied (the servo's at the step's end velocity), and the residual load.
                qdot = qvel[const[11]]
                kind, limit = const[1], const[14]
                torque = const[18] if kind == 3 else state[5] * (state[2] - qdot) + state[9]
                force[const[12]] = torque
                change = qdot - state[4]
                state[3] = const[17] * change / dt + damping[const[11]] * change - torque - state[8]
                state[10] = constraint[const[11]]
                if kind != 3 and not state[6] and (torque > limit or -torque > limit):
                    # The servo needed more than the limit (a load it did not foresee): saturated from the next
                    # step until u is within reach again.
                    state[6] = 1.0 if torque > 0.0 else -1.0
    finally:
        for const, state in rows:
            mo = const[0]
            st = mo.state
            st.integral, st.previous_error, st.current_velocity = state[0], state[1], state[2]
            mo.residual, mo.saturated, mo.stiffness, mo.reaction = state[3], state[6], state[7], state[10]


def servo_inertia(kv: float, dt: float, stiffness: float) -> float:
    """The inertia a servo's stiffness was sized for: ``dt·kv = stiffness·inertia``."""
    return kv * dt / stiffness


def relay_value(state: MotorState, mode: str, value: float) -> tuple[float, float]:
    """(value, max velocity) a command on ``state``'s motor relays to its coupled motors
    (:meth:`MotorState.relay`), as the Webots twin sends it: the gain applied, a velocity clamped to this motor's
    max velocity, a torque to its max torque."""
    p = state.params
    v = value * state.gain
    if mode == "velocity":
        v = max(-p.max_velocity, min(p.max_velocity, v))
    elif mode == "torque":
        v = max(-p.max_torque, min(p.max_torque, v))
    return v, p.max_velocity


class _Grouped(Protocol):
    name: str
    state: MotorState
    group: Any


def assign_groups(motors: Sequence[_Grouped]) -> None:
    """Set each motor's ``group``: the motors a command on it reaches, through :meth:`MotorState.relay` (itself
    first, then its coupled motors), when it is coupled or has a multiplier; None (a plain command) otherwise."""
    by_name = {mo.name: mo for mo in motors}
    groups = coupled_names(list(by_name))
    for mo in motors:
        if mo.name in groups or mo.state.params.multiplier != 1.0:
            mo.group = tuple(by_name[n] for n in groups.get(mo.name, [mo.name]))


def relay_command(motor: _Grouped, mode: str, value: float) -> Any:
    """Apply a command on ``motor`` to its group (:func:`assign_groups`) as Webots relays it; returns the group."""
    relayed, max_velocity = relay_value(motor.state, mode, value)
    for mo in motor.group:
        mo.state.relay(mode, relayed, max_velocity)
    return motor.group


def coupled_names(names: Sequence[str]) -> dict[str, list[str]]:
    """Each motor's coupled group (itself first, then the others in order): Webots couples the motors named
    ``prefix::suffix`` (exactly two parts) that share ``prefix`` (webots-devices §9)."""
    return {name: [name, *(n for n in group if n != name)] for group in coupled_groups(names).values()
            if len(group) > 1 for name in group}
