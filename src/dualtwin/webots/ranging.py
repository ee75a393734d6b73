"""DistanceSensor, Lidar and RangeFinder: Webots' ranging devices, cast as rays against the scene's geometry.

DistanceSensor (Webots ``WbDistanceSensor``)
    ``type`` generic / infra-red (also "infrared") / sonar / laser, case-insensitive; any other string is a
    sonar, as in Webots. ``numberOfRays`` rays (laser: always one) laid out in the sensor frame (axis +x) by
    Webots' predefined patterns for 2–10 rays and concentric cones beyond, spread over ``aperture``, with
    Gaussian weights ``exp(-(θ/(aperture·gaussianWidth))²)`` for generic and infra-red. Ray length is the last
    lookup-table input. Value: generic — weighted mean of the hit distances (a miss counts as the full length);
    sonar — the nearest hit whose surface faces the ray within π/8, else the full length; laser — the hit
    distance or the full length. Then the lookup table (interpolation, multiplicative noise) and the
    resolution. No hit therefore reads the table's *last output*. An empty table reads 0.
    Infra-red rays hit the *visual* Shapes of the scene (:mod:`.visual_rays`), as Webots intersects them with
    the Shapes' geometry, and the distance is weighted by the reflection factor of what each ray hit (from
    its colour's red, :func:`.visual_rays.infra_red_reflection`): ``d̄ + (d̄/f̄ − d̄)·redColorSensitivity``.

Lidar and RangeFinder
    Webots renders depth on the GPU from the visual scene. Here one ray per pixel is cast against the visual
    Shapes (:mod:`.visual_rays`): Lidar column ``j`` at azimuth ``fov/2 - (j+½)·fov/W``, layer ``i`` at elevation
    ``vfov/2 - i·vfov/(L-1) + tilt`` (``tilt`` for one layer); cylindrical projection reads the Euclidean
    distance, planar projection the depth along the device's x axis over a flat image plane. RangeFinder is a
    planar ``width × height`` depth image, vertical field of view ``2·atan(tan(fov/2)·height/width)``, row-major
    from the top-left pixel. Outside ``[minRange, maxRange)`` and where nothing is hit, the value is +inf. Noise is
    additive, ``σ = noise·maxRange``, then the resolution ``floor(r/res + ½)·res`` (Webots' order of the two is
    unknown; this one is a guess). A rotating lidar's image is the fixed one's with fov = 2π (cylindrical), filled
    column by column as its head turns (:mod:`.lidar_head`).
    Before the first sample the images read 0.0 (Webots zero-fills its shared buffer; UNVERIFIED).
    ``getLayerRangeImage(layer)`` returns that layer (Webots' Python wrapper returns layer 0 for every layer,
    a bug that is not reproduced).

Rays are cast only when a sample is due (the sampling protocol of :mod:`.device_base`: at the basic step where the
period elapses), in one vectorised batch per robot (:mod:`.rays`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import write_bytes
from dualtwin.webots.api_args import as_float, as_int, error, warn
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.display import png_bytes
from dualtwin.webots.image_edits import HEAD_FIELDS, SIZE_FIELDS, edited_image_size, edited_model
from dualtwin.webots.lidar_head import RotatingScan, frequencies
from dualtwin.webots.lidar_point import LidarPoint
from dualtwin.webots.lut import Table, discretize, lookup, table_from_field
from dualtwin.webots.physics import GeomRec, RobotRec, Simulation
from dualtwin.webots.ray_layout import distance_ray_directions, distance_ray_layout, distance_ray_weights
from dualtwin.webots.rays import RayCaster, RayHits, candidate_geoms
from dualtwin.webots.step_hints import step_value
from dualtwin.webots.visual_rays import scene_of, visual_targets

__all__ = [
    "DistanceSensor",
    "Lidar",
    "LidarPoint",
    "RangeFinder",
    "distance_ray_layout",
    "distance_ray_weights",
    "caster_for",
    "sample_ray_sensors",
]

SONAR_MAX_INCIDENCE = math.pi / 8  # 0.392699082 rad: a sonar echo returns only from a surface facing the ray


def caster_for(sim: Simulation) -> RayCaster:
    """The simulation's shared ray caster."""
    caster = sim.extensions.get("rays")
    if caster is None:
        caster = sim.extensions["rays"] = RayCaster(sim)
    return caster


