"""Ray casting against the ODE scene's bounding objects, for DistanceSensor, Lidar and RangeFinder.

Webots casts sensor rays as ODE ray geoms (``dCreateRay``) that take part in the ordinary collision pass:
a ray sees every boundingObject geom (primitives, meshes, planes, elevation grids) except those of its own
robot, unless that robot has ``selfCollision`` (the near callback's same-robot rule); static-static pairs are
kept and the joint-connection exclusion does not apply to rays. Per ray the nearest hit wins.

Two paths give the same answer:

* :func:`cast_ode` — one ODE ray geom, ``dCollide`` against each candidate geom. Exact by construction (it *is*
  ODE's ray collider), but one ctypes call per (ray, geom) pair.
* :class:`RayCaster.cast` — the same intersections computed for all rays at once with NumPy for ODE's
  primitive classes (box, sphere, capsule, cylinder, plane), after a bounding-box cull; triangle meshes and
  height fields still go through ODE rays. ``tests/webots/test_rays.py`` checks that both paths agree on
  random rays, including rays that start inside a geom.

Decision: the vectorised path is what sensors use, because a robot with eight distance sensors and a 180-ray
lidar sampled every step would otherwise spend milliseconds per step in ctypes calls.
ODE's conventions are kept: a ray starting inside a sphere, box, capsule or cylinder reports the exit point
with the normal facing inward, and a plane is hit from either side.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualtwin.webots import ode
from dualtwin.webots.physics import GeomRec, RobotRec, Simulation

__all__ = ["RayCaster", "RayHits", "cast_ode", "candidate_geoms"]

_PRIMITIVES = {ode.dBoxClass, ode.dSphereClass, ode.dCapsuleClass, ode.dCylinderClass, ode.dPlaneClass}


@dataclass
class RayHits:
    """Nearest hit per ray: distance (``inf`` = no hit), outward surface normal (world) and the geom hit."""

    distance: np.ndarray  # (N,)
    normal: np.ndarray  # (N, 3), zeros where no hit
    geom: list[GeomRec | None]


def candidate_geoms(sim: Simulation, robot: RobotRec | None) -> list[GeomRec]:
    """The geoms a ray of ``robot``'s sensor may hit (Webots' same-robot rule; rays ignore the rest)."""
    if robot is None or robot.self_collision:
        return list(sim.geoms.values())
    return [g for g in sim.geoms.values() if g.solid.robot is not robot]


def cast_ode(
    origins: np.ndarray,
    directions: np.ndarray,
    lengths: np.ndarray,
    geoms: Sequence[GeomRec],
) -> RayHits:
    """Nearest hit of each ray by ODE's own ray collider (``dCollide`` of a ray geom with each geom)."""
    lib = ode.load()
    ray = lib.dCreateRay(None, 1.0)
    buf = (ode.dContactGeom * 32)()
    size = ctypes.sizeof(ode.dContactGeom)
    n = len(origins)
    dist = np.full(n, np.inf)
    normal = np.zeros((n, 3))
    hit: list[GeomRec | None] = [None] * n
    base = ctypes.addressof(buf)
    try:
        for i in range(n):
            o, d = origins[i], directions[i]
            lib.dGeomRaySetLength(ray, float(lengths[i]))
            lib.dGeomRaySet(ray, float(o[0]), float(o[1]), float(o[2]), float(d[0]), float(d[1]), float(d[2]))
            for g in geoms:
                k = lib.dCollide(ray, g.ptr, 32, base, size)
                for j in range(k):
                    c = buf[j]
                    if c.depth < dist[i]:
                        dist[i] = c.depth
                        normal[i] = (c.normal[0], c.normal[1], c.normal[2])
                        hit[i] = g
    finally:
        lib.dGeomDestroy(ray)
    return RayHits(dist, normal, hit)


def _geom_frame(lib: Any, ptr: int) -> tuple[np.ndarray, np.ndarray]:
    p = ode.vec3(lib.dGeomGetPosition(ptr))
    r = ode.mat3(lib.dGeomGetRotation(ptr))
    R = np.array([[r[0], r[1], r[2]], [r[4], r[5], r[6]], [r[8], r[9], r[10]]])
    return np.array([p[0], p[1], p[2]]), R


