"""Webots' DistanceSensor rays in the MuJoCo twin: ``<numeric name="webots_distance.<sensor>" data="...">``.

A converted DistanceSensor keeps its MuJoCo ``rangefinder`` (one ray along the sensor's axis, for any MuJoCo
program), and the converter writes what Webots casts (:mod:`dualtwin.convert.sensor_models`) as this numeric::

    type group own length rays aperture gaussianWidth redColorSensitivity

``type`` is Webots' ``getType()`` code (0 generic, 1 infra-red, 2 sonar, 3 laser), ``group`` the geom group the
rays hit, ``own`` 1 when the sensor's robot is (partly) hidden from it, ``length`` the ray length D (the lookup
table's last input), then the sensor's ``numberOfRays``, ``aperture``, ``gaussianWidth`` and
``redColorSensitivity`` as Webots normalises them at load. The rays are Webots' layout and Gaussian weights of
those fields (``docs/reference/webots-devices.md`` §1.2, :mod:`dualtwin.webots.ray_layout`, as the Webots twin
casts them), turned from the device frame (axis +x) into the site's (axis +z).

The twin reads such a sensor as Webots computes it (§1.3, §1.4) instead of reading the rangefinder. The rays
start at the site and hit only geoms of ``group``; MuJoCo's ``mj_multiRay`` casts them all at once.

* generic, sonar, laser: ``group`` is the boundingObject (collision) geoms: a Shape without boundingObject is not
  seen, as Webots' ODE rays collide with bounding objects only. With ``own`` the sensor does not see its robot
  (Webots' near callback ignores same-robot pairs unless ``selfCollision``): the robot is the converted robot's
  kinematic tree, the bodies under the site body's root. ``mj_multiRay`` excludes only one body (the site's); a
  ray whose nearest hit is another body of the robot is cast again from that hit, that body excluded, until it
  hits something else or nothing. generic: Σ wᵢ·dᵢ, a miss counting as D; laser: its one ray's distance or D;
  sonar: the nearest hit whose surface faces the ray within π/8, else D (weights ignored). MuJoCo reports the
  surface's outward normal; ODE's (Webots' and the Webots twin's) faces the ray's side, so the incidence is taken
  from ``|ray·normal|``.
* infra-red: ``group`` is the visual geoms (Webots intersects the rays with the Shapes, its own robot's too);
  with ``own``, the robot's visual geoms whose box (MuJoCo's ``geom_aabb``, in the geom's frame) holds the sensor
  are not seen, the Webots twin's rule for a sensor inside its housing (:mod:`dualtwin.webots.visual_rays`; the
  same box for a primitive, whose frame is the Shape's; MuJoCo moves a mesh's frame to the mesh's own centre
  and axes, so there the box may differ from the one around the Shape in its frame): a ray
  that hits one is cast again just past that hit. Each ray reads ``dᵢ`` and the reflection factor ``fᵢ`` of the
  geom hit (``<numeric name="webots_reflection.<geom>">``, 1 for a miss or a geom without one), and the distance is
  ``d̄ + (d̄/f̄ − d̄)·redColorSensitivity`` with ``d̄ = Σ wᵢ·dᵢ``, ``f̄ = Σ wᵢ·fᵢ``. A geom whose rgba alpha is 0
  (a fully transparent Shape) is skipped by MuJoCo's ray, as the Webots twin skips the Shape.

The result is the distance Webots feeds to its lookup table; the twin then applies the table and the resolution
as for the rangefinder (:mod:`dualtwin.twins.sensor_tables`). Rays are cast only when such a sensor is read (or,
with a sensor-delay knob, once per control period for the delay's history).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from dualtwin.twins.mujoco_state import sensor_numerics
from dualtwin.webots.ray_layout import distance_ray_directions, distance_ray_weights

__all__ = ["GENERIC", "INFRA_RED", "LASER", "RAYS_NUMERIC", "REFLECTION_NUMERIC", "SONAR", "DistanceRays",
           "read_rays", "sensor_snapshot"]

#: The numeric prefix of a DistanceSensor's rays in a converted model.
RAYS_NUMERIC = "webots_distance."
#: The numeric prefix of a visual geom's infra-red reflection factor in a converted model.
REFLECTION_NUMERIC = "webots_reflection."
#: Webots' DistanceSensor type codes (``DistanceSensor.getType()``).
GENERIC, INFRA_RED, SONAR, LASER = 0, 1, 2, 3
#: A sonar echo returns only from a surface within this angle of facing the ray (webots-devices §1.4).
SONAR_MAX_INCIDENCE = math.pi / 8
#: Hits passed through per ray (the robot's bodies, an infra-red sensor's housing) before the ray counts as a miss
#: (a guard: each pass moves along the ray past one body or geom, so a real robot needs a handful).
MAX_PASSES = 64
#: How far past a hidden geom's surface an infra-red ray is cast again (m): MuJoCo's ray from a point on a surface
#: may report that surface; the distance is measured from the sensor, so the step adds no error of its own.
_NUDGE = 1e-9
_FIELDS = 8


@dataclass
class DistanceRays:
    """One converted DistanceSensor's rays (see the module docstring)."""

    adr: int  # the sensor's sensordata address
    site: int
    kind: int
    length: float
    directions: np.ndarray  # (n, 3) unit, site frame
    weights: np.ndarray  # (n,)
    groups: np.ndarray  # mj_ray's geomgroup mask: the one group the rays hit
    exclude: int  # the body the first cast excludes (the site's, for a sensor blind to its robot), else -1
    robot: np.ndarray | None  # per body: True for the robot's bodies a blind sensor passes through
    red_sensitivity: float = 1.0
    reflection: np.ndarray | None = None  # infra-red: per geom, its Shape's reflection factor
    housing: np.ndarray | None = None  # infra-red: the robot's visual geoms, hidden when they enclose the sensor
    _geom: np.ndarray = field(init=False)
    _dist: np.ndarray = field(init=False)
    _normal: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        n = len(self.directions)
        self._geom = np.zeros(n, dtype=np.int32)
        self._dist = np.zeros(n)
        self._normal = np.zeros(3 * n)
        # one ray (most sensors): its direction in the site frame and the buffers of :meth:`_one_ray`
        self._axis = np.ascontiguousarray(self.directions[0], dtype=np.float64)
        self._vec = np.zeros(3)
        self._hit_normal = np.zeros(3)
        self._housing = frozenset(self.housing.tolist()) if self.housing is not None else frozenset()

    def distance(self, m: mujoco.MjModel, d: mujoco.MjData) -> float:
        """The distance Webots feeds to the sensor's lookup table, from the poses in ``d``."""
        if len(self.directions) == 1:
            return self._one_ray(m, d)
        n, full = len(self.directions), self.length
        origin = d.site_xpos[self.site].copy()
        world = self.directions @ d.site_xmat[self.site].reshape(3, 3).T
        mujoco.mj_multiRay(m, d, origin, world.ravel(), self.groups, 1, self.exclude, self._geom, self._dist,
                           self._normal, n, full)
        geom = self._geom.copy()
        dist = np.where((geom >= 0) & (self._dist >= 0), self._dist, np.inf)
        normal = self._normal.reshape(n, 3).copy()
        if self.housing is not None:
            hidden = self._enclosing(m, d, origin)
            for i in range(n):
                if geom[i] in hidden:
                    dist[i], geom[i] = self._past_housing(m, d, origin, world[i], float(dist[i]), hidden)
        elif self.robot is not None:
            for i in range(n):
                if geom[i] >= 0 and self.robot[m.geom_bodyid[geom[i]]]:
                    dist[i], normal[i] = self._past_robot(m, d, origin, world[i], float(dist[i]), int(geom[i]))
        hit = dist < full  # beyond the ray's length: no hit (Webots' ray is D long)
        dist = np.where(hit, dist, full)
        if self.kind == LASER:
            return float(dist[0])
        if self.kind == SONAR:
            for i in np.argsort(dist).tolist():
                if not hit[i]:
                    break
                cos_incidence = abs(float(np.dot(world[i], normal[i])))
                if math.acos(min(1.0, cos_incidence)) < SONAR_MAX_INCIDENCE:
                    return float(dist[i])
            return full
        mean = float(np.dot(self.weights, dist))
        if self.kind != INFRA_RED or self.reflection is None:
            return mean
        factor = float(np.dot(self.weights, np.where(hit, self.reflection[np.maximum(geom, 0)], 1.0)))
        return mean + (mean / factor - mean) * self.red_sensitivity

    def _one_ray(self, m: mujoco.MjModel, d: mujoco.MjData) -> float:
        """:meth:`distance` of a one-ray sensor with ``mj_ray`` and scalars: the same rules, at a fraction of the
        array work (a robot reads a dozen such sensors every control period). Its weight is 1."""
        full = self.length
        origin = d.site_xpos[self.site]
        vec = self._vec
        np.matmul(d.site_xmat[self.site].reshape(3, 3), self._axis, out=vec)
        hit = self._geom[:1]
        dist = mujoco.mj_ray(m, d, origin, vec, self.groups, 1, self.exclude, hit, self._hit_normal)
        geom = int(hit[0])
        if geom < 0 or dist < 0:
            dist, geom = math.inf, -1
        normal = self._hit_normal
        if geom in self._housing:
            hidden = self._enclosing(m, d, origin)
            if geom in hidden:
                dist, geom = self._past_housing(m, d, origin, vec, dist, hidden)
        elif self.robot is not None and geom >= 0 and self.robot[m.geom_bodyid[geom]]:
            dist, normal = self._past_robot(m, d, origin, vec, dist, geom)
        if not dist < full:  # beyond the ray's length: no hit (Webots' ray is D long)
            return full
        if self.kind == SONAR:
            cos_incidence = abs(float(vec[0] * normal[0] + vec[1] * normal[1] + vec[2] * normal[2]))
            return dist if math.acos(min(1.0, cos_incidence)) < SONAR_MAX_INCIDENCE else full
        if self.kind != INFRA_RED or self.reflection is None:
            return dist
        factor = float(self.reflection[geom])
        return dist + (dist / factor - dist) * self.red_sensitivity

    def _enclosing(self, m: mujoco.MjModel, d: mujoco.MjData, origin: np.ndarray) -> set[int]:
        """The robot's visual geoms whose box, in the geom's own frame, holds ``origin``."""
        assert self.housing is not None
        ids = self.housing
        local = np.einsum("kji,kj->ki", d.geom_xmat[ids].reshape(-1, 3, 3), origin - d.geom_xpos[ids])
        box = m.geom_aabb[ids]
        inside = np.all(np.abs(local - box[:, :3]) <= box[:, 3:], axis=1)
        return set(ids[inside].tolist())

    def _past_housing(self, m: mujoco.MjModel, d: mujoco.MjData, origin: np.ndarray, direction: np.ndarray,
                      dist: float, hidden: set[int]) -> tuple[float, int]:
        """(distance, geom) of the nearest hit along the ray on no ``hidden`` geom ((inf, -1): none)."""
        hit = np.zeros(1, dtype=np.int32)
        for _ in range(MAX_PASSES):
            dist += _NUDGE
            if dist >= self.length:
                break
            step = mujoco.mj_ray(m, d, origin + dist * direction, direction, self.groups, 1, -1, hit, None)
            if hit[0] < 0 or step < 0:
                break
            dist += step
            if int(hit[0]) not in hidden:
                return dist, int(hit[0])
        return math.inf, -1

    def _past_robot(self, m: mujoco.MjModel, d: mujoco.MjData, origin: np.ndarray, direction: np.ndarray,
                    dist: float, geom: int) -> tuple[float, np.ndarray]:
        """The nearest hit along the ray that is not the robot's, cast again from each robot hit on (inf: none)."""
        assert self.robot is not None
        hit = np.zeros(1, dtype=np.int32)
        normal = np.zeros(3)
        for _ in range(MAX_PASSES):
            if dist >= self.length:
                break
            start = origin + dist * direction
            step = mujoco.mj_ray(m, d, start, direction, self.groups, 1, int(m.geom_bodyid[geom]), hit, normal)
            geom = int(hit[0])
            if geom < 0 or step < 0:
                break
            dist += step
            if not self.robot[m.geom_bodyid[geom]]:
                return dist, normal.copy()
        return math.inf, np.zeros(3)


