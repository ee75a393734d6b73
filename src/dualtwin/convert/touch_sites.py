"""A TouchSensor's site in a converted model: the volume MuJoCo's ``touch`` sensor counts contacts in.

Webots' TouchSensor senses every contact of its own boundingObject (webots-devices §2.3: the bumper flag is set
whenever one of the sensor's geoms collides, the force types read the sensor's own body). MuJoCo's ``touch`` sums
the normal forces of the contacts whose point lies *inside its site's volume* (and involves a geom of the site's
body), and a contact point lies on the geoms' surfaces, so the site must cover the sensor's boundingObject: it is
the box enclosing the boundingObject's primitives in the sensor's frame, grown by :data:`TOUCH_MARGIN` on every
side (a contact point is the middle of the penetration, just outside either surface). A TouchSensor without a
boundingObject keeps a 2 cm sphere at its origin (it touches nothing in Webots either); one with a geometry whose
extent is not computed here (a mesh, an elevation grid) too, with a warning.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from dualtwin.convert.mass import bounding_primitives
from dualtwin.webots.nodes import Node

__all__ = ["TOUCH_MARGIN", "touch_site_volume"]

#: Metres added on every side of the enclosing box (contact points sit up to half a penetration outside).
TOUCH_MARGIN = 0.005
#: The site of a TouchSensor without a boundingObject: a sphere of this radius at its origin.
DEFAULT_RADIUS = 0.02


def _half_extents(geometry: Node, scale: float) -> np.ndarray | None:
    kind = geometry.type_name
    if kind == "Box":
        return np.asarray(geometry["size"], dtype=float) * scale / 2.0
    if kind == "Sphere":
        return np.full(3, float(geometry["radius"]) * scale)
    if kind in ("Cylinder", "Capsule"):  # axis along z (R2022a+); a Capsule's height is its cylindrical part
        r, h = float(geometry["radius"]) * scale, float(geometry["height"]) * scale
        return np.array([r, r, h / 2.0 + (r if kind == "Capsule" else 0.0)])
    return None


def touch_site_volume(site: Any, solid: Node, scale: float) -> str | None:
    """Shape ``site`` (at the TouchSensor ``solid``'s pose) to cover its boundingObject; a warning when it cannot."""
    corners = []
    for prim in bounding_primitives(solid.get("boundingObject"), scale=scale):
        half = _half_extents(prim.geometry, prim.scale)
        if half is None:
            site.type, site.size = mujoco.mjtGeom.mjGEOM_SPHERE, [DEFAULT_RADIUS, 0, 0]
            return (f"touch sensor {solid.get('name')!r}: a {prim.geometry.type_name} boundingObject is not covered "
                    f"by its MuJoCo touch site (a {DEFAULT_RADIUS} m sphere at its origin senses the contacts inside)")
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        corners.append((signs * half) @ prim.rotation.T + prim.translation)
    if not corners:
        site.type, site.size = mujoco.mjtGeom.mjGEOM_SPHERE, [DEFAULT_RADIUS, 0, 0]
        return None
    points = np.concatenate(corners)
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2.0
    rotation = np.asarray(site.quat, dtype=float)
    offset = np.zeros(3)
    mujoco.mju_rotVecQuat(offset, centre, rotation)
    site.pos = [float(p + o) for p, o in zip(site.pos, offset, strict=True)]
    site.type = mujoco.mjtGeom.mjGEOM_BOX
    site.size = [float(v) for v in (high - low) / 2.0 + TOUCH_MARGIN]
    return None
