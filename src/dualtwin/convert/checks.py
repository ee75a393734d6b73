"""Checks for generated MJCF: a static lint pass and a physics smoke test.

MuJoCo's compiler stops at the first error and accepts several mistakes silently (a radian range in degree
mode, visual geoms adding mass, sensor noise that is only metadata), so every converted or generated model
also goes through :func:`lint_spec` and :func:`smoke_test`. The smoke test follows MuJoCo Menagerie's model
test: step with random controls inside the actuator ranges and fail on any ``mjData.warning`` or NaN.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

import mujoco
import numpy as np

from dualtwin.webots.nodes import Node

Level = Literal["error", "warning"]

#: Hinge ranges wider than this in radians are almost certainly degrees.
TWO_PI = 2.0 * math.pi + 1e-6


@dataclass(frozen=True)
class Finding:
    """One lint result. ``where`` names the element (or ``file:line:col`` for Webots-side findings)."""

    level: Level
    code: str
    message: str
    where: str = ""

    def __str__(self) -> str:
        where = f"{self.where}: " if self.where else ""
        return f"{self.level}: {where}{self.message} [{self.code}]"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def lint_world_rotations(root: Node) -> list[Finding]:
    """Webots ``rotation`` angles beyond 2*pi under ``root``: almost certainly degrees written as radians."""
    findings = []
    for node in root.walk():
        rotation = node.fields.get("rotation")
        if isinstance(rotation, tuple) and len(rotation) == 4 and abs(float(rotation[3])) > TWO_PI:
            findings.append(Finding(
                "warning", "rotation-in-degrees",
                f"{node.type_name} rotation angle {rotation[3]:g} exceeds 2*pi: degrees written as radians?",
                str(node.location) if node.location is not None else "<unknown location>"))
    return findings


def _visual(geom: Any) -> bool:
    return int(geom.contype) == 0 and int(geom.conaffinity) == 0


def _name(element: Any, kind: str) -> str:
    return f"{kind} {element.name!r}" if element.name else f"unnamed {kind}"


def lint_spec(spec: mujoco.MjSpec, model: mujoco.MjModel | None = None) -> list[Finding]:
    """Static checks on a spec (and its compiled model, when it compiles) for the traps MuJoCo accepts."""
    out: list[Finding] = []
    degree = bool(spec.compiler.degree)
    joints = {j.name for j in spec.joints if j.name}
    sites = {s.name for s in spec.sites if s.name}
    bodies = {b.name for b in spec.bodies if b.name}
    for joint in spec.joints:
        if joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            continue
        lo, hi = (float(v) for v in joint.range)
        if np.linalg.norm(np.asarray(joint.axis, dtype=float)) < 1e-9:
            out.append(Finding("error", "joint-axis-zero", "joint axis is zero", _name(joint, "joint")))
        if joint.type != mujoco.mjtJoint.mjJNT_HINGE or (lo == 0.0 and hi == 0.0):
            continue
        if not degree and (max(abs(lo), abs(hi)) > TWO_PI):
            out.append(Finding("error", "range-in-degrees",
                               f"hinge range [{lo:g}, {hi:g}] exceeds 2*pi in radian mode: degrees written as radians?",
                               _name(joint, "joint")))
        elif degree and 0.0 < max(abs(lo), abs(hi)) <= math.pi + 1e-3:
            out.append(Finding("warning", "range-in-radians",
                               f"hinge range [{lo:g}, {hi:g}] is read in degrees (compiler angle=\"degree\"), "
                               "i.e. under 3.2 degrees: radians written in degree mode?", _name(joint, "joint")))
    for body in spec.bodies:
        if body.name == "world":
            continue
        explicit = bool(body.explicitinertial) and not math.isnan(float(body.ipos[0]))
        if explicit and float(body.mass) <= 0.0 and (body.joints or body.first_joint() is not None):
            out.append(Finding("error", "non-positive-mass", f"moving body has mass {float(body.mass):g}",
                               _name(body, "body")))
        if float(body.mass) < 0.0:
            out.append(Finding("error", "negative-mass", f"mass {float(body.mass):g} is negative", _name(body, "body")))
        for geom in body.geoms:
            if not _visual(geom) or explicit:
                continue
            mass = float(geom.mass)
            adds = (not math.isnan(mass) and mass > 0) or (math.isnan(mass) and float(geom.density) > 0)
            lo_group, hi_group = (int(v) for v in spec.compiler.inertiagrouprange)
            if adds and lo_group <= int(geom.group) <= hi_group:
                out.append(Finding("warning", "visual-geom-mass",
                                   "visual geom (contype=conaffinity=0) adds mass to its body; give it density 0 or "
                                   "an explicit body inertial", _name(geom, "geom")))
    for sensor in spec.sensors:
        objtype, objname = sensor.objtype, sensor.objname
        known = {mujoco.mjtObj.mjOBJ_JOINT: joints, mujoco.mjtObj.mjOBJ_SITE: sites,
                 mujoco.mjtObj.mjOBJ_BODY: bodies, mujoco.mjtObj.mjOBJ_XBODY: bodies}.get(objtype)
        if known is not None and objname not in known:
            kind = objtype.name.removeprefix("mjOBJ_").lower()
            out.append(Finding("error", "sensor-target-missing", f"sensor refers to missing {kind} {objname!r}",
                               _name(sensor, "sensor")))
        if float(sensor.noise) > 0:
            out.append(Finding("warning", "sensor-noise-metadata",
                               "MJCF sensor noise does not affect MuJoCo's simulation; the dualtwin MuJoCo twin "
                               "adds it at read time", _name(sensor, "sensor")))
    for actuator in spec.actuators:
        if actuator.trntype == mujoco.mjtTrn.mjTRN_JOINT and actuator.target not in joints:
            out.append(Finding("error", "actuator-target-missing", f"actuator drives missing joint {actuator.target!r}",
                               _name(actuator, "actuator")))
    if model is not None:
        for b in range(1, model.nbody):
            if model.body_dofnum[b] and model.body_mass[b] <= mujoco.mjMINVAL and not _has_massive_child(model, b):
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body {b}"
                out.append(Finding("error", "zero-mass", "moving body has (almost) zero mass", f"body {name!r}"))
    return out


def _has_massive_child(model: mujoco.MjModel, body: int) -> bool:
    return bool(model.body_subtreemass[body] > mujoco.mjMINVAL)


@dataclass
class SmokeResult:
    """Outcome of :func:`smoke_test`."""

    ok: bool
    steps: int
    duration_s: float
    message: str = ""
    warnings: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def control_ranges(model: mujoco.MjModel) -> np.ndarray:
    """(nu, 2) control bounds for random inputs: ctrlrange, else forcerange, else ±1."""
    ranges = np.tile([-1.0, 1.0], (model.nu, 1))
    for i in range(model.nu):
        if model.actuator_ctrllimited[i]:
            ranges[i] = model.actuator_ctrlrange[i]
        elif model.actuator_forcelimited[i]:
            ranges[i] = model.actuator_forcerange[i]
    return ranges


def smoke_test(model: mujoco.MjModel, duration_s: float = 0.5, seed: int = 0) -> SmokeResult:
    """Step ``duration_s`` with uniform random controls inside the ranges; fail on any warning or NaN."""
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    ranges = control_ranges(model)
    steps = max(1, int(math.ceil(duration_s / model.opt.timestep - 1e-9)))
    message = ""
    done = 0
    for k in range(steps):
        if model.nu:
            data.ctrl[:] = ranges[:, 0] + (ranges[:, 1] - ranges[:, 0]) * rng.random(model.nu)
        mujoco.mj_step(model, data)
        done = k + 1
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            message = f"non-finite state at t = {data.time:.4f} s"
            break
    warnings = {}
    for label, w in mujoco.mjtWarning.__members__.items():
        if w == mujoco.mjtWarning.mjNWARNING:
            continue
        count = int(data.warning[int(w)].number)
        if count:
            warnings[label.removeprefix("mjWARN_")] = count
    if warnings and not message:
        first = ", ".join(f"{k} x{v}" for k, v in warnings.items())
        message = f"MuJoCo warnings during {done * model.opt.timestep:.3f} s of random controls: {first}"
    return SmokeResult(ok=not message, steps=done, duration_s=done * model.opt.timestep, message=message,
                       warnings=warnings)
