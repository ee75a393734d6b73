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
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualtwin.webots import ode
from dualtwin.webots.physics import GeomRec, RobotRec, Simulation

__all__ = ["RayCaster", "RayHits", "cast_ode", "candidate_geoms", "geom_list", "self_collision_flags"]

_PRIMITIVES = {ode.dBoxClass, ode.dSphereClass, ode.dCapsuleClass, ode.dCylinderClass, ode.dPlaneClass}


@dataclass
class RayHits:
    """Nearest hit per ray: distance (``inf`` = no hit), surface normal (world, facing the ray's side) and
    the index of the geom hit in ``geoms`` (-1 = none)."""

    distance: np.ndarray  # (N,)
    normal: np.ndarray  # (N, 3), zeros where no hit
    index: np.ndarray  # (N,) int
    geoms: Sequence[GeomRec]

    @property
    def geom(self) -> list[GeomRec | None]:
        return [self.geoms[i] if i >= 0 else None for i in self.index.tolist()]


def candidate_geoms(sim: Simulation, robot: RobotRec | None) -> list[GeomRec]:
    """The geoms a ray of ``robot``'s sensor may hit (Webots' same-robot rule; rays ignore the rest)."""
    if robot is None or robot.self_collision:
        return list(sim.geoms.values())
    return [g for g in sim.geoms.values() if g.solid.robot is not robot]


def self_collision_flags(sim: Simulation) -> tuple[bool, ...]:
    """Every robot's ``selfCollision`` now: what decides, with the geoms, which of them a robot's rays see."""
    return tuple(robot.self_collision for robot in sim.robots)


def geom_list(sim: Simulation, key: Hashable, build: Callable[[], list[GeomRec]]) -> list[GeomRec]:
    """The geoms a kind of ray may hit (``build()``), kept under ``key`` until the scene's geoms change or a
    robot's ``selfCollision`` does (the same-robot rule is the near callback's, read at every pass: a supervisor
    that turns it on makes the robot's sensors see its own parts from the next sample).

    :class:`RayCaster` groups the geoms of each list it is given once and keys that work by the list itself, so
    a device that built a fresh list at every sample would be regrouped every time and leave one grouping
    behind per sample. Light sensors, radars and infra-red links ask here instead."""
    stamp = (sim.geometry_version, len(sim.geoms), self_collision_flags(sim))
    cached: tuple[tuple[int, int, tuple[bool, ...]], dict[Hashable, list[GeomRec]]] | None = sim.extensions.get(
        "ray_geom_lists"
    )
    if cached is None or cached[0] != stamp:
        cached = sim.extensions["ray_geom_lists"] = (stamp, {})
    lists = cached[1]
    found = lists.get(key)
    if found is None:
        found = lists[key] = build()
    return found


def cast_ode(
    origins: np.ndarray,
    directions: np.ndarray,
    lengths: np.ndarray,
    geoms: Sequence[GeomRec],
) -> RayHits:
    """Nearest hit of each ray by ODE's own ray collider (``dCollide`` of a ray geom with each geom)."""
    lib = ode.load()
    ode.ensure_thread()  # controllers sample from their own threads; ODE's collider needs per-thread data
    ray = lib.dCreateRay(None, 1.0)
    buf = (ode.dContactGeom * 32)()
    size = ctypes.sizeof(ode.dContactGeom)
    n = len(origins)
    dist = np.full(n, np.inf)
    normal = np.zeros((n, 3))
    hit = np.full(n, -1, dtype=np.int64)
    base = ctypes.addressof(buf)
    try:
        for i in range(n):
            o, d = origins[i], directions[i]
            lib.dGeomRaySetLength(ray, float(lengths[i]))
            lib.dGeomRaySet(ray, float(o[0]), float(o[1]), float(o[2]), float(d[0]), float(d[1]), float(d[2]))
            for gi, g in enumerate(geoms):
                k = lib.dCollide(ray, g.ptr, 32, base, size)
                for j in range(k):
                    c = buf[j]
                    if c.depth < dist[i]:
                        dist[i] = c.depth
                        normal[i] = (c.normal[0], c.normal[1], c.normal[2])
                        hit[i] = gi
    finally:
        lib.dGeomDestroy(ray)
    return RayHits(dist, normal, hit, geoms)


