"""Geometries made of triangles in the MJCF converter: IndexedFaceSet, Mesh and CadShape as MuJoCo meshes.

The triangles are those the Webots twin collides, casts rays against and draws
(:func:`dualtwin.webots.shapes.surface_triangles`): an IndexedFaceSet's faces, a ``Mesh`` node's file (STL,
OBJ, COLLADA, read by :mod:`dualtwin.webots.mesh_files` with its ``name``, ``materialIndex`` and ``ccw``), a
``CadShape``'s whole file. They become an MjSpec mesh asset from arrays (``uservert``/``userface``): no file is
written, so a converted model stands alone and the same world gives the same bytes.

* **Masses** do not come from the mesh asset: every body's inertial is explicit, from
  :mod:`dualtwin.webots.mass_rules` (ODE's ``dMassSetTrimesh`` at the Solid's density, as Webots and the twin
  compute it). For a closed mesh centred on its file's origin that is MuJoCo's own volume inertia of the mesh
  (and a Box's, for a box); for a mesh centred elsewhere ODE's function gives more, by the parallel-axis term
  from the file's origin to the mesh's centre, and the converter keeps the twin's value. The asset's own
  inertia is set to ``shell``, which MuJoCo accepts for open and flat meshes too.
* **Collisions**: MuJoCo collides a mesh through its convex hull where ODE collides the triangles; each such
  boundingObject says so in one warning line.
* **A mesh file that cannot be read** (missing, outside the project, malformed): in a boundingObject the
  conversion stops with that one line (a body without its collision shape, or with a wrong mass, would be
  silently wrong); a visual Mesh or CadShape is skipped with one warning line naming its place.
* A ``CadShape`` is drawn in :data:`dualtwin.webots.shapes.CAD_SHAPE_RGBA` (its file's materials are not read)
  and cannot be a boundingObject (nor is it one in Webots).
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco

from dualtwin.convert.conversion import ConversionError
from dualtwin.convert.mass import FloatArray
from dualtwin.webots.mesh_files import MeshFileError
from dualtwin.webots.nodes import Node
from dualtwin.webots.shapes import surface_triangles

__all__ = ["add_surface_mesh"]


def _where(node: Node) -> str:
    return str(node.location) if node.location is not None else "<unknown location>"


def add_surface_mesh(spec: mujoco.MjSpec, geometry: Node, scale: float | FloatArray, name: Callable[[], str], *,
                     collision: bool, warn: Callable[[str, Node | None], None]) -> str | None:
    """Add the mesh asset of ``geometry`` (IndexedFaceSet, Mesh or CadShape, its vertices scaled by ``scale``,
    per axis or uniform) to ``spec`` and return its name (``name()`` is called only for a mesh that is added);
    None when it is skipped (``warn`` tells why). See the module's text for the rules.

    Raises:
        ConversionError: a CadShape or an unreadable mesh file in a boundingObject.
    """
    kind = geometry.type_name
    if kind == "CadShape" and collision:
        raise ConversionError(f"{_where(geometry)}: unsupported node CadShape (in a boundingObject); the converter "
                              "cannot map it to MuJoCo")
    try:
        points, faces = surface_triangles(geometry)
    except MeshFileError as exc:
        if collision:
            raise ConversionError(f"{exc} (a boundingObject)") from None
        warn(f"visual {kind} skipped: {exc}", None)
        return None
    points = points * scale
    if len(faces) == 0 or len(points) < 4:
        warn(f"{kind} with fewer than 4 points or no face: skipped", geometry)
        return None
    mesh = spec.add_mesh(name=name())
    mesh.uservert = points.reshape(-1).tolist()
    mesh.userface = faces.reshape(-1).tolist()
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL  # only the mesh frame is used: masses are explicit
    if collision:
        warn(f"{kind} collisions use the mesh's convex hull in MuJoCo (a trimesh in ODE)", geometry)
    return str(mesh.name)
