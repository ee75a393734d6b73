"""The converter's second pass: contact, joint-stop and joint-friction softness, written once every geom and joint
exists.

Both need the whole model first: a contact's spring uses the robot's mass shared by its touching bodies
(:func:`dualtwin.convert.equivalences.contact_effective_mass`), and a stop's or a friction's impedance uses the joint's
effective inertia from the compiled model. The mappings themselves are in :mod:`dualtwin.convert.equivalences`.

Contacts: the ContactProperties matching a robot geom's and the environment's ``contactMaterial`` (default
values if none matches) give that geom's ``friction``, ``solref`` and ``solimp``. MuJoCo mixes a contact's
parameters from its two geoms and takes the larger friction, so each environment material keeps the pair with
the smallest friction among the robot materials that meet it. Where that mixing does not give a robot geom and an
environment geom their own pair's values (the world has several environment materials, or robot materials of
different softness), an explicit MuJoCo ``<pair>`` carries them; MuJoCo then skips the mixed contact of those two
geoms, and the MuJoCo twin's geom knobs move the pair with its geoms (:func:`dualtwin.twins.mujoco_knobs.follow_pairs`).
Loose environment objects (Solids with Physics outside the robot) get the same against the rest of the environment:
their geoms carry the robot's pairs, so without a pair a box on the floor slid on the robot's friction.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco

from dualtwin.convert.equivalences import (
    CONTACT_FRICTION_TAIL,
    contact_effective_mass,
    contact_pair,
    friction_solref,
    limit_solimp,
    stop_solref,
)
from dualtwin.webots import schema

__all__ = ["ContactGeom", "Stop", "apply_contacts", "apply_stops", "contact_properties", "exclude_static_contacts"]


@dataclass
class ContactGeom:
    """A collision geom as written: its MuJoCo name and body, its Webots contactMaterial, robot or environment."""

    name: str
    body: str
    material: str
    robot: bool
    #: Geoms sharing a non-empty group never touch (one robot without selfCollision that is not the converted one:
    #: dualtwin.convert.world_robots); no explicit pair may bring them together.
    group: str = ""


#: A limited joint waiting for its stop softness: (MjSpec joint, ERP, CFM).
Stop = tuple[Any, float, float]


def contact_properties(world_info: Mapping[str, Any], a: str, b: str) -> dict[str, Any]:
    """The WorldInfo ContactProperties fields for materials ``a`` and ``b`` (either order), else the defaults."""
    for cp in world_info.get("contactProperties", []) or []:
        if cp is None:
            continue
        m1, m2 = str(cp.get("material1")), str(cp.get("material2"))
        if {m1, m2} == {a, b}:
            fields: dict[str, Any] = cp.fields
            return fields
    return schema.default_fields("ContactProperties")


def apply_contacts(spec: mujoco.MjSpec, geoms: Sequence[ContactGeom], world_info: Mapping[str, Any],
                   robot_mass: float, *, basic_ms: float, mujoco_step_s: float,
                   warn: Callable[[str], None]) -> None:
    """Write friction, solref and solimp on every collision geom (module docstring)."""
    robot_geoms = [g for g in geoms if g.robot]
    env_geoms = [g for g in geoms if not g.robot]
    separated = exclude_static_contacts(spec)
    if not robot_geoms:
        return
    env_materials = list(dict.fromkeys(g.material for g in env_geoms)) or ["default"]
    contact_bodies = max(1, len({g.body for g in robot_geoms}))
    m_eff = contact_effective_mass(robot_mass, contact_bodies)
    step = basic_ms / 1000.0
    env_params: dict[str, tuple[float, list[float], list[float]]] = {}
    noted: set[tuple[str, str]] = set()
    for g in robot_geoms:
        props = contact_properties(world_info, g.material, env_materials[0])
        friction, solref, solimp = contact_pair(props, m_eff, step, mujoco_step_s)
        geom = spec.geom(g.name)
        geom.friction = [friction, *CONTACT_FRICTION_TAIL]
        geom.solref = solref
        geom.solimp = solimp
        for env_material in env_materials:
            params = contact_pair(contact_properties(world_info, g.material, env_material), m_eff, step,
                                  mujoco_step_s)
            current = env_params.get(env_material)
            # MuJoCo takes the larger friction of the two geoms: the environment keeps the smallest.
            if current is None or params[0] < current[0]:
                env_params[env_material] = params
            key = (g.material, env_material)
            # Robot geoms touch only the environment: without one, no pair meets and nothing is lost.
            if env_geoms and key not in noted:
                noted.add(key)
                cp = contact_properties(world_info, *key)
                if float(cp.get("bounce", 0.0)) > 0:
                    warn(f"contact {key[0]!r}/{key[1]!r}: bounce {float(cp['bounce']):g} is not reproduced "
                         "(MuJoCo contacts have no restitution model; solref from softERP/softCFM)")
                if any(float(v) for v in cp.get("rollingFriction", (0.0, 0.0, 0.0))):
                    warn(f"contact {key[0]!r}/{key[1]!r}: rollingFriction not converted")
                if len(cp.get("coulombFriction", [1.0])) > 1:
                    warn(f"contact {key[0]!r}/{key[1]!r}: asymmetric coulombFriction uses the first value")
    for g in env_geoms:
        env = env_params.get(g.material)
        if env is None:
            continue
        geom = spec.geom(g.name)
        geom.friction = [env[0], *CONTACT_FRICTION_TAIL]
        geom.solref = env[1]
        geom.solimp = env[2]
    targets: dict[tuple[str, str], ContactParams] = {}
    robot_pairs: list[tuple[str, str, ContactParams]] = []  # (robot geom, environment geom, the pair's values)
    loose_pairs: list[tuple[str, str, ContactParams]] = []  # between environment geoms (a loose object's)
    for g in robot_geoms:
        for e in env_geoms:
            key = (g.material, e.material)
            if key not in targets:
                targets[key] = contact_pair(contact_properties(world_info, *key), m_eff, step, mujoco_step_s)
            if frozenset((g.body, e.body)) not in separated:
                _if_mixing_differs(spec, robot_pairs, g.name, e.name, targets[key])
    # Loose environment objects (free bodies) against the rest of the environment: their own materials' pair, on the
    # mass of the lighter moving body (as the robot's contacts are sized on the robot's mass).
    for i, a in enumerate(env_geoms):
        for b in env_geoms[i + 1:]:
            masses = [float(spec.body(x).mass) for x in (a.body, b.body) if x != WORLD]
            if (not masses or a.body == b.body or _joined(spec, a.body, b.body) or (a.group and a.group == b.group)
                    or frozenset((a.body, b.body)) in separated):
                continue  # static against static, one body, a joint between them or one robot: they never touch
            _if_mixing_differs(spec, loose_pairs, a.name, b.name, contact_pair(
                contact_properties(world_info, a.material, b.material), contact_effective_mass(min(masses), 1), step,
                mujoco_step_s))
    _add_pairs(spec, robot_pairs, loose_pairs, warn)


#: Explicit pairs a converted model gets at most. MuJoCo tests every explicit pair at every step, outside its
#: broad phase (about 5 ns each: 56,725 pairs made a 29 us step 321 us), where geoms alone are sorted first: a world
#: of many objects in several materials would pay for pairs that almost never touch.
MAX_EXPLICIT_PAIRS = 1000


def _add_pairs(spec: mujoco.MjSpec, robot_pairs: Sequence[tuple[str, str, ContactParams]],
               loose_pairs: Sequence[tuple[str, str, ContactParams]], warn: Callable[[str], None]) -> None:
    """Write the pairs as explicit ``<pair>``s, at most :data:`MAX_EXPLICIT_PAIRS`: the robot's first, and among
    them, when they are too many, those with the largest environment geoms (planes and height fields, then by size:
    the floor and the walls a robot meets before the stones); the others keep MuJoCo's mixing of their two geoms,
    with one warning."""
    spin, roll = CONTACT_FRICTION_TAIL
    pairs = [*robot_pairs, *loose_pairs]
    if len(pairs) > MAX_EXPLICIT_PAIRS:
        pairs = [*sorted(robot_pairs, key=lambda pair: -_reach(spec.geom(pair[1]))), *loose_pairs]
    for geom1, geom2, target in pairs[:MAX_EXPLICIT_PAIRS]:
        spec.add_pair(geomname1=geom1, geomname2=geom2, condim=3, friction=[target[0], target[0], spin, roll, roll],
                      solref=target[1], solimp=target[2])
    if len(pairs) > MAX_EXPLICIT_PAIRS:
        first = pairs[MAX_EXPLICIT_PAIRS]
        warn(f"{len(pairs)} geom pairs need their own contact values, more than the {MAX_EXPLICIT_PAIRS} explicit "
             f"pairs a converted model gets (MuJoCo tests each at every step): {len(pairs) - MAX_EXPLICIT_PAIRS} "
             f"(the first {first[0]!r}/{first[1]!r}) keep MuJoCo's mixing of their geoms' values (the larger "
             "friction, the mean softness)")


#: The MuJoCo world body's name (the static environment's geoms hang on it).
WORLD = "world"


def exclude_static_contacts(spec: mujoco.MjSpec) -> set[frozenset[str]]:
    """Keep each body jointed to the static environment from touching it, as Webots does (on-ODE §2.3 rule 6: ODE
    reports a body attached to the static environment by a joint as connected to body 0, and Webots skips its
    contacts with every static geom: a pendulum hinged to a static base passes through a static floor). The static
    part is every body welded to the world: the world body (the environment's static Solids) and a robot without
    Physics (its fixed base). MuJoCo would let them collide (its parent filter spares the world), so each such
    pair of bodies gets an ``<exclude>``; the pairs are returned (an explicit ``<pair>`` would bypass them)."""
    welded = [b for b in spec.bodies if _welded(b)]
    separated: set[frozenset[str]] = set()
    for body in spec.bodies:
        jointed = [j for j in body.joints if j.type != mujoco.mjtJoint.mjJNT_FREE]
        if jointed and body.parent is not None and _welded(body.parent):
            for static in welded:
                spec.add_exclude(bodyname1=static.name, bodyname2=body.name)
                separated.add(frozenset((static.name, body.name)))
    return separated


def _welded(body: Any) -> bool:
    """Whether ``body`` is fixed to the world: it and every body above it without a joint."""
    while body is not None and body.name != WORLD:
        if len(body.joints):
            return False
        body = body.parent
    return True


def _joined(spec: mujoco.MjSpec, a: str, b: str) -> bool:
    """Whether bodies ``a`` and ``b`` are parent and child (a joint between them: ODE, MuJoCo and Webots skip their
    contacts, which an explicit pair would force)."""
    return any(x != WORLD and y != WORLD and spec.body(y).parent.name == x for x, y in ((a, b), (b, a)))


def _reach(geom: Any) -> float:
    """How much of the world a geom covers: unbounded for a plane or a height field, else its size's length."""
    if geom.type in (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD):
        return math.inf
    return math.sqrt(sum(float(v) ** 2 for v in geom.size))


def _if_mixing_differs(spec: mujoco.MjSpec, pairs: list[tuple[str, str, ContactParams]], geom1: str, geom2: str,
                       target: ContactParams) -> None:
    """Add the two geoms with ``target`` to ``pairs`` (explicit ``<pair>``s to write) where MuJoCo's mixing of them
    would not give it."""
    if not _same(_mixed(spec.geom(geom1), spec.geom(geom2)), target):
        pairs.append((geom1, geom2, target))


#: A material pair's contact in MuJoCo: (friction, solref, solimp).
ContactParams = tuple[float, list[float], list[float]]


def _mixed(a: Any, b: Any) -> ContactParams:
    """The contact MuJoCo makes of geoms ``a`` and ``b`` (equal priority and solmix, as the converter writes them):
    the larger friction, the mean solref and solimp (MuJoCo's mj_contactParam)."""
    return (max(float(a.friction[0]), float(b.friction[0])),
            [(float(x) + float(y)) / 2.0 for x, y in zip(a.solref, b.solref, strict=True)],
            [(float(x) + float(y)) / 2.0 for x, y in zip(a.solimp, b.solimp, strict=True)])


def _same(a: ContactParams, b: ContactParams) -> bool:
    return math.isclose(a[0], b[0], rel_tol=1e-9) and all(
        math.isclose(float(x), float(y), rel_tol=1e-9, abs_tol=1e-12) for x, y in zip([*a[1], *a[2]], [*b[1], *b[2]],
                                                                                       strict=True))


def apply_stops(spec: mujoco.MjSpec, stops: Sequence[Stop], *, basic_ms: float, mujoco_step_s: float,
                cfm: float | None = None) -> None:
    """Hard Webots stops as stiff MuJoCo limits (:func:`~dualtwin.convert.equivalences.stop_solref`), and with the
    world ``cfm`` every joint's ``frictionloss`` (``staticFriction``) as ODE's stiff friction row
    (:func:`~dualtwin.convert.equivalences.friction_solref`).

    The impedance needs each joint's effective inertia (1/``dof_invweight0``), so the spec is compiled first.
    """
    frictions = [j for j in spec.joints if j.frictionloss > 0] if cfm is not None else []
    if not stops and not frictions:
        return
    model = spec.compile()
    for j in frictions:
        dof = int(model.jnt_dofadr[model.joint(j.name).id])
        timeconst, dampratio, d = friction_solref(cfm or 0.0, 1.0 / max(float(model.dof_invweight0[dof]), 1e-12),
                                                  mujoco_step_s)
        j.solref_friction = [timeconst, dampratio]
        j.solimp_friction = limit_solimp(d)
    for j, erp, cfm in stops:
        dof = int(model.jnt_dofadr[model.joint(j.name).id])
        inertia = 1.0 / max(float(model.dof_invweight0[dof]), 1e-12)
        timeconst, dampratio, d = stop_solref(erp, cfm, basic_ms / 1000.0, inertia, mujoco_step_s)
        j.solref_limit = [timeconst, dampratio]
        j.solimp_limit = limit_solimp(d)
