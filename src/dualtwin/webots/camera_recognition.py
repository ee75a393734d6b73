"""Webots' Camera ``Recognition`` headless: which Solids a camera recognises, and the segmentation image.

A Camera whose ``recognition`` field holds a Recognition node reports, at each sample of
``recognitionEnable(period)`` (the sensor protocol: the poses after the physics step of the sampling instant),
the objects it sees as :class:`~dualtwin.webots.recognition.CameraRecognitionObject` records. What follows
Webots' Recognition, Camera and CameraRecognitionObject reference pages:

* only Solids whose ``recognitionColors`` is not empty are recognised; ``maxRange`` (m) bounds the distance,
  ``maxObjects`` the count (-1: no limit), ``occlusion`` 0 ignores what hides an object;
* ``id`` is the node's unique id (the one ``Supervisor.getFromId`` resolves), ``position`` the object's origin
  in the camera frame (+x forward, +y left, +z up), ``orientation`` the axis-angle of the object's frame in
  the camera frame, ``size`` its extent (m) along the camera's y and z axes, ``position_on_image`` and
  ``size_on_image`` the centre and size (pixels) of its box on the image, ``colors`` its recognitionColors and
  ``model`` its ``model`` field;
* the segmentation image (``segmentation TRUE`` and ``enableRecognitionSegmentation()``) has the camera's size
  and layout (BGRA): a pixel showing a recognisable object has the object's first recognition colour, every
  other pixel is black.

Our reading where Webots' text does not say (Webots' own C++ is not at hand):

* **the object** is the Solid with everything below it (a robot with its wheels); its **bounding box** is the
  box, in the Solid's own frame, around the bounding objects of that subtree, or around its visible Shapes when
  the subtree has no bounding object (an object with neither is a point at its origin). ``size`` is the extent
  of that box's corners along the camera's y and z axes, and the image box is the 2D box around the corners'
  pinhole projections (focal length ``(width/2)/tan(fieldOfView/2)`` for both axes, square pixels), the box
  first cut at the ``near`` plane, then clipped to the image: ``position_on_image`` is the centre of
  the clipped box and ``size_on_image`` its width and height, rounded half up;
* an object **is in view** when its clipped image box has an area (part of it is inside the frustum), and
  within ``maxRange`` when its origin is;
* the camera's own Solid and the Solids it is mounted on (its robot among them) are never reported; the other
  parts of its robot are, like any Solid;
* **occlusion** (levels 1 and 2 alike): one ray from the camera to the centre of the object's bounding box,
  against the bounding objects of the world with Webots' ray rules (the camera's robot is transparent to it
  unless it has selfCollision; the Solids carrying the camera always are); the object is hidden when the
  first bounding object the ray meets before that centre is not the object's own (its subtree's), so an
  object whose centre is hidden is not reported even when an edge of it shows;
* the objects are reported nearest first (distance of their origin; node id breaks ties), and ``maxObjects``
  keeps the first ones;
* the segmentation image colours every recognisable Solid the camera draws (a Solid without colours of its
  own takes the nearest Solid above it that has some), whatever its range or occlusion level: what hides an
  object in the image is what is drawn in front of it; alpha is 255 as in the camera image; it is drawn
  without anti-aliasing at the first read after a sample, from the poses of that sample.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.device_base import DeviceBinding, SampledDevice
from dualtwin.webots.physics import GeomRec, Simulation, SolidRec
from dualtwin.webots.ranging import caster_for
from dualtwin.webots.rays import candidate_geoms, geom_list
from dualtwin.webots.recognition import CameraRecognitionObject
from dualtwin.webots.visual_rays import visual_targets

__all__ = [
    "CameraView", "RecognitionModel", "RecognitionSampler", "recognise", "segmentation_colours", "segmentation_image",
]

_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]


class CameraView(NamedTuple):
    """What recognition needs of the camera at a sample: image size, horizontal fov, near plane."""

    width: int
    height: int
    fov: float
    near: float


class RecognitionModel:
    """A Recognition node's fields (Webots' defaults where absent)."""

    def __init__(self, fields: dict[str, Any]) -> None:
        self.max_range = float(fields.get("maxRange", 100.0))
        self.max_objects = int(fields.get("maxObjects", -1))
        self.occlusion = int(fields.get("occlusion", 1))  # an R2023a world's SFBool TRUE reads 1
        self.segmentation = bool(fields.get("segmentation", False))


def colours_of(solid: SolidRec) -> list[tuple[float, float, float]]:
    values = solid.node.fields.get("recognitionColors") or []
    return [(float(c[0]), float(c[1]), float(c[2])) for c in values]


def _chain(solid: SolidRec) -> set[int]:
    """Ids of the Solid and the Solids it is mounted on."""
    return {id(s) for s in solid.carriers()}


def _geom_corners(lib: Any, g: GeomRec) -> np.ndarray:
    """World corners of the box around one ODE geom, in the geom's own frame when ODE tells its shape."""
    ptr = g.ptr
    cls = lib.dGeomGetClass(ptr)
    size = ode.primitive_size(lib, ptr, cls)
    if size is None:  # a mesh or a height field: ODE's world box around it
        box = (ctypes.c_double * 6)()
        lib.dGeomGetAABB(ptr, box)
        return np.array([(x, y, z) for x in box[0:2] for y in box[2:4] for z in box[4:6]], dtype=float)
    if cls == ode.dBoxClass:
        half = size
    elif cls == ode.dSphereClass:
        half = (size[0], size[0], size[0])
    else:  # capsule or cylinder along z, a capsule's caps included
        half = (size[0], size[0], size[1] + (size[0] if cls == ode.dCapsuleClass else 0.0))
    p, r = ode.geom_pose(lib, ptr)
    R = np.array(r, dtype=float).reshape(3, 3)
    local = np.array([(x, y, z) for x in (-half[0], half[0]) for y in (-half[1], half[1])
                      for z in (-half[2], half[2])], dtype=float)
    return local @ R.T + np.array(p, dtype=float)


