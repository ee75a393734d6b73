"""What Lidar, RangeFinder and infra-red DistanceSensor rays hit: the *visual* Shapes of the scene.

Webots computes a Lidar's or RangeFinder's ranges by rendering the visual scene (a depth camera) and casts an
infra-red DistanceSensor's rays against the Shapes' geometry (``WbNodeUtilities::findIntersectingShape``), not
against ODE bounding objects: these devices see an object that has a Shape but no ``boundingObject``, and do
not see a boundingObject that nothing draws. Generic, sonar and laser DistanceSensors keep to ODE's ray
collisions (bounding objects, :mod:`.rays`).

Headless, every Shape of every Solid (reached through Pose/Transform/Group, not through nested Solids) gets an
ODE geom of its own, outside the collision space (so it never makes contacts), placed at the Shape's current
world pose before each cast and intersected by the same ray code as bounding objects. A Plane draws a finite
``size`` rectangle, so it is a flat box here. An IndexedFaceSet, a Mesh (its file's triangles) and a
CadShape (every mesh of its file) are ODE triangle meshes of :func:`.shapes.surface_triangles`, the triangles
the camera draws; a mesh file that cannot be read is not seen (one warning). A Shape whose appearance is fully
transparent is skipped, as Webots' infra-red and depth rendering skip it. Shapes of the device's robot that enclose the device's origin
(its own housing) are not seen, as a camera inside a Shape does not draw its back faces; the rest of the robot
is seen. Enclosing is judged against the box around the Shape in the Shape's own frame: a box around it in
world axes would grow as the robot tilts, and a sensor just outside its robot's body would stop seeing that
body whenever the robot pitched.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.mass_rules import rot_matrix
from dualtwin.webots.mesh_files import MeshFileError
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import GeomRec, Simulation, SolidRec
from dualtwin.webots.physics.records import is_solid
from dualtwin.webots.shapes import CAD_SHAPE_RGBA, SURFACE_NODES, appearance_rgba, surface_triangles
from dualtwin.webots.solid_scale import holds_bodies, positive_scale, transform_factor

__all__ = ["VisualGeoms", "infra_red_reflection", "scene_of", "visual_targets"]

_PLANE_THICKNESS = 1e-6  # m: a Plane is a rectangle; rays hit its flat box from either side



def _shapes_scale(transform: Node) -> tuple[float, float, float]:
    """The scale a Transform among a Solid's children gives the Shapes below it, as the physics and the cameras take
    it (:mod:`dualtwin.webots.solid_scale`, the load warned): a non-positive component reset to 1, and above a Solid
    or joint one factor, its largest."""
    def quiet(_: str) -> None:
        return None

    if holds_bodies(transform):
        factor = transform_factor(transform, quiet)
        return factor, factor, factor
    return positive_scale(transform, quiet)


class VisualGeoms:
    """ODE geoms of the scene's Shapes (see the module docstring), rebuilt when a supervisor edits geometry."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.lib = ode.load()
        self.version = sim.geometry_version
        self.geoms: list[GeomRec] = []
        self._targets: dict[tuple[int, tuple[int, ...]], list[GeomRec]] = {}
        self._reflection: dict[int, float] = {}  # geom pointer → infra-red reflection factor
        self._extent: dict[int, tuple[float, ...]] = {}  # geom pointer → its box in its own frame
        self._world: dict[int, Pose] = {}  # geom pointer → world pose at the last place()
        for solid in sim.solids:
            for child in solid.node.children():  # a Solid below a scaled Transform: its Shapes scaled too
                self._walk(child, Pose(), (solid.scale,) * 3, solid)

    def _walk(self, node: Node, local: Pose, scale: Sequence[float], solid: SolidRec) -> None:
        if is_solid(node):
            return  # a nested Solid draws its own Shapes in its own frame
        t = node.type_name
        if t in ("Pose", "Transform", "TrackWheel"):  # a TrackWheel is a Pose at (position.x, 0, position.y)
            translation = node.fields.get("translation")
            if translation is not None:
                translation = tuple(float(v) * k for v, k in zip(translation, scale, strict=True))
            sub = local * Pose.from_fields(translation, node.fields.get("rotation"))
            sc = tuple(scale)
            if t == "Transform":
                s = _shapes_scale(node)
                sc = (scale[0] * s[0], scale[1] * s[1], scale[2] * s[2])
            for c in node.children():
                self._walk(c, sub, sc, solid)
        elif t in ("Group", "Billboard"):
            for c in node.children():
                self._walk(c, local, scale, solid)
        elif t == "Shape":
            rgba = appearance_rgba(node)
            geometry = node.fields.get("geometry")
            if isinstance(geometry, Node) and (rgba is None or rgba[3] > 0.0):
                made = self._make(geometry, local, scale, solid)
                if made is not None:
                    self._reflection[made.ptr] = infra_red_reflection(node)
        elif t == "CadShape":  # a Shape whose geometry is its file
            made = self._make(node, local, scale, solid)
            if made is not None:
                self._reflection[made.ptr] = infra_red_reflection(node)

    def _make(self, node: Node, local: Pose, scale: Sequence[float], solid: SolidRec) -> GeomRec | None:
        lib = self.lib
        t = node.type_name
        f = node.fields
        uniform = max(scale)
        ptr = 0
        keep: tuple[Any, ...] = ()
        if t == "Box":
            sx, sy, sz = (float(v) * k for v, k in zip(f.get("size", (2.0, 2.0, 2.0)), scale, strict=True))
            if min(sx, sy, sz) > 0:
                ptr = lib.dCreateBox(None, sx, sy, sz)
        elif t == "Plane":
            sx, sy = (float(v) * k for v, k in zip(f.get("size", (1.0, 1.0)), scale[:2], strict=True))
            if min(sx, sy) > 0:
                ptr = lib.dCreateBox(None, sx, sy, _PLANE_THICKNESS)
        elif t == "Sphere":
            r = float(f.get("radius", 1.0)) * uniform
            if r > 0:
                ptr = lib.dCreateSphere(None, r)
        elif t in ("Cylinder", "Capsule"):
            r, h = float(f.get("radius", 1.0)) * uniform, float(f.get("height", 2.0)) * uniform
            if r > 0 and h > 0:
                ptr = (lib.dCreateCylinder if t == "Cylinder" else lib.dCreateCapsule)(None, r, h)
        elif t in SURFACE_NODES:
            try:
                vertices, triangles = surface_triangles(node)
            except (ValueError, MeshFileError) as exc:
                message = f"{t} not seen by rays: {exc}"
                if message not in self.sim.build_warnings:  # once, not at every rebuild of the scene
                    self.sim.warn(message)
                return None
            if len(triangles):
                keep = ode.build_trimesh_data(vertices * scale, triangles)
                ptr = lib.dCreateTriMesh(None, keep[0], None, None, None)
        if not ptr:
            return None
        box = (ctypes.c_double * 6)()
        lib.dGeomGetAABB(ptr, box)  # created at the origin, unrotated: the box around it in its own frame
        self._extent[ptr] = tuple(box)
        gr = GeomRec(ptr=ptr, solid=solid, kind=t, local=local, body=None, keepalive=keep, source=node,
                     scale=tuple(float(v) for v in scale))  # fmt: skip
        self.geoms.append(gr)
        return gr

    def reflection(self, geom: GeomRec | None) -> float:
        """The infra-red reflection factor of what a ray hit (1 for a miss)."""
        return 1.0 if geom is None else self._reflection.get(geom.ptr, 1.0)

    def targets(self, own: SolidRec | None) -> list[GeomRec]:
        """The geoms a device mounted as Solid ``own`` sees: all but the Shapes of its robot that enclose its
        origin (a depth camera inside a Shape sees out of it: back faces are not drawn). Whether a Shape
        encloses the origin is decided in the Shape's own frame, so it does not change as the robot tilts or
        turns. A list that stays the same object while the answer does not change, so the ray caster's
        per-list caches hold. Call after :meth:`place`."""
        if own is None:
            return self.geoms
        origin = self.sim.solid_world_pose(own).t
        inside = []
        for i, g in enumerate(self.geoms):
            if g.solid is own or (own.robot is not None and g.solid.robot is own.robot):
                local = self._world[g.ptr].inverse().apply(origin)
                box = self._extent[g.ptr]
                if all(box[2 * k] <= local[k] <= box[2 * k + 1] for k in range(3)):
                    inside.append(i)
        key = (id(own), tuple(inside))
        found = self._targets.get(key)
        if found is None:
            skip = set(inside)
            found = self._targets[key] = [g for i, g in enumerate(self.geoms) if i not in skip]
        return found

    def place(self) -> None:
        """Move every visual geom to its Shape's current world pose."""
        lib = self.lib
        poses: dict[int, m3.Pose] = {}
        for g in self.geoms:
            solid_world = poses.get(id(g.solid))
            if solid_world is None:
                solid_world = poses[id(g.solid)] = self.sim.solid_world_pose(g.solid)
            world = self._world[g.ptr] = solid_world * g.local
            lib.dGeomSetPosition(g.ptr, *world.t)
            lib.dGeomSetRotation(g.ptr, rot_matrix(world.R))

    def close(self) -> None:
        for g in self.geoms:
            self.lib.dGeomDestroy(g.ptr)
            if g.keepalive:  # a trimesh's data, freed after its geom
                self.lib.dGeomTriMeshDataDestroy(g.keepalive[0])
        self.geoms = []
        self._targets.clear()
        self._world.clear()


