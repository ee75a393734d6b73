"""The converter maps Mesh and CadShape to MuJoCo meshes (dualtwin.convert.surfaces).

A robot whose boundingObject is a Mesh of a box (binary STL, OBJ) weighs, balances and rests on a floor as
the same robot with a Box (control): the mass comes from Webots' rule (ODE's dMassSetTrimesh at the Solid's
density, which for a closed box is the box's), collisions from MuJoCo's convex hull of the triangles. Visual
Mesh and CadShape Shapes become visual mesh geoms. Worlds are written into a project folder under tmp_path
with their mesh files; before, every Mesh and CadShape stopped the conversion (unsupported node).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.convert import ConversionError, convert_world
from dualtwin.webots.shapes import CAD_SHAPE_RGBA
from tests.support.mesh_worlds import box_mesh, write_obj, write_stl, write_world

# Binary fractions, exact in an STL's float32 coordinates, so the mesh is the Box to the last bit.
SIZE = (0.25, 0.375, 0.5)
OFFSET = (0.0625, -0.03125, 0.046875)  # the box's centre in the robot frame: the centre of mass moves with it
WORLD = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 4 }}
Solid {{ name "floor" boundingObject Plane {{ size 10 10 }} }}
DEF BLOCK Robot {{
  translation 0 0 {z}
  children [ {visual} ]
  boundingObject {bounding}
  physics Physics {{ density 700 }}
}}
"""
POSE = f"Pose {{ translation {OFFSET[0]} {OFFSET[1]} {OFFSET[2]} children [ %s ] }}"
BOX = POSE % f"Box {{ size {SIZE[0]} {SIZE[1]} {SIZE[2]} }}"


def _project(tmp_path: Path, bounding: str, visual: str = "", z: float = 0.5) -> Path:
    # centred on the file's origin: ODE's dMassSetTrimesh (Webots' rule) is the box's inertia only for a mesh
    # whose centroid is its frame's origin (for another it adds twice the parallel-axis term, as Webots would)
    vertices, triangles = box_mesh(SIZE)
    write_stl(tmp_path / "meshes" / "block.stl", vertices, triangles)
    write_obj(tmp_path / "meshes" / "block.obj", vertices, triangles)
    return write_world(tmp_path, WORLD.format(z=z, bounding=bounding, visual=visual))


def _convert(path: Path):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return convert_world(path)


@pytest.mark.parametrize("url", ["block.stl", "block.obj"])
def test_a_mesh_bounding_object_weighs_and_rests_as_the_box_it_encloses(tmp_path: Path, url: str) -> None:
    mesh = _convert(_project(tmp_path / "mesh", POSE % f'Mesh {{ url "../meshes/{url}" }}'))
    box = _convert(_project(tmp_path / "box", BOX))
    m, b = mesh.compile(), box.compile()
    body_m, body_b = m.body("BLOCK"), b.body("BLOCK")
    expected = 700.0 * SIZE[0] * SIZE[1] * SIZE[2]
    assert float(body_b.mass[0]) == pytest.approx(expected, rel=1e-12)
    assert float(body_m.mass[0]) == pytest.approx(float(body_b.mass[0]), rel=1e-9)
    assert body_m.ipos == pytest.approx(body_b.ipos, rel=1e-9, abs=1e-12)
    assert body_m.ipos == pytest.approx(OFFSET, abs=1e-9)
    assert body_m.inertia == pytest.approx(body_b.inertia, rel=1e-9)
    geom = m.geom(m.body_geomadr[body_m.id])
    assert int(geom.type[0]) == mujoco.mjtGeom.mjGEOM_MESH and int(geom.contype[0]) != 0
    assert any("Mesh collisions use the mesh's convex hull" in w for w in mesh.warnings)
    # dropped from 0.5 m onto the floor, it rests with its centre half its height above it, as the Box does
    rest = {}
    for name, model in (("mesh", m), ("box", b)):
        data = mujoco.MjData(model)
        mujoco.mj_step(model, data, nstep=int(1.5 / model.opt.timestep))
        rest[name] = float(data.xipos[body_m.id][2])
        assert np.abs(data.qvel).max() < 1e-2, name
    assert rest["mesh"] == pytest.approx(SIZE[2] / 2, abs=2e-3)
    assert rest["mesh"] == pytest.approx(rest["box"], abs=1e-4)


