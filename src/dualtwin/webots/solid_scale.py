"""A Transform's ``scale`` above Solids and joints: the one factor by which it magnifies what it holds.

Webots R2023b's Transform is a Pose with a ``scale`` (webots-on-ode.md §3.1), and a Solid below a scaled
Transform is scaled with it: "with a scaled Transform ancestor, sizes scale, mass ∝ s³ and inertia ∝ s⁵" (§3.2)
and "geometries inside a scaled Transform use scaled dimensions" (§3.4). A Solid's world frame is the product of
its ancestors' matrices (§3.1), so the translations of every frame below the Transform (Solids, Poses, joints'
anchors, devices) are multiplied by the scale, while rotations are not; a Solid's ODE body is placed in the
rigid part of that frame (its rotation and its scaled position).

What the reference does not say, decided here:

* A Solid's mass distribution is magnified as a whole, whatever defines it (boundingObject, ``mass``,
  ``inertiaMatrix``, ``centerOfMass``): mass × s³, centre of mass × s, inertia × s⁵ (§3.2's rule taken for every
  mass mode, :func:`dualtwin.webots.mass_rules.solid_mass`). With a density this is what the scaled geometry
  weighs; a given ``mass`` is scaled too.
* One factor: an ODE body is rigid (a mass and an inertia tensor) and a per-axis scale would shear the frames
  below any rotated Solid, which no ODE body or joint can follow. A non-uniform scale above a Solid or joint
  therefore acts as its largest factor (the factor the round primitives of a boundingObject already take in a
  non-uniform Transform), with a warning. A non-uniform scale above Shapes alone is only drawn.
* A zero or negative component is reset to 1 with a warning (Webots' Transform accepts non-zero scales only; a
  negative one would mirror the frame, which a rotation matrix cannot).
* Sensor specifications (a DistanceSensor's lookupTable and ray length, a Lidar's range, a camera's clipping) are
  not scaled: they are properties of the device, not sizes of its frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from dualtwin.webots._math3 import Pose
from dualtwin.webots.nodes import Node

__all__ = ["body_factor", "holds_bodies", "positive_scale", "scaled_local", "transform_factor"]

JOINTS = frozenset({"HingeJoint", "SliderJoint", "Hinge2Joint", "BallJoint"})


def holds_bodies(node: Node) -> bool:
    """Whether ``node``'s subtree holds a Solid (a node with a boundingObject and physics field) or a joint."""
    return any(n.type_name in JOINTS or ("boundingObject" in n.fields and "physics" in n.fields)
               for n in node.walk())


def transform_factor(node: Node, warn: Callable[[str], None]) -> float:
    """The factor a Transform scales the frames, Solids and joints below it by (1 for a Pose; the module
    docstring): its positive ``scale``, a non-positive component reset to 1 and a non-uniform scale above a Solid
    or joint taken as its largest component, each with one warning line."""
    if node.type_name != "Transform":
        return 1.0
    return body_factor(node, positive_scale(node, warn), warn)


def body_factor(node: Node, scale: tuple[float, float, float], warn: Callable[[str], None]) -> float:
    """The one factor the Transform ``node`` with the positive ``scale`` magnifies Solids and joints by: its largest
    component, with one warning line when the scale is not uniform and the Transform holds a Solid or joint (the
    converter takes the same, so the twins agree)."""
    largest = max(scale)
    if min(scale) != largest and holds_bodies(node):
        warn(f"{_where(node)}Transform scale {_text(node)} is not uniform above a Solid or joint: scaled by its "
             f"largest factor {largest:g} (a rigid body cannot be sheared)")
    return largest


def positive_scale(node: Node, warn: Callable[[str], None]) -> tuple[float, float, float]:
    """A Transform's ``scale`` with each zero, negative or non-finite component reset to 1, with one warning line
    when one was (the module docstring; the converter applies the same rule)."""
    given = tuple(float(v) for v in node.fields.get("scale") or (1.0, 1.0, 1.0))
    x, y, z = (v if v > 0 and math.isfinite(v) else 1.0 for v in given)
    if (x, y, z) != given:
        warn(f"{_where(node)}Transform scale {_text(node)}: a scale component must be positive; reset to 1")
    return x, y, z


def _where(node: Node) -> str:
    return f"{node.location}: " if node.location is not None else ""


def _text(node: Node) -> str:
    return " ".join(f"{float(v):g}" for v in node.fields.get("scale") or ())


def scaled_local(node: Node, factor: float) -> Pose:
    """``node``'s translation and rotation as a rigid pose in a frame scaled by ``factor``: the translation is
    multiplied by it, the rotation kept (§3.1: the world frame is the product of the ancestors' matrices)."""
    translation = node.fields.get("translation")
    if translation is not None and factor != 1.0:
        translation = tuple(float(v) * factor for v in translation)
    return Pose.from_fields(translation, node.fields.get("rotation"))
