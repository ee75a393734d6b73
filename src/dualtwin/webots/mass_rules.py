"""Webots' mass rules (§3.2): the mass, centre of mass and inertia of one Solid from its Physics node and its
boundingObject, computed with ODE's own ``dMass`` functions.

This is the only implementation. The Webots twin builds its ODE bodies from :func:`solid_mass`; the MJCF
converter writes :func:`solid_inertial` (the same ``dMass``, expressed about the centre of mass) as each
body's explicit ``inertial``, so a converted body weighs exactly what the twin's ODE body weighs
(``tests/convert/test_mass_agreement.py`` checks it on every fixture world).

The rules, as Webots applies them (``WbSolid::updateMass`` and ``WbSolidUtilities::addMass`` in Webots):

* Every primitive of the boundingObject contributes its ODE mass at the reference density 1000 kg/m³
  (``dMassSetBox``/``Sphere``/``Cylinder``/``Capsule`` along z, ``dMassSetTrimesh`` for an IndexedFaceSet or
  a Mesh, :mod:`.bounding_mesh`), rotated and translated by the enclosing Pose/Transform nodes; overlaps are
  counted twice. Plane and ElevationGrid contribute nothing; an invalid primitive (a non-positive size, a mesh
  without triangles or enclosing no volume, a Mesh whose file cannot be read) contributes 1 kg with an identity
  inertia.
* ``mass > 0`` rescales that reference distribution to ``mass`` (a density given too is ignored, with a
  warning); otherwise ``density`` (when it is not 1000) rescales it by ``density / 1000``.
  ``-1`` is the conventional "unset" value of both fields; if neither is positive, 1 kg is used.
* ``centerOfMass`` (one vector) moves the distribution rigidly so its centre sits there.
* ``inertiaMatrix`` (two vectors: I11 I22 I33, then I12 I13 I23, about the centre of mass) replaces the
  computed distribution when ``mass > 0``, ``centerOfMass`` is given and the matrix is positive definite;
  otherwise it is ignored with a warning.
* Without a boundingObject (or one that carries no mass): an identity inertia, 1 kg·m² with a positive
  ``mass``, ``density / 1000`` for both mass and inertia otherwise, at ``centerOfMass`` if given.

Scale: a Transform's ``scale`` inside the boundingObject scales the primitives the way the twin's collision
geoms are scaled (per axis for a Box and mesh vertices, by the largest factor for round primitives) and the
translations of the frames below it. The Transforms above the Solid (one factor ``s``,
:mod:`dualtwin.webots.solid_scale`) magnify its whole mass distribution, whatever mode defines it (§3.2: "mass ∝
s³ and inertia ∝ s⁵"): the mass is computed at scale 1, then its mass multiplied by s³, its centre of mass by s and
its inertia by s⁵ (a given ``mass`` and ``inertiaMatrix`` included); with a density that is what the scaled
boundingObject weighs. Both twins pass that factor: the Webots twin for each Solid, the converter for each body.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable, Sequence
from ctypes import byref
from dataclasses import dataclass
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.bounding_mesh import TRIMESH_TYPES, mesh_warning, trimesh_data
from dualtwin.webots.mesh_files import MeshFileError
from dualtwin.webots.nodes import Node

__all__ = [
    "REFERENCE_DENSITY",
    "SolidInertial",
    "bounding_mass",
    "field_or",
    "magnify",
    "mass_zero",
    "rot_matrix",
    "solid_inertial",
    "solid_mass",
]

#: ODE's reference density for boundingObject primitives (Webots ``WbSolidUtilities::addMass``).
REFERENCE_DENSITY = 1000.0

Warn = Callable[[str], None]
Scale = tuple[float, float, float]
_UNIT: Scale = (1.0, 1.0, 1.0)


def field_or(node: Node | None, name: str, default: Any) -> Any:
    """``node.fields[name]``, or ``default`` when the node is None or the field is missing or NULL."""
    if node is None:
        return default
    value = node.fields.get(name, default)
    return default if value is None else value


_f = field_or


def mass_zero() -> ode.dMass:
    """A zeroed ODE mass (``dMassSetZero``)."""
    m = ode.dMass()
    ode.load().dMassSetZero(byref(m))
    return m


def rot_matrix(R: Sequence[float]) -> Any:
    """A row-major 3×3 rotation as ODE's padded ``dMatrix3``."""
    mat = ode.dMatrix3()
    for i in range(3):
        for j in range(3):
            mat[4 * i + j] = R[3 * i + j]
    return mat


