"""A Webots ``Mesh`` as a boundingObject (dualtwin.webots.bounding_mesh): an ODE triangle mesh of its file's
triangles, weighed by dMassSetTrimesh, seen by rays; one warning and Webots' 1 kg fallback when it cannot be.

Every world is written into the test's folder (``worlds/w.wbt``, its mesh files beside it) and run on real ODE.
Controls: the same world with a ``Box`` of the mesh's shape. Before Mesh bounding objects were built, a Mesh
made no geom and weighed 1 kg with a warning that it is not supported: the mesh bodies fell through the floor,
the sensors saw nothing.
"""

from __future__ import annotations

import ctypes
import warnings
from collections.abc import Sequence
from pathlib import Path

import pytest

from dualtwin.webots import load_world, ode
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.mesh_writers import binary_stl, box_collada, box_obj, box_triangles

HEADER = "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n"
WEIGHTLESS = "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 gravity 0 }\n"
FLOOR = "Solid { name \"floor\" boundingObject Plane { size 10 10 } }\n"
# side 0.25, centred: STL holds single-precision floats and ODE's triangle collider (OPCODE) reads vertices as
# such, so the sides are exact in single precision for the masses to match a Box's to 1e-9
CUBE = box_triangles((-0.125, -0.125, -0.125), (0.125, 0.125, 0.125))
SIDE = 0.25
CUBE_MASS = 1000 * SIDE**3  # 15.625 kg


def world_in(tmp_path: Path, body: str, files: dict[str, str | bytes] | None = None, header: str = HEADER) -> Simulation:
    """A Simulation of ``header + body`` written as tmp_path/worlds/w.wbt, with ``files`` beside it."""
    folder = tmp_path / "worlds"
    folder.mkdir(exist_ok=True)
    for name, content in (files or {}).items():
        target = folder / name
        if isinstance(content, bytes):
            target.write_bytes(content)
        else:
            target.write_text(content)
    world = folder / "w.wbt"
    world.write_text(header + body)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world(world))


def stl(tmp_path: Path, name: str, triangles: Sequence[Sequence[Sequence[float]]]) -> bytes:
    return binary_stl(tmp_path / name, triangles).read_bytes()


def box_inertia(mass: float, sides: tuple[float, float, float]) -> tuple[float, float, float]:
    m = ode.dMass()
    ode.load().dMassSetBox(ctypes.byref(m), 1000.0, *sides)
    ode.load().dMassAdjust(ctypes.byref(m), mass)
    return float(m.I[0]), float(m.I[5]), float(m.I[10])


def diagonal(inertia: tuple[float, ...]) -> tuple[float, float, float]:
    return inertia[0], inertia[4], inertia[8]


def solid_z(sim: Simulation, name: str) -> float:
    solid = next(s for s in sim.solids if s.name == name)
    assert solid.body is not None
    return solid.body.pose().t[2]


def test_a_closed_stl_cube_weighs_like_its_box_and_rests_where_it_does(tmp_path: Path) -> None:
    cube = stl(tmp_path, "cube.stl", CUBE)
    sim = world_in(tmp_path, FLOOR + (
        'Solid { name "mesh" translation 0 0 0.3 boundingObject Mesh { url "cube.stl" } '
        "physics Physics { density 1000 } }\n"
        'Solid { name "box" translation 1 0 0.3 boundingObject Box { size 0.25 0.25 0.25 } '
        "physics Physics { density 1000 } }\n"), {"cube.stl": cube})
    mesh, box = (next(s for s in sim.solids if s.name == n).body for n in ("mesh", "box"))
    assert mesh is not None and box is not None
    assert mesh.mass == pytest.approx(CUBE_MASS, abs=1e-9)
    assert mesh.com == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert diagonal(mesh.inertia) == pytest.approx(box_inertia(CUBE_MASS, (SIDE, SIDE, SIDE)), abs=1e-9)
    assert diagonal(box.inertia) == pytest.approx(box_inertia(CUBE_MASS, (SIDE, SIDE, SIDE)), abs=1e-12)  # control
    assert [g.kind for g in sim.solids[1].geoms] == ["Mesh"]
    sim.step(250)  # 2 s: both fell and settled
    assert solid_z(sim, "box") == pytest.approx(SIDE / 2, abs=2e-3)
    assert solid_z(sim, "mesh") == pytest.approx(solid_z(sim, "box"), abs=1e-3)
    sim.close()


