"""Webots' motor law as a MuJoCo engine plugin (``native/webots_motor.c``): built, loaded, and put on models.

The plugin ``dualtwin-webots-motor`` runs the law of :func:`dualtwin.twins.motors.servo_steps` inside
``mj_step``, so a model that uses it steps with Webots' motors in any MuJoCo program (``simulate``,
``mujoco.rollout``, ``mujoco.batch``), and the twin pays no Python per physics step.

Decision: built on first use, not when the package installs. The source ships with the package; the shared
library is compiled once per source and MuJoCo version with the system C compiler (``cc``; Debian:
``gcc`` and ``libc6-dev``) against the headers and library in the ``mujoco`` wheel, into
``$DUALTWIN_CACHE`` (default ``~/.cache/dualtwin``), and loaded with ``mujoco.mj_loadPluginLibrary``. An
editable install and a wheel behave the same, and a machine without a compiler still runs the Python law
(:func:`available` says why not). ``DUALTWIN_NATIVE_LAW=0`` turns the plugin off in the twin.

The plugin keeps everything in ``plugin_state`` (see the layout below, the C file's enum): targets, limits,
gains, the servo stiffness and the law's state. A model compiled with the plugin starts from its config
(the Webots motor fields); the twin writes its own values over it.
"""

from __future__ import annotations

import math
import os
import sys
import threading
from pathlib import Path

import mujoco
import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.native_build import compile_library, library_path
from dualtwin.twins.motors import MotorParams, MotorState

PLUGIN = "dualtwin-webots-motor"
SOURCE = Path(__file__).with_name("native") / "webots_motor.c"

# plugin_state slots per instance (the enum in native/webots_motor.c, in its order).
SLOTS = ("torque_mode", "target_position", "target_velocity", "torque", "available", "kp", "ki", "kd",
         "acceleration", "kv", "inertia", "integral", "previous_error", "u", "residual", "saturated",
         "next_integral", "next_previous_error", "next_u", "next_saturated", "step_velocity", "step_smooth",
         "ctrl_mode", "last_ctrl", "max_velocity", "max_torque", "min_position", "max_position", "gain", "actuator",
         "dof", "qpos", "last", "armature", "step_stiffness",
         "step_torque", "reaction")
SLOT = {name: index for index, name in enumerate(SLOTS)}
NSTATE = len(SLOTS)

_lock = threading.Lock()
_loaded: Path | None = None
_failure: str | None = None


def _library_path() -> Path:
    return library_path(SOURCE, "webots_motor", mujoco.__version__)


def _mujoco_library() -> Path:
    folder = Path(mujoco.__file__).parent
    candidates = sorted(folder.glob("libmujoco.so*")) + sorted(folder.glob("libmujoco*.dylib"))
    if not candidates:
        raise DualtwinError(f"no libmujoco shared library in {folder}")
    return candidates[0]


def build(target: Path | None = None) -> Path:
    """Compile the plugin (``cc``) into ``target`` (default: the cache); returns the library's path."""
    target = target or _library_path()
    if target.exists():
        return target
    library = _mujoco_library()
    include = Path(mujoco.__file__).parent / "include"
    return compile_library(SOURCE, target, [f"-I{include}", f"-L{library.parent}", f"-l:{library.name}",
                                            f"-Wl,-rpath,{library.parent}", "-lm"], "the MuJoCo motor plugin")


def load() -> Path:
    """Build (once) and load the plugin into this process; returns the library's path."""
    global _loaded, _failure
    with _lock:
        if _loaded is not None:
            return _loaded
        if _failure is not None:
            raise DualtwinError(_failure)
        try:
            path = build()
            mujoco.mj_loadPluginLibrary(str(path))
        except (DualtwinError, OSError, RuntimeError) as exc:
            _failure = str(exc)
            raise DualtwinError(_failure) from None
        _loaded = path
        return path


def available() -> str | None:
    """None when the plugin is loaded (building it if needed), else why it cannot be."""
    if os.environ.get("DUALTWIN_NATIVE_LAW", "1") == "0":
        return "turned off by DUALTWIN_NATIVE_LAW=0"
    try:
        load()
    except DualtwinError as exc:
        return str(exc)
    return None


