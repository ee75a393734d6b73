"""Mesh and CadShape Shapes are seen as IndexedFaceSet Shapes are: by Lidar, RangeFinder and infra-red
DistanceSensor rays (visual rays), by the Camera image, its recognition segmentation and its object boxes.

Worlds are written into a project folder under tmp_path with their mesh files (binary STL, OBJ) generated
here; the meshes are boxes, so every expectation follows from the box's place and size. Controls: the same
box as an IndexedFaceSet (rays) or a Box (camera) gives the same readings and pixels, and before Mesh and
CadShape were drawn every ray passed through them (+inf, the infra-red table's far end) and the camera saw the
background.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots import load_world
from dualtwin.webots.camera import Camera
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.shapes import CAD_SHAPE_RGBA
from tests.support.mesh_worlds import box_mesh, write_obj, write_stl, write_world

RED = "appearance PBRAppearance { baseColor 1 0 0 roughness 1 metalness 0 }"


def _geometry(kind: str, project: Path, size: tuple[float, float, float]) -> str:
    """A Shape (or CadShape) drawing a box of ``size`` centred at its frame's origin, by ``kind``."""
    vertices, triangles = box_mesh(size)
    if kind == "ifs":
        points = ", ".join(" ".join(repr(v) for v in p) for p in vertices.tolist())
        index = ", ".join(f"{a} {b} {c} -1" for a, b, c in triangles.tolist())
        return f"Shape {{ {RED} geometry IndexedFaceSet {{ coord Coordinate {{ point [ {points} ] }} coordIndex [ {index} ] }} }}"
    if kind == "box":
        return f"Shape {{ {RED} geometry Box {{ size {size[0]} {size[1]} {size[2]} }} }}"
    if kind == "stl":
        write_stl(project / "meshes" / "box.stl", vertices, triangles)
        return f'Shape {{ {RED} geometry Mesh {{ url "../meshes/box.stl" }} }}'
    if kind == "obj":
        write_obj(project / "meshes" / "box.obj", vertices, triangles)
        return f'Shape {{ {RED} geometry Mesh {{ url "../meshes/box.obj" }} }}'
    assert kind == "cad"
    write_obj(project / "meshes" / "box.obj", vertices, triangles)
    return 'CadShape { url "../meshes/box.obj" }'


def _supervisor(path: Path) -> tuple[Supervisor, Simulation]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world(path))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node), sim


RAYS = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
Solid {{ translation {x} 0 0 children [ {wall} ] }}
Solid {{ translation 0 {y} 0 rotation 0 0 1 1.5707963267948966 children [ Pose {{ children [ {wall} ] }} ] }}
Robot {{
  supervisor TRUE
  children [
    Lidar {{ name "lidar" horizontalResolution 3 fieldOfView 0.3 numberOfLayers 1 maxRange 3 }}
    Lidar {{ name "left" rotation 0 0 1 1.5707963267948966 horizontalResolution 1 fieldOfView 0.1
            numberOfLayers 1 maxRange 3 }}
    RangeFinder {{ name "depth" width 4 height 3 fieldOfView 0.3 maxRange 3 }}
    DistanceSensor {{ name "ir" type "infra-red" lookupTable [ 0 0 0, 4 4 0 ] }}
  ]
}}
"""


@pytest.mark.parametrize("kind", ["stl", "obj", "cad", "ifs"])
def test_lidar_range_finder_and_infra_red_rays_hit_a_mesh_wall_as_an_indexed_face_set(tmp_path: Path,
                                                                                     kind: str) -> None:
    # a wall 0.1 m thick, 1.2 m wide and tall, its near face d = 1.3 m ahead (+x); a second one on the left (+y)
    # whose near face is 0.7 m away. "ifs" is the control: the same triangles as an IndexedFaceSet.
    d, left, thick = 1.3, 0.7, 0.1
    wall = _geometry(kind, tmp_path, (thick, 1.2, 1.2))
    path = write_world(tmp_path, RAYS.format(x=d + thick / 2, y=left + thick / 2, wall=wall))
    sup, _ = _supervisor(path)
    devices = {n: sup.getDevice(n) for n in ("lidar", "left", "depth", "ir")}
    for device in devices.values():
        device.enable(8)
    sup.step(8)
    assert devices["lidar"].getRangeImage() == pytest.approx([d / math.cos(a) for a in (0.1, 0.0, -0.1)])
    assert devices["left"].getRangeImage() == pytest.approx([left])
    assert devices["depth"].getRangeImage() == pytest.approx([d] * 12)  # planar depth: the wall's distance
    # infra-red: distance over the reflection factor 0.2 + 0.8·red·(1 − 0.5·roughness): red 1 and roughness 1
    # for the red Shapes, the default colour's red and roughness 0 for a CadShape
    reflection = 0.2 + 0.8 * (CAD_SHAPE_RGBA[0] if kind == "cad" else 0.5)
    assert devices["ir"].getValue() == pytest.approx(d / reflection)


def test_an_unreadable_mesh_is_not_seen_and_says_so_once(tmp_path: Path) -> None:
    wall = 'Shape { geometry Mesh { url "../meshes/missing.stl" } }'
    path = write_world(tmp_path, RAYS.format(x=1.35, y=0.75, wall=wall))
    sup, sim = _supervisor(path)
    lidar = sup.getDevice("lidar")
    lidar.enable(8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sup.step(8)
        sim.geometry_version += 1  # the visual geoms are built again (as after a supervisor's edit)
        sup.step(8)
    assert lidar.getRangeImage() == [math.inf] * 3
    lines = [w for w in sim.build_warnings if "missing.stl" in w]
    assert len(lines) == 2 and all("not seen by rays" in w and "\n" not in w for w in lines)  # one per Shape


CAMERA = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
DirectionalLight {{ direction 0 0 -1 }}
DEF OBJECT Solid {{ translation 2.25 0.5 0 recognitionColors [ 0 0 1 ] children [ {shape} ] }}
Robot {{
  children [ Camera {{ name "cam" width 64 height 48 fieldOfView 1.5707963267948966
                       recognition Recognition {{ segmentation TRUE }} }} ]
  controller "<extern>"
  supervisor TRUE
}}
"""