def _pick(t: np.ndarray, n: np.ndarray, t2: np.ndarray, n2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elementwise nearer of two candidate (t, normal) sets."""
    better = t2 < t
    return np.where(better, t2, t), np.where(better[:, None], n2, n)


class RayCaster:
    """Casts batches of rays for the sensors of one simulation (see the module docstring)."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.lib = ode.load()
        self._classes: dict[int, int] = {}
        self._aabb = (ctypes.c_double * 6)()

    def _class(self, g: GeomRec) -> int:
        c = self._classes.get(g.ptr)
        if c is None:
            c = self._classes[g.ptr] = int(self.lib.dGeomGetClass(g.ptr))
        return c

    def cast(
        self, origins: np.ndarray, directions: np.ndarray, length: float, geoms: Sequence[GeomRec]
    ) -> RayHits:
        """Nearest hit of each ray (unit ``directions``, world frame) within ``length`` among ``geoms``."""
        n = len(origins)
        best_t = np.full(n, np.inf)
        best_n = np.zeros((n, 3))
        best_g = np.full(n, -1, dtype=np.int64)
        if n == 0:
            return RayHits(best_t, best_n, [])
        ends = origins + directions * length
        lo = np.minimum(origins, ends).min(axis=0)
        hi = np.maximum(origins, ends).max(axis=0)
        lib = self.lib
        aabb = self._aabb
        slow: list[GeomRec] = []
        for gi, g in enumerate(geoms):
            cls = self._class(g)
            if cls not in _PRIMITIVES:
                slow.append(g)
                continue
            if cls != ode.dPlaneClass:
                lib.dGeomGetAABB(g.ptr, aabb)
                if (
                    aabb[0] > hi[0] or aabb[1] < lo[0] or aabb[2] > hi[1]
                    or aabb[3] < lo[1] or aabb[4] > hi[2] or aabb[5] < lo[2]
                ):  # fmt: skip
                    continue  # no ray of the batch comes near this geom
            t, nrm = self._intersect(cls, g.ptr, origins, directions)
            t = np.where((t >= 0) & (t <= length), t, np.inf)
            better = t < best_t
            if better.any():
                best_t = np.where(better, t, best_t)
                best_n = np.where(better[:, None], nrm, best_n)
                best_g = np.where(better, gi, best_g)
        hit: list[GeomRec | None] = [geoms[i] if i >= 0 else None for i in best_g.tolist()]
        if slow:
            extra = cast_ode(origins, directions, np.full(n, length), slow)
            for i in np.nonzero(extra.distance < best_t)[0].tolist():
                best_t[i] = extra.distance[i]
                best_n[i] = extra.normal[i]
                hit[i] = extra.geom[i]
        return RayHits(best_t, best_n, hit)

    # -- analytic intersections in the geom frame (ODE's ray colliders, vectorised)

    def _intersect(
        self, cls: int, ptr: int, origins: np.ndarray, directions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        lib = self.lib
        if cls == ode.dPlaneClass:
            p = (ctypes.c_double * 4)()
            lib.dGeomPlaneGetParams(ptr, p)
            nrm = np.array([p[0], p[1], p[2]])
            alpha = p[3] - origins @ nrm
            k = directions @ nrm
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(k != 0.0, alpha / k, np.inf)
            t = np.where(t >= 0, t, np.inf)
            sign = np.where(alpha > 0, -1.0, 1.0)  # normal faces the side the ray comes from
            return t, sign[:, None] * nrm[None, :]
        pos, R = _geom_frame(lib, ptr)
        o = (origins - pos) @ R  # into the geom frame: R^T (x - p)
        d = directions @ R
        if cls == ode.dSphereClass:
            t, nl = self._sphere(o, d, float(lib.dGeomSphereGetRadius(ptr)))
        elif cls == ode.dBoxClass:
            v = (ctypes.c_double * 4)()
            lib.dGeomBoxGetLengths(ptr, v)
            t, nl = self._box(o, d, np.array([v[0], v[1], v[2]]) * 0.5)
        else:
            r, h = ctypes.c_double(), ctypes.c_double()
            getter = lib.dGeomCapsuleGetParams if cls == ode.dCapsuleClass else lib.dGeomCylinderGetParams
            getter(ptr, ctypes.byref(r), ctypes.byref(h))
            if cls == ode.dCapsuleClass:
                t, nl = self._capsule(o, d, r.value, h.value * 0.5)
            else:
                t, nl = self._cylinder(o, d, r.value, h.value * 0.5)
        return t, nl @ R.T

    @staticmethod
    def _sphere(o: np.ndarray, d: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
        b = np.einsum("ij,ij->i", o, d)
        c = np.einsum("ij,ij->i", o, o) - r * r
        disc = b * b - c
        ok = disc >= 0
        s = np.sqrt(np.where(ok, disc, 0.0))
        inside = c < 0
        t = np.where(inside, -b + s, -b - s)  # from inside: the exit point, normal facing inward
        t = np.where(ok, t, np.inf)
        p = o + d * np.where(np.isfinite(t), t, 0.0)[:, None]
        nrm = p / r
        nrm = np.where(inside[:, None], -nrm, nrm)
        return t, nrm

    @staticmethod
    def _box(o: np.ndarray, d: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (-h - o) * inv
            t2 = (h - o) * inv
        tmin = np.minimum(t1, t2)
        tmax = np.maximum(t1, t2)
        # a ray parallel to a slab misses unless it lies within it
        parallel = d == 0.0
        within = np.abs(o) <= h
        tmin = np.where(parallel, np.where(within, -np.inf, np.inf), tmin)
        tmax = np.where(parallel, np.where(within, np.inf, -np.inf), tmax)
        near = tmin.max(axis=1)
        far = tmax.min(axis=1)
        inside = np.all(within, axis=1)
        # from inside, ODE reports the exit point with the normal facing back into the box
        t = np.where(inside, far, near)
        axis = np.where(inside, tmax.argmin(axis=1), tmin.argmax(axis=1))
        ok = (near <= far) & (t >= 0)
        t = np.where(ok, t, np.inf)
        nrm = np.zeros_like(o)
        rows = np.arange(len(o))
        nrm[rows, axis] = -np.sign(d[rows, axis])
        return t, nrm

    @staticmethod
    def _side(
        o: np.ndarray, d: np.ndarray, r: float, half: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Entry and exit of the infinite cylinder x²+y² = r² (local z axis), NaN-free."""
        a = d[:, 0] ** 2 + d[:, 1] ** 2
        b = o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]
        c = o[:, 0] ** 2 + o[:, 1] ** 2 - r * r
        disc = b * b - a * c
        ok = (disc >= 0) & (a > 0)
        s = np.sqrt(np.where(ok, disc, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_in = np.where(ok, (-b - s) / a, np.inf)
            t_out = np.where(ok, (-b + s) / a, -np.inf)
        return t_in, t_out, c

    def _cylinder(self, o: np.ndarray, d: np.ndarray, r: float, half: float) -> tuple[np.ndarray, np.ndarray]:
        t_in, t_out, c = self._side(o, d, r, half)
        inside = (c < 0) & (np.abs(o[:, 2]) < half)
        best = np.full(len(o), np.inf)
        nrm = np.zeros_like(o)
        # side, entering from outside or leaving from inside
        for t_side, sgn in ((t_in, 1.0), (t_out, -1.0)):
            z = o[:, 2] + d[:, 2] * np.where(np.isfinite(t_side), t_side, 0.0)
            use = np.isfinite(t_side) & (np.abs(z) <= half) & (t_side >= 0)
            use &= inside if sgn < 0 else ~inside
            p = o + d * np.where(use, t_side, 0.0)[:, None]
            n_side = np.stack([p[:, 0] / r, p[:, 1] / r, np.zeros(len(o))], axis=1) * sgn
            best, nrm = _pick(best, nrm, np.where(use, t_side, np.inf), n_side)
        # caps
        for zc in (half, -half):
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(d[:, 2] != 0, (zc - o[:, 2]) / d[:, 2], np.inf)
            p = o + d * np.where(np.isfinite(t), t, 0.0)[:, None]
            use = np.isfinite(t) & (t >= 0) & (p[:, 0] ** 2 + p[:, 1] ** 2 <= r * r)
            outward = np.sign(zc)
            facing = np.where(inside, -outward, outward)
            n_cap = np.zeros_like(o)
            n_cap[:, 2] = facing
            best, nrm = _pick(best, nrm, np.where(use, t, np.inf), n_cap)
        return best, nrm

    def _capsule(self, o: np.ndarray, d: np.ndarray, r: float, half: float) -> tuple[np.ndarray, np.ndarray]:
        t_in, t_out, c = self._side(o, d, r, half)
        # inside: within the side tube, or within either end sphere
        in_tube = (c < 0) & (np.abs(o[:, 2]) <= half)
        in_caps = np.zeros(len(o), dtype=bool)
        for zc in (half, -half):
            q = o - np.array([0.0, 0.0, zc])
            in_caps |= np.einsum("ij,ij->i", q, q) < r * r
        inside = in_tube | in_caps
        best = np.full(len(o), np.inf)
        nrm = np.zeros_like(o)
        for t_side, sgn in ((t_in, 1.0), (t_out, -1.0)):
            z = o[:, 2] + d[:, 2] * np.where(np.isfinite(t_side), t_side, 0.0)
            use = np.isfinite(t_side) & (np.abs(z) <= half) & (t_side >= 0)
            use &= inside if sgn < 0 else ~inside
            p = o + d * np.where(use, t_side, 0.0)[:, None]
            n_side = np.stack([p[:, 0] / r, p[:, 1] / r, np.zeros(len(o))], axis=1) * sgn
            best, nrm = _pick(best, nrm, np.where(use, t_side, np.inf), n_side)
        for zc in (half, -half):
            q = o - np.array([0.0, 0.0, zc])
            b = np.einsum("ij,ij->i", q, d)
            cc = np.einsum("ij,ij->i", q, q) - r * r
            disc = b * b - cc
            ok = disc >= 0
            s = np.sqrt(np.where(ok, disc, 0.0))
            for t, sgn in ((-b - s, 1.0), (-b + s, -1.0)):
                p = q + d * np.where(ok, t, 0.0)[:, None]
                # only the hemisphere beyond the tube end counts
                cap_side = p[:, 2] * np.sign(zc) >= 0
                use = ok & (t >= 0) & cap_side & (inside if sgn < 0 else ~inside)
                best, nrm = _pick(best, nrm, np.where(use, t, np.inf), sgn * p / r)
        return best, nrm

