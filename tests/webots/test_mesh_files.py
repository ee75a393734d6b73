"""Reading a Webots Mesh node's file (dualtwin.webots.mesh_files): STL, OBJ and COLLADA as Webots merges them."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots.mesh_files import MeshFileError, locate_mesh, read_mesh, read_mesh_node, url_extension
from dualtwin.webots.nodes import Node
from dualtwin.webots.protos import load_world_text
from tests.support.mesh_writers import binary_stl

TWO_OBJECTS = """\
# two objects; the first uses two materials
o first
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
usemtl red
f 1 2 3
f 1/1 2/2/2 4//4
usemtl blue
f 1 3 4
f 2 3 4
o second
v 5 0 0
v 6 0 0
v 5 1 0
v 6 1 0
f -4 -3 -1 -2
"""

COLLADA = """\
<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="tri-mesh" name="tri">
      <mesh>
        <source id="p"><float_array id="pa" count="12">0 0 0 100 0 0 0 100 0 100 100 0</float_array>
          <technique_common><accessor source="#pa" count="4" stride="3">
            <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
          </accessor></technique_common></source>
        <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
        <polylist count="1"><input semantic="VERTEX" source="#v" offset="0"/><vcount>4</vcount><p>0 1 3 2</p></polylist>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="Scene">
      <node id="up" name="up"><translate>0 0 50</translate><instance_geometry url="#tri-mesh"/></node>
      <node id="turned" name="turned"><rotate>0 0 1 90</rotate><instance_geometry url="#tri-mesh"/></node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
