"""Camera Recognition headless: which Solids a camera recognises, where, and the segmentation image.

Expectations by hand. The camera sits at the world origin, unrotated (looks along +x, +y left, +z up), 64×48
pixels, fieldOfView π/2: the focal length is f = (64/2)/tan(π/4) = 32 px for both axes and a point (x, y, z)
of the camera frame projects to u = 32 − 32·y/x, v = 24 − 32·z/x.

A 0.5 m cube centred at (2.25, 0.5, 0): its near face is at x = 2.0 (y 0.25..0.75, z ±0.25), its far face at
x = 2.5. Columns: the near face's left edge y = 0.75 gives u = 32 − 12 = 20, the right edge is the far face's
y = 0.25 corner, u = 32 − 3.2 = 28.8 (the near face's is 28): the box spans u 20..28.8, centre 24.4 → 24,
width 8.8 → 9. Rows: the near face's z = ±0.25 gives v = 24 ∓ 4: rows 20..28, centre 24, height 8.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots.camera import Camera
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.protos import load_world_text

W, H, FOV = 64, 48, math.pi / 2
HEAD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
DirectionalLight {{ direction 0 0 -1 }}
Robot {{
  children [ Camera {{ name "cam" width {W} height {H} fieldOfView {FOV!r} RECOGNITION }} ]
  controller "<extern>"
  supervisor TRUE
}}
"""


def box(name: str, x: float, y: float, z: float = 0.0, *, size: float = 0.5, colours: str = "1 0 0",
        rotation: str = "0 0 1 0", model: str = "") -> str:
    recognition = f"recognitionColors [ {colours} ]" if colours else ""
    rgb = colours.split(",")[0] if colours else "0 1 0"
    return (f'DEF {name} Solid {{ translation {x} {y} {z} rotation {rotation} name "{name}" model "{model}" '
            f"{recognition} children [ Shape {{ appearance PBRAppearance {{ baseColor {rgb} roughness 1 "
            f"metalness 0 }} geometry Box {{ size {size} {size} {size} }} }} ] "
            f"boundingObject Box {{ size {size} {size} {size} }} }}\n")


def camera(objects: str, recognition: str = "") -> tuple[Supervisor, Camera]:
    text = HEAD.replace("RECOGNITION", f"recognition Recognition {{ {recognition} }}") + objects
    sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    cam = sup.getDevice("cam")
    assert isinstance(cam, Camera)
    return sup, cam


def seen(objects: str, recognition: str = "") -> list[str]:
    """The DEF names of the objects recognised after one sample, in the order reported."""
    sup, cam = camera(objects, recognition)
    cam.recognitionEnable(8)
    sup.step(8)
    names = []
    for obj in cam.getRecognitionObjects():
        node = sup.getFromId(obj.getId())
        assert node is not None
        names.append(node.getDef())
    assert cam.getRecognitionNumberOfObjects() == len(names)
    return names


