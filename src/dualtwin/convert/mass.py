"""Masses for the MJCF converter: each Solid's mass from Webots' rules, combined into MuJoCo bodies.

MuJoCo would derive inertia from geoms with its own conventions (every geom, visual ones included, at its
own density). The converter instead takes each Solid's mass, centre of mass and inertia from
:mod:`dualtwin.webots.mass_rules`, the one implementation of Webots' rules, which the Webots twin builds its
ODE bodies with too; Solids merged into one MuJoCo body are combined here (parallel-axis theorem) and the
result is written as an explicit ``inertial`` (mass, pos, fullinertia).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from dualtwin.geometry import axis_angle_matrix
from dualtwin.webots.mass_rules import REFERENCE_DENSITY, solid_inertial
from dualtwin.webots.nodes import Node

FloatArray = npt.NDArray[np.float64]

__all__ = ["REFERENCE_DENSITY", "MassProps", "Primitive", "axis_scales", "bounding_primitives", "combine", "round_scale",
           "solid_mass"]


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
# boundingObject traversal


def axis_scales(scale: float | Sequence[float] | FloatArray) -> FloatArray:
    """A scale as its three factors (x, y, z): a uniform one repeated."""
    return np.broadcast_to(np.asarray(scale, dtype=float), (3,)).copy()


@dataclass
class Primitive:
    """One geometry of a boundingObject with its pose in the Solid frame and the scale of the Transforms above it,
    per axis of the geometry's frame (a Box's sizes and a mesh's vertices scale per axis, the round primitives by
    the largest factor: :func:`round_scale`)."""

    geometry: Node
    rotation: FloatArray
    translation: FloatArray
    scale: FloatArray


def round_scale(scale: float | FloatArray) -> float:
    """The factor a Sphere's radius and a Cylinder's or Capsule's radius and height take in a scaled Transform: the
    largest of the three, as our Webots twin builds their ODE geoms and :mod:`dualtwin.webots.mass_rules` their mass
    (on-ODE §3.4 says only that geometries in a scaled Transform use scaled dimensions)."""
    return float(np.max(scale))


def bounding_primitives(node: Node | None, rotation: FloatArray | None = None,
                        translation: FloatArray | None = None,
                        scale: float | FloatArray = 1.0) -> Iterator[Primitive]:
    """Geometries of a boundingObject: a geometry, a Shape, a Pose/Transform (one child) or a Group.

    ``scale`` (uniform, from the Transforms above the Solid, or per axis) times each Transform's own ``scale``, per
    axis, scales the geometries and the translations of the frames below, as in :mod:`dualtwin.webots.mass_rules`
    (whose mass the converter writes) and in our Webots twin's geoms: a non-uniform scale used to be read as its x
    factor alone, so a Box in ``Transform { scale 1 1 3 }`` collided as a third of its height."""
    if node is None:
        return
    R = np.eye(3) if rotation is None else rotation
    t = np.zeros(3) if translation is None else translation
    scales = axis_scales(scale)
    kind = node.type_name
    if kind == "Shape":
        yield from bounding_primitives(node.get("geometry"), R, t, scales)
    elif kind in ("Pose", "Transform"):
        local_scales = scales * axis_scales(node.get("scale", (1.0, 1.0, 1.0))) if kind == "Transform" else scales
        R2 = R @ axis_angle_matrix(node.get("rotation", (0, 0, 1, 0)))
        t2 = t + R @ (np.asarray(node.get("translation", (0, 0, 0)), dtype=float) * scales)
        for child in node.children():
            yield from bounding_primitives(child, R2, t2, local_scales)
    elif kind == "Group":
        for child in node.children():
            yield from bounding_primitives(child, R, t, scales)
    else:
        yield Primitive(node, R, t, scales)


def solid_mass(solid: Node, *, scale: float = 1.0) -> tuple[MassProps | None, list[str]]:
    """The ODE mass of one Solid in its own frame (None without Physics) and the warnings Webots prints.

    ``scale`` is the uniform scale of the Transforms above the Solid (the converter applies it; see
    :mod:`dualtwin.webots.mass_rules`).
    """
    warnings: list[str] = []
    name = str(solid.get("name") or solid.type_name)
    inertial = solid_inertial(solid, name, warnings.append, scale)
    if inertial is None:
        return None, warnings
    inertia = np.array(inertial.inertia, dtype=float).reshape(3, 3)
    moments = np.linalg.eigvalsh(inertia)  # ascending principal moments
    if moments[0] + moments[1] < moments[2]:
        # Webots takes any positive-definite inertiaMatrix (on-ODE §3.2) and ODE simulates it; MuJoCo refuses
        # principal moments that break A + B >= C (no rigid body has them). Only a custom matrix can: bounding-
        # object masses and sums of them are physical. MuJoCo's own repair (balanceinertia) sets them to the mean.
        mean = float(moments.mean())
        warnings.append(f"{name}: inertiaMatrix principal moments {moments[0]:g} {moments[1]:g} {moments[2]:g} break "
                        f"A + B >= C, which MuJoCo requires: converted as {mean:g} about every axis (MuJoCo's "
                        "balanceinertia); Webots (ODE) uses the matrix as given")
        inertia = np.eye(3) * mean
    return MassProps(inertial.mass, np.array(inertial.com, dtype=float), inertia), warnings