"""


def test_binary_and_ascii_stl_give_their_triangles(tmp_path: Path) -> None:
    tris = [((0, 0, 0), (1, 0, 0), (0, 1, 0)), ((0, 0, 0), (0, 0, 2), (1, 0, 0))]
    mesh = read_mesh(binary_stl(tmp_path / "b.stl", tris))
    assert mesh.vertices.tolist() == [list(map(float, v)) for t in tris for v in t]
    assert mesh.triangles.tolist() == [[0, 1, 2], [3, 4, 5]]
    ascii_file = tmp_path / "a.STL"
    ascii_file.write_text("solid part\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1.5e0 0 0\n"
                          "   vertex 0 1 0\n  endloop\n endfacet\nendsolid part\n")
    mesh = read_mesh(ascii_file, name="part")
    assert mesh.vertices.tolist() == [[0, 0, 0], [1.5, 0, 0], [0, 1, 0]]
    with pytest.raises(MeshFileError, match="no triangles for name 'other'"):
        read_mesh(ascii_file, name="other")


def test_obj_objects_groups_materials_negative_indices_and_polygons(tmp_path: Path) -> None:
    path = tmp_path / "two.obj"
    path.write_text(TWO_OBJECTS)
    whole = read_mesh(path)
    assert len(whole.triangles) == 4 + 2  # the quad of "second" is two triangles
    second = read_mesh(path, name="second")
    assert second.vertices.tolist() == [[5, 0, 0], [6, 0, 0], [5, 1, 0], [6, 1, 0]]
    assert second.triangles.tolist() == [[0, 1, 3], [0, 3, 2]]  # fan of (-4 -3 -1 -2)
    red = read_mesh(path, material_index=0)
    assert len(red.triangles) == 2
    blue = read_mesh(path, material_index=1)  # "blue" stays current in "second", as OBJ's state does
    assert len(blue.triangles) == 2 + 2
    flipped = read_mesh(path, name="second", ccw=False)
    assert flipped.triangles.tolist() == [[3, 1, 0], [2, 3, 0]]


def test_collada_applies_node_transforms_and_the_unit(tmp_path: Path) -> None:
    path = tmp_path / "part.dae"
    path.write_text(COLLADA)
    mesh = read_mesh(path, name="tri")
    v = mesh.vertices
    assert len(mesh.triangles) == 4  # one quad in two nodes
    # pycollada composes the node transforms in single precision, as COLLADA's float arrays are
    np.testing.assert_allclose(v[:4], [[0, 0, 0.5], [1, 0, 0.5], [0, 1, 0.5], [1, 1, 0.5]], atol=1e-6)
    np.testing.assert_allclose(v[4:], [[0, 0, 0], [0, 1, 0], [-1, 0, 0], [-1, 1, 0]], atol=1e-6)


@pytest.mark.parametrize(("name", "content", "message"), [
    ("x.ply", b"ply\n", "format '.ply' is not read here"),
    ("x.stl", b"\0" * 10, "shorter than its 84-byte header"),
    ("x.stl", b"\0" * 80 + struct.pack("<I", 5), "announces 5 triangles but holds 0"),
    ("x.obj", b"v 0 0 0\nf 1 2 3\n", "vertex that does not exist"),
    ("x.obj", b"v 0 0 zero\n", "malformed OBJ"),
    ("x.dae", b"<COLLADA><oops", "malformed COLLADA"),
    ("missing.stl", None, "cannot read the mesh file"),
])
def test_a_bad_file_is_one_line(tmp_path: Path, name: str, content: bytes | None, message: str) -> None:
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(MeshFileError, match=message) as caught:
        read_mesh(path)
    assert "\n" not in str(caught.value)


def test_an_edited_file_is_read_again(tmp_path: Path) -> None:
    path = binary_stl(tmp_path / "p.stl", [((0, 0, 0), (1, 0, 0), (0, 1, 0))])
    assert len(read_mesh(path).triangles) == 1
    binary_stl(path, [((0, 0, 0), (1, 0, 0), (0, 1, 0))] * 3)
    assert len(read_mesh(path).triangles) == 3


def mesh_node_of(world: Path, url: str) -> Node:
    world.write_text(f'#VRML_SIM R2023b utf8\nSolid {{ children [ Shape {{ geometry Mesh {{ url "{url}" name "part" }} }} ] '
                     f'boundingObject Mesh {{ url "{url}" }} }}\n')
    loaded = load_world_text(world.read_text(), world)
    return [n for n in loaded.nodes[0].walk() if n.type_name == "Mesh"][0]


def test_a_mesh_url_is_joined_to_its_world_and_confined_to_the_project(tmp_path: Path) -> None:
    project = tmp_path / "project"
    (project / "worlds").mkdir(parents=True)
    (project / "protos" / "meshes").mkdir(parents=True)
    part = project / "protos" / "meshes" / "part.stl"
    part.write_text("solid part\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                    "endloop\nendfacet\nendsolid part\n")
    node = mesh_node_of(project / "worlds" / "w.wbt", "../protos/meshes/part.stl")
    assert locate_mesh(node) == part.resolve()
    assert read_mesh_node(node).triangles.shape == (1, 3)
    outside = tmp_path / "secret.stl"
    outside.write_bytes(part.read_bytes())
    for url in ("../../secret.stl", str(outside), "file://" + str(outside)):
        node = mesh_node_of(project / "worlds" / "w.wbt", url)
        with pytest.raises(MeshFileError, match="outside the project folder|is not read"):
            locate_mesh(node)


def test_a_webots_url_is_read_from_webots_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    home = tmp_path / "webots"
    target = home / "projects" / "meshes" / "m.stl"
    target.parent.mkdir(parents=True)
    binary_stl(target, [((0, 0, 0), (1, 0, 0), (0, 1, 0))])
    monkeypatch.setenv("WEBOTS_HOME", str(home))  # the environment a user sets; the lookup is what is tested
    (tmp_path / "worlds").mkdir()
    node = mesh_node_of(tmp_path / "worlds" / "w.wbt", "webots://projects/meshes/m.stl")
    assert locate_mesh(node) == target


def test_a_downloaded_file_is_read_in_the_format_its_url_names(tmp_path: Path) -> None:
    # the PROTO cache keeps a download under a name without extension: the url's says what the file is
    cached = binary_stl(tmp_path / "c160414dc0e2969b55d6989c08ca17134232409c", [((0, 0, 0), (1, 0, 0), (0, 1, 0))])
    with pytest.raises(MeshFileError, match="no extension"):
        read_mesh(cached)
    assert read_mesh(cached, extension=".STL").triangles.shape == (1, 3)
    (tmp_path / "worlds").mkdir()
    node = mesh_node_of(tmp_path / "worlds" / "w.wbt", "https://example.org/robot/meshes/Base.Link.DAE?raw=1")
    assert url_extension(node) == ".dae"
