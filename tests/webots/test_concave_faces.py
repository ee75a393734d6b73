"""A concave IndexedFaceSet face becomes triangles that cover the face and nothing else (webots-on-ode.md §3.4: the
bounding IndexedFaceSet is ODE's triangle mesh of its triangulated faces; the rays and the renderer see the same
triangles, dualtwin.webots.shapes).

The face is an L: the square [0, 2] × [0, 2] at z = 0 less its corner [1, 2] × [1, 2] (area 4 − 1 = 3 m²), its
corners listed from (2, 0), a corner that does not see the notch's far side. Fanned from that corner, the triangle
(2, 0), (1, 1), (1, 2) lies partly in the notch: at y = 1.3 it spans x ∈ [1, 1.35] (the edge from (2, 0) to
(1, 2) is x = 2 − y/2), so a floor made of that fan holds a ball dropped at (1.2, 1.3) though the face has
nothing there. The same face in an OBJ file (a bounding Mesh) is cut the same way. Controls: before this change
the ball rested on that phantom triangle at z = 0.05.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots.polygons import triangulate_polygon
from tests.support.quiet_worlds import quiet_supervisor

TS = 8
L_CORNERS = [(2, 0, 0), (2, 1, 0), (1, 1, 0), (1, 2, 0), (0, 2, 0), (0, 0, 0)]
L_POINTS = ", ".join(" ".join(str(c) for c in p) for p in L_CORNERS)


def _area(points: np.ndarray, tri: tuple[int, int, int]) -> float:
    a, b, c = points[list(tri)]
    return float(np.linalg.norm(np.cross(b - a, c - a))) / 2


def _in_l(x: float, y: float) -> bool:
    return 0 <= x <= 2 and 0 <= y <= 2 and not (x > 1 and y > 1)


@pytest.mark.parametrize("plane", ["xy", "xz"])
def test_the_triangles_of_an_l_shaped_face_cover_the_l_only(plane: str) -> None:
    points = np.array(L_CORNERS, dtype=float)
    if plane == "xz":  # the same face standing up: its plane is found from the corners
        points = points[:, [0, 2, 1]]
    triangles = triangulate_polygon(points, range(6))
    assert len(triangles) == 4  # a hexagon: n - 2
    assert sum(_area(points, t) for t in triangles) == pytest.approx(3.0)  # the L's area, no overlap
    flat = points[:, [0, 1]] if plane == "xy" else points[:, [0, 2]]
    for t in triangles:
        cx, cy = flat[list(t)].mean(axis=0)
        assert _in_l(cx, cy)
        a, b, c = flat[list(t)]
        assert (b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0] > 0  # the face's winding (counter-clockwise) kept


def test_a_convex_face_is_fanned_from_its_first_corner() -> None:
    points = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0.5, 1.5, 0), (0, 1, 0)], dtype=float)
    assert triangulate_polygon(points, range(5)) == [(0, 1, 2), (0, 2, 3), (0, 3, 4)]


@pytest.mark.parametrize(("x", "y", "rests"), [(1.2, 1.3, False), (0.5, 0.5, True)])
def test_a_ball_falls_through_the_notch_of_an_l_shaped_floor_and_rests_on_the_l(x: float, y: float, rests: bool) -> None:
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{ supervisor TRUE }}
Solid {{ boundingObject IndexedFaceSet {{ coord Coordinate {{ point [ {L_POINTS} ] }} coordIndex [ 0 1 2 3 4 5 -1 ] }} }}
DEF BALL Solid {{ translation {x} {y} 0.5 boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }}
""")
    for _ in range(125):  # 1 s: a free fall of 0.5·g·1² = 4.9 m
        sup.step(TS)
    z = sup.getFromDef("BALL").getPosition()[2]
    if rests:
        assert z == pytest.approx(0.05, abs=0.005)  # on the face: its radius above z = 0
    else:
        assert z < -4.0


def test_a_ball_falls_through_the_notch_of_an_l_shaped_obj_face(tmp_path: Path) -> None:
    # the same L as one OBJ face (1-based corners); Webots reads the file's polygons as triangles covering them
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "l.obj").write_text(
        "".join(f"v {x} {y} {z}\n" for x, y, z in L_CORNERS) + "f 1 2 3 4 5 6\n")
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
Robot {{ supervisor TRUE }}
Solid {{ boundingObject Mesh {{ url "l.obj" }} }}
DEF NOTCH Solid {{ translation 1.2 1.3 0.5 boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }}
DEF ON_L Solid {{ translation 0.5 0.5 0.5 boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }}
""", tmp_path / "worlds" / "w.wbt")
    for _ in range(125):  # 1 s
        sup.step(TS)
    assert sup.getFromDef("NOTCH").getPosition()[2] < -4.0
    assert sup.getFromDef("ON_L").getPosition()[2] == pytest.approx(0.05, abs=0.005)