def infra_red_reflection(shape: Node) -> float:
    """Webots' infra-red reflection factor of a Shape: ``0.2 + 0.8·red·(1 − 0.5·roughness)`` with the red of
    its PBRAppearance ``baseColor`` (and its ``roughness``) or Material ``diffuseColor``; a Shape without
    appearance counts as white, a CadShape as the colour it is drawn in (:data:`.shapes.CAD_SHAPE_RGBA`,
    roughness 0). Textures and occlusion maps are not read (Webots samples them at the hit)."""
    if shape.type_name == "CadShape":
        return 0.2 + 0.8 * CAD_SHAPE_RGBA[0]
    appearance = shape.fields.get("appearance")
    red, roughness = 1.0, 0.0
    if isinstance(appearance, Node):
        if appearance.type_name == "PBRAppearance":
            red = float(appearance.fields.get("baseColor", (1.0, 1.0, 1.0))[0])
            roughness = float(appearance.fields.get("roughness", 0.0))
        else:
            material = appearance.fields.get("material")
            if isinstance(material, Node):
                red = float(material.fields.get("diffuseColor", (0.8, 0.8, 0.8))[0])
    return 0.2 + 0.8 * red * (1.0 - 0.5 * roughness)


def scene_of(sim: Simulation) -> VisualGeoms | None:
    """The simulation's visual geoms, if a visual-ray device has sampled yet."""
    scene: VisualGeoms | None = sim.extensions.get("visual_geoms")
    return scene


def visual_targets(sim: Simulation, own: SolidRec | None) -> list[GeomRec]:
    """The visual geoms (placed at their current poses) that a visual-ray device mounted as ``own`` sees."""
    scene: VisualGeoms | None = sim.extensions.get("visual_geoms")
    if scene is None or scene.version != sim.geometry_version:
        if scene is not None:
            scene.close()
        scene = sim.extensions["visual_geoms"] = VisualGeoms(sim)
    scene.place()
    return scene.targets(own)