def bounding_mass(node: Node, acc: ode.dMass, warn: Warn, scale: Scale = _UNIT) -> float:
    """Add the reference-density (1000) mass of a boundingObject subtree into ``acc``; return its volume."""
    lib = ode.load()
    t = node.type_name
    if t in ("Pose", "Transform"):
        sc = scale
        if t == "Transform":
            s = _f(node, "scale", _UNIT)
            if tuple(s) != _UNIT:
                sc = (scale[0] * float(s[0]), scale[1] * float(s[1]), scale[2] * float(s[2]))
        sub = mass_zero()
        vol = 0.0
        for c in node.children():
            vol += bounding_mass(c, sub, warn, sc)
        if sub.mass > 0:
            R = m3.rot_axis_angle(_f(node, "rotation", (0, 0, 1, 0)))
            if R != m3.IDENTITY:
                lib.dMassRotate(byref(sub), rot_matrix(R))
            tr = _f(node, "translation", (0.0, 0.0, 0.0))
            if scale != _UNIT:
                tr = tuple(float(v) * k for v, k in zip(tr, scale, strict=True))
            lib.dMassTranslate(byref(sub), *tr)
            lib.dMassAdd(byref(acc), byref(sub))
        return vol
    if t == "Group":
        return sum(bounding_mass(c, acc, warn, scale) for c in node.children())
    if t == "Shape":
        geom = _f(node, "geometry", None)
        return bounding_mass(geom, acc, warn, scale) if isinstance(geom, Node) else 0.0
    m = mass_zero()
    ok = True
    uniform = max(scale)
    if t == "Box":
        sx, sy, sz = (float(v) for v in _f(node, "size", (2.0, 2.0, 2.0)))
        if scale != _UNIT:
            sx, sy, sz = sx * scale[0], sy * scale[1], sz * scale[2]
        ok = sx > 0 and sy > 0 and sz > 0
        if ok:
            lib.dMassSetBox(byref(m), REFERENCE_DENSITY, sx, sy, sz)
    elif t == "Sphere":
        r = float(_f(node, "radius", 1.0))
        if scale != _UNIT:
            r *= uniform
        ok = r > 0
        if ok:
            lib.dMassSetSphere(byref(m), REFERENCE_DENSITY, r)
    elif t in ("Cylinder", "Capsule"):
        r, h = float(_f(node, "radius", 1.0)), float(_f(node, "height", 2.0))
        if scale != _UNIT:
            r, h = r * uniform, h * uniform
        ok = r > 0 and h > 0
        if ok:
            fn = lib.dMassSetCylinder if t == "Cylinder" else lib.dMassSetCapsule
            fn(byref(m), REFERENCE_DENSITY, 3, r, h)
    elif t in TRIMESH_TYPES:
        ok = _add_trimesh(node, m, warn, scale)
    elif t in ("Plane", "ElevationGrid"):
        return 0.0  # §3.2: contributes nothing
    else:
        return 0.0
    if not ok:
        # §3.2: invalid primitives contribute 1 kg with identity inertia
        lib.dMassSetParameters(byref(m), 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
        lib.dMassAdd(byref(acc), byref(m))
        return 0.0
    lib.dMassAdd(byref(acc), byref(m))
    return m.mass / REFERENCE_DENSITY


def _add_trimesh(node: Node, m: ode.dMass, warn: Warn, scale: Scale) -> bool:
    """``dMassSetTrimesh`` at the reference density into ``m``. False (Webots' 1 kg fallback) for an
    IndexedFaceSet without triangles, or, with one warning naming the node, a Mesh whose file cannot be read
    and a mesh whose triangles enclose no volume."""
    lib = ode.load()
    try:
        built = trimesh_data(node, scale)
    except MeshFileError as exc:
        warn(mesh_warning(exc))
        return False
    if built is None:
        return False
    tmp = lib.dCreateTriMesh(None, built[0], None, None, None)
    lib.dMassSetTrimesh(byref(m), REFERENCE_DENSITY, tmp)
    lib.dGeomDestroy(tmp)
    lib.dGeomTriMeshDataDestroy(built[0])
    if m.mass > 0 and math.isfinite(m.mass):
        return True
    where = str(node.location) if node.location is not None else node.type_name
    warn(f"{where}: {node.type_name} encloses no volume (ODE's trimesh mass at density 1000 is {m.mass:g} kg: "
         "a flat, open or inside-out mesh); Webots' fallback mass used (1 kg, identity inertia)")
    return False


def solid_mass(solid: Node, name: str, warn: Warn, scale: float = 1.0) -> tuple[ode.dMass, float]:
    """§3.2: the ODE mass of one Solid with Physics, in the Solid's own frame, and its boundingObject volume.

    ``name`` labels the warnings (``Solid '<name>': ...``). The mass's ``I`` is about the Solid's origin (ODE
    keeps it about the point of reference; ``c`` is the centre of mass), as the twin needs it for merging.
    ``scale`` is the factor of the Transforms above the Solid (the module docstring): the Solid's frame is that
    many times larger than its fields say, and so is its mass distribution.
    """
    m, volume = _unscaled_solid_mass(solid, name, warn)
    if scale != 1.0:
        magnify(m, scale)
        volume *= scale**3
    return m, volume


def magnify(m: ode.dMass, s: float) -> None:
    """Scale an ODE mass distribution about its point of reference by ``s`` in every direction: mass × s³,
    centre of mass × s and inertia (about the point of reference) × s⁵ (§3.2; a length² per unit mass)."""
    m.mass *= s**3
    for k in range(3):
        m.c[k] *= s
    for k in range(12):
        m.I[k] *= s**5


def _unscaled_solid_mass(solid: Node, name: str, warn: Warn) -> tuple[ode.dMass, float]:
    """:func:`solid_mass` at scale 1."""
    lib = ode.load()
    phys: Node = solid.fields["physics"]
    density = float(_f(phys, "density", 1000.0))
    mass = float(_f(phys, "mass", -1.0))
    com_list = list(_f(phys, "centerOfMass", []) or [])
    inertia = list(_f(phys, "inertiaMatrix", []) or [])
    bo = solid.fields.get("boundingObject")
    m = mass_zero()
    ref = mass_zero()
    volume = 0.0
    if isinstance(bo, Node):
        volume = bounding_mass(bo, ref, warn)
    com = tuple(float(v) for v in com_list[0]) if com_list else None
    if mass > 0 and density > 0 and density != 1000.0 and not inertia:
        warn(f"Solid '{name}': both mass and density given, density ignored")
    if inertia:
        i1 = [float(v) for v in inertia[0]] if len(inertia) > 0 else []
        i2 = [float(v) for v in inertia[1]] if len(inertia) > 1 else [0.0, 0.0, 0.0]
        full = (i1 + [0.0] * 3)[:3]
        mat = (full[0], i2[0], i2[1], i2[0], full[1], i2[2], i2[1], i2[2], full[2])
        if mass > 0 and com is not None and len(inertia) == 2 and m3.is_positive_definite3(mat):
            lib.dMassSetParameters(byref(m), mass, 0.0, 0.0, 0.0, full[0], full[1], full[2], i2[0], i2[1], i2[2])
            lib.dMassTranslate(byref(m), *com)
            return m, volume
        warn(f"Solid '{name}': invalid inertiaMatrix ignored")
    if mass <= 0 and density <= 0:
        warn(f"Solid '{name}': Physics has neither mass nor density; using 1 kg")
        mass = 1.0
    if ref.mass > 0:
        ctypes.memmove(byref(m), byref(ref), ctypes.sizeof(ode.dMass))
        if mass > 0:
            lib.dMassAdjust(byref(m), mass)
        elif density != 1000.0:
            lib.dMassAdjust(byref(m), m.mass * density / 1000.0)
        if com is not None:
            lib.dMassTranslate(byref(m), com[0] - m.c[0], com[1] - m.c[1], com[2] - m.c[2])
        return m, volume
    # no boundingObject: identity inertia (§3.2, WbSolid.setDefaultMassSettings)
    total = mass if mass > 0 else density / 1000.0
    inert = 1.0 if mass > 0 else density / 1000.0
    lib.dMassSetParameters(byref(m), total, 0.0, 0.0, 0.0, inert, inert, inert, 0.0, 0.0, 0.0)
    if com is not None:
        lib.dMassTranslate(byref(m), *com)
    if not isinstance(bo, Node):
        warn(f"Solid '{name}' has Physics but no boundingObject: identity inertia")
    return m, volume


@dataclass(frozen=True)
class SolidInertial:
    """One Solid's mass in its own frame: total mass, centre of mass, and the row-major 3×3 inertia about it."""

    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, ...]


def solid_inertial(solid: Node, name: str, warn: Warn, scale: float = 1.0) -> SolidInertial | None:
    """:func:`solid_mass` expressed about the centre of mass (None for a Solid without Physics).

    The ODE mass is moved by ``-com`` with ``dMassTranslate``, the same call the twin makes when it centres a
    body on its centre of mass, so the inertia is the twin's to the last bit for single-Solid bodies.
    """
    if solid.fields.get("physics") is None:
        return None
    ode.ensure_thread()
    lib = ode.load()
    m, _ = solid_mass(solid, name, warn, scale)
    com = (float(m.c[0]), float(m.c[1]), float(m.c[2]))
    lib.dMassTranslate(byref(m), -com[0], -com[1], -com[2])
    inertia = tuple(float(m.I[k]) for k in (0, 1, 2, 4, 5, 6, 8, 9, 10))
    return SolidInertial(float(m.mass), com, inertia)