def _targets(sim: Simulation, robot: RobotRec | None) -> list[GeomRec]:
    cache = sim.extensions.setdefault("ray_targets", {})
    # the robot's selfCollision now, not at load: a supervisor may turn it on or off (§1.3's same-robot rule)
    key = (id(robot), len(sim.geoms), robot is not None and robot.self_collision)
    geoms = cache.get(key)
    if geoms is None:
        geoms = cache[key] = candidate_geoms(sim, robot)
    return geoms


def _anchor(solid: Any) -> tuple[Any, Any]:
    """(solid whose world pose is looked up, the device's fixed pose in it or None)."""
    if solid.parent is None or solid.body is not None or solid.joint is not None:
        return solid, None
    return solid.parent, solid.rel


@dataclass
class _Batch:
    """Concatenated rays of one robot's due devices, in their anchors' frames (reused while unchanged)."""

    devices: list[Any]
    stamps: list[Any]
    segments: list[tuple[Any, int, int]]  # (anchor solid, first ray, end)
    origins: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray
    slices: list[tuple[int, int]]
    specs: list[tuple[np.ndarray, np.ndarray]]


def _build_batch(devices: list[Any], specs: list[tuple[np.ndarray, np.ndarray]]) -> _Batch:
    origins: list[np.ndarray] = []
    dirs: list[np.ndarray] = []
    lengths: list[np.ndarray] = []
    segments: list[tuple[Any, int, int]] = []
    slices: list[tuple[int, int]] = []
    stamps: list[Any] = []
    start = 0
    for dev, (local_dirs, local_lengths) in zip(devices, specs, strict=True):
        anchor, rel = _anchor(dev._record.solid)
        stamps.append(rel)
        k = len(local_dirs)
        if rel is None:
            origins.append(np.zeros((k, 3)))
            dirs.append(local_dirs)
        else:
            t, R = _np_pose(rel)
            origins.append(np.broadcast_to(t, (k, 3)))
            dirs.append(local_dirs @ R.T)
        lengths.append(local_lengths)
        if segments and segments[-1][0] is anchor:
            segments[-1] = (anchor, segments[-1][1], start + k)
        else:
            segments.append((anchor, start, start + k))
        slices.append((start, start + k))
        start += k
    return _Batch(
        devices,
        stamps,
        segments,
        np.concatenate(origins),
        np.concatenate(dirs),
        np.concatenate(lengths),
        slices,
        specs,
    )


