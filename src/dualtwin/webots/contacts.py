"""Contact points and the static-balance test of Supervisor nodes, computed on demand.

The simulation does not keep the contact points it hands to ODE (they live in scratch arrays reused per pair),
so a query runs ODE's narrow phase (``dCollide``) again for the node's own geoms against every other geom of
the scene, with the same pair filter and the same per-pair limit (``maxContactJoints``, deepest first) as the
collision pass. Run after a step, it sees the state that pass saw, so it returns the points that pass gave ODE
for the next step. Bodies put to sleep by auto-disable are not special-cased. Cost: one ``dCollide`` per geom
pair, only when a controller asks.

Static balance (Webots' ``getStaticBalance``): the centre of mass of the node's bodies, projected along gravity,
lies inside the convex hull of its contact points (the support polygon) projected the same way.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.physics import GeomRec, Simulation, SolidRec

__all__ = ["Contact", "contact_points", "solids_of", "static_balance"]

_CAPACITY = 64


@dataclass(frozen=True)
class Contact:
    point: m3.Vec3  # world frame (ENU)
    solid: SolidRec  # the queried Solid that touches
    other: SolidRec


def solids_of(sim: Simulation, solid: SolidRec, include_descendants: bool) -> list[SolidRec]:
    """``solid``, and with ``include_descendants`` every Solid below it (pre-order)."""
    out = [solid]
    if include_descendants:
        stack = list(reversed(solid.children))
        while stack:
            s = stack.pop()
            out.append(s)
            stack.extend(reversed(s.children))
    return out


def contact_points(sim: Simulation, solids: list[SolidRec]) -> list[Contact]:
    """Contacts of the geoms of ``solids`` with every other geom, in a deterministic order."""
    mine: list[GeomRec] = [g for s in solids for g in s.geoms]
    own = {g.ptr for g in mine}
    # scene order (the order geoms were built), not pointer order, which changes from run to run
    others = [g for ptr, g in sim.geoms.items() if ptr not in own]
    array = (ode.dContactGeom * _CAPACITY)()
    collide = sim._lib.dCollide
    size = ctypes.sizeof(ode.dContactGeom)
    out: list[Contact] = []
    order = sim.space_order()  # the collision pass's argument order (some colliders are order-dependent)
    for g in mine:
        for h in others:
            first, second = (g, h) if order.get(g.ptr, 0) <= order.get(h.ptr, 0) else (h, g)
            plan = sim._plan_pair(first.ptr, second.ptr)  # the collision pass's own filter (Webots' rules)
            if plan is False:
                continue
            n = collide(first.ptr, second.ptr, _CAPACITY, ctypes.addressof(array), size)
            if n <= 0:
                continue
            indices = list(range(n))
            limit = plan[0].max_joints
            if n > limit:
                indices = sorted(sorted(indices, key=lambda i: -array[i].depth)[:limit])
            for i in indices:
                p = array[i].pos
                out.append(Contact((float(p[0]), float(p[1]), float(p[2])), g.solid, h.solid))
    return out


def _hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def static_balance(sim: Simulation, solids: list[SolidRec], contacts: list[Contact], tol: float = 1e-9) -> bool:
    """True when the bodies' centre of mass projects inside the support polygon of ``contacts``."""
    if not contacts:
        return False
    g = sim.gravity
    norm = m3.norm(g)
    if norm == 0.0:
        return False
    down = m3.scale(g, 1.0 / norm)
    # any two unit vectors orthogonal to gravity span the projection plane
    helper = (1.0, 0.0, 0.0) if abs(down[0]) < 0.9 else (0.0, 1.0, 0.0)
    u = m3.normalized(m3.cross(down, helper))
    v = m3.cross(down, u)
    bodies = {id(s.body): s.body for s in solids if s.body is not None}
    total = sum(b.mass for b in bodies.values())
    if total > 0:
        com = [sum(b.mass * b.pos[k] for b in bodies.values()) / total for k in range(3)]
    else:
        com = list(sim.solid_world_pose(solids[0]).t)
    c = (m3.dot(com, u), m3.dot(com, v))
    hull = _hull([(m3.dot(p.point, u), m3.dot(p.point, v)) for p in contacts])
    if len(hull) == 1:
        return abs(c[0] - hull[0][0]) <= tol and abs(c[1] - hull[0][1]) <= tol
    if len(hull) == 2:
        (ax, ay), (bx, by) = hull
        cross = (bx - ax) * (c[1] - ay) - (by - ay) * (c[0] - ax)
        length = ((bx - ax) ** 2 + (by - ay) ** 2) ** 0.5
        t = ((c[0] - ax) * (bx - ax) + (c[1] - ay) * (by - ay)) / (length * length)
        return abs(cross) <= tol * max(length, 1.0) and -tol <= t <= 1 + tol
    for i in range(len(hull)):
        (ax, ay), (bx, by) = hull[i], hull[(i + 1) % len(hull)]
        if (bx - ax) * (c[1] - ay) - (by - ay) * (c[0] - ax) < -tol:
            return False  # the hull is counter-clockwise: the CoM is right of an edge, outside
    return True
