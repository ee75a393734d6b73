"""A supervisor's edit of a bounding ``Mesh``'s ``url``, ``name``, ``materialIndex`` or ``ccw`` builds its geom
again from the file at the next step, and the mass of the body it bounds follows (Webots re-reads the mesh).

One-ray generic distance sensors whose table maps distance to itself look at mesh walls; the edit is made on the
visual Shape's DEF Mesh while the boundingObject is a USE of it, as worlds do. Controls: a Box wall that no edit
touches, and the reading before the edit. Before Mesh edits were applied, the field read back the new value while
the geom kept the old triangles (or, before Mesh bounding objects were built, there was no geom at all).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.mesh_writers import binary_stl, box_obj, box_triangles

HEADER = "#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n"
TABLE = "lookupTable [ 0 0 0, 2 2 0 ]"


def supervisor_in(tmp_path: Path, body: str) -> Supervisor:
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(HEADER + body)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world(world))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def mesh_files(tmp_path: Path) -> None:
    """Slabs 1 m tall and wide, 0.25 m deep, seen from the origin along +x: near.stl's face at x = 0.5 (in the
    wall Solid's frame x = 0), far.stl's at 0.75; walls.obj holds both as objects "near" and "far", with
    materials "a" and "b"."""
    folder = tmp_path / "worlds"
    folder.mkdir()
    binary_stl(folder / "near.stl", box_triangles((0.0, -0.5, -0.5), (0.25, 0.5, 0.5)))
    binary_stl(folder / "far.stl", box_triangles((0.25, -0.5, -0.5), (0.5, 0.5, 0.5)))
    obj = box_obj([("near", (0.0, -0.5, -0.5), (0.25, 0.5, 0.5)), ("far", (0.25, -0.5, -0.5), (0.5, 0.5, 0.5))])
    lines = obj.splitlines()
    lines.insert(lines.index("o near") + 9, "usemtl a")  # before the faces of "near"
    lines.insert(lines.index("o far") + 9, "usemtl b")
    (folder / "walls.obj").write_text("\n".join(lines) + "\n")


def wall_world(mesh: str) -> str:
    return (
        f'Solid {{ translation 0.5 0 0 children [ Shape {{ geometry DEF WALL {mesh} }} ] boundingObject USE WALL }}\n'
        "Solid { translation 1.125 3 0 boundingObject Box { size 0.25 1 1 } }\n"
        f'Robot {{ supervisor TRUE children [ DistanceSensor {{ name "mesh" {TABLE} }} '
        f'DistanceSensor {{ name "box" translation 0 3 0 {TABLE} }} ] }}\n'
    )


def readings(sup: Supervisor) -> tuple[float, float]:
    sup.step(8)
    return sup.getDevice("mesh").getValue(), sup.getDevice("box").getValue()


def enabled(sup: Supervisor) -> Supervisor:
    for name in ("mesh", "box"):
        sup.getDevice(name).enable(8)
    return sup


def test_a_new_url_is_read_and_seen_at_the_next_step(tmp_path: Path) -> None:
    mesh_files(tmp_path)
    sup = enabled(supervisor_in(tmp_path, wall_world('Mesh { url "near.stl" }')))
    assert readings(sup) == pytest.approx((0.5, 1.0), rel=1e-6)
    url = sup.getFromDef("WALL").getField("url")
    url.setMFString(0, "far.stl")
    assert readings(sup) == pytest.approx((0.75, 1.0), rel=1e-6)
    assert url.getMFString(0) == "far.stl"
    # an unreadable url: Webots' fallback (no geom), one warning naming the node and the file
    url.setMFString(0, "gone.stl")
    mesh_reading, _ = readings(sup)
    assert mesh_reading == 2.0  # nothing in range: the table's last value
    assert sum("gone.stl" in w and "cannot read" in w for w in sup.simulation.build_warnings) == 1
    # a reset puts the url and the geom back as they were at load
    sup.simulationReset()
    sup.step(8)
    assert readings(sup) == pytest.approx((0.5, 1.0), rel=1e-6)
    sup.simulation.close()


def test_a_mesh_unreadable_at_load_gets_its_geom_when_its_url_is_fixed(tmp_path: Path) -> None:
    mesh_files(tmp_path)
    sup = enabled(supervisor_in(tmp_path, wall_world('Mesh { url "nothing-yet.stl" }')))
    assert readings(sup)[0] == 2.0
    sup.getFromDef("WALL").getField("url").setMFString(0, "near.stl")
    assert readings(sup) == pytest.approx((0.5, 1.0), rel=1e-6)
    sup.simulation.close()


@pytest.mark.parametrize(("field", "value", "before", "after"), [
    ("name", "far", 0.5, 0.75),  # the object named "near", then the one named "far"
    ("materialIndex", 1, 0.5, 0.75),  # material "a" (index 0), then "b"
])
def test_name_and_material_index_select_other_triangles(
    tmp_path: Path, field: str, value: str | int, before: float, after: float
) -> None:
    mesh_files(tmp_path)
    initial = 'name "near"' if field == "name" else "materialIndex 0"
    sup = enabled(supervisor_in(tmp_path, wall_world(f'Mesh {{ url "walls.obj" {initial} }}')))
    assert readings(sup) == pytest.approx((before, 1.0), rel=1e-6)
    handle = sup.getFromDef("WALL").getField(field)
    if field == "name":
        handle.setSFString(value)
    else:
        handle.setSFInt32(value)
    assert readings(sup) == pytest.approx((after, 1.0), rel=1e-6)
    sup.simulation.close()


def test_turning_a_mesh_inside_out_gives_its_body_webots_fallback_mass(tmp_path: Path) -> None:
    mesh_files(tmp_path)
    sup = supervisor_in(tmp_path, (
        'DEF PART Solid { translation 0 0 5 boundingObject DEF HULL Mesh { url "near.stl" } physics Physics { } }\n'
        'Solid { translation 3 0 5 boundingObject Box { size 0.25 1 1 } physics Physics { } }\n'
        "Robot { supervisor TRUE }\n"))
    sim = sup.simulation
    part, box = sim.bodies
    assert part.mass == pytest.approx(250.0, abs=1e-9) and box.mass == pytest.approx(250.0, abs=1e-9)
    hull = sup.getFromDef("HULL").getField("ccw")
    hull.setSFBool(False)  # the triangles face inwards: ODE's volume is negative, Webots falls back to 1 kg
    sup.step(8)
    assert part.mass == 1.0 and part.inertia == (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    assert sum("encloses no volume" in w for w in sim.build_warnings) == 1
    hull.setSFBool(True)
    sup.step(8)
    assert part.mass == pytest.approx(250.0, abs=1e-9)
    assert box.mass == pytest.approx(250.0, abs=1e-9)  # control
    sim.close()


def test_a_proto_parameter_that_names_the_mesh_rebuilds_its_geom(tmp_path: Path) -> None:
    # a local PROTO whose boundingObject Mesh takes its url from a parameter; its relative urls name files
    # beside the PROTO file (protos/), and the supervisor edits the parameter on the instance
    mesh_files(tmp_path)
    protos = tmp_path / "protos"
    protos.mkdir()
    for name in ("near.stl", "far.stl"):
        (protos / name).write_bytes((tmp_path / "worlds" / name).read_bytes())
    (protos / "MeshWall.proto").write_text(
        "#VRML_SIM R2023b utf8\nPROTO MeshWall [ field SFVec3f translation 0.5 0 0 field MFString meshUrl "
        '"near.stl" ]\n{ Solid { translation IS translation boundingObject Mesh { url IS meshUrl } } }\n')
    sup = enabled(supervisor_in(tmp_path, (
        'EXTERNPROTO "../protos/MeshWall.proto"\nDEF WALL MeshWall { }\n'
        "Solid { translation 1.125 3 0 boundingObject Box { size 0.25 1 1 } }\n"
        f'Robot {{ supervisor TRUE children [ DistanceSensor {{ name "mesh" {TABLE} }} '
        f'DistanceSensor {{ name "box" translation 0 3 0 {TABLE} }} ] }}\n')))
    assert readings(sup) == pytest.approx((0.5, 1.0), rel=1e-6)
    sup.getFromDef("WALL").getField("meshUrl").setMFString(0, "far.stl")
    assert readings(sup) == pytest.approx((0.75, 1.0), rel=1e-6)
    sup.simulation.close()
