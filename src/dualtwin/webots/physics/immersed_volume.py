"""Volume and centroid of the part of a bounding geometry that lies inside a fluid box (Archimedes' buoyancy).

The fluid box is given as half-spaces ``n·x <= d`` (its six faces, outward normals ``n``). Shapes:

* Box: exact. The box is a convex polyhedron; it is clipped by each half-space in turn (every face polygon
  clipped Sutherland-Hodgman style, the cut closed by a new face on the plane), and the clipped polyhedron's
  volume and centroid are integrated exactly as tetrahedra from one of its vertices to its faces' triangles.
* Sphere: exact for the surface plane only: the spherical cap below the fluid's top face (volume
  ``π·h²·(3r − h)/3``, centroid ``3·(2r − h)²/(4·(3r − h))`` below the centre). The other faces are not cut:
  the sphere counts while its centre lies inside the fluid box's footprint and above its bottom face.
* Cylinder and Capsule: approximated. The shape becomes a convex polyhedron of revolution (``SEGMENTS``
  sides; a capsule's hemispheres ``RINGS`` latitude bands each) that is clipped exactly as a box is; the volume
  found is scaled by (true volume / polyhedron volume), so a fully immersed shape has its exact volume and a
  partly immersed one its polyhedron's share of it (the centroid is the polyhedron's).
* A closed triangle mesh (IndexedFaceSet, Mesh; every edge shared by two triangles wound the opposite ways, the
  triangles facing out): exact. The mesh is the signed sum of the tetrahedra from a reference point to its
  triangles; each tetrahedron is a convex polyhedron clipped as a box is, and the signed volumes and moments
  are summed (:func:`mesh_immersed`). With the reference point on the surface, only the tetrahedra of the
  triangles that cross a cutting face need clipping; the others count whole or not at all. An open mesh
  encloses no volume: it is not immersed (:func:`closed_mesh`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualtwin.webots import _math3 as m3

Vec3 = tuple[float, float, float]
Face = list[Vec3]
HalfSpace = tuple[Vec3, float]  # (outward unit normal n, offset d): the inside is n·x <= d

SEGMENTS = 24
RINGS = 4

__all__ = ["RINGS", "SEGMENTS", "ClosedMesh", "Mesh", "box_faces", "clip", "closed_mesh", "immersed",
           "mesh_immersed", "place", "polyhedron_volume", "revolution_mesh", "sphere_cap"]


def box_faces(center: Sequence[float], R: Sequence[float], half: Sequence[float]) -> list[Face]:
    """The six faces of a box (row-major rotation ``R`` from its frame to the world), vertices in cyclic order."""
    def corner(sx: float, sy: float, sz: float) -> Vec3:
        return m3.add(center, m3.mat_vec(R, (sx * half[0], sy * half[1], sz * half[2])))

    faces = []
    cycle = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
    for axis in range(3):
        for sign in (-1.0, 1.0):
            face = []
            for a, b in cycle:
                s = [a, b]
                s.insert(axis, sign)
                face.append(corner(*s))
            faces.append(face)
    return faces


Mesh = tuple[list[Vec3], list[list[int]]]  # vertices in the shape's frame, faces as vertex indices


def revolution_mesh(profile: Sequence[tuple[float, float]], segments: int = SEGMENTS) -> Mesh:
    """A convex polyhedron of revolution about the z axis: ``profile`` lists (radius, z) rings from bottom to top;
    each ring is a regular ``segments``-gon (a ring of radius 0 is one point, a pole)."""
    vertices: list[Vec3] = []
    rings: list[list[int]] = []
    for radius, z in profile:
        if radius == 0.0:
            vertices.append((0.0, 0.0, z))
            rings.append([len(vertices) - 1] * segments)
            continue
        ring = []
        for k in range(segments):
            a = 2.0 * math.pi * k / segments
            vertices.append((radius * math.cos(a), radius * math.sin(a), z))
            ring.append(len(vertices) - 1)
        rings.append(ring)
    faces: list[list[int]] = []
    if profile[0][0] > 0.0:
        faces.append(list(rings[0]))
    if profile[-1][0] > 0.0:
        faces.append(list(rings[-1]))
    for low, high in zip(rings, rings[1:], strict=False):
        for k in range(segments):
            j = (k + 1) % segments
            face = [low[k], low[j], high[j], high[k]]
            faces.append([v for i, v in enumerate(face) if v != face[i - 1]])  # a pole's triangle
    return vertices, faces


def place(mesh: Mesh, center: Sequence[float], R: Sequence[float]) -> list[Face]:
    """The faces of ``mesh`` with its frame at ``center``, turned by the row-major rotation ``R``."""
    r0, r1, r2, r3, r4, r5, r6, r7, r8 = R
    cx, cy, cz = center
    world = [(r0 * x + r1 * y + r2 * z + cx, r3 * x + r4 * y + r5 * z + cy, r6 * x + r7 * y + r8 * z + cz)
             for x, y, z in mesh[0]]
    return [[world[i] for i in face] for face in mesh[1]]


def clip(faces: list[Face], plane: HalfSpace) -> list[Face]:
    """The convex polyhedron ``faces`` cut by the half-space ``n·x <= d`` (faces of the part inside)."""
    n, d = plane
    nx, ny, nz = n
    signed = [[nx * p[0] + ny * p[1] + nz * p[2] - d for p in face] for face in faces]
    if all(s <= 0.0 for row in signed for s in row):
        return faces
    if all(s >= 0.0 for row in signed for s in row):
        return []
    out: list[Face] = []
    cut: list[Vec3] = []
    for face, dist in zip(faces, signed, strict=True):
        if max(dist) < 0.0:
            out.append(face)
            continue
        if min(dist) > 0.0:
            continue
        poly: Face = []
        k = len(face)
        for i in range(k):
            a, da = face[i], dist[i]
            b, db = face[(i + 1) % k], dist[(i + 1) % k]
            if da <= 0.0:
                poly.append(a)
                if da == 0.0:
                    cut.append(a)
            if (da < 0.0 < db) or (db < 0.0 < da):
                t = da / (da - db)
                p = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2]))
                poly.append(p)
                cut.append(p)
        if len(poly) >= 3:
            out.append(poly)
    if len(cut) >= 3:
        out.append(_cyclic(cut, n))
    return out


def _cyclic(points: list[Vec3], n: Vec3) -> Face:
    """Points of one convex polygon lying in a plane of normal ``n``, sorted by angle about their mean."""
    count = len(points)
    mean = (sum(p[0] for p in points) / count, sum(p[1] for p in points) / count, sum(p[2] for p in points) / count)
    helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    u = m3.normalized(m3.cross(n, helper))
    w = m3.cross(n, u)
    return sorted(points, key=lambda p: math.atan2(m3.dot(m3.sub(p, mean), w), m3.dot(m3.sub(p, mean), u)))


def polyhedron_volume(faces: list[Face]) -> tuple[float, Vec3]:
    """Volume and centroid of a convex polyhedron (faces with vertices in cyclic order, either orientation)."""
    if not faces:
        return 0.0, (0.0, 0.0, 0.0)
    # any point of a convex polyhedron sees every face from inside (or in its plane): the tetrahedra from one of
    # its vertices to the faces' triangles tile it, and their unsigned volumes need no face orientation
    ox, oy, oz = faces[0][0]
    volume = cx = cy = cz = 0.0
    for face in faces:
        a = face[0]
        ax, ay, az = a[0] - ox, a[1] - oy, a[2] - oz
        for i in range(1, len(face) - 1):
            b, c = face[i], face[i + 1]
            bx, by, bz = b[0] - ox, b[1] - oy, b[2] - oz
            qx, qy, qz = c[0] - ox, c[1] - oy, c[2] - oz
            v = abs(ax * (by * qz - bz * qy) - ay * (bx * qz - bz * qx) + az * (bx * qy - by * qx)) / 6.0
            volume += v
            cx += v * (ax + bx + qx) / 4.0
            cy += v * (ay + by + qy) / 4.0
            cz += v * (az + bz + qz) / 4.0
    if volume <= 0.0:
        return 0.0, (ox, oy, oz)
    return volume, (ox + cx / volume, oy + cy / volume, oz + cz / volume)


def sphere_cap(center: Sequence[float], radius: float, surface: HalfSpace) -> tuple[float, Vec3]:
    """Volume and centroid of the part of a sphere below the plane ``n·x = d`` (the inside is ``n·x <= d``)."""
    n, d = surface
    above = m3.dot(n, center) - d  # the centre's height above the surface
    if above >= radius:
        return 0.0, (float(center[0]), float(center[1]), float(center[2]))
    if above <= -radius:
        return 4.0 / 3.0 * math.pi * radius**3, (float(center[0]), float(center[1]), float(center[2]))
    h = radius - above  # cap height
    volume = math.pi * h * h * (3.0 * radius - h) / 3.0
    below = 3.0 * (2.0 * radius - h) ** 2 / (4.0 * (3.0 * radius - h))
    return volume, m3.sub(center, m3.scale(n, below))


def immersed(faces: list[Face], planes: Sequence[HalfSpace]) -> tuple[float, Vec3]:
    """Volume and centroid of the convex polyhedron ``faces`` inside every half-space of ``planes``."""
    for plane in planes:
        faces = clip(faces, plane)
        if not faces:
            return 0.0, (0.0, 0.0, 0.0)
    return polyhedron_volume(faces)


@dataclass(frozen=True)
class ClosedMesh:
    """A closed, outward-wound triangle mesh in its own frame: ``vertices`` (n, 3), ``triangles`` (m, 3) indices
    into them (coincident vertices merged), its volume and centroid, and the ball around it (centre, radius)."""

    vertices: np.ndarray
    triangles: np.ndarray
    volume: float
    centroid: Vec3
    center: Vec3
    radius: float


def closed_mesh(vertices: np.ndarray, triangles: np.ndarray) -> ClosedMesh | None:
    """``vertices`` and ``triangles`` as a :class:`ClosedMesh`; None when some edge is not shared by exactly two
    triangles wound the opposite ways, or the triangles face inwards (a non-positive volume)."""
    points, index = np.unique(np.asarray(vertices, dtype=np.float64).reshape(-1, 3), axis=0, return_inverse=True)
    tri = index.reshape(-1)[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])]
    if len(tri) < 4:
        return None
    n = len(points)
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    forward = edges[:, 0] * n + edges[:, 1]
    if len(np.unique(forward)) != len(forward) or not np.isin(edges[:, 1] * n + edges[:, 0], forward).all():
        return None
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    volumes = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    volume = float(volumes.sum())
    if not volume > 0.0:
        return None
    centroid = (volumes[:, None] * (a + b + c)).sum(axis=0) / (4.0 * volume)
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = (lo + hi) / 2.0
    radius = float(np.sqrt(((points - center) ** 2).sum(axis=1).max()))
    return ClosedMesh(points, tri, volume, _vec(centroid), _vec(center), radius)


def mesh_immersed(mesh: ClosedMesh, center: Sequence[float], R: Sequence[float], planes: Sequence[HalfSpace],
                  origin: Sequence[float]) -> tuple[float, Vec3]:
    """Volume and centroid of the part of ``mesh`` (its frame at ``center``, turned by the row-major ``R``) inside
    every half-space of ``planes``, summed over the signed tetrahedra from ``origin`` to its triangles (exact
    for any reference point; one on the cutting faces leaves fewest tetrahedra to clip)."""
    world = mesh.vertices @ np.asarray(R, dtype=np.float64).reshape(3, 3).T + np.asarray(center, dtype=np.float64)
    o = np.asarray(origin, dtype=np.float64)
    a, b, c = (world[mesh.triangles[:, k]] for k in range(3))
    signed = np.einsum("ij,ij->i", a - o, np.cross(b - o, c - o)) / 6.0
    outside = np.zeros(len(signed), dtype=bool)
    crossing = np.zeros(len(signed), dtype=bool)
    for n, d in planes:
        normal = np.asarray(n, dtype=np.float64)
        level = world @ normal - d
        corners = np.stack([np.full(len(signed), float(o @ normal - d)), level[mesh.triangles[:, 0]],
                            level[mesh.triangles[:, 1]], level[mesh.triangles[:, 2]]], axis=1)
        outside |= corners.min(axis=1) >= 0.0
        crossing |= corners.max(axis=1) > 0.0
    whole = ~outside & ~crossing
    volume = float(signed[whole].sum())
    moment = (signed[whole, None] * (o + a[whole] + b[whole] + c[whole])).sum(axis=0) / 4.0
    op = _vec(o)
    for i in np.flatnonzero(crossing & ~outside):
        pa, pb, pc = _vec(a[i]), _vec(b[i]), _vec(c[i])
        part, where = immersed([[op, pa, pb], [op, pb, pc], [op, pc, pa], [pa, pb, pc]], planes)
        if part > 0.0:
            sign = 1.0 if signed[i] > 0.0 else -1.0
            volume += sign * part
            moment += sign * part * np.asarray(where)
    if volume <= 0.0:
        return 0.0, (0.0, 0.0, 0.0)
    return volume, _vec(moment / volume)


def _vec(v: np.ndarray) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))
