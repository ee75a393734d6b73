"""A supervisor's edit of a motor's ``controlPID``, ``minPosition``/``maxPosition`` or ``multiplier`` at run time,
and what ``simulationReset`` puts back.

S = webots-on-ode.md, D = webots-devices.md. Webots' WbMotor connects these fields to update slots that take the
new value from the next step on and configure the motor's controller again (its getters follow):

* ``controlPID``: the gains of the position loop (S §5.3 step 2); the error integral and the previous error start
  again from 0, as for ``setControlPID``, which replaces the same field (S §5.2).
* ``minPosition``/``maxPosition``: the soft limits ``setPosition`` clips into (S §5.2). A target the new limits
  leave outside is clipped into them now, without a warning (dualtwin's reading where the sources are silent:
  otherwise the joint would keep servoing to a position the motor no longer allows).
* ``multiplier``: what the next ``setPosition``/``setVelocity``/``setForce`` (and their relays to coupled
  siblings) are scaled by (D §9); 0 is refused as at load, with the same warning, and 1 used.

The motor's getters (``getMaxVelocity``, ``getMaxTorque``, ``getMinPosition``, ...) give its configuration as the
steps executed it (:func:`executed_config`): the write of any of these fields is executed at the beginning of the
next step and reaches a controller with that step's answer (S §6), so a robot reading the getter between a
supervisor's write and that step reads the value before it, whichever of the two requests came first in real time.

A joint's PositionSensor takes an edited ``noise`` or ``resolution`` from its next sample (S §5.4).

The coupled motors' limits harmonised at load (D §9, "at load (postFinalize)") are not harmonised again after an
edit. A reset restores every motor edited here to its configuration of the load (with the load's widening and
harmonisation, which the restored fields alone do not give back).
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.motor_api import field_multiplier, target_in_limits
from dualtwin.webots.physics.records import MotorRec, PositionSensorRec

__all__ = [
    "MOTOR_FIELDS",
    "apply_motor_field",
    "apply_position_sensor_field",
    "execute_motor_edits",
    "executed_config",
    "remember_executed",
    "remember_load",
]

#: the motor fields this module applies (maxVelocity, maxTorque/maxForce and acceleration are applied by edits.py)
MOTOR_FIELDS = ("controlPID", "minPosition", "maxPosition", "multiplier")

_KEY = "motor_load_config"
_CONFIG = ("min_position", "max_position", "multiplier", "max_velocity", "max_force")
_EXECUTED_KEY = "motor_executed_config"


def remember_load(sim: Any, motor: MotorRec) -> None:
    """Keep ``motor``'s load configuration before its first edit, and have ``simulationReset`` put it back."""
    kept: dict[int, tuple[MotorRec, tuple[float, ...]]] | None = sim.extensions.get(_KEY)
    if kept is None:
        table: dict[int, tuple[MotorRec, tuple[float, ...]]] = {}
        kept = sim.extensions[_KEY] = table

        def reset() -> None:
            for rec, values in table.values():
                for name, value in zip(_CONFIG, values, strict=True):
                    setattr(rec, name, value)
                rec.reset_state()  # §5.1 again, on the load limits: target velocity = the load maxVelocity

        sim.reset_hooks.append(reset)
    if id(motor) not in kept:
        kept[id(motor)] = (motor, tuple(getattr(motor, name) for name in _CONFIG))


def remember_executed(sim: Any, motor: MotorRec) -> None:
    """Keep ``motor``'s configuration as the steps executed it, before the first write of one of its fields that no
    step executed yet changes it (the getters read it until the next step: :func:`executed_config`)."""
    kept: dict[int, dict[str, float]] | None = sim.extensions.get(_EXECUTED_KEY)
    if kept is None:
        kept = sim.extensions[_EXECUTED_KEY] = {}
        sim.reset_hooks.append(kept.clear)  # (the reset put back the load configuration, which every getter reads)
    if id(motor) not in kept:
        kept[id(motor)] = {name: getattr(motor, name) for name in _CONFIG}


def executed_config(sim: Any, motor: MotorRec, name: str) -> float:
    """``motor``'s configuration value ``name`` (one of ``min_position``, ``max_position``, ``multiplier``,
    ``max_velocity``, ``max_force``) as the steps executed it: before the writes of this step, if any."""
    kept: dict[int, dict[str, float]] | None = sim.extensions.get(_EXECUTED_KEY)
    values = kept.get(id(motor)) if kept else None
    return float(getattr(motor, name) if values is None else values[name])


def execute_motor_edits(sim: Any) -> None:
    """The beginning of a step executes the supervisors' writes: every getter reads the motors' new configuration."""
    kept: dict[int, dict[str, float]] | None = sim.extensions.get(_EXECUTED_KEY)
    if kept:
        kept.clear()


def apply_motor_field(sim: Any, motor: MotorRec, name: str) -> bool:
    """Apply the edit of ``motor``'s field ``name`` (one of :data:`MOTOR_FIELDS`); False for another field."""
    fields = motor.node.fields
    if name == "controlPID":
        motor.kp, motor.ki, motor.kd = (float(v) for v in fields.get("controlPID", (10.0, 0.0, 0.0)))
        motor.integral = 0.0
        motor.prev_error = 0.0
        return True
    if name in ("minPosition", "maxPosition"):
        motor.min_position = float(fields.get("minPosition", 0.0))
        motor.max_position = float(fields.get("maxPosition", 0.0))
        # (silently: a reset applies the load limits again before it puts the motors back in their initial state,
        # and would warn about a target it is about to replace)
        motor.target_position = target_in_limits(motor.target_position, motor.min_position, motor.max_position)
        return True
    if name == "multiplier":
        motor.multiplier = field_multiplier(motor.node, motor.name, sim.warn)
        return True
    return False


def apply_position_sensor_field(sensor: PositionSensorRec, name: str) -> bool:
    """Apply the edit of a PositionSensor's ``noise`` or ``resolution``; False for another field (a reset applies the
    restored load value the same way)."""
    if name == "noise":
        sensor.noise = float(sensor.node.fields.get("noise", 0.0))
        return True
    if name == "resolution":
        sensor.resolution = float(sensor.node.fields.get("resolution", -1.0))
        return True
    return False