class _Shapes:
    """The visual Shapes' geoms of each Solid, placed once per sample and only if an object needs them."""

    def __init__(self, sim: Simulation) -> None:
        self._sim = sim
        self._by_solid: dict[int, list[GeomRec]] | None = None

    def of(self, solids: list[SolidRec]) -> list[GeomRec]:
        if self._by_solid is None:
            self._by_solid = {}
            for g in visual_targets(self._sim, None):
                self._by_solid.setdefault(id(g.solid), []).append(g)
        return [g for s in solids for g in self._by_solid.get(id(s), [])]


def _bounds(solid: SolidRec, pose: m3.Pose, shapes: _Shapes) -> np.ndarray | None:
    """The 8 corners (world) of the object's bounding box in its own frame, or None (module docstring)."""
    subtree = solid.subtree()
    geoms = [g for s in subtree for g in s.geoms if not g.is_plane]
    if not geoms:
        geoms = shapes.of(subtree)
    if not geoms:
        return None
    lib = ode.load()
    world = np.concatenate([_geom_corners(lib, g) for g in geoms])
    R = np.asarray(pose.R, dtype=float).reshape(3, 3)
    local = (world - np.asarray(pose.t, dtype=float)) @ R  # into the object's frame
    lo, hi = local.min(axis=0), local.max(axis=0)
    box = np.array([(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return box @ R.T + np.asarray(pose.t, dtype=float)


def _image_box(corners: np.ndarray, view: CameraView) -> tuple[float, float, float, float] | None:
    """(u0, v0, u1, v1) of the camera-frame corners' projection, cut at the near plane and clipped to the
    image; None when nothing of it is in the frustum."""
    near = max(view.near, 1e-9)
    points = [c for c in corners if c[0] >= near]
    if len(corners) == 8:
        for a, b in _EDGES:
            xa, xb = corners[a][0], corners[b][0]
            if (xa - near) * (xb - near) < 0.0:
                s = (near - xa) / (xb - xa)
                points.append(corners[a] + s * (corners[b] - corners[a]))
    if not points:
        return None
    pts = np.asarray(points, dtype=float)
    f = (view.width / 2.0) / math.tan(view.fov / 2.0)
    u = view.width / 2.0 - f * pts[:, 1] / pts[:, 0]
    v = view.height / 2.0 - f * pts[:, 2] / pts[:, 0]
    u0, u1 = max(float(u.min()), 0.0), min(float(u.max()), float(view.width))
    v0, v1 = max(float(v.min()), 0.0), min(float(v.max()), float(view.height))
    if len(corners) == 8 and (u1 <= u0 or v1 <= v0):
        return None
    if len(corners) == 1 and not (u0 <= u1 and v0 <= v1):
        return None  # a point object outside the image
    return u0, v0, u1, v1


def _pixel(value: float) -> int:
    """A pixel coordinate or size rounded half up (Python's round() would send 24.5 to 24 and 25.5 to 26)."""
    return math.floor(value + 0.5)


def _occluded(sim: Simulation, camera: SolidRec, origin: m3.Vec3, targets: list[tuple[SolidRec, m3.Vec3]]
              ) -> list[bool]:
    """Whether a ray from ``origin`` to each target point first hits a bounding object outside the target's
    subtree (the module docstring's occlusion); all rays in one batch."""
    mount = _chain(camera)

    def build() -> list[GeomRec]:
        return [g for g in candidate_geoms(sim, camera.robot) if id(g.solid) not in mount]

    geoms = geom_list(sim, ("recognition", id(camera)), build)
    out = [False] * len(targets)
    rays = [(i, m3.sub(point, origin)) for i, (_, point) in enumerate(targets)]
    rays = [(i, d) for i, d in rays if m3.norm(d) > 0.0]
    if not geoms or not rays:
        return out
    lengths = np.array([m3.norm(d) for _, d in rays], dtype=float)
    directions = np.array([d for _, d in rays], dtype=float) / lengths[:, None]
    hits = caster_for(sim).cast(np.repeat(np.array([origin], dtype=float), len(rays), axis=0), directions, lengths,
                                geoms, normals=False)
    for k, ((i, _), hit) in enumerate(zip(rays, hits.geom, strict=True)):
        distance = float(hits.distance[k])
        if hit is not None and distance < lengths[k] - 1e-9:
            out[i] = id(hit.solid) not in {id(s) for s in targets[i][0].subtree()}
    return out


def recognise(sim: Simulation, camera: SolidRec, view: CameraView, model: RecognitionModel,
              node_ids: dict[int, int]) -> list[CameraRecognitionObject]:
    """The objects ``camera`` recognises now (module docstring), nearest first."""
    pose = sim.solid_world_pose(camera)
    inverse = pose.inverse()
    Rc = np.asarray(pose.R, dtype=float).reshape(3, 3)
    tc = np.asarray(pose.t, dtype=float)
    mount = _chain(camera)
    shapes = _Shapes(sim)
    seen: list[tuple[SolidRec, m3.Pose, m3.Vec3, float, np.ndarray, tuple[float, float, float, float], m3.Vec3]] = []
    for solid in sim.solids:
        colours = colours_of(solid)
        if not colours or id(solid) in mount:
            continue
        spose = sim.solid_world_pose(solid)
        position = inverse.apply(spose.t)
        distance = m3.norm(position)
        if distance > model.max_range:
            continue
        box = _bounds(solid, spose, shapes)
        corners = (box - tc) @ Rc if box is not None else np.array([position], dtype=float)
        on_image = _image_box(corners, view)
        if on_image is None:
            continue
        c = box.mean(axis=0) if box is not None else spose.t
        seen.append((solid, spose, position, distance, corners, on_image, (float(c[0]), float(c[1]), float(c[2]))))
    hidden = (_occluded(sim, camera, pose.t, [(item[0], item[6]) for item in seen]) if model.occlusion > 0
              else [False] * len(seen))
    found: list[tuple[float, int, CameraRecognitionObject]] = []
    for (solid, spose, position, distance, corners, on_image, _), occluded in zip(seen, hidden, strict=True):
        if occluded:
            continue
        colours = colours_of(solid)
        u0, v0, u1, v1 = on_image
        relative = np.asarray((inverse * spose).R, dtype=float)
        node_id = node_ids.get(id(solid.node), -1)
        found.append((distance, node_id, CameraRecognitionObject(
            id=node_id,
            position=[float(v) for v in position],
            orientation=[float(v) for v in m3.axis_angle_from_mat(tuple(relative))],
            size=[float(np.ptp(corners[:, 1])), float(np.ptp(corners[:, 2]))],
            position_on_image=[_pixel((u0 + u1) / 2.0), _pixel((v0 + v1) / 2.0)],
            size_on_image=[_pixel(u1 - u0), _pixel(v1 - v0)],
            number_of_colors=len(colours),
            colors=[c for colour in colours for c in colour],
            _model=str(solid.node.fields.get("model", "")),
        )))
    found.sort(key=lambda item: (item[0], item[1]))
    objects = [obj for _, _, obj in found]
    return objects if model.max_objects < 0 else objects[: model.max_objects]


def segmentation_colours(sim: Simulation, camera: SolidRec) -> dict[int, tuple[int, int, int]]:
    """``id(Solid node) -> (r, g, b)`` bytes of every Solid the segmentation image colours (module docstring)."""
    mount = _chain(camera)
    out: dict[int, tuple[int, int, int]] = {}
    for solid in sim.solids:
        s: SolidRec | None = solid
        while s is not None and not colours_of(s):
            s = s.parent
        if s is None or id(s) in mount:
            continue
        r, g, b = (round(min(max(c, 0.0), 1.0) * 255) for c in colours_of(s)[0])
        out[id(solid.node)] = (r, g, b)
    return out


class RecognitionSampler(SampledDevice):
    """The recognition of one camera, sampled with its own period like every Webots sensor."""

    def __init__(self, binding: DeviceBinding, view: Callable[[], CameraView], node_ids: Callable[[], dict[int, int]],
                 on_sample: Callable[[], None]) -> None:
        self._view = view
        self._node_ids = node_ids
        self._on_sample = on_sample  # the camera keeps the poses its segmentation image will be drawn from
        super().__init__(binding)
        self.objects: list[CameraRecognitionObject] = []
        self.pending = False  # a segmentation image is due at the next read

    def _invalidate(self) -> None:
        self.objects = []
        self.pending = False

    def _read(self) -> None:
        record = self._record
        model = RecognitionModel(record.node.fields["recognition"].fields)
        self.objects = recognise(self._robot._sim, record.solid, self._view(), model, self._node_ids())
        self._on_sample()
        self.pending = True


def segmentation_image(ids: np.ndarray, solid_geoms: list[tuple[Any, np.ndarray]],
                       colours: dict[int, tuple[int, int, int]]) -> np.ndarray:
    """The BGRA segmentation image of a frame of geom ids (-1: none) of the visual scene (module docstring)."""
    size = max([int(g.max()) + 1 for _, g in solid_geoms if len(g)] + [1])
    table = np.zeros((size + 1, 3), dtype=np.uint8)  # the last row: no geom
    for node, geoms in solid_geoms:
        colour = colours.get(id(node))
        if colour is not None and len(geoms):
            table[geoms] = colour
    index = np.where((ids >= 0) & (ids < size), ids, size)
    rgb = table[index]
    out = np.empty(ids.shape + (4,), dtype=np.uint8)
    out[..., 0], out[..., 1], out[..., 2] = rgb[..., 2], rgb[..., 1], rgb[..., 0]
    out[..., 3] = 255
    return out
