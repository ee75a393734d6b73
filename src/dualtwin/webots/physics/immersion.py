"""Buoyancy of Solids immersed in Webots ``Fluid`` nodes (Archimedes), applied before every physics step.

A Solid with a body whose ``immersionProperties`` hold an ``ImmersionProperties`` whose ``fluidName`` is a Fluid's
``name`` is pushed, each step before ``dWorldStep`` (Webots applies immersion forces in its pre-physics pass,
§1.6), by ``−ρ_fluid · V · g`` at the centroid of ``V`` (``dBodyAddForceAtPos``), ``V`` being the part of each geom
of the Solid's boundingObject, in its current pose, that lies inside the Fluid's boundingObject Box (its top face
is the surface). :mod:`.immersed_volume` computes ``V`` (Box and Sphere exactly, Cylinder and Capsule through a
polyhedron of revolution, closed triangle meshes, IndexedFaceSet and Mesh, exactly). A world without a Fluid
registers nothing, so its steps are unchanged.

Not simulated (one warning at load names what a world would miss): drag and viscous resistance (the
ImmersionProperties coefficients, with the Fluid's streamVelocity and viscosity), fluids whose boundingObject is
not a Box, Fluids inside a Solid, open meshes (they enclose no volume), and immersed ElevationGrids and Planes.
Fluids are read
from the scene tree at every step (a supervisor's edit of their pose, size or density counts), and so are the
immersed Solids: every Solid with a body and ImmersionProperties naming a Fluid, at that step (a supervisor's
import or removal of ImmersionProperties, or of a Solid's Physics, and an imported Solid count); the Fluids are
those of the load (a Fluid imported at run time takes no part).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots._math3 import Pose
from dualtwin.webots.bounding_mesh import TRIMESH_TYPES
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.physics.immersed_volume import (
    RINGS,
    ClosedMesh,
    HalfSpace,
    Mesh,
    box_faces,
    closed_mesh,
    immersed,
    mesh_immersed,
    place,
    polyhedron_volume,
    revolution_mesh,
    sphere_cap,
)
from dualtwin.webots.physics.records import GeomRec, SolidRec, is_solid
from dualtwin.webots.physics.records import field_or as _f
from dualtwin.webots.solid_scale import scaled_local, transform_factor

__all__ = ["Buoyancy", "install"]

_CLASSES = {"Box": ode.dBoxClass, "Sphere": ode.dSphereClass, "Cylinder": ode.dCylinderClass,
            "Capsule": ode.dCapsuleClass}
_SHAPES = tuple(_CLASSES)
ClosedMeshes = dict[int, tuple[Any, ClosedMesh | None]]  # by id of the vertex array: (the array, its mesh)
_DRAG_FIELDS = ("dragForceCoefficients", "dragTorqueCoefficients", "viscousResistanceForceCoefficient",
                "viscousResistanceTorqueCoefficient")


@dataclass
class _Fluid:
    node: Node
    frames: list[Node]  # the Pose-like nodes above it, outermost first


def _fluids(world: World, warn: Callable[[str], None]) -> list[_Fluid]:
    found: list[_Fluid] = []
    inside_solid = False

    def walk(nodes: Iterable[Node | None], frames: list[Node], in_solid: bool) -> None:
        nonlocal inside_solid
        for node in nodes:
            if node is None:
                continue
            if node.type_name == "Fluid":
                if in_solid:
                    inside_solid = True
                else:
                    found.append(_Fluid(node, frames))
                continue
            solid = is_solid(node)
            if "children" in node.fields:
                pose_like = "translation" in node.fields and "rotation" in node.fields and not solid
                walk(node.children(), [*frames, node] if pose_like else frames, in_solid or solid)

    walk(world.nodes, [], False)
    if inside_solid:
        warn("the world has a Fluid node inside a Solid: such a fluid is not simulated here (only fluids outside "
             "Solids push what is immersed in them) (docs/webots-coverage.md)")
    return found


def _fluid_boxes(node: Node, local: Pose, out: list[tuple[Pose, tuple[float, float, float]]]) -> bool:
    """Boxes of a Fluid's boundingObject (in the Fluid's frame); False if it holds any other geometry."""
    t = node.type_name
    if t in ("Pose", "Transform"):
        sub = local * Pose.from_fields(_f(node, "translation", None), _f(node, "rotation", None))
        s = _f(node, "scale", (1.0, 1.0, 1.0)) if t == "Transform" else (1.0, 1.0, 1.0)
        ok = True
        for child in node.children():
            inner: list[tuple[Pose, tuple[float, float, float]]] = []
            ok = _fluid_boxes(child, Pose(), inner) and ok
            for pose, half in inner:
                scaled = Pose(pose.R, tuple(v * k for v, k in zip(pose.t, s, strict=True)))
                out.append((sub * scaled, (half[0] * s[0], half[1] * s[1], half[2] * s[2])))
        return ok
    if t == "Group":
        ok = True
        for child in node.children():
            ok = _fluid_boxes(child, local, out) and ok
        return ok
    if t == "Shape":
        geometry = _f(node, "geometry", None)
        return _fluid_boxes(geometry, local, out) if isinstance(geometry, Node) else True
    if t == "Box":
        size = _f(node, "size", (2.0, 2.0, 2.0))
        out.append((local, (float(size[0]) / 2, float(size[1]) / 2, float(size[2]) / 2)))
        return True
    return False


def _half_spaces(pose: Pose, half: Sequence[float], up: Sequence[float]) -> tuple[list[HalfSpace], int]:
    """The six faces of a fluid box as half-spaces, and the index of its top face (the surface)."""
    planes: list[HalfSpace] = []
    for axis in range(3):
        direction = (pose.R[axis], pose.R[3 + axis], pose.R[6 + axis])
        for sign in (-1.0, 1.0):
            n = m3.scale(direction, sign)
            planes.append((n, m3.dot(n, pose.t) + half[axis]))
    top = max(range(6), key=lambda i: m3.dot(planes[i][0], up))
    return planes, top


class Buoyancy:
    """The per-step pre-physics hook: Archimedes' force on every immersed Solid's body (see the module)."""

    def __init__(self, lib: Any, gravity: Sequence[float], up: Sequence[float], fluids: list[_Fluid],
                 solids: list[SolidRec], closed: ClosedMeshes) -> None:
        self._lib = lib
        self._up = tuple(float(v) for v in up)
        self.gravity = gravity  # WorldInfo's, set again by a run-time edit
        self._fluids = fluids
        self._solids = solids  # the simulation's own list: Solids imported or removed at run time included
        self._meshes: dict[tuple[str, float, float], tuple[Mesh, float]] = {}  # and true / polyhedron volume
        self._closed = closed
        self.last_forces: list[tuple[SolidRec, tuple[float, float, float], tuple[float, float, float]]] = []

    @property
    def gravity(self) -> m3.Vec3:
        """The world's gravity the fluids push against; setting it (a supervisor's edit of WorldInfo.gravity) turns
        the fluids' surface to the new up as well: the face of each Fluid box the most against the gravity."""
        return self._gravity

    @gravity.setter
    def gravity(self, gravity: Sequence[float]) -> None:
        self._gravity: m3.Vec3 = (float(gravity[0]), float(gravity[1]), float(gravity[2]))
        if any(self._gravity):  # (without gravity the former up stays: nothing is pushed anyway)
            self._up = m3.normalized(m3.scale(self._gravity, -1.0))

    def __call__(self, dt: float) -> None:
        del dt
        fluids = []
        for fluid in self._fluids:
            pose, k = Pose(), 1.0  # k: the factor of the scaled Transforms above the Fluid (solid_scale)
            for frame in fluid.frames:
                pose, k = pose * scaled_local(frame, k), k * transform_factor(frame, lambda _: None)
            pose = pose * scaled_local(fluid.node, k)
            bo = _f(fluid.node, "boundingObject", None)
            boxes: list[tuple[Pose, tuple[float, float, float]]] = []
            if isinstance(bo, Node):
                _fluid_boxes(bo, Pose(), boxes)
                boxes = [(Pose(p.R, m3.scale(p.t, k)), (h[0] * k, h[1] * k, h[2] * k)) for p, h in boxes]
            name = str(_f(fluid.node, "name", "fluid"))
            density = float(_f(fluid.node, "density", 1000.0))
            for local, half in boxes:
                if min(half) > 0.0:
                    fluids.append((name, density, _half_spaces(pose * local, half, self._up)))
        self.last_forces = []
        add_force = self._lib.dBodyAddForceAtPos
        for solid in self._solids:
            body = solid.body
            if body is None or body.removed:
                continue
            # read at every step: a supervisor may import or remove ImmersionProperties, give a Solid Physics, or
            # rename the fluid a Solid is in
            names = _fluid_names(solid)
            if not names:
                continue
            for name, density, (planes, top) in fluids:
                if name not in names:
                    continue
                for geom in solid.geoms:
                    volume, centroid = self._immersed(geom, planes, top)
                    if volume <= 0.0:
                        continue
                    force = m3.scale(self.gravity, -density * volume)
                    add_force(body.ptr, *force, *centroid)
                    self.last_forces.append((solid, force, centroid))

    def _immersed(self, geom: GeomRec, planes: list[HalfSpace], top: int) -> tuple[float, m3.Vec3]:
        lib = self._lib
        ptr = geom.ptr
        kind = geom.kind
        if geom.body is None:
            return 0.0, m3.ZERO
        if kind in TRIMESH_TYPES:
            return self._immersed_mesh(geom, planes, top)
        if kind not in _SHAPES:
            return 0.0, m3.ZERO
        size = ode.primitive_size(lib, ptr, _CLASSES[kind])
        if size is None:  # (each of _SHAPES is a primitive: not reached)
            return 0.0, m3.ZERO
        center, R = ode.geom_pose(lib, ptr)
        if kind == "Sphere":
            radius = size[0]
            for i, (n, d) in enumerate(planes):
                if i != top and m3.dot(n, center) > d:
                    return 0.0, m3.ZERO  # the centre is outside the footprint or below the bottom
            return sphere_cap(center, radius, planes[top])
        if kind == "Box":
            bound = math.sqrt(size[0] ** 2 + size[1] ** 2 + size[2] ** 2)
            full = 8.0 * size[0] * size[1] * size[2]
            cutting = self._cutting(center, bound, planes)
            if cutting is None or not cutting:
                return (0.0, m3.ZERO) if cutting is None else (full, center)
            return immersed(box_faces(center, R, size), cutting)
        radius, height = size[0], 2.0 * size[1]
        capsule = kind == "Capsule"
        full = math.pi * radius * radius * (height + (4.0 / 3.0 * radius if capsule else 0.0))
        bound = height / 2 + radius if capsule else math.hypot(radius, height / 2)
        cutting = self._cutting(center, bound, planes)
        if cutting is None or not cutting:
            return (0.0, m3.ZERO) if cutting is None else (full, center)
        key = (kind, radius, height)
        if key not in self._meshes:
            mesh = revolution_mesh(_profile(radius, height, capsule))
            self._meshes[key] = mesh, full / polyhedron_volume(place(mesh, m3.ZERO, m3.IDENTITY))[0]
        mesh, scale = self._meshes[key]
        volume, centroid = immersed(place(mesh, center, R), cutting)
        return volume * scale, centroid

    def _immersed_mesh(self, geom: GeomRec, planes: list[HalfSpace], top: int) -> tuple[float, m3.Vec3]:
        mesh = _closed_geom_mesh(geom, self._closed)
        if mesh is None:
            return 0.0, m3.ZERO
        center, R = ode.geom_pose(self._lib, geom.ptr)
        middle = m3.add(center, m3.mat_vec(R, mesh.center))
        cutting = self._cutting(middle, mesh.radius, planes)
        if cutting is None or not cutting:
            return (0.0, m3.ZERO) if cutting is None else (mesh.volume, m3.add(center, m3.mat_vec(R, mesh.centroid)))
        origin = middle
        if planes[top] in cutting:  # on the surface: only the triangles that cross it are clipped
            n, d = planes[top]
            origin = m3.sub(middle, m3.scale(n, m3.dot(n, middle) - d))
        return mesh_immersed(mesh, center, R, cutting, origin)

    @staticmethod
    def _cutting(center: Sequence[float], bound: float, planes: list[HalfSpace]) -> list[HalfSpace] | None:
        """The faces that cut the ball of radius ``bound`` about ``center`` (empty: it is inside them all), or None
        when it lies outside one of them."""
        cutting = []
        for n, d in planes:
            s = m3.dot(n, center) - d
            if s >= bound:
                return None
            if s > -bound:
                cutting.append((n, d))
        return cutting


