"""Buoyancy of closed triangle meshes (IndexedFaceSet and Mesh bounding objects) in a Fluid: ρ_fluid · V · g at
the centroid of the immersed part V, computed exactly from the mesh's signed tetrahedra clipped by the fluid box.

The pool is a Fluid Box 4 × 4 × 1 m (surface at z = 1) as in test_fluid_buoyancy.py; mesh files are written
beside the world. Controls: the same Box; an open mesh (it encloses no volume) gets no force and a warning.
Before meshes were immersed, a Mesh or IndexedFaceSet bounding object got no force at all (and a Mesh no geom).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world
from dualtwin.webots.physics import Simulation
from tests.support.mesh_writers import BOX_FACES, binary_stl, box_corners, box_triangles

G = 9.81
H = 0.016
POOL = 'Fluid { translation 0 0 0.5 boundingObject Box { size 4 4 1 } }\n'
IMMERSED = 'immersionProperties [ ImmersionProperties { fluidName "fluid" } ]'
# a U-shaped prism (not convex): in x-z the polygon below, 0.2 m along y, a 0.3 × 0.1 m base and two 0.1 m prongs
# up to z = 0.2 with a notch between them; its caps triangulated by hand (each triangle inside the U)
U_OUTLINE = [(0.0, 0.0), (0.3, 0.0), (0.3, 0.2), (0.2, 0.2), (0.2, 0.1), (0.1, 0.1), (0.1, 0.2), (0.0, 0.2)]
U_CAP = [(0, 1, 4), (1, 2, 4), (2, 3, 4), (0, 4, 5), (0, 5, 7), (5, 6, 7)]


def u_prism_obj() -> str:
    k = len(U_OUTLINE)
    lines = [f"v {x!r} {y!r} {z!r}" for y in (0.0, 0.2) for x, z in U_OUTLINE]
    # the outline runs counter-clockwise seen from -y: the y = 0 cap faces -y as written, the y = 0.2 cap reversed
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in U_CAP]
    lines += [f"f {k + a + 1} {k + c + 1} {k + b + 1}" for a, b, c in U_CAP]
    for i in range(k):
        j = (i + 1) % k
        lines.append(f"f {i + 1} {k + i + 1} {k + j + 1} {j + 1}")
    return "\n".join(lines) + "\n"


def pool_world(tmp_path: Path, solids: str, files: dict[str, bytes | str]) -> Simulation:
    folder = tmp_path / "worlds"
    folder.mkdir(exist_ok=True)
    for name, content in files.items():
        if isinstance(content, bytes):
            (folder / name).write_bytes(content)
        else:
            (folder / name).write_text(content)
    world = folder / "w.wbt"
    world.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 16 }\n" + POOL + solids)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world(world))


def cube_stl(tmp_path: Path) -> bytes:
    return binary_stl(tmp_path / "cube.stl", box_triangles((-0.125,) * 3, (0.125,) * 3)).read_bytes()


def test_a_mesh_cube_partly_immersed_is_pushed_as_its_box_twin(tmp_path: Path) -> None:
    # both 0.25 cubes (density 500: 7.8125 kg) level, centres 5 cm below the surface: V = 0.25 · 0.25 · 0.175
    ifs_points = ", ".join(" ".join(repr(v) for v in c) for c in box_corners((-0.125,) * 3, (0.125,) * 3))
    ifs_index = " ".join(f"{a} {b} {c} -1" for a, b, c in BOX_FACES)
    bounding = {"mesh": 'Mesh { url "cube.stl" }', "box": "Box { size 0.25 0.25 0.25 }",
                "ifs": f"IndexedFaceSet {{ coord Coordinate {{ point [ {ifs_points} ] }} coordIndex [ {ifs_index} ] }}"}
    solids = "".join(f'Solid {{ name "{name}" translation {x} 0 0.95 boundingObject {bo} '
                     f"physics Physics {{ density 500 }} {IMMERSED} }}\n"
                     for x, (name, bo) in zip((-1, 0, 1), bounding.items(), strict=True))
    sim = pool_world(tmp_path, solids, {"cube.stl": cube_stl(tmp_path)})
    sim.step(1)
    force = 1000.0 * 0.25 * 0.25 * 0.175 * G
    for body in sim.bodies:
        assert body.mass == pytest.approx(7.8125, abs=1e-9)
        vx, vy, vz = body.lvel[:3]
        assert vz == pytest.approx(H * (force / 7.8125 - G), rel=1e-9), body.root.name
        assert abs(vx) < 1e-12 and abs(vy) < 1e-12 and max(map(abs, body.avel[:3])) < 1e-9
    sim.close()


def test_a_non_convex_mesh_displaces_exactly_its_immersed_part(tmp_path: Path) -> None:
    # the U stands on its base, 0.15 m of it under water: the base (0.3 · 0.1 · 0.2 m³, centroid x 0.15, z 0.05
    # above the bottom) and 5 cm of each prong (0.1 · 0.05 · 0.2, centroids x 0.05 and 0.25, z 0.125); the
    # water line cuts the mesh in two separate rectangles (a convex clipper would close them as one)
    sim = pool_world(tmp_path, 'Solid { translation 0 0 0.85 boundingObject Mesh { url "u.obj" } '
                               f"physics Physics {{ density 500 }} {IMMERSED} }}\n", {"u.obj": u_prism_obj()})
    assert sim.bodies[0].mass == pytest.approx(500 * 0.05 * 0.2, rel=1e-6)  # the U's area · length · density
    sim.step(1)
    ((_, force, centroid),) = sim.extensions["buoyancy"].last_forces
    volume = 0.3 * 0.1 * 0.2 + 2 * 0.1 * 0.05 * 0.2
    assert force == pytest.approx((0.0, 0.0, 1000.0 * volume * G), rel=1e-9, abs=1e-12)
    z = 0.85 + (0.006 * 0.05 + 0.002 * 0.125) / volume
    assert centroid == pytest.approx((0.15, 0.1, z), abs=1e-9)
    sim.close()


def test_a_light_mesh_cube_floats_at_the_archimedes_depth(tmp_path: Path) -> None:
    sim = pool_world(tmp_path, 'Solid { translation 0 0 1.3 boundingObject Mesh { url "cube.stl" } physics Physics '
                               f"{{ density 400 damping Damping {{ linear 0.9 angular 0.9 }} }} {IMMERSED} }}\n",
                     {"cube.stl": cube_stl(tmp_path)})
    sim.step(int(12.0 / H))
    depth = 0.4 * 0.25
    assert sim.bodies[0].pos[2] == pytest.approx(1.0 - depth + 0.125, abs=2e-3)
    sim.close()


def test_an_open_mesh_is_not_immersed_and_says_so(tmp_path: Path) -> None:
    lidless = box_triangles((-0.125,) * 3, (0.125,) * 3)[:-2]  # the last two triangles close the top (z = +)
    open_stl = binary_stl(tmp_path / "open.stl", lidless).read_bytes()
    sim = pool_world(tmp_path, 'Solid { translation 0 0 0.5 boundingObject Mesh { url "open.stl" } '
                               f"physics Physics {{ mass 1 }} {IMMERSED} }}\n", {"open.stl": open_stl})
    assert any("open Mesh" in w for w in sim.build_warnings)
    sim.step(10)
    assert sim.bodies[0].lvel[2] == pytest.approx(-10 * H * G, rel=1e-12)  # falls as in air
    sim.close()
