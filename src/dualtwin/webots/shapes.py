"""What a Shape looks like: its colour and, for a geometry made of triangles, its triangles.

Functions on parsed scene nodes, shared by the Webots runtime's renderer (:mod:`.visual_scene`, which draws
``Camera`` images), its visual rays (:mod:`.visual_rays`: Lidar, RangeFinder, infra-red DistanceSensor), the
converter (``dualtwin.convert``, which re-exports them) and perception, so a Shape gets one colour and one
triangulation everywhere.

Surfaces made of triangles (:data:`SURFACE_NODES`, read by :func:`surface_triangles`): an ``IndexedFaceSet``
(its faces), a ``Mesh`` (its file's meshes as :func:`~dualtwin.webots.mesh_files.read_mesh_node` merges them)
and a ``CadShape``, a Shape-like node whose geometry is every mesh of its file (its ``ccw`` honoured). A
``CadShape`` is drawn in :data:`CAD_SHAPE_RGBA`: the materials of its file are not read.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from dualtwin.webots.mesh_files import read_mesh_node
from dualtwin.webots.nodes import Node
from dualtwin.webots.polygons import triangulate_polygon

__all__ = ["CAD_SHAPE_RGBA", "SURFACE_NODES", "appearance_rgba", "indexed_face_set_mesh", "surface_triangles"]

#: Nodes whose surface is a set of triangles (:func:`surface_triangles`): two geometries and the CadShape.
SURFACE_NODES = ("IndexedFaceSet", "Mesh", "CadShape")
#: The colour a CadShape is drawn in: Assimp's default material (grey 0.6), what Webots shows for a file
#: without materials. The file's own materials (OBJ ``.mtl``, COLLADA effects) are not read.
CAD_SHAPE_RGBA = (0.6, 0.6, 0.6, 1.0)


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
    """Vertices and triangulated faces of an IndexedFaceSet (``-1`` ends a polygon; ``ccw FALSE`` flips): each face
    cut into triangles that cover it (:func:`~dualtwin.webots.polygons.triangulate_polygon`: a concave face too).

    A polygon that names a point ``coord`` does not have is left out (the rest of the surface stays), so the
    collision geometry, the mass, the rays and the drawn shape all see the same triangles."""
    coord = node.get("coord")
    points = np.asarray(coord.get("point", []) if coord is not None else [], dtype=float).reshape(-1, 3) * scale
    faces: list[tuple[int, int, int]] = []
    polygon: list[int] = []
    for index in [*node.get("coordIndex", []), -1]:
        if index >= 0:
            polygon.append(int(index))
            continue
        if all(i < len(points) for i in polygon):
            faces.extend(triangulate_polygon(points, polygon))
        polygon = []
    tri = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not node.get("ccw", True):
        tri = tri[:, ::-1].copy()
    return points, tri


def surface_triangles(node: Node) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Vertices (n, 3) in the node's frame, unscaled, and triangles (m, 3) of a node of :data:`SURFACE_NODES`:
    an IndexedFaceSet's triangulated faces, a Mesh's file by its ``name``, ``materialIndex`` and ``ccw``,
    or every mesh of a CadShape's file (its ``ccw`` honoured).

    Raises:
        ValueError: the node is of another type.
        MeshFileError: a Mesh's or CadShape's file cannot be located or read (a one-line message with the node's
            location; a :class:`ValueError` too).
    """
    kind = node.type_name
    if kind == "IndexedFaceSet":
        return indexed_face_set_mesh(node)
    if kind not in ("Mesh", "CadShape"):
        raise ValueError(f"{kind} is not a surface of triangles")
    mesh = read_mesh_node(node)  # a CadShape's fields are a Mesh's without name and materialIndex: its whole file
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.triangles, dtype=np.int64)