@pytest.mark.parametrize(("physics", "mass"), [
    ("Physics { density 500 }", CUBE_MASS / 2),  # density scales the reference mass
    ("Physics { density -1 mass 3 }", 3.0),  # mass adjusts it
])
def test_density_and_mass_rescale_a_mesh_as_a_box(tmp_path: Path, physics: str, mass: float) -> None:
    cube = stl(tmp_path, "cube.stl", CUBE)
    sim = world_in(tmp_path, f'Solid {{ boundingObject Mesh {{ url "cube.stl" }} physics {physics} }}\n'
                             f'Solid {{ boundingObject Box {{ size {SIDE} {SIDE} {SIDE} }} physics {physics} }}\n',
                   {"cube.stl": cube})
    mesh, box = sim.bodies
    assert mesh.mass == pytest.approx(mass, abs=1e-9)
    assert box.mass == pytest.approx(mass, abs=1e-12)  # control
    assert diagonal(mesh.inertia) == pytest.approx(diagonal(box.inertia), abs=1e-9)
    sim.close()


def test_obj_and_collada_meshes_land_where_their_geometry_says(tmp_path: Path) -> None:
    # OBJ: a 0.25 x 0.25 x 0.375 box standing on the Solid's origin (its centre of volume 0.1875 m above it)
    obj = box_obj([("tall", (-0.125, -0.125, 0.0), (0.125, 0.125, 0.375))])
    # COLLADA in centimetres: a 20 cm cube centred 50 cm above the file's origin by its node's translate
    dae = box_collada((-10, -10, -10), (10, 10, 10), meter=0.01, translate=(0, 0, 50))
    sim = world_in(tmp_path, FLOOR + (
        'Solid { name "obj" translation 0 0 0.2 boundingObject Mesh { url "tall.obj" } physics Physics { } }\n'
        'Solid { name "dae" translation 1 0 0.2 boundingObject Mesh { url "cube.dae" } physics Physics { } }\n'
        'Solid { name "obj box" translation 2 0 0.2 boundingObject Pose { translation 0 0 0.1875 children [ '
        "Box { size 0.25 0.25 0.375 } ] } physics Physics { } }\n"), {"tall.obj": obj, "cube.dae": dae})
    bodies = {s.name: s.body for s in sim.solids if s.body is not None}
    assert bodies["obj"].mass == pytest.approx(23.4375, abs=1e-9)
    assert bodies["obj"].com == pytest.approx((0.0, 0.0, 0.1875), abs=1e-9)  # the volume's centroid
    assert bodies["dae"].mass == pytest.approx(8.0, rel=1e-6)  # 1 cm is not exact in single precision
    assert bodies["dae"].com == pytest.approx((0.0, 0.0, 0.5), abs=1e-6)
    assert bodies["obj box"].mass == pytest.approx(23.4375, abs=1e-9)  # control
    sim.step(375)  # 3 s
    # the OBJ box's bottom and the Solid's origin on the floor; the COLLADA cube's bottom 0.4 m above its origin
    assert solid_z(sim, "obj box") == pytest.approx(0.0, abs=4e-3)  # resting a few millimetres in (soft ERP)
    assert solid_z(sim, "obj") == pytest.approx(solid_z(sim, "obj box"), abs=1e-3)
    assert solid_z(sim, "dae") == pytest.approx(-0.4, abs=4e-3)
    sim.close()


def test_a_static_mesh_in_frames_and_shapes_holds_a_falling_box(tmp_path: Path) -> None:
    # a 1.25 x 1.25 x 0.25 slab (the cube scaled 5 x 5 x 1) inside Transform > Group > Shape, its top at z = 0.5
    cube = stl(tmp_path, "cube.stl", CUBE)
    sim = world_in(tmp_path, FLOOR + (
        'Solid { name "stand" boundingObject Transform { translation 0 0 0.375 scale 5 5 1 children [ Group { '
        'children [ Shape { geometry Mesh { url "cube.stl" } } ] } ] } }\n'
        'Solid { name "falling" translation 0 0 1 boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } }\n'
        'Solid { name "beside" translation 2 0 1 boundingObject Box { size 0.1 0.1 0.1 } physics Physics { } }\n'),
        {"cube.stl": cube})
    (stand,) = (s for s in sim.solids if s.name == "stand")
    assert [g.kind for g in stand.geoms] == ["Mesh"] and stand.geoms[0].body is None
    sim.step(250)
    assert solid_z(sim, "falling") == pytest.approx(0.55, abs=2e-3)
    assert solid_z(sim, "beside") == pytest.approx(0.05, abs=2e-3)  # control: the floor, off the stand
    sim.close()


