"""Supervisor edits of bounding geometry (``Box.size``, ``Sphere.radius``, ``Cylinder``/``Capsule``
``radius``/``height``, an ``IndexedFaceSet``'s ``Coordinate.point``, an ``ElevationGrid``'s fields; a
``Mesh``'s file fields, see :mod:`.scene_changes`) reaching the ODE scene.

Webots re-applies a geometry field to its ODE geom as soon as the field changes (``WbBox::updateSize`` and
friends call ``applyToOdeData``), so contacts and ray sensors see the new shape from the next step on, and a
sleeping body touching or owning the geom is woken. A field written on a DEF node is written on every USE of
it as well (Webots keeps DEF and USE nodes identical), which matters because a world's boundingObject is
usually ``USE`` of a visual Shape's geometry: the supervisor edits the visual node, the geom is the copy.

Ray sensors cache geom dimensions; :attr:`GeometryEdits.geometry_version` changes with every edit so they can
tell (see :mod:`dualtwin.webots.rays`).
"""

from __future__ import annotations

import ctypes
from collections.abc import Iterable, Sequence
from typing import Any

from dualtwin.webots.bounding_mesh import trimesh_data
from dualtwin.webots.nodes import Node, copy_value
from dualtwin.webots.physics.collision import CollisionPass
from dualtwin.webots.physics.records import GeomRec, SolidRec
from dualtwin.webots.physics.records import field_or as _f

__all__ = ["GEOMETRY_TYPES", "GeometryEdits"]

#: Node types whose fields shape a geom (Coordinate: the points of an IndexedFaceSet; a Mesh's file fields are
#: applied by rebuilding its Solids' geoms, :meth:`.scene_changes.SceneChanges._apply_geometry`).
GEOMETRY_TYPES = frozenset(
    {"Box", "Sphere", "Cylinder", "Capsule", "Plane", "IndexedFaceSet", "Coordinate", "ElevationGrid", "Cone",
     "Mesh"}
)

_WAKE_MARGIN = 1e-3  # m: bodies whose geoms come this close to a resized geom are woken


