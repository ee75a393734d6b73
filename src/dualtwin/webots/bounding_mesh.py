"""Triangle-mesh bounding geometries, ``IndexedFaceSet`` and ``Mesh``, as ODE triangle mesh data: one path for
both, used by the collision geoms, the mass rules and the supervisor's geometry edits.

Webots makes an ODE triangle mesh (``dCreateTriMesh`` on ``dGeomTriMeshDataBuildDouble`` data) of both: of an
IndexedFaceSet's ``coordIndex`` polygons (:func:`dualtwin.webots.shapes.indexed_face_set_mesh`: triangulated,
``ccw`` honoured, a polygon naming a point that does not exist left out), and of the
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
from dualtwin.webots.shapes import indexed_face_set_mesh

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
        vertices, triangles = indexed_face_set_mesh(node)  # the triangles the rays and the camera see
        if len(vertices) == 0 or len(triangles) == 0:
            return None
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