def sample_ray_sensors(sim: Simulation, sensors: Sequence[Any]) -> None:
    """Sample ray devices together: one ray batch per robot (their rays see the same geoms).

    Each device gives ``_ray_spec()`` (unit directions and lengths in its own frame, or None when it needs no
    ray) and takes its slice of the hits in ``_ray_result(hits, world_directions)``. A device fixed to its
    parent Solid is carried in the parent's frame, so the whole batch needs one world pose per parent. Devices
    finish in the order given, so noise draws happen in the same order as sampling them one by one.
    """
    groups: dict[tuple[int, int], tuple[RobotRec | None, list[Any], list[tuple[np.ndarray, np.ndarray]]]] = {}
    for dev in sensors:
        spec = dev._ray_spec()
        if spec is None:
            continue
        robot = dev._record.solid.robot
        # devices whose rays hit visual Shapes (each blind to its own Shapes) go in a batch of their own
        group_key = (id(robot), id(dev._record.solid) if dev._visual_rays else 0)
        groups.setdefault(group_key, (robot, [], []))
        groups[group_key][1].append(dev)
        groups[group_key][2].append(spec)
    caster = caster_for(sim)
    cache = sim.extensions.setdefault("ray_batches", {})
    for robot, devices, specs in groups.values():
        key = tuple(id(d) for d in devices)
        batch = cache.get(key)
        if batch is None or any(
            # moved, or other rays (a rotating lidar, a device whose fields a supervisor edited)
            _anchor(d._record.solid)[1] is not stamp or spec[0] is not old[0] or spec[1] is not old[1]
            for d, stamp, spec, old in zip(batch.devices, batch.stamps, specs, batch.specs, strict=True)
        ):
            batch = cache[key] = _build_batch(devices, specs)
        origins = np.empty_like(batch.origins)
        dirs = np.empty_like(batch.directions)
        for anchor, a, b in batch.segments:
            t, R = _np_pose(sim.solid_world_pose(anchor))
            origins[a:b] = batch.origins[a:b] @ R.T + t
            dirs[a:b] = batch.directions[a:b] @ R.T
        normals = any(getattr(d, "_needs_normals", False) for d in devices)  # sonars only
        if devices[0]._visual_rays:
            targets = visual_targets(sim, devices[0]._record.solid)
        else:
            targets = _targets(sim, robot)
        hits = caster.cast(origins, dirs, batch.lengths, targets, normals=normals)
        for dev, (a, b) in zip(devices, batch.slices, strict=True):
            part = RayHits(hits.distance[a:b], hits.normal[a:b], hits.index[a:b], hits.geoms)
            dev._ray_result(part, dirs[a:b])


def _np_pose(pose: Any) -> tuple[np.ndarray, np.ndarray]:
    return np.array(pose.t, dtype=float), np.array(pose.R, dtype=float).reshape(3, 3)


# ------------------------------------------------------------------------------------------ distance sensor