def test_a_box_at_a_known_pose_is_reported_with_its_id_position_size_and_image_box() -> None:
    sup, cam = camera(box("BOX", 2.25, 0.5, model="red box") + box("TURNED", 4.0, -1.0, colours="0 0 1, 0 1 0",
                                                                  rotation="0 0 1 0.3"))
    assert cam.hasRecognition()
    cam.recognitionEnable(8)
    assert cam.getRecognitionSamplingPeriod() == 8
    sup.step(8)
    objects = cam.getRecognitionObjects()
    assert len(objects) == 2
    near, turned = objects  # nearest first
    node = sup.getFromId(near.getId())
    assert node is not None and node.getDef() == "BOX" and near.getId() == sup.getFromDef("BOX").getId()
    assert near.getPosition() == pytest.approx([2.25, 0.5, 0.0], abs=1e-9)
    assert near.getOrientation()[3] == pytest.approx(0.0, abs=1e-9)
    assert near.getSize() == pytest.approx([0.5, 0.5], abs=1e-9)
    assert near.getPositionOnImage() == [24, 24] and near.getSizeOnImage() == [9, 8]
    assert (near.getNumberOfColors(), near.getColors(), near.getModel(), near.model) == (1, [1.0, 0.0, 0.0],
                                                                                        "red box", "red box")
    # the second box: turned 0.3 rad about z, two colours; its extent along the camera's y grows by the turn
    assert turned.getPosition() == pytest.approx([4.0, -1.0, 0.0], abs=1e-9)
    assert turned.getOrientation() == pytest.approx([0.0, 0.0, 1.0, 0.3], abs=1e-9)
    assert turned.getSize() == pytest.approx([0.5 * (math.cos(0.3) + math.sin(0.3)), 0.5], abs=1e-9)
    assert (turned.getNumberOfColors(), turned.getColors()) == (2, [0.0, 0.0, 1.0, 0.0, 1.0, 0.0])
    # the record follows the box: moved 1 m away, its image box shrinks
    sup.getFromDef("BOX").getField("translation").setSFVec3f([3.25, 0.5, 0.0])
    sup.step(8)
    moved = cam.getRecognitionObjects()[0]
    assert moved.getPosition() == pytest.approx([3.25, 0.5, 0.0], abs=1e-9)
    assert moved.getSizeOnImage()[1] == round(2 * 32 * 0.25 / 3.0)  # rows 24 ∓ 32·0.25/3


def test_sampling_follows_the_sensor_protocol() -> None:
    sup, cam = camera(box("BOX", 2.25, 0.5))
    assert cam.getRecognitionSamplingPeriod() == 0 and cam.getRecognitionObjects() == []
    cam.recognitionEnable(16)
    sup.step(8)
    assert cam.getRecognitionObjects() == []  # the first sample is due after one period
    sup.step(8)
    assert cam.getRecognitionNumberOfObjects() == 1
    cam.recognitionDisable()
    assert cam.getRecognitionSamplingPeriod() == 0 and cam.getRecognitionObjects() == []


def test_a_sample_sees_the_poses_after_the_physics_step_of_its_instant() -> None:
    # a falling box: after each 8 ms step its recognised position is the one the supervisor reads after that
    # step's physics (the camera sits at the world origin, unrotated), not the one before
    sup, cam = camera(box("BOX", 2.25, 0.5).replace("boundingObject", "physics Physics { } boundingObject"))
    cam.recognitionEnable(8)
    node = sup.getFromDef("BOX")
    for _ in range(3):
        before = node.getPosition()[2]
        sup.step(8)
        z = cam.getRecognitionObjects()[0].getPosition()[2]
        assert z == pytest.approx(node.getPosition()[2], abs=1e-12) and z < before - 1e-5


def test_only_what_is_in_the_frustum_is_reported_and_a_box_on_the_edge_is_clipped() -> None:
    objects = (box("AHEAD", 2.25, 0.5) + box("BEHIND", -2.25, 0.0) + box("LEFT", 2.25, 5.0)
               + box("ABOVE", 2.25, 0.0, 4.0) + box("EDGE", 2.25, 2.2))
    sup, cam = camera(objects)
    cam.recognitionEnable(8)
    sup.step(8)
    names = {sup.getFromId(o.getId()).getDef(): o for o in cam.getRecognitionObjects()}
    assert set(names) == {"AHEAD", "EDGE"}
    # EDGE: y 1.95..2.45; its near face (x = 2) spans u 32 − 32·2.45/2 = −7.2 .. 32 − 32·1.95/2 = 0.8 and its
    # far face's inner edge reaches 32 − 32·1.95/2.5 = 7.04: clipped to the image, u 0..7.04
    edge = names["EDGE"]
    assert edge.getPositionOnImage() == [round(7.04 / 2), 24] and edge.getSizeOnImage() == [7, 8]


def test_max_range_bounds_the_distance() -> None:
    assert seen(box("FAR", 3.0, 0.0), "maxRange 2.9") == []
    assert seen(box("FAR", 3.0, 0.0), "maxRange 3.1") == ["FAR"]
    assert seen(box("FAR", 3.0, 0.0)) == ["FAR"]  # the default 100 m


