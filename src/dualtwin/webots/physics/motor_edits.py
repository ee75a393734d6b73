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

A write of any of these fields, or of ``maxVelocity``, ``maxTorque``/``maxForce`` or ``acceleration``, is executed at
the beginning of the next step (S §6: "queued and executed at the beginning of the next step"), after the motor
commands of the step before it (:func:`queue_motor_field`, :func:`execute_motor_edits`): a command made in the same
step as the write, by whichever controller and whichever came first in real time, is multiplied and clipped with the
configuration before the write (and clipped into the new limits when it executes), and the motor's getters give the
configuration before the write until that step.

A joint's PositionSensor takes an edited ``noise`` or ``resolution`` from its next sample (S §5.4).

The coupled motors' limits harmonised at load (D §9, "at load (postFinalize)") are not harmonised again after an
edit. A reset restores every motor edited here to its configuration of the load (with the load's widening and
harmonisation, which the restored fields alone do not give back).
"""

from __future__ import annotations

from typing import Any

from dualtwin.webots.motor_api import read_motor_fields
from dualtwin.webots.physics.records import MotorRec, PositionSensorRec

__all__ = [
    "MOTOR_FIELDS",
    "QUEUED_MOTOR_FIELDS",
    "apply_position_sensor_field",
    "execute_motor_edits",
    "queue_motor_field",
    "remember_load",
]

#: the fields this module documents (maxVelocity, maxTorque/maxForce and acceleration are queued too)
MOTOR_FIELDS = ("controlPID", "minPosition", "maxPosition", "multiplier")

#: the motor fields whose write waits for the beginning of the next step (see the module docstring)
QUEUED_MOTOR_FIELDS = ("maxVelocity", "maxTorque", "maxForce", "acceleration", *MOTOR_FIELDS)

_KEY = "motor_load_config"
_QUEUE_KEY = "motor_field_writes"
_CONFIG = ("min_position", "max_position", "multiplier", "max_velocity", "max_force")


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


def queue_motor_field(sim: Any, motor: MotorRec, name: str) -> None:
    """A supervisor wrote ``motor``'s field ``name`` (one of :data:`QUEUED_MOTOR_FIELDS`): the motor takes the
    field's value at the beginning of the next step (:func:`execute_motor_edits`); until then it keeps its
    configuration."""
    queued: dict[tuple[int, str], tuple[MotorRec, str]] | None = sim.extensions.get(_QUEUE_KEY)
    if queued is None:
        queued = sim.extensions[_QUEUE_KEY] = {}
    queued[(id(motor), name)] = (motor, name)


def execute_motor_edits(sim: Any) -> None:
    """The beginning of a step: every motor takes the fields written since the last one, in the order they were
    first written (the value is the field's, which the supervisors' scene-tree order decided). A reset calls it
    too, for the fields it restored, before it puts the load configuration back."""
    queued: dict[tuple[int, str], tuple[MotorRec, str]] | None = sim.extensions.get(_QUEUE_KEY)
    if not queued:
        return
    writes = list(queued.values())
    queued.clear()
    for motor, name in writes:
        _apply_motor_field(sim, motor, name)


def _apply_motor_field(sim: Any, motor: MotorRec, name: str) -> None:
    # (a limit edit clips the target silently: a reset applies the load limits again before it puts the motors back
    # in their initial state, and would warn about a target it is about to replace)
    read_motor_fields(motor, motor.node, (name,), motor.name, sim.warn)


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