@dataclass
class DistanceModel:
    """A DistanceSensor's fields, normalised as Webots does at load (and built again after a supervisor's edit)."""

    kind: int
    table: Table
    directions: np.ndarray
    weights: np.ndarray
    aperture: float
    resolution: float
    red_sensitivity: float = 1.0

    @classmethod
    def from_node(cls, fields: dict[str, Any]) -> DistanceModel:
        raw = str(fields.get("type", "generic")).lower()
        kind = {"generic": 0, "infra-red": 1, "infrared": 1, "sonar": 2, "laser": 3}.get(raw, 2)
        n = int(fields.get("numberOfRays", 1))
        n = n if n >= 1 else 1
        if kind == DistanceSensor.LASER and n != 1:
            warn("DistanceSensor: a laser casts one ray; numberOfRays set to 1")
            n = 1
        aperture = abs(float(fields.get("aperture", 1.5708)))
        width = float(fields.get("gaussianWidth", 1.0))
        width = width if width > 0 else 1.0
        if aperture == 0.0:
            n = 1
        dirs = distance_ray_directions(n, aperture)
        return cls(
            kind=kind,
            table=table_from_field(fields.get("lookupTable", [])),
            directions=dirs,
            weights=distance_ray_weights(dirs, aperture, width),
            aperture=aperture,
            resolution=float(fields.get("resolution", -1.0)),
            red_sensitivity=abs(float(fields.get("redColorSensitivity", 1.0))),
        )

    @property
    def length(self) -> float:
        return self.table[-1][0] if self.table else 0.0

    def distance(self, hits: RayHits, world_dirs: np.ndarray, reflections: np.ndarray | None = None) -> float:
        """The distance Webots feeds to the lookup table (§ value computation in the module docstring)."""
        full = self.length
        d = np.where(np.isfinite(hits.distance), hits.distance, full)
        if self.kind == DistanceSensor.GENERIC:
            return float(np.dot(self.weights, d))
        if self.kind == DistanceSensor.INFRA_RED:
            # Webots: d̄ + (d̄/f̄ − d̄)·redColorSensitivity, f the reflection factor of what each ray hit
            mean = float(np.dot(self.weights, d))
            f = float(np.dot(self.weights, reflections)) if reflections is not None else 1.0
            return mean + (mean / f - mean) * self.red_sensitivity
        if self.kind == DistanceSensor.LASER:
            return float(d[0])
        best = full  # sonar: the nearest echo from a surface facing the ray
        for i in np.argsort(hits.distance).tolist():
            if not hits.distance[i] < best:
                break
            cos_incidence = -float(np.dot(world_dirs[i], hits.normal[i]))
            if math.acos(max(-1.0, min(1.0, cos_incidence))) < SONAR_MAX_INCIDENCE:
                best = float(hits.distance[i])
                break
        return best

    def spec(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions (sensor frame) and lengths of the sensor's rays."""
        return self.directions, self.lengths

    def __post_init__(self) -> None:
        self.lengths = np.full(len(self.directions), self.length)

    def finish(self, sim: Simulation, hits: RayHits, dirs: np.ndarray) -> float:
        reflections = None
        scene = scene_of(sim) if self.kind == DistanceSensor.INFRA_RED else None
        if scene is not None:
            reflections = np.array([scene.reflection(g) for g in hits.geom])
        v = lookup(self.table, self.distance(hits, dirs, reflections), sim.rng)
        return discretize(v, self.resolution)


class DistanceSensor(SolidSensor):
    """Webots ``DistanceSensor`` (see the module docstring)."""

    GENERIC = 0
    INFRA_RED = 1
    SONAR = 2
    LASER = 3

    _batch_sampler = staticmethod(sample_ray_sensors)  # rays of all due devices are cast together

    @property
    def _visual_rays(self) -> bool:
        """Infra-red rays hit visual Shapes (:mod:`.visual_rays`); the other types hit bounding objects."""
        return self._sampled_model().kind == self.INFRA_RED

    def _model(self) -> DistanceModel:
        # Webots' updateLookupTable / updateRaySetup: a supervisor's edit of any of these fields takes effect from
        # the next sample, and the getters (max and min value, aperture, type, lookup table) follow it
        kept = self.__dict__.get("_model_cache")
        if kept is not None and kept[0] == self._edit_stamp():  # (the common case, without building a lambda)
            return kept[1]  # type: ignore[no-any-return]
        return self._configured("_model_cache", lambda: DistanceModel.from_node(self._fields()))

    def _sampled_model(self) -> DistanceModel:
        """The model :meth:`_ray_spec` took at the start of this sample (the batch asks it several times)."""
        return self.__dict__["_model_cache"][1]  # type: ignore[no-any-return]

    def _invalidate(self) -> None:
        self._value = math.nan

    def _read(self) -> None:
        sample_ray_sensors(self._robot._sim, [self])

    def _ray_spec(self) -> tuple[np.ndarray, np.ndarray] | None:
        model = self._model()
        if not model.table:
            self._value = 0.0  # an empty lookup table reads 0 without casting
            return None
        return model.spec()

    def _ray_result(self, hits: RayHits, dirs: np.ndarray) -> None:
        self._value = self._sampled_model().finish(self._robot._sim, hits, dirs)

    @property
    def _needs_normals(self) -> bool:
        return self._sampled_model().kind == self.SONAR

    @step_value
    def getValue(self) -> float:
        self._check_enabled("wb_distance_sensor_get_value")
        return getattr(self, "_value", math.nan)

    def getMaxValue(self) -> float:
        table = self._model().table
        return max((r[1] for r in table), default=0.0)

    def getMinValue(self) -> float:
        table = self._model().table
        return min((r[1] for r in table), default=0.0)

    def getAperture(self) -> float:
        return self._model().aperture

    def getType(self) -> int:
        return self._model().kind

    def getLookupTable(self) -> list[float]:
        return [v for row in self._model().table for v in row]

    value = property(getValue)
    max_value = property(getMaxValue)
    min_value = property(getMinValue)
    aperture = property(getAperture)
    type = property(getType)
    lookup_table = property(getLookupTable)


# ------------------------------------------------------------------------------------------ lidar / range finder


@dataclass
class _Grid:
    """Per-pixel rays of a depth device in its own frame, and how a hit distance becomes a range value."""

    directions: np.ndarray  # (N, 3) unit
    to_range: np.ndarray  # (N,) factor: 1 (Euclidean) or the cosine to the image-plane normal (planar depth)
    min_range: float
    max_range: float
    noise: float
    resolution: float

    def spec(self) -> tuple[np.ndarray, np.ndarray]:
        return self.directions, self.lengths

    def __post_init__(self) -> None:
        self.lengths = self.max_range / self.to_range

    def finish(self, sim: Simulation, hits: RayHits, rays: np.ndarray | None = None) -> np.ndarray:
        """The range values of ``hits``, the hits of all the grid's rays or of those indexed by ``rays``."""
        r = hits.distance * (self.to_range if rays is None else self.to_range[rays])
        r = np.where((r >= self.min_range) & (r < self.max_range), r, np.inf)
        if self.noise > 0:
            finite = np.isfinite(r)
            draws = np.array([sim.rng.gauss(0.0, 1.0) for _ in range(int(finite.sum()))])
            r[finite] += self.noise * self.max_range * draws
        if self.resolution > 0:
            r = np.floor(r / self.resolution + 0.5) * self.resolution
        return r


def _range_limits(fields: dict[str, Any]) -> tuple[float, float]:
    near = float(fields.get("near", 0.01))
    lo = max(float(fields.get("minRange", 0.01)), near)
    hi = float(fields.get("maxRange", 1.0))
    if hi <= lo:
        hi = lo + 1.0
    return lo, hi


#: the fields of a Lidar or RangeFinder whose edit at run time changes its next image
_DEPTH_EDITABLE = ("fieldOfView", "minRange", "maxRange", "near", "noise", "resolution")
_LIDAR_EDITABLE = (*_DEPTH_EDITABLE, "verticalFieldOfView", "tiltAngle", "projection", *HEAD_FIELDS)
_RANGE_FINDER_EDITABLE = (*_DEPTH_EDITABLE, *SIZE_FIELDS)


def _pitch(dirs: np.ndarray, angle: float) -> np.ndarray:
    """Rotate directions about the device's y axis so that +x tilts up by ``angle``."""
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    return np.stack([c * x - s * z, y, s * x + c * z], axis=1)


@dataclass
class LidarModel:
    width: int
    layers: int
    fov: float
    vfov: float
    tilt: float
    planar: bool
    grid: _Grid
    azimuths: np.ndarray
    elevations: np.ndarray
    min_frequency: float
    max_frequency: float
    frequency: float
    rotating: bool

    @classmethod
    def from_node(cls, fields: dict[str, Any]) -> LidarModel:
        width = max(1, int(fields.get("horizontalResolution", 512)))
        layers = max(1, int(fields.get("numberOfLayers", 4)))
        rotating = str(fields.get("type", "fixed")) == "rotating"
        # a rotating lidar's image spans the whole turn (webots-devices.md §3.1: 2π in its layer check)
        fov = 2 * math.pi if rotating else float(fields.get("fieldOfView", 1.5708))
        vfov = float(fields.get("verticalFieldOfView", 0.2))
        tilt = float(fields.get("tiltAngle", 0.0))
        planar = str(fields.get("projection", "cylindrical")) == "planar" and not rotating  # no flat plane spans 2π
        lo, hi = _range_limits(fields)
        az = fov / 2 - (np.arange(width) + 0.5) * fov / width
        el = vfov / 2 - np.arange(layers) * vfov / (layers - 1) if layers > 1 else np.zeros(1)
        if planar:
            # a flat image plane at x = 1: columns evenly spaced on it, layers at their elevation angles
            y = math.tan(fov / 2) * (1 - (2 * np.arange(width) + 1) / width)
            Y, Z = np.meshgrid(y, np.tan(el))
            raw = np.stack([np.ones(Y.size), Y.ravel(), Z.ravel()], axis=1)
            unitd = raw / np.linalg.norm(raw, axis=1)[:, None]
            factor = unitd[:, 0].copy()
        else:
            grid_a, grid_e = np.meshgrid(az, el)
            A, E = grid_a.ravel(), grid_e.ravel()
            unitd = np.stack([np.cos(A) * np.cos(E), np.sin(A) * np.cos(E), np.sin(E)], axis=1)
            factor = np.ones(len(unitd))
        dirs = _pitch(unitd, tilt)
        grid = _Grid(
            dirs, factor, lo, hi, float(fields.get("noise", 0.0)), float(fields.get("resolution", -1.0))
        )
        fmin, fmax, f = frequencies(fields, warn)
        return cls(width, layers, fov, vfov, tilt, planar, grid, az, el + tilt, fmin, fmax, f, rotating)


class _DepthDevice(SolidSensor):
    _batch_sampler = staticmethod(sample_ray_sensors)
    _visual_rays = True  # Webots renders the visual scene (:mod:`.visual_rays`)

    def _invalidate(self) -> None:
        self._image: np.ndarray | None = None

    def _grid(self) -> _Grid:
        raise NotImplementedError

    def _size(self) -> int:
        raise NotImplementedError

    def _read(self) -> None:
        sample_ray_sensors(self._robot._sim, [self])

    def _ray_spec(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self._grid().spec()

    def _ray_result(self, hits: RayHits, dirs: np.ndarray) -> None:
        self._sampled_at = self._robot.getTime()
        self._image = self._grid().finish(self._robot._sim, hits)

    def _flat(self) -> np.ndarray:
        image = getattr(self, "_image", None)
        return image if image is not None else np.zeros(self._size())


class Lidar(_DepthDevice):
    """Webots ``Lidar``, fixed or rotating (:mod:`.lidar_head`); see the module docstring."""

    def _model(self) -> LidarModel:
        changed = self._fields_changed(_LIDAR_EDITABLE)
        model = getattr(self, "_model_cache", None)
        if model is not None and changed:
            model = self._model_cache = self._edited(model, changed)
        if model is None:
            model = self._model_cache = LidarModel.from_node(self._fields())
            self._cloud = False
            self._sampled_at = 0.0
            self._scan = RotatingScan(self._robot._sim, self._record, model.width, model.layers) if model.rotating \
                else None  # fmt: skip
        return model

    def _edited(self, model: LidarModel, changed: frozenset[str]) -> LidarModel:
        """The model after a supervisor's edit (Webots' update slots; :mod:`.image_edits`)."""
        new = edited_model(model, self._fields(), changed, self._name, LidarModel.from_node)
        if (new.width, new.layers) != (model.width, model.layers):
            self._image = None  # zeros of the new size until the next sample
            if self._scan is not None:
                self._scan.resize(new.width, new.layers)
        return new

    def _rotating(self) -> RotatingScan | None:
        self._model()
        return self._scan

    def _invalidate(self) -> None:
        super()._invalidate()
        scan = getattr(self, "_scan", None)
        if scan is not None:  # a reset clears the image before any column is cast again: their times too
            scan.clear()

    def enable(self, p: Any) -> None:
        super().enable(p)
        scan = self._rotating()
        if scan is not None and self._period > 0:
            scan.start(self._owner)

    def disable(self) -> None:
        super().disable()
        scan = self._rotating()
        if scan is not None:
            scan.stop()

    def _due(self, now: float) -> bool:
        # a rotating lidar's "sampling period [is] forced to basicTimeStep" (webots-devices.md §3.2)
        return True if self._rotating() is not None else super()._due(now)

    def _ray_spec(self) -> tuple[np.ndarray, np.ndarray] | None:
        scan = self._rotating()
        return super()._ray_spec() if scan is None else scan.spec(*self._grid().spec())

    def _ray_result(self, hits: RayHits, dirs: np.ndarray) -> None:
        scan = self._rotating()
        if scan is None:
            super()._ray_result(hits, dirs)
            return
        ranges = self._grid().finish(self._robot._sim, hits, scan.rays)
        self._image = scan.fill(getattr(self, "_image", None), ranges, self._robot.getTime())

    def _size(self) -> int:
        m = self._model()
        return m.width * m.layers

    def _grid(self) -> _Grid:
        return self._model().grid

    def getRangeImage(self) -> list[float]:
        self._check_enabled("wb_lidar_get_range_image")
        return [float(v) for v in self._flat()]

    def getRangeImageArray(self) -> list[list[float]]:
        self._check_enabled("wb_lidar_get_range_image")
        m = self._model()
        return self._flat().reshape(m.layers, m.width).tolist()

    def getLayerRangeImage(self, layer: Any) -> list[float] | None:
        m = self._model()
        i = as_int(layer, "Lidar.getLayerRangeImage")
        self._check_enabled("wb_lidar_get_layer_range_image")
        if not 0 <= i < m.layers:
            warn(f"Lidar.getLayerRangeImage(): layer {i} out of range [0, {m.layers - 1}]")
            return None
        return self._flat()[i * m.width : (i + 1) * m.width].tolist()

    # point cloud

    def enablePointCloud(self) -> None:
        self._model()
        self._cloud = True

    def disablePointCloud(self) -> None:
        self._model()
        self._cloud = False

    def isPointCloudEnabled(self) -> bool:
        self._model()
        return self._cloud

    def _points(self, layers: range) -> list[LidarPoint]:
        m = self._model()
        if not self._cloud or self._period == 0:
            warn("Lidar: the point cloud is not enabled")
            return []
        r = self._flat().reshape(m.layers, m.width)
        dt = (self._period / 1000.0) / m.width
        scan = self._rotating()
        # a rotating lidar's point is stamped when its column was cast (lidar_head)
        times = [self._sampled_at - j * dt for j in range(m.width)] if scan is None else scan.times.tolist()
        out = []
        for i in layers:
            phi = float(m.elevations[i])
            for j in range(m.width):
                rr, theta = float(r[i, j]), float(m.azimuths[j])
                x = rr * math.cos(theta) * math.cos(phi) if rr else 0.0
                y = rr * math.sin(theta) * math.cos(phi) if rr else 0.0
                z = rr * math.sin(phi) if rr else 0.0
                out.append(LidarPoint(((x, y, z, i, times[j]),), 0))
        return out

    def getPointCloud(self) -> list[LidarPoint]:
        return self._points(range(self._model().layers))

    def getLayerPointCloud(self, layer: Any) -> list[LidarPoint]:
        i = as_int(layer, "Lidar.getLayerPointCloud")
        if not 0 <= i < self._model().layers:
            return []
        return self._points(range(i, i + 1))

    def getNumberOfPoints(self) -> int:
        m = self._model()
        if not self._cloud or self._period == 0:
            error("Lidar.getNumberOfPoints(): the point cloud (or the lidar) is not enabled")
            return 0
        return m.width * m.layers

    # parameters

    def getFrequency(self) -> float:
        return self._model().frequency

    def setFrequency(self, frequency: Any) -> None:
        m = self._model()
        f = as_float(frequency, "Lidar.setFrequency")
        if not m.min_frequency <= f <= m.max_frequency:
            error(f"Lidar.setFrequency(): {f} is outside [{m.min_frequency}, {m.max_frequency}]")
            return
        m.frequency = f

    def getMinFrequency(self) -> float:
        return self._model().min_frequency

    def getMaxFrequency(self) -> float:
        return self._model().max_frequency

    def getHorizontalResolution(self) -> int:
        return self._model().width

    def getNumberOfLayers(self) -> int:
        return self._model().layers

    def getFov(self) -> float:
        return self._model().fov

    def getVerticalFov(self) -> float:
        return self._model().vfov

    def getMinRange(self) -> float:
        return self._model().grid.min_range

    def getMaxRange(self) -> float:
        return self._model().grid.max_range

    # Webots' read-only properties (and ``frequency``, settable)
    range_image = property(getRangeImage)
    fov = property(getFov)
    vertical_fov = property(getVerticalFov)
    max_frequency = property(getMaxFrequency)
    min_frequency = property(getMinFrequency)
    max_range = property(getMaxRange)
    min_range = property(getMinRange)
    horizontal_resolution = property(getHorizontalResolution)
    number_of_layers = property(getNumberOfLayers)
    number_of_points = property(getNumberOfPoints)
    frequency = property(getFrequency, setFrequency)


class RangeFinder(_DepthDevice):
    """Webots ``RangeFinder`` (planar depth image); see the module docstring."""

    def _model(self) -> tuple[int, int, float, _Grid]:
        changed = self._fields_changed(_RANGE_FINDER_EDITABLE)
        model = getattr(self, "_model_cache", None)
        if model is None or changed:
            # built again after an edit of its size, field of view, ranges, noise or resolution (Webots' update
            # slots), from the next image on (:mod:`.image_edits`)
            f = self._fields()
            w, h = (max(1, int(f.get("width", 64))), max(1, int(f.get("height", 64)))) if model is None else model[:2]
            if model is not None and changed & {"width", "height"}:
                w, h = edited_image_size(f, (w, h), "RangeFinder", self._name)
                self._image = None  # zeros of the new size until the next sample
            fov = float(f.get("fieldOfView", 0.7854))
            if str(f.get("projection", "planar")) != "planar":
                warn("RangeFinder: only the planar projection is cast; spherical/cylindrical read as planar")
            vfov = 2 * math.atan(math.tan(fov / 2) * h / w)
            ys = math.tan(fov / 2) * (1 - (2 * np.arange(w) + 1) / w)
            zs = math.tan(vfov / 2) * (1 - (2 * np.arange(h) + 1) / h)
            Y, Z = np.meshgrid(ys, zs)  # row-major from the top-left pixel
            raw = np.stack([np.ones(Y.size), Y.ravel(), Z.ravel()], axis=1)
            unitd = raw / np.linalg.norm(raw, axis=1)[:, None]
            lo, hi = _range_limits(f)
            grid = _Grid(
                unitd,
                unitd[:, 0].copy(),
                lo,
                hi,
                float(f.get("noise", 0.0)),
                float(f.get("resolution", -1.0)),
            )
            model = self._model_cache = (w, h, fov, grid)
        return model

    def _size(self) -> int:
        w, h, _, _ = self._model()
        return w * h

    def _grid(self) -> _Grid:
        return self._model()[3]

    def getRangeImage(self, data_type: str = "list") -> Any:
        self._check_enabled("wb_range_finder_get_range_image")
        flat = self._flat()
        return flat.copy() if data_type == "array" else flat.tolist()

    def getRangeImageArray(self) -> list[list[float]]:
        self._check_enabled("wb_range_finder_get_range_image")
        w, h, _, _ = self._model()
        return self._flat().reshape(h, w).tolist()

    @staticmethod
    def rangeImageGetDepth(image: Any, width: int, x: int, y: int) -> float:
        return float(image[y * width + x])

    def getWidth(self) -> int:
        return self._model()[0]

    def getHeight(self) -> int:
        return self._model()[1]

    def getFov(self) -> float:
        return self._model()[2]

    def getMinRange(self) -> float:
        return self._model()[3].min_range

    def getMaxRange(self) -> float:
        return self._model()[3].max_range

    def saveImage(self, filename: str, quality: Any) -> int:
        """Write the last range image as a grey PNG (0 = black at 0 m, white at maxRange or no hit); 0 on
        success, -1 on failure, as Webots."""
        as_int(quality, "RangeFinder.saveImage")
        w, h, _, grid = self._model()
        if not str(filename).lower().endswith(".png"):
            warn(f"RangeFinder.saveImage(): {filename}: only .png is supported headless")
            return -1
        depth = np.nan_to_num(self._flat().reshape(h, w), posinf=grid.max_range) / grid.max_range
        grey = (np.clip(depth, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        rgba = np.dstack([grey, grey, grey, np.full_like(grey, 255)])
        try:
            write_bytes(Path(filename), png_bytes(np.ascontiguousarray(rgba)))
        except OSError as exc:
            warn(f"RangeFinder.saveImage(): cannot write {filename}: {exc}")
            return -1
        return 0

    range_image = property(getRangeImage)
    fov = property(getFov)
    width = property(getWidth)
    height = property(getHeight)
    max_range = property(getMaxRange)
    min_range = property(getMinRange)