def test_occluded_by_a_box_with_occlusion_on_seen_with_it_off_and_no_colours_never_reported() -> None:
    # WALL has no recognitionColors: it is never reported, and it hides BOX from the camera
    objects = box("BOX", 3.0, 0.0) + box("WALL", 1.5, 0.0, size=0.6, colours="")
    assert seen(objects) == []  # occlusion 1 by default
    assert seen(objects, "occlusion 1") == []
    assert seen(objects, "occlusion 0") == ["BOX"]
    # control: the wall beside the line of sight hides nothing
    assert seen(box("BOX", 3.0, 0.0) + box("WALL", 1.5, 1.0, size=0.6, colours="")) == ["BOX"]
    # in one sample, the wall hides the box behind it and not the one beside it (its ray passes y = 0.4·x,
    # 0.48..0.72 m across the wall's x 1.2..1.8, beyond its y ±0.3)
    assert seen(objects + box("SIDE", 3.0, 1.2)) == ["SIDE"]
    # a recognisable object in front hides as well, and is reported itself
    front = box("BOX", 3.0, 0.0) + box("FRONT", 1.5, 0.0, size=0.6)
    assert seen(front) == ["FRONT"]
    assert seen(front, "occlusion 0") == ["FRONT", "BOX"]


def test_max_objects_keeps_the_nearest() -> None:
    objects = box("C", 4.0, -0.8) + box("A", 2.0, 0.6) + box("B", 3.0, 0.0)
    assert seen(objects) == ["A", "B", "C"]
    assert seen(objects, "maxObjects 2") == ["A", "B"]
    assert seen(objects, "maxObjects -1") == ["A", "B", "C"]


def test_a_turned_camera_sees_in_its_own_frame_and_a_solid_without_bounding_object_by_its_shapes() -> None:
    # The robot at (1, 2, 0) turned +90° about z: the camera looks along world +y and its +y is world −x, so a
    # cube at world (0.5, 4.25, 0) is at (2.25, 0.5, 0) in the camera frame (the same image box as above); the
    # cube is unturned in the world, so in the camera frame it is turned −90° about z. It has no
    # boundingObject: its box comes from its Shape.
    text = (HEAD.replace("RECOGNITION", "recognition Recognition { }")
            .replace("Robot {", "Robot { translation 1 2 0 rotation 0 0 1 1.5707963267948966")
            + box("SHAPE_ONLY", 0.5, 4.25).replace("boundingObject Box { size 0.5 0.5 0.5 }", ""))
    sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    cam = sup.getDevice("cam")
    cam.recognitionEnable(8)
    sup.step(8)
    (obj,) = cam.getRecognitionObjects()
    assert obj.getPosition() == pytest.approx([2.25, 0.5, 0.0], abs=1e-9)
    assert obj.getOrientation() == pytest.approx([0.0, 0.0, -1.0, math.pi / 2], abs=1e-9)
    assert obj.getSize() == pytest.approx([0.5, 0.5], abs=1e-9)
    assert obj.getPositionOnImage() == [24, 24] and obj.getSizeOnImage() == [9, 8]