def read_rays(m: mujoco.MjModel) -> dict[int, DistanceRays]:
    """Sensor id -> its rays, for each sensor at a site with a well-formed ``webots_distance.<name>`` numeric."""
    out: dict[int, DistanceRays] = {}
    reflection: np.ndarray | None = None
    for s, data in sensor_numerics(m, RAYS_NUMERIC).items():
        if len(data) != _FIELDS or int(m.sensor_objtype[s]) != mujoco.mjtObj.mjOBJ_SITE:
            continue
        kind, group, own, length = int(data[0]), int(data[1]), bool(data[2]), float(data[3])
        rays, aperture, width, sensitivity = int(data[4]), float(data[5]), float(data[6]), float(data[7])
        if kind not in (GENERIC, INFRA_RED, SONAR, LASER) or not 0 <= group < mujoco.mjNGROUP or length <= 0 \
                or rays < 1:
            continue
        rays = 1 if aperture <= 0 else rays
        device = distance_ray_directions(rays, aperture)
        # the device casts along +x, the site along +z (the converter turns the device frame by +pi/2 about y,
        # dualtwin.convert.equivalences.rangefinder_rotation): (x, y, z) in the device frame is (-z, y, x) here
        directions = np.stack([-device[:, 2], device[:, 1], device[:, 0]], axis=1)
        weights = distance_ray_weights(device, aperture, width if width > 0 else 1.0)
        groups = np.zeros(mujoco.mjNGROUP, dtype=np.uint8)
        groups[group] = 1
        site = int(m.sensor_objid[s])
        body = int(m.site_bodyid[site])
        root = int(m.body_rootid[body])
        robot = np.asarray(m.body_rootid == root) if own and root > 0 else None
        if kind == INFRA_RED:
            reflection = _reflections(m) if reflection is None else reflection
            housing = np.flatnonzero((m.geom_group == group) & robot[m.geom_bodyid]) if robot is not None else None
            out[s] = DistanceRays(int(m.sensor_adr[s]), site, kind, length, directions, weights, groups, -1, None,
                                  sensitivity, reflection, housing)
        else:
            out[s] = DistanceRays(int(m.sensor_adr[s]), site, kind, length, directions, weights, groups,
                                  body if robot is not None else -1, robot)
    return out


def _reflections(m: mujoco.MjModel) -> np.ndarray:
    """Each geom's infra-red reflection factor from its ``webots_reflection.<geom>`` numeric (1 without one, or
    with one that is not a positive number: Webots' factor is 0.2 to 1, and the distance divides by the weighted
    factor, so a 0 in a hand-edited model would fail the sensor's reading, as a malformed rays numeric is not
    read either)."""
    out = np.ones(m.ngeom)
    for i in range(m.nnumeric):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_NUMERIC, i) or ""
        geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name[len(REFLECTION_NUMERIC):]) \
            if name.startswith(REFLECTION_NUMERIC) and m.numeric_size[i] >= 1 else -1
        factor = float(m.numeric_data[m.numeric_adr[i]]) if geom >= 0 else math.nan
        if factor > 0 and math.isfinite(factor):
            out[geom] = factor
    return out


def sensor_snapshot(m: mujoco.MjModel, d: mujoco.MjData, rays: dict[int, DistanceRays]) -> np.ndarray:
    """``sensordata`` with each DistanceSensor's entry replaced by Webots' distance (a delayed sensor's history)."""
    out: np.ndarray = d.sensordata.copy()
    for r in rays.values():
        out[r.adr] = r.distance(m, d)
    return out