def _frames(tmp_path: Path, shape: str) -> tuple[np.ndarray, np.ndarray, list[float], list[int], list[int]]:
    """The camera image and segmentation (BGRA), the object's size, image position and image size."""
    sup, _ = _supervisor(write_world(tmp_path, CAMERA.format(shape=shape)))
    cam = sup.getDevice("cam")
    assert isinstance(cam, Camera)
    cam.enable(8)
    cam.recognitionEnable(8)
    cam.enableRecognitionSegmentation()
    sup.step(8)
    image = np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(48, 64, 4).copy()
    segmentation = np.frombuffer(cam.getRecognitionSegmentationImage(), dtype=np.uint8).reshape(48, 64, 4).copy()
    (obj,) = cam.getRecognitionObjects()
    return image, segmentation, list(obj.getSize()), list(obj.getPositionOnImage()), list(obj.getSizeOnImage())


@pytest.mark.parametrize("kind", ["stl", "obj"])
def test_the_camera_draws_a_mesh_in_its_colour_where_a_box_is_drawn(tmp_path: Path, kind: str) -> None:
    # A 0.5 m cube centred at (2.25, 0.5, 0) in front of a camera with f = 32 px: its near face spans columns
    # 20..28 and rows 20..28 (see test_camera_recognition). Control: the same cube as a Box.
    image, segmentation, size, position, image_size = _frames(tmp_path / kind, _geometry(kind, tmp_path / kind,
                                                                                          (0.5, 0.5, 0.5)))
    box_image, box_segmentation, box_size, box_position, box_image_size = _frames(
        tmp_path / "box", _geometry("box", tmp_path / "box", (0.5, 0.5, 0.5)))
    red = (image[..., 2] > 100) & (image[..., 1] < 60) & (image[..., 0] < 60)
    assert red[21:28, 21:28].all() and not red[:, 32:].any()
    box_red = (box_image[..., 2] > 100) & (box_image[..., 1] < 60) & (box_image[..., 0] < 60)
    assert int((red != box_red).sum()) <= 4  # the same pixels, up to a few on the edges
    both = red & box_red
    assert np.abs(image[both].astype(int) - box_image[both].astype(int)).max() <= 8  # the same shading
    blue = (segmentation[..., 0] == 255) & (segmentation[..., 1] == 0) & (segmentation[..., 2] == 0)
    assert blue[21:28, 21:28].all() and int((blue != ((box_segmentation[..., 0] == 255)
                                                       & (box_segmentation[..., 2] == 0))).sum()) <= 4
    # the object box of a Solid without boundingObject comes from its Shapes: the mesh's, as the Box's
    assert size == pytest.approx(box_size, abs=1e-6) and size == pytest.approx([0.5, 0.5], abs=1e-6)
    assert position == box_position == [24, 24] and image_size == box_image_size == [9, 8]


def test_a_cad_shape_is_drawn_in_the_default_colour_as_a_box_of_that_colour(tmp_path: Path) -> None:
    image, segmentation, size, _, _ = _frames(tmp_path / "cad", _geometry("cad", tmp_path / "cad", (0.5, 0.5, 0.5)))
    grey = " ".join(repr(v) for v in CAD_SHAPE_RGBA[:3])
    control = f"Shape {{ appearance PBRAppearance {{ baseColor {grey} }} geometry Box {{ size 0.5 0.5 0.5 }} }}"
    box_image, *_ = _frames(tmp_path / "box", control)
    background = image[2, 2].copy()
    drawn = (image[..., :3] != background[:3]).any(axis=2)
    box_drawn = (box_image[..., :3] != background[:3]).any(axis=2)
    assert drawn[21:28, 21:28].all() and int((drawn != box_drawn).sum()) <= 4
    assert np.abs(image[drawn & box_drawn].astype(int) - box_image[drawn & box_drawn].astype(int)).max() <= 8
    assert (segmentation[21:28, 21:28, 0] == 255).all() and size == pytest.approx([0.5, 0.5], abs=1e-6)
