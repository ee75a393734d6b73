"""Webots' mass rules (docs/reference/webots-on-ode.md §3.2), reproduced so a converted body weighs what ODE's body weighs.

MuJoCo would derive inertia from geoms with its own conventions (every geom, visual ones included, at its
own density). Webots instead sums the ODE masses of the *boundingObject* primitives at a reference density of
1000 kg/m³ (Pose rotations and translations applied, overlaps counted twice), then rescales to ``mass`` or
``density``, moves the centre of mass to ``centerOfMass`` and falls back to an identity inertia when there
is no boundingObject. The converter writes the result as an explicit ``inertial`` (mass, pos, fullinertia).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from dualtwin.webots.nodes import Node
from dualtwin.webots.shapes import indexed_face_set_mesh  # noqa: F401 - re-exported for the converter

FloatArray = npt.NDArray[np.float64]

#: ODE's reference density for boundingObject primitives (Webots WbSolidUtilities::addMass).
REFERENCE_DENSITY = 1000.0


@dataclass
class MassProps:
    """A rigid mass distribution: total mass, centre of mass and inertia about the CoM (frame axes)."""

    mass: float
    com: FloatArray
    inertia: FloatArray  # 3x3 about the CoM

    @staticmethod
    def point(mass: float, com: Sequence[float], inertia: FloatArray | None = None) -> MassProps:
        return MassProps(float(mass), np.asarray(com, dtype=float).copy(),
                         np.eye(3) if inertia is None else np.asarray(inertia, dtype=float).copy())

    def transformed(self, rotation: FloatArray, translation: Sequence[float] | FloatArray) -> MassProps:
        """The same body seen from a parent frame (ODE dMassRotate then dMassTranslate)."""
        return MassProps(self.mass, rotation @ self.com + np.asarray(translation, dtype=float),
                         rotation @ self.inertia @ rotation.T)

    def scaled(self, factor: float) -> MassProps:
        """Same shape, denser material (ODE dMassAdjust): mass and inertia scale together."""
        return MassProps(self.mass * factor, self.com.copy(), self.inertia * factor)

    def moved_to(self, com: Sequence[float]) -> MassProps:
        """Rigidly translate the distribution so its CoM sits at ``com`` (inertia about the CoM unchanged)."""
        return MassProps(self.mass, np.asarray(com, dtype=float).copy(), self.inertia.copy())

    def full_inertia(self) -> list[float]:
        """MuJoCo ``fullinertia`` order: Ixx Iyy Izz Ixy Ixz Iyz."""
        i = self.inertia
        return [float(i[0, 0]), float(i[1, 1]), float(i[2, 2]), float(i[0, 1]), float(i[0, 2]), float(i[1, 2])]


def combine(parts: Sequence[MassProps]) -> MassProps | None:
    """Sum of distributions in one frame (ODE dMassAdd): parallel-axis theorem about the common CoM."""
    total = sum(p.mass for p in parts)
    if not parts or total <= 0.0:
        return None
    com = sum((p.mass * p.com for p in parts), np.zeros(3)) / total
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com - com
        inertia += p.inertia + p.mass * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return MassProps(total, com, inertia)


# ------------------------------------------------------------------------------------------------
# primitives (ODE dMassSet* formulas)


def box_mass(size: Sequence[float], density: float = REFERENCE_DENSITY) -> MassProps:
    """``size`` = full extents (Webots and ODE both use full lengths)."""
    sx, sy, sz = (float(v) for v in size)
    m = density * sx * sy * sz
    return MassProps.point(m, (0, 0, 0), np.diag([m * (sy * sy + sz * sz) / 12, m * (sx * sx + sz * sz) / 12,
                                                  m * (sx * sx + sy * sy) / 12]))


def sphere_mass(radius: float, density: float = REFERENCE_DENSITY) -> MassProps:
    m = density * 4.0 / 3.0 * math.pi * radius ** 3
    return MassProps.point(m, (0, 0, 0), np.eye(3) * 0.4 * m * radius * radius)


def cylinder_mass(radius: float, height: float, density: float = REFERENCE_DENSITY) -> MassProps:
    """Axis z (ODE direction 3, as Webots R2022a+ Cylinder)."""
    m = density * math.pi * radius * radius * height
    side = m * (0.25 * radius * radius + height * height / 12.0)
    return MassProps.point(m, (0, 0, 0), np.diag([side, side, 0.5 * m * radius * radius]))


def capsule_mass(radius: float, height: float, density: float = REFERENCE_DENSITY) -> MassProps:
    """``height`` = length of the cylindrical part (ODE dMassSetCapsule, axis z)."""
    m1 = math.pi * radius * radius * height * density
    m2 = 4.0 / 3.0 * math.pi * radius ** 3 * density
    ia = m1 * (0.25 * radius * radius + height * height / 12.0) + m2 * (
        0.4 * radius * radius + 0.375 * radius * height + 0.25 * height * height)
    ib = (0.5 * m1 + 0.4 * m2) * radius * radius
    return MassProps.point(m1 + m2, (0, 0, 0), np.diag([ia, ia, ib]))


def trimesh_mass(vertices: FloatArray, faces: npt.NDArray[np.int64],
                 density: float = REFERENCE_DENSITY) -> MassProps | None:
    """Closed triangle mesh by signed tetrahedra from the origin (what dMassSetTrimesh integrates).

    Returns None when the enclosed volume is not positive (open or inverted mesh): Webots then uses 1 kg.
    """
    if len(faces) == 0:
        return None
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    vol6 = np.einsum("ij,ij->i", a, np.cross(b, c))
    volume = float(vol6.sum()) / 6.0
    if volume <= 1e-12:
        return None
    com = ((a + b + c) * vol6[:, None]).sum(axis=0) / (4.0 * vol6.sum())
    # Second moments of each tetrahedron (origin, a, b, c): ∫ x_i x_j dV = V/20 (Σ p_i p_j + s_i s_j).
    s = a + b + c
    cov = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            cov[i, j] = float(((vol6 / 6.0) / 20.0 * (a[:, i] * a[:, j] + b[:, i] * b[:, j] + c[:, i] * c[:, j]
                                                      + s[:, i] * s[:, j])).sum())
    mass = density * volume
    cov *= density
    inertia_origin = np.trace(cov) * np.eye(3) - cov
    d = com
    inertia = inertia_origin - mass * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return MassProps(mass, com, inertia)


# ------------------------------------------------------------------------------------------------
# boundingObject traversal


@dataclass
class Primitive:
    """One geometry of a boundingObject with its pose in the Solid frame."""

    geometry: Node
    rotation: FloatArray
    translation: FloatArray
    scale: float = 1.0


def rotation_matrix(rotation: Sequence[float]) -> FloatArray:
    """Webots SFRotation (axis x y z, angle rad; axis normalised as ODE does) -> 3x3 matrix."""
    x, y, z, angle = (float(v) for v in rotation)
    n = math.sqrt(x * x + y * y + z * z)
    if n < 1e-12 or angle == 0.0:
        return np.eye(3)
    x, y, z = x / n, y / n, z / n
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array([
        [x * x * C + c, x * y * C - z * s, x * z * C + y * s],
        [y * x * C + z * s, y * y * C + c, y * z * C - x * s],
        [z * x * C - y * s, z * y * C + x * s, z * z * C + c],
    ])


def bounding_primitives(node: Node | None, rotation: FloatArray | None = None,
                        translation: FloatArray | None = None, scale: float = 1.0) -> Iterator[Primitive]:
    """Geometries of a boundingObject: a geometry, a Shape, a Pose/Transform (one child) or a Group."""
    if node is None:
        return
    R = np.eye(3) if rotation is None else rotation
    t = np.zeros(3) if translation is None else translation
    kind = node.type_name
    if kind == "Shape":
        yield from bounding_primitives(node.get("geometry"), R, t, scale)
    elif kind in ("Pose", "Transform"):
        local_scale = scale
        if kind == "Transform":
            sx, sy, sz = node.get("scale", (1.0, 1.0, 1.0))
            local_scale = scale * float(sx)  # non-uniform scales are rejected by the converter
        R2 = R @ rotation_matrix(node.get("rotation", (0, 0, 1, 0)))
        t2 = t + R @ (np.asarray(node.get("translation", (0, 0, 0)), dtype=float) * scale)
        for child in node.children():
            yield from bounding_primitives(child, R2, t2, local_scale)
    elif kind == "Group":
        for child in node.children():
            yield from bounding_primitives(child, R, t, scale)
    else:
        yield Primitive(node, R, t, scale)


def primitive_mass(prim: Primitive) -> tuple[MassProps | None, str | None]:
    """ODE mass of one primitive at the reference density in the Solid frame, and a warning if any.

    Invalid or zero-size primitives count as 1 kg with identity inertia, as in Webots; Plane and
    ElevationGrid contribute nothing.
    """
    g = prim.geometry
    s = prim.scale
    kind = g.type_name
    warning = None
    local: MassProps | None
    if kind == "Box":
        size = [float(v) * s for v in g.get("size")]
        local = box_mass(size) if min(size) > 0 else None
    elif kind == "Sphere":
        r = float(g.get("radius")) * s
        local = sphere_mass(r) if r > 0 else None
    elif kind == "Cylinder":
        r, h = float(g.get("radius")) * s, float(g.get("height")) * s
        local = cylinder_mass(r, h) if r > 0 and h > 0 else None
    elif kind == "Capsule":
        r, h = float(g.get("radius")) * s, float(g.get("height")) * s
        local = capsule_mass(r, h) if r > 0 and h >= 0 else None
    elif kind == "IndexedFaceSet":
        points, faces = indexed_face_set_mesh(g, s)
        local = trimesh_mass(points, faces)
        if local is None:
            warning = "IndexedFaceSet encloses no positive volume: Webots counts it as 1 kg"
    elif kind in ("Plane", "ElevationGrid"):
        return None, f"{kind} in a boundingObject adds no mass"
    else:
        return None, None
    if local is None:
        warning = warning or f"{kind} has a zero or negative size: Webots counts it as 1 kg"
        local = MassProps.point(1.0, (0, 0, 0))
    return local.transformed(prim.rotation, prim.translation), warning


def _valid_inertia(values: Sequence[Sequence[float]]) -> FloatArray | None:
    if len(values) != 2:
        return None
    (i11, i22, i33), (i12, i13, i23) = values
    inertia = np.array([[i11, i12, i13], [i12, i22, i23], [i13, i23, i33]], dtype=float)
    if min(i11, i22, i33) <= 0:
        return None
    if np.linalg.eigvalsh(inertia).min() <= 0:
        return None
    return inertia


def solid_mass(solid: Node, *, scale: float = 1.0) -> tuple[MassProps | None, list[str]]:
    """The ODE mass of one Solid in its own frame (None without Physics) and the warnings Webots prints."""
    physics = solid.get("physics")
    if physics is None:
        return None, []
    warnings: list[str] = []
    mass = float(physics.get("mass", -1.0))
    density = float(physics.get("density", 1000.0))
    com = physics.get("centerOfMass") or []
    inertia_fields = physics.get("inertiaMatrix") or []
    custom = _valid_inertia(inertia_fields)
    if inertia_fields and custom is None:
        warnings.append("inertiaMatrix is not positive definite: ignored (Webots falls back to the boundingObject)")
    if mass > 0 and len(com) == 1 and custom is not None:
        return MassProps.point(mass, com[0], custom), warnings
    if mass > 0 and density > 0 and density != 1000.0:
        warnings.append("both mass and density are given: density is ignored")
    parts: list[MassProps] = []
    for prim in bounding_primitives(solid.get("boundingObject"), scale=scale):
        props, warning = primitive_mass(prim)
        if warning:
            warnings.append(warning)
        if props is not None:
            parts.append(props)
    total = combine(parts)
    if total is not None:
        if mass > 0:
            total = total.scaled(mass / total.mass)
        elif density > 0:
            total = total.scaled(density / REFERENCE_DENSITY)
        else:
            warnings.append("Physics has neither a positive mass nor a positive density: mass left at density 1000")
        if len(com) == 1:
            total = total.moved_to(com[0])
        return total, warnings
    # No usable boundingObject: Webots prints a warning and uses an identity inertia.
    if mass > 0:
        m, inertia = mass, np.eye(3)
    else:
        m = density / REFERENCE_DENSITY if density > 0 else 1.0
        inertia = np.eye(3) * m
    warnings.append("Physics without a boundingObject: Webots uses an identity inertia matrix")
    return MassProps.point(m, com[0] if len(com) == 1 else (0, 0, 0), inertia), warnings