class _Group:
    """Geoms of one ODE class, with live views of their ODE poses and their (fixed) dimensions."""

    def __init__(self, lib: Any, cls: int, geoms: list[tuple[int, GeomRec]]) -> None:
        self.cls = cls
        self.index = np.array([i for i, _ in geoms], dtype=np.int64)
        self.ptrs = [g.ptr for _, g in geoms]
        m = len(geoms)
        self.P = np.zeros((m, 3))
        self.R = np.zeros((m, 3, 3))
        self.plane = np.zeros((m, 4))
        self.params = np.zeros((m, 3))
        self._pos = [ode.vec3(lib.dGeomGetPosition(p)) for p in self.ptrs] if cls != ode.dPlaneClass else []
        self._rot = [ode.mat3(lib.dGeomGetRotation(p)) for p in self.ptrs] if cls != ode.dPlaneClass else []
        for k, ptr in enumerate(self.ptrs):
            size = ode.primitive_size(lib, ptr, cls)  # box half-extents; sphere radius; (radius, half length)
            if size is not None:
                self.params[k, :len(size)] = size

    def refresh(self, lib: Any) -> None:
        """Copy the current poses (ODE recomputes a moved geom's pose when asked for it)."""
        if self.cls == ode.dPlaneClass:
            buf = (ctypes.c_double * 4)()
            for k, ptr in enumerate(self.ptrs):
                lib.dGeomPlaneGetParams(ptr, buf)
                self.plane[k] = (buf[0], buf[1], buf[2], buf[3])
            return
        get_pos = lib.dGeomGetPosition
        for k, ptr in enumerate(self.ptrs):
            get_pos(ptr)  # brings a dirty geom's pose up to date before the views are read
            p, r = self._pos[k], self._rot[k]
            self.P[k] = (p[0], p[1], p[2])
            self.R[k] = ((r[0], r[1], r[2]), (r[4], r[5], r[6]), (r[8], r[9], r[10]))


