"""A TouchSensor's site in a converted model: the volume MuJoCo's ``touch`` sensor counts contacts in.

Webots' TouchSensor senses every contact of its own boundingObject (webots-devices §2.3: the bumper flag is set
whenever one of the sensor's geoms collides, the force types read the sensor's own body). MuJoCo's ``touch`` sums
the normal forces of the contacts whose point lies *inside its site's volume* (and involves a geom of the site's
body), and a contact point lies on the geoms' surfaces, so the site must cover the sensor's boundingObject: it is
the box enclosing the boundingObject's primitives in the sensor's frame, grown by :data:`TOUCH_MARGIN` on every
side (a contact point is the middle of the penetration, just outside either surface). A TouchSensor without a
boundingObject keeps a 2 cm sphere at its origin (it touches nothing in Webots either); one with a geometry whose
extent is not computed here (a mesh, an elevation grid) too, with a warning.

What MuJoCo's ``touch`` reads is the sum of those normal forces, in newtons, whatever their direction; the
conversion notes how each Webots ``type`` differs (§2.3): a bumper reads 1 while touched, ``force`` reads only the
push along the sensor's −x that its fixed joint passes on to its parent (0 for a push along any other axis, and
without the sensor body's own weight), ``force-3d`` that joint force as a vector in the sensor frame.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from dualtwin.convert.mass import FloatArray, bounding_primitives, round_scale
from dualtwin.webots.nodes import Node

__all__ = ["TOUCH_MARGIN", "touch_site_notes", "touch_site_volume"]

#: Metres added on every side of the enclosing box (contact points sit up to half a penetration outside).
TOUCH_MARGIN = 0.005
#: The site of a TouchSensor without a boundingObject: a sphere of this radius at its origin.
DEFAULT_RADIUS = 0.02


def _half_extents(geometry: Node, scale: FloatArray) -> np.ndarray | None:
    kind = geometry.type_name
    if kind == "Box":
        return np.asarray(geometry["size"], dtype=float) * scale / 2.0
    if kind == "Sphere":
        return np.full(3, float(geometry["radius"]) * round_scale(scale))
    if kind in ("Cylinder", "Capsule"):  # axis along z (R2022a+); a Capsule's height is its cylindrical part
        r, h = float(geometry["radius"]) * round_scale(scale), float(geometry["height"]) * round_scale(scale)
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


#: What a TouchSensor ``type`` reads in Webots (webots-devices §2.3) where MuJoCo's touch reads the normal force.
_TYPE_NOTES = {
    "bumper": "a Webots bumper reads 1 while touched and 0 otherwise",
    "force": ("a Webots force sensor reads only the push along its -x that its fixed joint passes on to its parent "
              "(0 for pushes along its other axes; its own body's weight not included)"),
    "force-3d": "a Webots force-3d sensor reads its fixed joint's force on its parent as a vector in its own frame",
}


def touch_site_notes(site: Any, solid: Node, scale: float) -> list[str]:
    """Shape the TouchSensor's site (:func:`touch_site_volume`) and say what of its reading MuJoCo's touch differs in.

    An unknown ``type`` is a bumper, as in Webots.
    """
    notes = [note] if (note := touch_site_volume(site, solid, scale)) is not None else []
    kind = str(solid.get("type", "bumper"))
    notes.append(f"touch sensor {solid.get('name')!r}: MuJoCo's touch reads the total normal force (N) of the "
                 f"contacts in its site, {_TYPE_NOTES.get(kind, _TYPE_NOTES['bumper'])}")
    return notes