def test_the_camera_and_what_carries_it_are_not_reported_the_other_parts_of_its_robot_are() -> None:
    # The robot and the head Solid carrying the camera have recognitionColors: not reported. An arm of the same
    # robot in front of the camera is (our reading, docs/webots-coverage.md).
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
Robot {{
  recognitionColors [ 1 1 1 ]
  children [
    {box("ARM", 2.25, 0.5)}
    DEF HEAD Solid {{
      name "head"
      recognitionColors [ 0 1 1 ]
      children [ Camera {{ name "cam" width {W} height {H} fieldOfView {FOV!r} recognition Recognition {{ }} }} ]
      boundingObject Box {{ size 0.2 0.2 0.2 }}
    }}
  ]
  controller "<extern>"
  supervisor TRUE
}}
"""
    sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    cam = sup.getDevice("cam")
    cam.recognitionEnable(8)
    sup.step(8)
    assert [sup.getFromId(o.getId()).getDef() for o in cam.getRecognitionObjects()] == ["ARM"]


def _segmentation(cam: Camera) -> np.ndarray:
    image = cam.getRecognitionSegmentationImage()
    assert image is not None and len(image) == 4 * W * H
    return np.frombuffer(image, dtype=np.uint8).reshape(H, W, 4)


@pytest.fixture(scope="module")
def headless_gl() -> None:
    """Segmentation is drawn by MuJoCo's offscreen renderer (MUJOCO_GL=egl or osmesa): skip without one."""
    try:
        import mujoco

        from dualtwin.webots.render import FrameRenderer

        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
        FrameRenderer(model, 8, 8).close()
    except Exception as exc:  # noqa: BLE001 - any failure means: no headless GL here
        pytest.skip(f"headless rendering unavailable: {type(exc).__name__}: {exc}")


def test_segmentation_paints_the_object_in_its_colour_and_the_rest_black(tmp_path: Path, headless_gl: None
                                                                          ) -> None:
    # a red recognisable box (u 20..28.8, v 20..28) and a green box without colours (drawn in the image,
    # black in the segmentation), the blue colour of the box (its first recognition colour) not its red look
    objects = (box("BOX", 2.25, 0.5, colours="0 0 1, 1 1 0").replace("baseColor 0 0 1", "baseColor 1 0 0")
               + box("PLAIN", 2.25, -0.5, colours=""))
    sup, cam = camera(objects, "segmentation TRUE")
    assert cam.hasRecognitionSegmentation()
    cam.enable(8)
    cam.recognitionEnable(8)
    cam.enableRecognitionSegmentation()
    assert cam.isRecognitionSegmentationEnabled()
    sup.step(8)
    seg = _segmentation(cam)
    assert (seg[..., 3] == 255).all()
    blue = (seg[..., 0] == 255) & (seg[..., 1] == 0) & (seg[..., 2] == 0)
    black = (seg[..., :3] == 0).all(axis=2)
    assert (blue | black).all()
    assert blue[21:28, 21:28].all()  # inside the box's image box
    rows, cols = np.flatnonzero(blue.any(axis=1)), np.flatnonzero(blue.any(axis=0))
    assert rows.min() >= 20 and rows.max() <= 28 and cols.min() >= 20 and cols.max() <= 29
    # the plain box is drawn in the camera image (green, on the right) but black in the segmentation
    image = np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(H, W, 4)
    assert (image[20:28, 36:44, 1] > 100).any() and black[20:28, 36:44].all()
    array = cam.getRecognitionSegmentationImageArray()
    assert array is not None and array[24][24] == [0, 0, 255] and array[40][24] == [0, 0, 0]
    png = tmp_path / "seg.png"
    assert cam.saveRecognitionSegmentationImage(str(png), 100) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    cam.disableRecognitionSegmentation()
    assert cam.getRecognitionSegmentationImage() is None


