"""Triangle-mesh bounding geometries, ``IndexedFaceSet`` and ``Mesh``, as ODE triangle mesh data: one path for
both, used by the collision geoms, the mass rules and the supervisor's geometry edits.

Webots makes an ODE triangle mesh (``dCreateTriMesh`` on ``dGeomTriMeshDataBuildDouble`` data) of both: of an
IndexedFaceSet's ``coordIndex`` polygons (fan-triangulated; an index past the last point is skipped), and of the
triangles of a Mesh's file as :mod:`dualtwin.webots.mesh_files` reads them (url, ``name``, ``materialIndex`` and
``ccw`` applied). A Transform's ``scale`` above the geometry scales the vertices per axis. A Mesh whose file
cannot be read, or that selects no triangle, raises :class:`~dualtwin.webots.mesh_files.MeshFileError`: it has
no collision geometry and weighs Webots' fallback 1 kg (:func:`mesh_warning` is the line that says so).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from dualtwin.webots import ode
from dualtwin.webots.mesh_files import MeshFileError, read_mesh_node
from dualtwin.webots.nodes import Node

__all__ = ["TRIMESH_TYPES", "bounding_triangles", "mesh_warning", "trimesh_data"]

#: The bounding geometries that become ODE triangle meshes.
TRIMESH_TYPES = ("IndexedFaceSet", "Mesh")

_UNIT = (1.0, 1.0, 1.0)


def bounding_triangles(node: Node, scale: Sequence[float] = _UNIT) -> tuple[np.ndarray, np.ndarray] | None:
    """``(vertices, triangles)`` of an IndexedFaceSet or Mesh node: (n, 3) float64 vertices scaled per axis by
    ``scale``, (m, 3) uint32 vertex indices. None for an IndexedFaceSet without a triangle.

    Raises:
        MeshFileError: a Mesh whose file cannot be read or holds no triangle (the message names the node).
    """
    if node.type_name == "Mesh":
        mesh = read_mesh_node(node)
        vertices, triangles = mesh.vertices, mesh.triangles
        if len(triangles) == 0:
            where = str(node.location) if node.location is not None else "Mesh"
            raise MeshFileError(f"{where}: the mesh has no triangles")
    else:
        coord = node.fields.get("coord")
        points = list(coord.fields.get("point") or []) if isinstance(coord, Node) else []
        tris: list[int] = []
        face: list[int] = []
        for i in [*(int(i) for i in (node.fields.get("coordIndex") or [])), -1]:
            if i < 0:
                for k in range(1, len(face) - 1):  # fan triangulation
                    tris.extend((face[0], face[k], face[k + 1]))
                face = []
            elif i < len(points):
                face.append(i)
        if not points or not tris:
            return None
        vertices = np.array([[float(v) for v in p] for p in points], dtype=np.float64).reshape(-1, 3)
        triangles = np.array(tris, dtype=np.int64).reshape(-1, 3)
    if tuple(scale) != _UNIT:
        vertices = vertices * np.asarray(scale, dtype=np.float64)
    return np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(triangles, dtype=np.uint32)


def trimesh_data(node: Node, scale: Sequence[float] = _UNIT) -> tuple[Any, ...] | None:
    """An IndexedFaceSet or Mesh as ODE trimesh data (:func:`bounding_triangles`, :func:`.ode.build_trimesh_data`).

    Returns ``(data, vertices, indices)`` (the arrays must outlive the data) or None without triangles.

    Raises:
        MeshFileError: a Mesh whose file cannot be read or holds no triangle.
    """
    built = bounding_triangles(node, scale)
    return None if built is None else ode.build_trimesh_data(*built)


def mesh_warning(error: MeshFileError) -> str:
    """The one line that says a bounding Mesh could not be made (the error names the node and why) and what
    Webots does instead; the geom build and the mass rules give the same line, so it can be given once."""
    return (f"{error}; this bounding Mesh has no collision geometry and, in a Solid with Physics, weighs Webots' "
            "fallback 1 kg with an identity inertia")