def test_a_scaled_mesh_weighs_as_the_scaled_box(tmp_path: Path) -> None:
    cube = stl(tmp_path, "cube.stl", CUBE)
    scaled = "Transform {{ scale 2 1 0.5 children [ {} ] }}"
    mesh_bo, box_bo = scaled.format('Mesh { url "cube.stl" }'), scaled.format(f"Box {{ size {SIDE} {SIDE} {SIDE} }}")
    sim = world_in(tmp_path, (f"Solid {{ boundingObject {mesh_bo} physics Physics {{ }} }}\n"
                              f"Solid {{ boundingObject {box_bo} physics Physics {{ }} }}\n"), {"cube.stl": cube})
    mesh, box = sim.bodies
    assert mesh.mass == pytest.approx(CUBE_MASS, abs=1e-9) and box.mass == pytest.approx(CUBE_MASS, abs=1e-12)
    assert diagonal(mesh.inertia) == pytest.approx(box_inertia(CUBE_MASS, (0.5, 0.25, 0.125)), abs=1e-9)
    assert diagonal(box.inertia) == pytest.approx(diagonal(mesh.inertia), abs=1e-9)  # control
    sim.close()


@pytest.mark.parametrize(("mesh", "reason"), [
    ('Mesh { url "missing.stl" }', "cannot read the mesh file"),
    ('Mesh { url "empty.stl" }', "the mesh has no triangles"),
    ('Mesh { url "cube.stl" ccw FALSE }', "encloses no volume"),  # inside out: ODE's volume is negative
    ("Mesh { }", "Mesh has no url"),
])
def test_a_mesh_that_cannot_be_weighed_is_one_warning_and_webots_fallback(
    tmp_path: Path, mesh: str, reason: str
) -> None:
    files = {"cube.stl": stl(tmp_path, "cube.stl", CUBE), "empty.stl": stl(tmp_path, "empty.stl", [])}
    folder = tmp_path / "worlds"
    folder.mkdir()
    for name, content in files.items():
        (folder / name).write_bytes(content)
    world = folder / "w.wbt"
    world.write_text(HEADER + f'Solid {{ name "part" translation 0 0 1 boundingObject {mesh} '
                              "physics Physics { } }\n")
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        sim = Simulation(load_world(world))
    (body,) = sim.bodies
    assert body.mass == 1.0 and body.inertia == (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    lines = [w for w in sim.build_warnings if reason in w]
    assert len(lines) == 1, sim.build_warnings
    assert f"{world}:3:" in lines[0] and "\n" not in lines[0]  # the Mesh node's place in its file
    assert "1 kg" in lines[0]
    sim.close()


def test_the_sensors_that_use_bounding_objects_see_a_mesh(tmp_path: Path) -> None:
    # a mesh wall whose face is 0.5 m ahead of the sensors and a Box wall 1 m ahead of others (control)
    wall = stl(tmp_path, "wall.stl", box_triangles((0.0, -0.5, -0.5), (0.2, 0.5, 0.5)))
    sensors = " ".join(
        f'DistanceSensor {{ name "{kind}" translation 0 {y} 0 type "{kind}" lookupTable [ 0 0 0, 2 2 0 ] }}'
        for kind, y in (("generic", 0.0), ("sonar", 0.1), ("laser", -0.1)))
    sim_sup = world_in(tmp_path, (
        'Solid { name "mesh wall" translation 0.5 0 0.1 boundingObject Mesh { url "wall.stl" } }\n'
        'Solid { name "box wall" translation 1.1 3 0.1 boundingObject Box { size 0.2 1 1 } }\n'
        f"Robot {{ translation 0 0 0.1 supervisor TRUE children [ {sensors} "
        'DistanceSensor { name "control" translation 0 3 0 lookupTable [ 0 0 0, 2 2 0 ] } ] }\n'),
        {"wall.stl": wall})
    sup = Supervisor(simulation=sim_sup, robot_node=sim_sup.robots[0].node)
    devices = {n: sup.getDevice(n) for n in ("generic", "sonar", "laser", "control")}
    for device in devices.values():
        device.enable(8)
    sup.step(8)
    assert devices["control"].getValue() == pytest.approx(1.0, rel=1e-9)
    for kind in ("generic", "sonar", "laser"):
        assert devices[kind].getValue() == pytest.approx(0.5, rel=1e-6), kind
    sim_sup.close()


def test_a_touch_sensor_bounded_by_a_mesh_is_pressed(tmp_path: Path) -> None:
    cube = stl(tmp_path, "cube.stl", CUBE)
    sim = world_in(tmp_path, FLOOR + (
        'Robot { translation 0 0 0.3 supervisor TRUE children [ TouchSensor { name "mesh" '
        'boundingObject Mesh { url "cube.stl" } physics Physics { } } '
        'TouchSensor { name "air" translation 2 0 1 boundingObject Mesh { url "cube.stl" } } ] '
        'boundingObject Box { size 0.05 0.05 0.05 } physics Physics { } }\n'), {"cube.stl": cube})
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    pressed, free = sup.getDevice("mesh"), sup.getDevice("air")
    pressed.enable(8)
    free.enable(8)
    for _ in range(125):
        sup.step(8)
    assert pressed.getValue() == 1.0
    assert free.getValue() == 0.0  # control: a mesh touching nothing
    sim.close()


@pytest.mark.parametrize("occlusion", ["FALSE", "TRUE"])
def test_a_radar_sees_a_mesh_target_and_a_mesh_wall_hides_one(tmp_path: Path, occlusion: str) -> None:
    cube = stl(tmp_path, "cube.stl", CUBE)
    wall = stl(tmp_path, "wall.stl", box_triangles((-0.025, -0.5, -0.5), (0.025, 0.5, 0.5)))
    sim = world_in(tmp_path, (
        'Solid { name "mesh target" translation 2 1 0 radarCrossSection 1 boundingObject Mesh { url "cube.stl" } }\n'
        'Solid { name "hidden target" translation 3 0 0 radarCrossSection 1 boundingObject Box { size 0.1 0.1 0.1 } }\n'
        'Solid { name "wall" translation 1.5 0 0 boundingObject Mesh { url "wall.stl" } }\n'
        f'Robot {{ children [ Radar {{ name "radar" minRange 0.5 maxRange 10 occlusion {occlusion} '
        "horizontalFieldOfView 1.2 } ] }\n"), {"cube.stl": cube, "wall.stl": wall}, WEIGHTLESS)
    robot = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    radar = robot.getDevice("radar")
    radar.enable(8)
    robot.step(8)
    distances = sorted(t.distance for t in radar.getTargets())
    # the mesh target is seen where its Solid is; the Box behind the mesh wall only without occlusion (control)
    expected = [pytest.approx(5**0.5, abs=1e-9)] + ([pytest.approx(3.0, abs=1e-9)] if occlusion == "FALSE" else [])
    assert distances == expected
    sim.close()


def ifs_cube(ccw: bool, extra_face: str = "") -> str:
    """The 0.25 m cube as an IndexedFaceSet: its triangles outward counter-clockwise, or, with ``ccw`` FALSE,
    written clockwise (each reversed) as that flag declares."""
    points: list[tuple[float, float, float]] = []
    index: list[int] = []
    for tri in CUBE:
        ordered = tri if ccw else tri[::-1]
        for p in ordered:
            index.append(len(points))
            points.append(tuple(float(c) for c in p))  # type: ignore[arg-type]
        index.append(-1)
    coords = ", ".join(" ".join(f"{c:g}" for c in p) for p in points)
    faces = " ".join(str(i) for i in index) + extra_face
    return (f"IndexedFaceSet {{ ccw {'TRUE' if ccw else 'FALSE'} coord Coordinate {{ point [ {coords} ] }} "
            f"coordIndex [ {faces} ] }}")


@pytest.mark.parametrize("ccw", [True, False])
def test_an_indexed_face_set_declared_clockwise_weighs_as_the_cube_it_is(tmp_path: Path, ccw: bool) -> None:
    # ccw FALSE says the faces are clockwise: the collision mesh and its mass turn them round, as the drawn
    # shape and the rays do. Ignoring the flag weighed the cube inside out (negative volume: the 1 kg fallback).
    # A face naming a point that does not exist is left out; the cube's own faces stay.
    sim = world_in(tmp_path, (
        f'Solid {{ name "ifs" boundingObject {ifs_cube(ccw, " 0 1 999 -1")} physics Physics {{ density 1000 }} }}\n'))
    body = next(s for s in sim.solids if s.name == "ifs").body
    assert body is not None
    assert body.mass == pytest.approx(CUBE_MASS, rel=1e-9)
    assert diagonal(body.inertia) == pytest.approx(box_inertia(CUBE_MASS, (SIDE, SIDE, SIDE)), rel=1e-9)