CONTROLLER = """
    from controller import Robot
    robot = Robot()
    cam = robot.getDevice("cam")
    cam.recognitionEnable(8)
    robot.step(8)
    for obj in cam.getRecognitionObjects():
        print("OBJ", obj.getId(), obj.id, [round(v, 6) for v in obj.getPosition()], obj.getPositionOnImage(),
              obj.getSizeOnImage(), list(obj.size), obj.getColors(), obj.getModel(), obj.model)
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_an_unchanged_controller_reads_the_objects_in_both_isolation_modes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], isolation: str
) -> None:
    from dualtwin.webots.runner import run_world

    world = (HEAD.replace("RECOGNITION", "recognition Recognition { }")
             .replace('controller "<extern>"', 'controller "looker"') + box("BOX", 2.25, 0.5, colours="0 0 1",
                                                                             model="blue box"))
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "w.wbt").write_text(world)
    (tmp_path / "controllers" / "looker").mkdir(parents=True)
    (tmp_path / "controllers" / "looker" / "looker.py").write_text(textwrap.dedent(CONTROLLER))
    assert run_world(tmp_path / "worlds" / "w.wbt", None, 0.016, isolation=isolation) == 0
    out = capsys.readouterr().out.splitlines()
    objects = [line for line in out if line.startswith("OBJ")]
    sim = Simulation(load_world_text(world))
    box_id = Supervisor(simulation=sim, robot_node=sim.robots[0].node).getFromDef("BOX").getId()
    assert objects == [f"OBJ {box_id} {box_id} [2.25, 0.5, 0.0] [24, 24] [9, 8] [0.5, 0.5] [0.0, 0.0, 1.0] "
                       "blue box blue box"]


def test_segmentation_is_drawn_from_the_poses_of_the_recognition_sample(headless_gl: None) -> None:
    # recognition every 16 ms, the controller steps 8 ms: after the step to 24 ms the last sample is still the
    # one of 16 ms, so the segmentation (read now) shows the box where the objects list has it, not where a
    # supervisor moved it at 16 ms (y 0.5 → −0.5: from the left half of the image to the right half)
    sup, cam = camera(box("BOX", 2.25, 0.5), "segmentation TRUE")
    cam.recognitionEnable(16)
    cam.enableRecognitionSegmentation()
    sup.step(16)
    sup.getFromDef("BOX").getField("translation").setSFVec3f([2.25, -0.5, 0.0])
    sup.step(8)
    assert cam.getRecognitionObjects()[0].getPosition()[1] == pytest.approx(0.5)
    red = (_segmentation(cam)[..., 2] == 255).any(axis=0)
    assert red[20:29].any() and not red[W // 2:].any()
    sup.step(8)  # the sample of 32 ms sees the box moved
    assert cam.getRecognitionObjects()[0].getPosition()[1] == pytest.approx(-0.5)
    red = (_segmentation(cam)[..., 2] == 255).any(axis=0)
    assert red[36:44].any() and not red[: W // 2].any()


CAMERA_CONTROLLER = """
    from controller import Robot
    robot = Robot()
    cam = robot.getDevice("cam")
    cam.enable(8)
    cam.recognitionEnable(8)
    cam.enableRecognitionSegmentation()
    robot.step(8)
    print("IMAGE", len(cam.getImage()), len(cam.getRecognitionSegmentationImage()))
"""


def test_a_controllers_renderers_are_freed_in_its_own_thread(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                             headless_gl: None) -> None:
    """A camera draws with EGL contexts made in its controller's thread (a thread of the run in either mode);
    they are closed there when the controller ends. Before, they lived on with the run's objects and were freed
    by a later run or the collector in another thread, where EGL refuses (EGL_BAD_ACCESS): an ignored exception
    with its traceback on stderr. Runs in both modes, one after the other, as a script or a test session does."""
    import gc
    import sys

    from dualtwin.webots.runner import run_world

    world = (HEAD.replace("RECOGNITION", "recognition Recognition { segmentation TRUE }")
             .replace('controller "<extern>"', 'controller "looker"') + box("BOX", 2.25, 0.5, colours="0 0 1"))
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "w.wbt").write_text(world)
    (tmp_path / "controllers" / "looker").mkdir(parents=True)
    (tmp_path / "controllers" / "looker" / "looker.py").write_text(textwrap.dedent(CAMERA_CONTROLLER))
    ignored: list[str] = []
    previous = sys.unraisablehook
    sys.unraisablehook = lambda failure: ignored.append(f"{failure.exc_type.__name__}: {failure.exc_value}")
    try:
        for isolation in ("threads", "process", "threads", "process"):
            assert run_world(tmp_path / "worlds" / "w.wbt", None, 0.016, isolation=isolation) == 0
            gc.collect()
    finally:
        sys.unraisablehook = previous
    assert capsys.readouterr().out.count(f"IMAGE {4 * W * H} {4 * W * H}") == 4
    assert ignored == []