def _profile(radius: float, height: float, capsule: bool) -> list[tuple[float, float]]:
    if not capsule:
        return [(radius, -height / 2), (radius, height / 2)]
    rings = []
    for j in range(RINGS + 1):  # bottom hemisphere, pole to equator
        a = -math.pi / 2 + j * (math.pi / 2) / RINGS
        rings.append((radius * math.cos(a), -height / 2 + radius * math.sin(a)))
    return rings + [(rr, -z) for rr, z in reversed(rings)]


def install(sim: Any) -> Buoyancy | None:
    """Register the buoyancy hook on ``sim`` (a :class:`~dualtwin.webots.physics.Simulation` after its build) when
    the world has a Fluid and some Solid with a body has immersionProperties; warn once about what is not
    simulated."""
    fluids = _fluids(sim.world, sim.warn)
    if not fluids:
        return None
    names = {str(_f(fluid.node, "name", "fluid")) for fluid in fluids}
    missing = []
    if any(not _fluid_boxes(bo, Pose(), []) for bo in (_f(f.node, "boundingObject", None) for f in fluids)
           if isinstance(bo, Node)):
        missing.append("fluids whose boundingObject is not a Box (they push nothing)")
    closed: ClosedMeshes = {}
    drag = False
    other_shapes: set[str] = set()
    for solid in sim.solids:
        props = _properties(solid)
        if not _fluid_names(solid) & names:
            continue
        drag = drag or any(_nonzero(_f(p, field, 0.0)) for p in props for field in _DRAG_FIELDS)
        other_shapes.update(g.kind if g.kind not in TRIMESH_TYPES else f"open {g.kind}" for g in solid.geoms
                            if g.kind not in _SHAPES and (g.kind not in TRIMESH_TYPES or _closed_geom_mesh(g, closed) is None))
    if drag:
        missing.append("drag and viscous resistance (dragForceCoefficients, dragTorqueCoefficients, "
                       "viscousResistance*Coefficient, with the fluid's streamVelocity and viscosity)")
    if other_shapes:
        missing.append(f"the immersion of {', '.join(sorted(other_shapes))} bounding objects")
    if missing:
        sim.warn("the world has a Fluid node: buoyancy of immersed Box, Sphere, Cylinder, Capsule and closed "
                 f"IndexedFaceSet and Mesh bounding objects is simulated, but {'; '.join(missing)} are not simulated here (docs/webots-coverage.md)")
    g = sim.gravity
    up = m3.normalized(m3.scale(g, -1.0)) if any(g) else ((0.0, 0.0, 1.0) if sim.coordinate_system == "ENU"
                                                           else (0.0, 1.0, 0.0))
    hook = Buoyancy(sim._lib, g, up, fluids, sim.solids, closed)
    sim.pre_step_hooks.append(hook)
    sim.extensions["buoyancy"] = hook
    return hook


def _closed_geom_mesh(geom: GeomRec, known: ClosedMeshes) -> ClosedMesh | None:
    """The closed mesh of a triangle-mesh geom (its vertices as built, Transform scale applied), None when it is
    open; found once per triangle data in ``known`` (a supervisor's edit builds new data)."""
    if not geom.keepalive:
        return None
    vertices = geom.keepalive[1]
    found = known.get(id(vertices))
    if found is None or found[0] is not vertices:
        if len(known) > 256:  # data of geoms rebuilt many times over
            known.clear()
        found = known[id(vertices)] = (vertices, closed_mesh(vertices, geom.keepalive[2]))
    return found[1]


def _properties(solid: SolidRec) -> list[Node]:
    return [p for p in (_f(solid.node, "immersionProperties", []) or []) if isinstance(p, Node)]


def _fluid_names(solid: SolidRec) -> set[str]:
    return {str(_f(p, "fluidName", "")) for p in _properties(solid)}


def _nonzero(value: Any) -> bool:
    if isinstance(value, (list, tuple)):
        return any(float(v) != 0.0 for v in value)
    return float(value) != 0.0
