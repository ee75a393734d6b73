"""Triangles covering a polygon face, in the face's winding: what a mesh face becomes before ODE, the rays or the
renderer see it.

A triangulation of a face covers the face and nothing else (webots-on-ode.md §3.4: an IndexedFaceSet or Mesh
becomes ODE's triangle mesh of its triangulated faces). A fan from the first corner does that for a convex face
only; a concave face (an L-shaped floor, a star) fanned from a corner that does not see every other corner gets
triangles outside it, surfaces that are not in the world. A convex face is fanned from its first corner (the
triangles every earlier version made, so convex meshes are unchanged); another face is cut by ear clipping in the
plane the face is closest to (Newell's normal), each triangle keeping the face's winding.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["triangulate_polygon"]

Triangle = tuple[int, int, int]


def triangulate_polygon(points: npt.NDArray[np.float64] | Sequence[Sequence[float]], polygon: Sequence[int]
                        ) -> list[Triangle]:
    """Triangles (indices into ``points``, (n, 3) coordinates) covering the face whose corners are ``polygon``, in its
    order; fewer than three corners give none. A face that ear clipping cannot cut (corners all on one line, a
    self-crossing outline) is fanned from its first corner, as a convex one is."""
    n = len(polygon)
    fan = [(polygon[0], polygon[k], polygon[k + 1]) for k in range(1, n - 1)]
    if n <= 3:
        return fan
    flat = _in_plane([points[i] for i in polygon])
    turns = [_cross(flat[k - 1], flat[k], flat[(k + 1) % n]) for k in range(n)]
    if all(t >= 0.0 for t in turns) or all(t <= 0.0 for t in turns):
        return fan  # convex
    area = sum(flat[k - 1][0] * flat[k][1] - flat[k][0] * flat[k - 1][1] for k in range(n))
    if area == 0.0:
        return fan
    sign = 1.0 if area > 0.0 else -1.0
    left = list(range(n))  # corners not yet cut off, as positions in ``polygon``
    out: list[Triangle] = []
    while len(left) > 3:
        for j in range(len(left)):
            a, b, c = left[j - 1], left[j], left[(j + 1) % len(left)]
            if sign * _cross(flat[a], flat[b], flat[c]) <= 0.0:
                continue  # a reflex (or flat) corner is no ear
            if any(_inside(flat[p], flat[a], flat[b], flat[c], sign) for p in left if p not in (a, b, c)):
                continue
            out.append((polygon[a], polygon[b], polygon[c]))
            del left[j]
            break
        else:
            return fan  # no ear: not a simple polygon
    out.append((polygon[left[0]], polygon[left[1]], polygon[left[2]]))
    return out


def _in_plane(corners: Sequence[Sequence[float]]) -> list[tuple[float, float]]:
    """The corners in 2-D: dropped along the axis of the face's largest (Newell) normal component."""
    normal = [0.0, 0.0, 0.0]
    for k, p in enumerate(corners):
        q = corners[(k + 1) % len(corners)]
        normal[0] += (p[1] - q[1]) * (p[2] + q[2])
        normal[1] += (p[2] - q[2]) * (p[0] + q[0])
        normal[2] += (p[0] - q[0]) * (p[1] + q[1])
    drop = max(range(3), key=lambda k: abs(normal[k]))
    u, v = [k for k in range(3) if k != drop]
    return [(float(p[u]), float(p[v])) for p in corners]


def _cross(a: tuple[float, float], b: tuple[float, float], c: tuple[float, float]) -> float:
    """The turn at ``b`` going a → b → c (> 0: to the left)."""
    return (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])


def _inside(p: tuple[float, float], a: tuple[float, float], b: tuple[float, float], c: tuple[float, float],
            sign: float) -> bool:
    """Whether ``p`` lies in the triangle abc (turning ``sign``) or on its border."""
    return (sign * _cross(a, b, p) >= 0.0 and sign * _cross(b, c, p) >= 0.0 and sign * _cross(c, a, p) >= 0.0)