class RayCaster:
    """Casts batches of rays for the sensors of one simulation (see the module docstring).

    Geoms are grouped by ODE class and each group is intersected with every ray in one set of array
    operations, so the cost grows with the number of geom *classes*, not geoms, in the ray batch's reach.
    """

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.lib = ode.load()
        self._groups: dict[int, tuple[Sequence[GeomRec], list[_Group], list[GeomRec]]] = {}
        self._aabb = (ctypes.c_double * 6)()
        self._version = sim.geometry_version

    def _grouped(self, geoms: Sequence[GeomRec]) -> tuple[list[_Group], list[GeomRec]]:
        version = self.sim.geometry_version  # a supervisor resized a geom: cached dimensions are stale
        if version != self._version:
            self._groups.clear()
            self._version = version
        cached = self._groups.get(id(geoms))
        if cached is not None and cached[0] is geoms:
            return cached[1], cached[2]
        by_class: dict[int, list[tuple[int, GeomRec]]] = {}
        slow: list[GeomRec] = []
        for i, g in enumerate(geoms):
            cls = int(self.lib.dGeomGetClass(g.ptr))
            if cls in _PRIMITIVES:
                by_class.setdefault(cls, []).append((i, g))
            else:
                slow.append(g)
        groups = [_Group(self.lib, cls, members) for cls, members in sorted(by_class.items())]
        self._groups[id(geoms)] = (geoms, groups, slow)
        return groups, slow

    def cast(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        length: float | np.ndarray,
        geoms: Sequence[GeomRec],
        normals: bool = True,
    ) -> RayHits:
        """Nearest hit of each ray (unit ``directions``, world frame) within ``length`` (scalar or per ray).

        Distances are found for every (ray, geom) pair first; surface normals, which only sonars need, are
        then computed for the winning pairs alone (``normals=False`` skips them: zeros).
        """
        n = len(origins)
        best_t = np.full(n, np.inf)
        best_n = np.zeros((n, 3))
        best_g = np.full(n, -1, dtype=np.int64)
        if n == 0:
            return RayHits(best_t, best_n, best_g, geoms)
        lengths = np.broadcast_to(np.asarray(length, dtype=float), (n,))
        groups, slow = self._grouped(geoms)
        lib = self.lib
        rows = np.arange(n)
        owner = np.full(n, -1, dtype=np.int64)  # group of the nearest hit
        column = np.zeros(n, dtype=np.int64)  # the geom within that group
        for gi, group in enumerate(groups):
            group.refresh(lib)
            t = self._distances(group, origins, directions)  # (n, m)
            t = np.where((t >= 0) & (t <= lengths[:, None]), t, np.inf)
            k = t.argmin(axis=1) if t.shape[1] > 1 else np.zeros(n, dtype=np.int64)
            tk = t[rows, k]
            better = tk < best_t
            if better.any():
                best_t = np.where(better, tk, best_t)
                owner = np.where(better, gi, owner)
                column = np.where(better, k, column)
        if normals:
            for gi, group in enumerate(groups):
                sel = np.nonzero(owner == gi)[0]
                if len(sel):
                    best_n[sel] = self._normals(
                        group, origins[sel], directions[sel], column[sel], best_t[sel]
                    )
        for gi, group in enumerate(groups):
            sel = np.nonzero(owner == gi)[0]
            best_g[sel] = group.index[column[sel]]
        if slow:
            extra = cast_ode(origins, directions, lengths, slow)
            closer = extra.distance < best_t
            if closer.any():
                best_t = np.where(closer, extra.distance, best_t)
                best_n = np.where(closer[:, None], extra.normal, best_n)
                slow_index = np.array([geoms.index(g) for g in slow], dtype=np.int64)
                best_g = np.where(closer, slow_index[np.maximum(extra.index, 0)], best_g)
        return RayHits(best_t, best_n, best_g, geoms)

    # -- analytic intersections in the geom frames (ODE's ray colliders, vectorised over rays × geoms)

    def _distances(self, group: _Group, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(n, m) distance of every ray to every geom of the group (inf = miss)."""
        n, m = len(origins), len(group.ptrs)
        if group.cls == ode.dPlaneClass:
            nrm = group.plane[:, :3]
            alpha = group.plane[None, :, 3] - origins @ nrm.T  # (n, m)
            k = directions @ nrm.T
            moving = k != 0.0
            t = np.where(moving, alpha / np.where(moving, k, 1.0), np.inf)
            return np.where(t >= 0, t, np.inf)
        R = group.R
        # rows ordered (geom, ray); components as contiguous rows: reductions over a length-3 axis and
        # einsum are far slower than plain elementwise operations at these sizes
        o = np.matmul(origins[None, :, :] - group.P[:, None, :], R).reshape(-1, 3).T.copy()
        d = np.matmul(directions[None, :, :], R).reshape(-1, 3).T.copy()
        params = np.repeat(group.params, n, axis=0).T
        t, _ = _KERNELS[group.cls](o, d, params, False)
        return t.reshape(m, n).T

    def _normals(
        self, group: _Group, origins: np.ndarray, directions: np.ndarray, column: np.ndarray, t: np.ndarray
    ) -> np.ndarray:
        """World surface normals of rays hitting the group's geom ``column[i]`` at distance ``t[i]``."""
        if group.cls == ode.dPlaneClass:
            plane = group.plane[column]
            alpha = plane[:, 3] - (origins * plane[:, :3]).sum(axis=1)
            return np.where(alpha > 0, -1.0, 1.0)[:, None] * plane[:, :3]  # facing the ray's side
        R = group.R[column]  # (k, 3, 3)
        o = np.matmul((origins - group.P[column])[:, None, :], R)[:, 0, :].T.copy()
        d = np.matmul(directions[:, None, :], R)[:, 0, :].T.copy()
        _, nl = _KERNELS[group.cls](o, d, group.params[column].T, True)
        assert nl is not None
        return np.matmul(R, nl.T[:, :, None])[:, :, 0]


# Kernels: ``o`` and ``d`` are (3, K) ray origins and directions in the geom frame; they return the distance
# along the ray (inf = miss) and the (3, K) surface normal facing the ray's side, as ODE's ray colliders do.


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


Kernel = Callable[[np.ndarray, np.ndarray, np.ndarray, bool], tuple[np.ndarray, np.ndarray | None]]


def _sphere(
    o: np.ndarray, d: np.ndarray, p: np.ndarray, normals: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    r = p[0]
    b = _dot(o, d)
    c = _dot(o, o) - r * r
    disc = b * b - c
    ok = disc >= 0
    s = np.sqrt(np.where(ok, disc, 0.0))
    inside = c < 0
    t = np.where(inside, -b + s, -b - s)  # from inside: the exit point, normal facing inward
    t = np.where(ok, t, np.inf)
    if not normals:
        return t, None
    hit = o + d * np.where(ok, t, 0.0)
    return t, hit * (np.where(inside, -1.0, 1.0) / r)


def _box(o: np.ndarray, d: np.ndarray, h: np.ndarray, normals: bool) -> tuple[np.ndarray, np.ndarray | None]:
    within = np.abs(o) <= h
    parallel = d == 0.0
    safe = np.where(parallel, 1.0, d)
    t1 = (-h - o) / safe
    t2 = (h - o) / safe
    tmin = np.minimum(t1, t2)
    tmax = np.maximum(t1, t2)
    if parallel.any():  # a ray parallel to a slab misses unless it lies within it
        tmin = np.where(parallel, np.where(within, -np.inf, np.inf), tmin)
        tmax = np.where(parallel, np.where(within, np.inf, -np.inf), tmax)
    near = np.maximum(np.maximum(tmin[0], tmin[1]), tmin[2])
    far = np.minimum(np.minimum(tmax[0], tmax[1]), tmax[2])
    inside = within[0] & within[1] & within[2]
    # from inside, ODE reports the exit point with the normal facing back into the box
    t = np.where(inside, far, near)
    t = np.where((near <= far) & (t >= 0), t, np.inf)
    if not normals:
        return t, None
    # the face hit: first axis reaching near (entry) or far (exit), like argmax/argmin
    bound = np.where(inside, tmax, tmin)
    ax0 = bound[0] == t
    ax1 = ~ax0 & (bound[1] == t)
    ax2 = ~ax0 & ~ax1
    sign = -np.sign(d)
    return t, np.stack(
        [np.where(ax0, sign[0], 0.0), np.where(ax1, sign[1], 0.0), np.where(ax2, sign[2], 0.0)]
    )


def _side(o: np.ndarray, d: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entry and exit of the infinite cylinder x²+y² = r² (local z axis), NaN-free."""
    a = d[0] * d[0] + d[1] * d[1]
    b = o[0] * d[0] + o[1] * d[1]
    c = o[0] * o[0] + o[1] * o[1] - r * r
    disc = b * b - a * c
    ok = (disc >= 0) & (a > 0)
    s = np.sqrt(np.where(ok, disc, 0.0))
    safe_a = np.where(ok, a, 1.0)
    t_in = np.where(ok, (-b - s) / safe_a, np.inf)
    t_out = np.where(ok, (-b + s) / safe_a, -np.inf)
    return t_in, t_out, c


def _tube(
    o: np.ndarray, d: np.ndarray, r: np.ndarray, half: np.ndarray, inside: np.ndarray,
    t_in: np.ndarray, t_out: np.ndarray, normals: bool,
) -> tuple[np.ndarray, np.ndarray | None]:  # fmt: skip
    """Nearest hit on the side wall (|z| ≤ half): entering from outside, or leaving from inside."""
    t_side = np.where(inside, t_out, t_in)
    finite = np.isfinite(t_side)
    tt = np.where(finite, t_side, 0.0)
    z = o[2] + d[2] * tt
    t = np.where(finite & (np.abs(z) <= half) & (t_side >= 0), t_side, np.inf)
    if not normals:
        return t, None
    sgn = np.where(inside, -1.0, 1.0) / r
    return t, np.stack([(o[0] + d[0] * tt) * sgn, (o[1] + d[1] * tt) * sgn, np.zeros_like(tt)])


def _nearer(
    t: np.ndarray, n: np.ndarray | None, t2: np.ndarray, n2: Callable[[], np.ndarray]
) -> tuple[np.ndarray, np.ndarray | None]:
    """Elementwise nearer of two candidates; normals (built lazily) only when tracked."""
    if n is None:
        return np.minimum(t, t2), None
    better = t2 < t
    return np.where(better, t2, t), np.where(better, n2(), n)


def _cylinder(
    o: np.ndarray, d: np.ndarray, p: np.ndarray, normals: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    r, half = p[0], p[1]
    t_in, t_out, c = _side(o, d, r)
    inside = (c < 0) & (np.abs(o[2]) < half)
    best, nrm = _tube(o, d, r, half, inside, t_in, t_out, normals)
    dz = d[2]
    moving = dz != 0
    safe = np.where(moving, dz, 1.0)
    zero = np.zeros_like(dz)
    for sign in (1.0, -1.0):
        t = np.where(moving, (sign * half - o[2]) / safe, np.inf)
        tt = np.where(moving, t, 0.0)
        px, py = o[0] + d[0] * tt, o[1] + d[1] * tt
        t = np.where(moving & (t >= 0) & (px * px + py * py <= r * r), t, np.inf)
        cap = np.where(inside, -sign, sign)

        def cap_normal(cap: np.ndarray = cap) -> np.ndarray:
            return np.stack([zero, zero, cap])

        best, nrm = _nearer(best, nrm, t, cap_normal)
    return best, nrm


def _capsule(
    o: np.ndarray, d: np.ndarray, p: np.ndarray, normals: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    r, half = p[0], p[1]
    t_in, t_out, c = _side(o, d, r)
    inside = (c < 0) & (np.abs(o[2]) <= half)
    ends = []
    for sign in (1.0, -1.0):
        q = o.copy()
        q[2] -= sign * half
        inside |= _dot(q, q) < r * r
        ends.append((sign, q))
    best, nrm = _tube(o, d, r, half, inside, t_in, t_out, normals)
    flip = np.where(inside, -1.0, 1.0) / r
    for sign, q in ends:
        b = _dot(q, d)
        cc = _dot(q, q) - r * r
        disc = b * b - cc
        ok = disc >= 0
        s = np.sqrt(np.where(ok, disc, 0.0))
        t = np.where(inside, -b + s, -b - s)
        hit = q + d * np.where(ok, t, 0.0)
        # only the hemisphere beyond the tube end counts
        t = np.where(ok & (t >= 0) & (hit[2] * sign >= 0), t, np.inf)

        def end_normal(hit: np.ndarray = hit) -> np.ndarray:
            return hit * flip

        best, nrm = _nearer(best, nrm, t, end_normal)
    return best, nrm


_KERNELS: dict[int, Kernel] = {
    ode.dSphereClass: _sphere,
    ode.dBoxClass: _box,
    ode.dCylinderClass: _cylinder,
    ode.dCapsuleClass: _capsule,
}