def config(max_velocity: float, max_torque: float, kp: float, ki: float, kd: float, acceleration: float,
           min_position: float, max_position: float, ctrl: str = "none", multiplier: float = 1.0) -> dict[str, str]:
    """The plugin instance's config from a Webots motor's fields (``ctrl``: how it reads ``ctrl``; ``multiplier``
    scales it, as Webots scales a motor's commands, written only when it is not 1)."""
    values = {"maxVelocity": max_velocity, "maxTorque": max_torque, "Kp": kp, "Ki": ki, "Kd": kd,
              "acceleration": acceleration, "minPosition": min_position, "maxPosition": max_position}
    if multiplier != 1.0:
        values["multiplier"] = multiplier
    out = {key: repr(float(value)) for key, value in values.items()}
    out["ctrl"] = ctrl
    return out


def attach(spec: mujoco.MjSpec, actuators: list[mujoco.MjsActuator], settings: dict[str, str], name: str) -> None:
    """Make ``actuators`` (joint actuators of ``spec``) plugin motors driven by one new instance ``name`` with
    ``settings`` (see :func:`config`; it applies to each of them)."""
    if not any(p.plugin_name == PLUGIN for p in spec.plugins if not p.name):
        spec.activate_plugin(PLUGIN)
    instance = spec.add_plugin(name=name, plugin_name=PLUGIN, active=True)
    instance.config = settings
    for actuator in actuators:
        actuator.plugin = instance
        actuator.plugin.active = True


def state_address(model: mujoco.MjModel, actuator: int) -> int:
    """The first plugin_state slot of ``actuator``'s block (-1 for an actuator without the plugin): an
    instance keeps one block of ``NSTATE`` slots per actuator it drives, in actuator order."""
    instance = int(model.actuator_plugin[actuator])
    if instance < 0:
        return -1
    before = int(np.count_nonzero(model.actuator_plugin[:actuator] == instance))
    return int(model.plugin_stateadr[instance]) + NSTATE * before


def native_spec(spec: mujoco.MjSpec, wanted: bool | None = None, origin: str = "<MjSpec>") -> mujoco.MjSpec | None:
    """A copy of ``spec`` whose joint actuators run Webots' law in the plugin, or None for the Python law:
    when ``wanted`` is False, or None and the plugin cannot be loaded. Actuators that already use it keep
    their config; the MuJoCo twin writes its own values into plugin_state anyway, so injected ones share one
    instance with an empty config (``ctrl`` unused).

    Raises:
        DualtwinError: ``wanted`` is True and the plugin cannot be loaded, or False for a model whose
            actuators are plugin motors already (:func:`standalone_spec`: the Python law needs plain ones).
    """
    if wanted is False:
        if any(a.plugin.active for a in spec.actuators):
            raise DualtwinError(f"{origin}: the model's motors are plugin actuators ({PLUGIN}); the Python "
                                "motor law needs the plain model (Conversion.xml, not native_law_xml)")
        return None
    why = available()
    if why is not None:
        if wanted:
            raise DualtwinError(f"{origin}: the native motor law is unavailable: {why}")
        return None
    native = spec.copy()
    # One instance for all of them: MuJoCo's dispatch per instance and stage costs more than the law itself.
    plain = [a for a in native.actuators if a.trntype == mujoco.mjtTrn.mjTRN_JOINT and not a.plugin.active]
    if plain:
        attach(native, plain, {"ctrl": "none"}, "webots_motors")
    return native


def standalone_spec(spec: mujoco.MjSpec, ctrl: str = "position") -> mujoco.MjSpec:
    """A copy of ``spec`` that carries Webots' motors for any MuJoCo program: every joint actuator becomes a
    plugin motor configured from its ``webots_motor.<name>`` numeric (maxVelocity, Kp, Ki, Kd, acceleration
    [, minPosition, maxPosition]) and its force range (maxTorque), and reads ``ctrl`` as ``ctrl`` says
    (``position``, ``velocity`` or ``torque``: Webots' setPosition, setVelocity, setTorque).

    Raises:
        DualtwinError: The plugin cannot be loaded (no C compiler), or ``ctrl`` is not one of those.
    """
    if ctrl not in ("position", "velocity", "torque"):
        raise DualtwinError(f"ctrl must be position, velocity or torque, not {ctrl!r}")
    load()
    out = spec.copy()
    numerics = {n.name: list(n.data) for n in out.numerics}
    for actuator in out.actuators:
        if actuator.trntype != mujoco.mjtTrn.mjTRN_JOINT or actuator.plugin.active:
            continue
        fields = numerics.get(f"webots_motor.{actuator.name}", []) + [math.nan] * 8
        defaults = (10.0, 10.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0)
        v = [d if math.isnan(f) else f for f, d in zip(fields[:8], defaults, strict=True)]
        torque = abs(float(actuator.forcerange[1])) if actuator.forcerange[1] else 10.0
        attach(out, [actuator], config(v[0], torque, v[1], v[2], v[3], v[4], v[5], v[6], ctrl, v[7] or 1.0),
               f"webots_motor:{actuator.name or len(out.plugins)}")
        # Webots clamps the torque and the command itself; MuJoCo's clamps would cut the servo.
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
        actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    return out


