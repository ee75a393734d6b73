"""Write fitted knob values back into a twin's model file.

MuJoCo: the MJCF is loaded as an ``MjSpec``, the values are written into the spec, and ``to_xml`` gives
the patched model. A body whose mass, inertia or centre of mass changed gets an explicit ``inertial``
(mass, centre of mass, principal inertia and frame from the compiled nominal model, scaled as the twin
scales them), and the compiler switches from ``inertiafromgeom="true"`` to ``"auto"`` so the explicit
values are used while other bodies still take theirs from their geoms. Knobs with no MJCF field (command
gain, delays, sensor bias and resolution) are listed as not applied; they are also stored as JSON in a
``<text name="dualtwin.knobs">`` element, so the file still records them.

Webots: `patch_webots` calls ``dualtwin.webots.writer.patch_webots_world(world_path, knobs) -> str`` when
the Webots side provides it, and otherwise explains that it is missing.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.twins.mujoco_knobs import impedance_pair, restitution_to_dampratio

#: Knob properties that have no MJCF field.
NOT_IN_MJCF: dict[str, str] = {
    "gain": "a command gain is applied by the twin's controller side",
    "delay": "delays are applied by the twin, not the model",
    "delay_periods": "delays are applied by the twin, not the model",
    "bias": "sensor bias is applied by the twin",
    "quantization": "sensor resolution is applied by the twin",
}


@dataclass
class PatchResult:
    """A patched model text (None if not produced) and what was and was not written into it."""

    text: str | None
    applied: list[str] = field(default_factory=list)
    not_applied: dict[str, str] = field(default_factory=dict)
    note: str = ""


def _find(getter: object, name: str, kind: str, origin: str) -> object:
    element = getter(name) if callable(getter) else None
    if element is None:
        raise DualtwinError(f"{origin}: no {kind} named {name!r} to patch")
    return element


def patch_mjcf(model_path: Path, knobs: Mapping[str, float], aliases: Mapping[str, str] | None = None,
               control_period: float | None = None) -> PatchResult:
    """The MJCF at ``model_path`` with ``knobs`` written in (values as the MuJoCo twin applies them).

    ``control_period`` (s) turns ``physics.substeps`` into the option ``timestep``; without it that knob is
    listed as not applied.
    """
    origin = str(model_path)
    spec = mujoco.MjSpec.from_file(origin)
    nominal = spec.compile()
    alias = dict(aliases or {})
    applied: list[str] = []
    not_applied: dict[str, str] = {}
    bodies: dict[str, dict[str, float]] = {}
    for key, value in knobs.items():
        value = float(value)
        if key.startswith("control."):
            not_applied[key] = NOT_IN_MJCF["delay"]
            continue
        if key == "physics.substeps":
            if control_period is None:
                not_applied[key] = "the timestep needs the control period"
                continue
            steps = int(round(value))
            # The twin keeps the compiled step bit for bit at the nominal count (see MuJoCoTwin._set_substeps).
            if abs(control_period / nominal.opt.timestep - steps) > 1e-6:
                spec.option.timestep = control_period / steps
            applied.append(key)
            continue
        if key == "option.impratio":
            spec.option.impratio = value
            applied.append(key)
            continue
        kind, rest = key.split(".", 1)
        name, prop = rest.rsplit(".", 1)
        name = alias.get(name, name)
        if prop in NOT_IN_MJCF:
            not_applied[key] = NOT_IN_MJCF[prop]
            continue
        if kind == "joint":
            joint = _find(spec.joint, name, "joint", origin)
            if prop == "damping":
                joint.damping[0] = value  # type: ignore[attr-defined]  # an array since MuJoCo 3.7
            elif prop == "armature":
                joint.armature = value  # type: ignore[attr-defined]
            elif prop == "limit_timeconst":
                j = mujoco.mj_name2id(nominal, mujoco.mjtObj.mjOBJ_JOINT, name)
                joint.solref_limit = [value, float(nominal.jnt_solref[j, 1])]  # type: ignore[attr-defined]
            elif prop == "limit_impedance":
                j = mujoco.mj_name2id(nominal, mujoco.mjtObj.mjOBJ_JOINT, name)
                joint.solimp_limit = [*impedance_pair(nominal.jnt_solimp[j], value),  # type: ignore[attr-defined]
                                      *(float(v) for v in nominal.jnt_solimp[j, 2:])]
            else:
                joint.frictionloss = value  # type: ignore[attr-defined]
        elif kind == "geom":
            geom = _find(spec.geom, name, "geom", origin)
            g = mujoco.mj_name2id(nominal, mujoco.mjtObj.mjOBJ_GEOM, name)
            if prop == "friction":
                geom.friction[0] = value  # type: ignore[attr-defined]
            elif prop == "radius":
                geom.size[0] = value  # type: ignore[attr-defined]
            elif prop == "solref_timeconst":
                geom.solref = [value, float(nominal.geom_solref[g, 1])]  # type: ignore[attr-defined]
            elif prop == "impedance":
                geom.solimp = [*impedance_pair(nominal.geom_solimp[g], value),  # type: ignore[attr-defined]
                               *(float(v) for v in nominal.geom_solimp[g, 2:])]
            else:
                geom.solref = [float(nominal.geom_solref[g, 0]),  # type: ignore[attr-defined]
                               restitution_to_dampratio(value, float(nominal.geom_solref[g, 1]))]
        elif kind == "body":
            bodies.setdefault(name, {})[prop] = value
            continue  # written per body below, once all of its knobs are known
        elif kind == "motor":
            actuator = _find(spec.actuator, name, "actuator", origin)
            if prop == "max_torque":
                actuator.forcerange = [-value, value]  # type: ignore[attr-defined]
                actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE  # type: ignore[attr-defined]
            elif prop in ("max_velocity", "kp"):
                # webots_motor data: maxVelocity Kp Ki Kd acceleration [minPosition maxPosition]
                index = 0 if prop == "max_velocity" else 1
                numeric = spec.numeric(f"webots_motor.{name}")
                data = list(numeric.data) if numeric is not None else [10.0, 10.0, 0.0, 0.0, -1.0]
                data[index] = value
                if numeric is None:
                    spec.add_numeric(name=f"webots_motor.{name}", data=data[:index + 1])
                else:
                    numeric.data = data
        elif kind == "sensor" and prop == "noise":
            _find(spec.sensor, name, "sensor", origin).noise = value  # type: ignore[attr-defined]
        else:
            not_applied[key] = "no MJCF field for this knob"
            continue
        applied.append(key)
    for name, props in bodies.items():
        body = _find(spec.body, name, "body", origin)
        b = mujoco.mj_name2id(nominal, mujoco.mjtObj.mjOBJ_BODY, name)
        mass0 = float(nominal.body_mass[b])
        mass = props.get("mass", mass0)
        factor = mass / mass0 * props.get("inertia_scale", 1.0)
        offset = np.array([props.get(f"com_offset_{a}", 0.0) for a in "xyz"])
        body.explicitinertial = True  # type: ignore[attr-defined]
        body.mass = mass  # type: ignore[attr-defined]
        body.ipos = nominal.body_ipos[b] + offset  # type: ignore[attr-defined]
        body.iquat = nominal.body_iquat[b].copy()  # type: ignore[attr-defined]
        body.inertia = nominal.body_inertia[b] * factor  # type: ignore[attr-defined]
        applied.extend(f"body.{name}.{p}" for p in props)
    if bodies:
        # "true" would recompute every body from its geoms and ignore the explicit inertials.
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
    if not_applied:
        spec.add_text(name="dualtwin.knobs", data=json.dumps({k: float(knobs[k]) for k in sorted(not_applied)}))
    try:
        spec.compile()
    except ValueError as exc:
        raise DualtwinError(f"{origin}: the patched model does not compile: {' '.join(str(exc).split())}") from None
    return PatchResult(spec.to_xml(), sorted(applied), not_applied)


def patch_webots(world_path: Path, knobs: Mapping[str, float]) -> PatchResult:
    """Patch a Webots world through ``dualtwin.webots.writer.patch_webots_world`` if the Webots side has it."""
    try:
        from dualtwin.webots import writer
    except ImportError as exc:
        return PatchResult(None, note=f"the Webots writer cannot be imported ({exc}); knobs.json holds the values")
    hook = getattr(writer, "patch_webots_world", None)
    if hook is None:
        return PatchResult(None, note="this installation cannot patch Webots worlds; knobs.json holds the "
                                      "fitted values")
    text = hook(Path(world_path), dict(knobs))
    return PatchResult(str(text), applied=sorted(knobs))