def test_visual_mesh_and_cad_shape_become_visual_mesh_geoms_and_the_model_is_the_same_each_time(
        tmp_path: Path) -> None:
    visual = ('Shape { appearance PBRAppearance { baseColor 0 0.5 1 } geometry Mesh { url "../meshes/block.stl" } } '
              'Pose { translation 0 0 0.5 children [ CadShape { url "../meshes/block.obj" } ] }')
    visual = POSE % visual
    path = _project(tmp_path, BOX, visual)
    conversion = _convert(path)
    model = conversion.compile()
    visuals = [g for g in range(model.ngeom) if model.geom_group[g] == 2]
    assert len(visuals) == 2
    # the STL's triangles have 3 vertices each, the OBJ's share the box's 8 corners
    for g, rgba, z, nvert in zip(visuals, ([0.0, 0.5, 1.0, 1.0], list(CAD_SHAPE_RGBA)), (0.0, 0.5), (36, 8),
                                 strict=True):
        assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0
        assert model.geom_rgba[g].tolist() == pytest.approx(rgba)
        mesh = int(model.geom_dataid[g])
        assert model.mesh_vertnum[mesh] == nvert and model.mesh_facenum[mesh] == 12
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        # the mesh's centre where the box's centre is (MuJoCo recentres mesh vertices at the geom's frame)
        assert data.geom_xpos[g] - data.xpos[model.geom_bodyid[g]] == pytest.approx(
            np.array(OFFSET) + [0.0, 0.0, z], abs=1e-9)
    assert not any("skipped" in w for w in conversion.warnings)
    assert _convert(path).xml == conversion.xml  # the same world gives the same model, byte for byte


def test_an_unreadable_mesh_file_skips_a_visual_and_stops_a_bounding_object(tmp_path: Path) -> None:
    missing = 'Mesh { url "../meshes/missing.stl" }'
    conversion = _convert(_project(tmp_path / "visual", BOX, f"Shape {{ geometry {missing} }}"))
    (line,) = [w for w in conversion.warnings if "missing.stl" in w]
    assert line.startswith("visual Mesh skipped: ") and "mesh.wbt:" in line and "\n" not in line
    assert all(conversion.compile().geom_group[g] != 2 for g in range(conversion.compile().ngeom))
    with pytest.raises(ConversionError, match=r"mesh\.wbt:\d+:\d+: .*missing\.stl.*a boundingObject"):
        _convert(_project(tmp_path / "bounding", missing))
    with pytest.raises(ConversionError, match=r"unsupported node CadShape \(in a boundingObject\)"):
        _convert(_project(tmp_path / "cad", 'CadShape { url "../meshes/block.obj" }'))


@pytest.mark.parametrize("index", ["99999999999999999999999", "-99999999999999999999999", "0"])
def test_an_obj_face_index_that_cannot_exist_is_one_line_not_a_traceback(tmp_path: Path, index: str) -> None:
    # Found by fuzzing `dualtwin convert` with hostile mesh files: an index past int64 raised OverflowError
    # (a traceback) building the triangle array; index 0 (OBJ counts from 1) is no vertex either.
    project = tmp_path / "p"
    (project / "meshes").mkdir(parents=True)
    (project / "meshes" / "bad.obj").write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 {index}\nv 1 1 1\n")
    with pytest.raises(ConversionError, match=rf"bad\.obj: OBJ face refers to vertex {index}, which cannot exist"):
        _convert(_project(project, POSE % 'Mesh { url "../meshes/bad.obj" }'))