class GeometryEdits(CollisionPass):
    """Geometry field edits (see the module docstring)."""

    geometry_version: int = 0

    def linked_nodes(self, node: Node) -> list[Node]:
        """``node`` and the nodes that are the same node in Webots: its DEF and every USE of that DEF (a DEF in a PROTO
        body too, which getFromProtoDef reaches, and its USEs in that instance's body)."""
        name = node.def_name or node.use_name or node.proto_def_name
        if not name:
            return [node]
        out = [node]
        group = node.def_group  # recorded at load: a DEF name repeats in every instance of a PROTO
        for top in self.world.nodes:
            for other in top.walk():
                if other is node or other.type_name != node.type_name:
                    continue
                if other.def_group == group if group is not None else name in (other.def_name, other.use_name):
                    out.append(other)
        return out

    def _bounded_by(self, ids: set[int]) -> list[SolidRec]:
        """The Solids whose boundingObject holds one of the nodes whose ``id`` is in ``ids``."""
        out = []
        for solid in self.solids:
            bounds = solid.node.fields.get("boundingObject")
            if isinstance(bounds, Node) and any(id(n) in ids for n in bounds.walk()):
                out.append(solid)
        return out

    def _apply_geometry(self, node: Node, name: str) -> bool:
        """Propagate the edited field to the node's DEF/USE copies and resize every geom built from them."""
        linked = self.linked_nodes(node)
        value = node.fields.get(name)
        for other in linked[1:]:
            other.fields[name] = copy_value(value)
        ids = {id(n) for n in linked}
        for gr in list(self.geoms.values()):
            src = gr.source
            if src is None:
                continue
            built_from = id(src) in ids or (node.type_name == "Coordinate" and id(src.fields.get("coord")) in ids)
            if not built_from:
                continue
            before = self._aabb(gr)
            if self._resize_geom(gr):
                self._wake_around(gr, before)
        self.geometry_version += 1
        return True

    def _resize_geom(self, gr: GeomRec) -> bool:
        lib = self._lib
        src = gr.source
        assert src is not None
        scale = gr.scale
        uniform = max(scale)
        if gr.kind == "Box":
            sx, sy, sz = (float(v) * k for v, k in zip(_f(src, "size", (2.0, 2.0, 2.0)), scale, strict=True))
            if min(sx, sy, sz) <= 0:
                self.warn(f"Solid '{gr.solid.name}': invalid Box size; geom left unchanged")
                return False
            lib.dGeomBoxSetLengths(gr.ptr, sx, sy, sz)
        elif gr.kind == "Sphere":
            r = float(_f(src, "radius", 1.0)) * uniform
            if r <= 0:
                self.warn(f"Solid '{gr.solid.name}': invalid Sphere radius; geom left unchanged")
                return False
            lib.dGeomSphereSetRadius(gr.ptr, r)
        elif gr.kind in ("Cylinder", "Capsule"):
            r, h = float(_f(src, "radius", 1.0)) * uniform, float(_f(src, "height", 2.0)) * uniform
            if r <= 0 or h <= 0:
                self.warn(f"Solid '{gr.solid.name}': invalid {gr.kind} dimensions; geom left unchanged")
                return False
            (lib.dGeomCylinderSetParams if gr.kind == "Cylinder" else lib.dGeomCapsuleSetParams)(gr.ptr, r, h)
        elif gr.kind == "IndexedFaceSet":
            built = trimesh_data(src, scale)
            if built is None:
                self.warn(f"Solid '{gr.solid.name}': IndexedFaceSet without triangles; geom left unchanged")
                return False
            old = gr.keepalive
            lib.dGeomTriMeshSetData(gr.ptr, built[0])
            gr.keepalive = built
            if old:
                lib.dGeomTriMeshDataDestroy(old[0])
        elif gr.kind == "ElevationGrid":
            # Webots rebuilds the field's ODE data from the grid's fields (WbElevationGrid's applyToOdeData); the
            # geom keeps its place, the grid's corner, as its size moves ODE's centre
            built = self._heightfield_data(src, gr.scale)
            if built is None:
                return False
            old = gr.keepalive
            grid = gr.local * old[2].inverse()  # the grid's frame in the Solid's
            lib.dGeomHeightfieldSetHeightfieldData(gr.ptr, built[0])
            gr.keepalive = built
            gr.local = grid * built[2]
            lib.dGeomHeightfieldDataDestroy(old[0])
            self._place_static_geom(gr, self.solid_world_pose(gr.solid))
        else:
            return False
        return True

    def _aabb(self, gr: GeomRec) -> list[float]:
        box = (ctypes.c_double * 6)()
        self._lib.dGeomGetAABB(gr.ptr, box)
        return list(box)

    def _wake_around(self, gr: GeomRec, before: list[float]) -> None:
        """Wake the geom's body and every body with a geom within reach of the box holding the geom's old and new
        bounding boxes (a body resting on a support that shrank is no longer touching it, yet must fall)."""
        after = self._aabb(gr)
        self._wake_reaching([tuple(min(before[k], after[k]) if k % 2 == 0 else max(before[k], after[k])
                                   for k in range(6))])
        if gr.body is not None:
            self._wake_body(gr.body.index)

    def _static_reach(self, geoms: Iterable[GeomRec]) -> list[tuple[float, ...]]:
        """Where body-less geoms are now, for :meth:`_wake_reaching`: a geom's bounding box (six values: min x,
        max x, min y, ...) or, for a Plane, its half-space ``(nx, ny, nz, d)`` (ODE gives a plane an infinite
        box, which would reach every body in the world)."""
        reach: list[tuple[float, ...]] = []
        params = (ctypes.c_double * 4)()
        for g in geoms:
            if g.is_plane:
                self._lib.dGeomPlaneGetParams(g.ptr, params)
                reach.append(tuple(params))
            else:
                reach.append(tuple(self._aabb(g)))
        return reach

    def _wake_reaching(self, reach: Sequence[tuple[float, ...]]) -> None:
        """Wake every body with a geom within :data:`_WAKE_MARGIN` of one of ``reach``'s boxes or half-spaces
        (:meth:`_static_reach`): a body asleep on a static shape that moved away from under it, or asleep where
        one arrived, is not touched by anything awake, so no contact would wake it."""
        woken: set[int] = set()
        for g in self.geoms.values():
            if g.body is None or g.body.index in woken or g.body.removed:
                continue
            box = self._aabb(g)
            for region in reach:
                if len(region) == 4:  # a half-space n·p <= d: the box's lowest corner along n
                    low = sum(n * (box[2 * k] if n >= 0 else box[2 * k + 1]) for k, n in enumerate(region[:3]))
                    touches = low <= region[3] + _WAKE_MARGIN
                else:
                    touches = all(box[2 * k] <= region[2 * k + 1] + _WAKE_MARGIN
                                  and box[2 * k + 1] >= region[2 * k] - _WAKE_MARGIN for k in range(3))
                if touches:
                    woken.add(g.body.index)
                    break
        for index in woken:
            self._wake_body(index)

    def _wake_body(self, index: int) -> None:
        body = self.bodies[index]
        self._lib.dBodyEnable(body.ptr)
        enabled: Any = getattr(self, "_enabled", None)
        if enabled is not None and index < len(enabled):
            enabled[index] = True
