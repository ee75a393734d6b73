"""What a Shape looks like: its colour and, for an IndexedFaceSet, its triangles.

Pure functions on parsed scene nodes, shared by the Webots runtime's renderer (:mod:`.visual_scene`, which
draws ``Camera`` images), the converter (``dualtwin.convert``, which re-exports them) and perception, so a
Shape gets one colour and one triangulation everywhere.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from dualtwin.webots.nodes import Node

__all__ = ["appearance_rgba", "indexed_face_set_mesh"]


def appearance_rgba(shape: Any) -> list[float] | None:
    """A Shape's colour and opacity (PBR ``baseColor`` or Material ``diffuseColor``), None without either."""
    appearance = shape.get("appearance")
    if appearance is None:
        return None
    if appearance.type_name == "PBRAppearance":
        r, g, b = appearance.get("baseColor", (1.0, 1.0, 1.0))
        return [float(r), float(g), float(b), 1.0 - float(appearance.get("transparency", 0.0))]
    material = appearance.get("material")
    if material is not None:
        r, g, b = material.get("diffuseColor", (0.8, 0.8, 0.8))
        return [float(r), float(g), float(b), 1.0 - float(material.get("transparency", 0.0))]
    return None


def indexed_face_set_mesh(node: Node, scale: float = 1.0) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Vertices and fan-triangulated faces of an IndexedFaceSet (``-1`` ends a polygon; ``ccw FALSE`` flips)."""
    coord = node.get("coord")
    points = np.asarray(coord.get("point", []) if coord is not None else [], dtype=float).reshape(-1, 3) * scale
    faces: list[tuple[int, int, int]] = []
    polygon: list[int] = []
    for index in [*node.get("coordIndex", []), -1]:
        if index >= 0:
            polygon.append(int(index))
            continue
        for k in range(1, len(polygon) - 1):
            faces.append((polygon[0], polygon[k], polygon[k + 1]))
        polygon = []
    tri = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not node.get("ccw", True):
        tri = tri[:, ::-1].copy()
    if len(tri) and (tri.max() >= len(points)):
        raise ValueError(f"coordIndex refers to point {int(tri.max())} but coord has {len(points)} points")
    return points, tri