ATTRIBUTES = ("maxVelocity", "maxTorque", "Kp", "Ki", "Kd", "acceleration", "minPosition", "maxPosition",
              "stiffness", "ctrl", "multiplier")  # the plugin's config keys, in its order (kAttributes in the C file)


def max_torque(model: mujoco.MjModel, actuator: int, default: float) -> float:
    """A motor's torque limit: its force range when limited, else a plugin motor's ``maxTorque`` config."""
    if model.actuator_forcelimited[actuator]:
        return float(abs(model.actuator_forcerange[actuator, 1]))
    instance = int(model.actuator_plugin[actuator])
    if instance < 0:
        return default
    start = int(model.plugin_attradr[instance])
    end = int(model.plugin_attradr[instance + 1]) if instance + 1 < model.nplugin else len(model.plugin_attr)
    values = bytes(model.plugin_attr[start:end]).decode().split("\0")
    text = dict(zip(ATTRIBUTES, values, strict=False)).get("maxTorque", "")
    return float(text) if text else default


def motor_params(model: mujoco.MjModel, name: str, actuator: int) -> MotorParams:
    """A joint actuator's Webots motor fields: its ``webots_motor.NAME`` numeric (maxVelocity Kp Ki Kd
    acceleration [minPosition maxPosition [multiplier]]; Webots' defaults for those missing) and :func:`max_torque`."""
    params = MotorParams()
    numeric = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, f"webots_motor.{name}")
    if numeric >= 0:
        adr, size = model.numeric_adr[numeric], model.numeric_size[numeric]
        fields = ("max_velocity", "kp", "ki", "kd", "acceleration", "min_position", "max_position", "multiplier")
        values = list(model.numeric_data[adr:adr + size]) + [math.nan] * len(fields)
        for attr, value in zip(fields, values[:len(fields)], strict=True):
            if not math.isnan(value):
                setattr(params, attr, float(value))
    params.max_torque = max_torque(model, actuator, params.max_torque)
    return params


def slot_values(state: MotorState, kv: float, armature: float, inertia: float,
                law: tuple[float, float, float] | None = None) -> list[tuple[int, float]]:
    """(slot, value) for one motor's plugin_state from the twin's motor state: targets, limits, gains, servo
    stiffness ``kv``, rotor ``armature`` and the ``inertia`` kv was sized for; with ``law`` (saturation,
    residual load; not None) its law state too (integral, previous error, last u and those)."""
    p = state.params
    values = {"torque_mode": 1.0 if state.torque_mode else 0.0, "target_position": state.target_position,
              "target_velocity": state.target_velocity, "torque": state.torque, "available": state.available_torque,
              "kp": p.kp, "ki": p.ki, "kd": p.kd, "acceleration": p.acceleration, "kv": kv, "inertia": inertia,
              "ctrl_mode": 0.0, "max_velocity": p.max_velocity, "max_torque": p.max_torque,
              "min_position": p.min_position, "max_position": p.max_position, "gain": state.gain,
              "armature": armature}
    if law is not None:
        values.update(integral=state.integral, previous_error=state.previous_error, u=state.current_velocity,
                      saturated=law[0], residual=law[1], reaction=law[2])
    return [(SLOT[key], float(value)) for key, value in values.items()]


if __name__ == "__main__":  # ``python -m dualtwin.twins.motor_plugin``: build now, print the library's path
    try:
        print(load())
    except DualtwinError as exc:
        print(exc, file=sys.stderr)
        sys.exit(2)
