"""The Camera device: a red box at a known place appears where the pinhole projection puts it, the image
follows the scene, and a disabled camera, noise, the image helpers and saveImage behave as in Webots."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots.camera import Camera
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.protos import load_world_text

W, H, FOV = 64, 48, 1.0
WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 randomSeed 7 }
DirectionalLight { direction 0 0 -1 }
DEF BOX Solid {
  translation 2 0.5 0
  children [ Shape { appearance PBRAppearance { baseColor 1 0 0 } geometry Box { size 0.4 0.4 0.4 } } ]
}
Robot {
  children [ Camera { name "cam" width %d height %d fieldOfView %g NOISE } ]
  controller "<extern>"
  supervisor TRUE
}
"""


def _camera_in(text: str) -> tuple[Simulation, Supervisor, Camera]:
    """The world ``text`` loaded, its supervisor robot's camera ``cam``."""
    sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    cam = sup.getDevice("cam")
    assert isinstance(cam, Camera)
    return sim, sup, cam


def _camera(noise: float = 0.0) -> tuple[Supervisor, Camera]:
    _, sup, cam = _camera_in((WORLD % (W, H, FOV)).replace("NOISE", f"noise {noise}" if noise else ""))
    return sup, cam


def _bgra(cam: Camera) -> np.ndarray:
    return np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(cam.getHeight(), cam.getWidth(), 4)


def _red(image: np.ndarray) -> np.ndarray:
    return (image[..., 2] > 100) & (image[..., 1] < 80) & (image[..., 0] < 80)


def _columns(y_near: float, y_far: float, x: float) -> tuple[float, float]:
    """Image columns (pixel-edge coordinates) of two points at depth x: +y is left, the centre is W/2."""
    f = (W / 2) / math.tan(FOV / 2)
    return W / 2 - f * y_far / x, W / 2 - f * y_near / x


def test_red_box_appears_where_the_projection_puts_it_and_follows_the_box() -> None:
    sup, cam = _camera()
    cam.enable(8)
    sup.step(8)
    image = _bgra(cam)
    assert image.shape == (H, W, 4) and len(cam.getImage()) == 4 * W * H
    assert (image[..., 3] == 255).all()
    red = _red(image)
    # The box's near face (x = 1.8 m, y 0.3..0.7 m, z -0.2..0.2 m) spans these pixel edges; the side face at
    # y = 0.3 m reaches to its far edge (x = 2.2 m). Inside the near face is red, outside the box is not.
    left, right = _columns(0.3, 0.7, 1.8)
    far_right = _columns(0.3, 0.7, 2.2)[1]
    f = (W / 2) / math.tan(FOV / 2)
    top, bottom = H / 2 - f * 0.2 / 1.8, H / 2 + f * 0.2 / 1.8
    inside = red[math.ceil(top) + 1:math.floor(bottom) - 1, math.ceil(left) + 1:math.floor(right) - 1]
    assert inside.all(), f"near face not all red: {inside.mean():.2f}"
    cols = np.flatnonzero(red.any(axis=0))
    rows = np.flatnonzero(red.any(axis=1))
    assert cols.min() >= math.floor(left) and cols.max() <= math.ceil(far_right), (cols.min(), cols.max())
    assert rows.min() >= math.floor(top) and rows.max() <= math.ceil(bottom), (rows.min(), rows.max())
    assert not red[:, W // 2:].any(), "a box on the camera's left (+y) must be in the left half"

    # Control: the same box moved to y = -0.5 m appears mirrored, in the right half.
    box = sup.getFromDef("BOX")
    field = box.getField("translation") if box is not None else None
    assert field is not None
    field.setSFVec3f([2.0, -0.5, 0.0])
    sup.step(8)
    moved = _red(_bgra(cam))
    assert moved.any() and not moved[:, : W // 2].any()
    assert abs(int(moved.sum()) - int(red.sum())) <= 0.1 * red.sum()
    # mirror geometry about the image centre: the columns it covers are the original ones mirrored
    assert int((np.asarray(moved.any(axis=0))[::-1] != np.asarray(red.any(axis=0))).sum()) <= 2


def test_disabled_camera_raises_as_webots_python_does(capsys: pytest.CaptureFixture[str]) -> None:
    sup, cam = _camera()
    assert cam.getSamplingPeriod() == 0
    assert (cam.getWidth(), cam.getHeight(), cam.getFov(), cam.getNear()) == (W, H, FOV, 0.01)
    with pytest.raises(ValueError):
        cam.getImage()
    assert "wb_camera_get_image() called for a disabled device" in capsys.readouterr().err
    cam.enable(16)
    assert cam.getSamplingPeriod() == 16
    assert cam.getImage() == bytes(4 * W * H)  # enabled, not sampled yet: a black frame
    sup.step(8)
    assert cam.getImage() == bytes(4 * W * H)  # the first sample is due after one period
    sup.step(8)
    assert _red(_bgra(cam)).any()
    cam.disable()
    assert cam.getSamplingPeriod() == 0
    with pytest.raises(ValueError):
        cam.getImageArray()
    cam.enable(0)  # enable(0) is disable()
    assert cam.getSamplingPeriod() == 0


def test_noise_is_gaussian_with_sigma_noise_times_255_and_seeded() -> None:
    images = []
    for noise in (0.0, 0.1, 0.1):
        sup, cam = _camera(noise)
        cam.enable(8)
        sup.step(8)
        images.append(_bgra(cam).astype(int))
    clean, noisy, again = images
    assert np.array_equal(noisy, again), "same randomSeed, same noise"
    # Only where the clean value is far from 0 and 255 is the noise unclipped.
    mid = (clean[..., :3] > 80) & (clean[..., :3] < 175)
    diff = (noisy[..., :3] - clean[..., :3])[mid]
    assert diff.size > 50
    assert abs(diff.std() - 25.5) < 0.15 * 25.5, diff.std()
    assert abs(diff.mean()) < 3 * 25.5 / math.sqrt(diff.size)
    assert (noisy[..., 3] == 255).all()


def test_image_helpers_array_and_png(tmp_path: Path) -> None:
    sup, cam = _camera()
    cam.enable(8)
    sup.step(8)
    raw = cam.getImage()
    image = _bgra(cam)
    array = cam.getImageArray()
    assert len(array) == W and len(array[0]) == H  # [x][y]
    for x, y in ((0, 0), (15, 24), (W - 1, H - 1), (20, 30)):
        r, g, b = Camera.imageGetRed(raw, W, x, y), Camera.imageGetGreen(raw, W, x, y), Camera.imageGetBlue(raw, W, x, y)
        assert [r, g, b] == array[x][y] == image[y, x, 2::-1].tolist()
        assert Camera.imageGetGray(raw, W, x, y) == (r + g + b) / 3
    png = tmp_path / "frame.png"
    assert cam.saveImage(str(png), 100) == 0
    from PIL import Image

    with Image.open(io.BytesIO(png.read_bytes()), formats=["PNG"]) as img:
        back = np.asarray(img.convert("RGBA"))
    assert np.array_equal(back[..., :3], image[..., 2::-1]) and (back[..., 3] == 255).all()
    assert cam.saveImage(str(tmp_path / "frame.bmp"), 100) == -1
    assert not (tmp_path / "frame.bmp").exists()


RUNNER_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 16 }
Solid {
  translation 1.5 0 0.3
  children [ Shape { appearance PBRAppearance { baseColor 1 0 0 } geometry Box { size 0.3 0.3 0.3 } } ]
}
Robot {
  translation 0 0 0.3
  children [ Camera { name "camera" width 32 height 24 } ]
  controller "looker"
}
"""

LOOKER = """
from controller import Camera, Robot
robot = Robot()
camera = robot.getDevice("camera")
camera.enable(32)
while robot.step(16) != -1:
    image = camera.getImage()
    w, h = camera.getWidth(), camera.getHeight()
    red = sum(1 for y in range(h) for x in range(w)
              if Camera.imageGetRed(image, w, x, y) > 100 and Camera.imageGetGreen(image, w, x, y) < 80)
    print(f"t={robot.getTime():.3f} red={red} centre={Camera.imageGetRed(image, w, w // 2, h // 2)}")
camera.saveImage(PNG_PATH, 100)
"""


def test_unchanged_controller_reads_the_camera_through_the_runner(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dualtwin.webots.runner import run_world

    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "look.wbt").write_text(RUNNER_WORLD)
    (tmp_path / "controllers" / "looker").mkdir(parents=True)
    png = tmp_path / "seen.png"
    (tmp_path / "controllers" / "looker" / "looker.py").write_text(LOOKER.replace("PNG_PATH", repr(str(png))))
    assert run_world(tmp_path / "worlds" / "look.wbt", duration_s=0.096) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("t=")]
    reds = [int(line.split("red=")[1].split()[0]) for line in lines]
    # enable(32) with 16 ms steps: the first image arrives at 32 ms (black before), then the box ahead.
    assert reds[0] == 0 and all(r > 20 for r in reds[1:]), lines
    assert all(int(line.split("centre=")[1]) > 100 for line in lines[1:]), lines
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("clip", "visible"), [("near 0.01", True), ("near 0.5", False), ("far 3.0", True),
                                               ("far 1.0", False)])
def test_near_and_far_clip_the_box(clip: str, visible: bool) -> None:
    # the box's near face is 1.8 m ahead: hidden by far 1.0 m, not by 3.0 m; a 0.2 m box 0.4 m ahead (its faces
    # 0.3-0.5 m) is hidden by near 0.5 m, not by 0.01 m
    text = (WORLD % (W, H, FOV)).replace("NOISE", clip)
    if clip.startswith("near"):
        text = text.replace("translation 2 0.5 0", "translation 0.4 0 0").replace("size 0.4 0.4 0.4",
                                                                                  "size 0.2 0.2 0.2")
    _, sup, cam = _camera_in(text)
    cam.enable(8)
    sup.step(8)
    assert bool(_red(_bgra(cam)).any()) == visible


BACKGROUND_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
BACKGROUND
DirectionalLight { direction 0 0 -1 }
Solid {
  translation 2 0 0
  children [ Shape { appearance PBRAppearance { baseColor 1 0 0 } geometry Box { size 0.4 0.4 0.4 } } ]
}
Robot {
  children [ Camera { name "cam" width WIDTH height HEIGHT fieldOfView FOV antiAliasing AA } ]
  controller "<extern>"
  supervisor TRUE
}
"""


def _background_image(background: str, anti_aliasing: bool = False) -> tuple[np.ndarray, list[str]]:
    text = (BACKGROUND_WORLD.replace("BACKGROUND", background).replace("AA", "TRUE" if anti_aliasing else "FALSE")
            .replace("WIDTH", str(W)).replace("HEIGHT", str(H)).replace("FOV", str(FOV)))
    sim, sup, cam = _camera_in(text)
    cam.enable(8)
    sup.step(8)
    image = _bgra(cam).copy()
    return image, list(sim.extensions["visual_scene"].warnings)


@pytest.mark.parametrize("anti_aliasing", [False, True])
def test_the_sky_is_the_backgrounds_first_sky_colour_behind_the_shapes(anti_aliasing: bool) -> None:
    """Webots draws a Background without cube-map textures in its skyColor (the first colour): every pixel that
    shows no Shape has it, in bytes rounded to the nearest (0.7 -> 179), and the box in front is unchanged."""
    image, _ = _background_image("Background { skyColor [ 0.4 0.7 1, 0 1 0 ] }", anti_aliasing)
    control, _ = _background_image("", anti_aliasing)  # no Background: Webots' default sky, black
    box = _red(control)
    assert box[H // 2, W // 2] and box.sum() > 50
    sky = (control[..., :3] == 0).all(axis=-1)  # no Shape in the pixel (with antiAliasing, in none of its samples)
    assert sky.sum() > 0.8 * W * H - box.sum(), "without a Background the sky stays black"
    # BGRA of (0.4, 0.7, 1.0): the first colour of the list, not the second
    assert (image[sky] == np.array([255, 179, 102, 255], dtype=np.uint8)).all()
    assert (image[box] == control[box]).all(), "the box is drawn over the sky, unchanged"


def test_a_textured_background_shows_its_sky_colour_and_says_its_textures_are_not_drawn(
        capsys: pytest.CaptureFixture[str]) -> None:
    image, warnings = _background_image(
        'Background { skyColor [ 0.2 0.2 0.2 ] backUrl [ "back.jpg" ] topUrl [ "top.jpg" ] }')
    assert tuple(image[0, 0]) == (51, 51, 51, 255)
    assert any("Background textures are not drawn" in w for w in warnings), warnings
    err = capsys.readouterr().err
    assert err.count("Warning: Camera:") == 1 and "Background textures are not drawn" in err, err
    # the TexturedBackground PROTO (our stand-in when the file is not on the search path) passes skyColor on
    image, _ = _background_image('EXTERNPROTO "webots://projects/objects/backgrounds/protos/TexturedBackground.proto"\n'
                                 "TexturedBackground { skybox FALSE skyColor [ 0 0 1 ] }")
    assert tuple(image[0, 0]) == (255, 0, 0, 255)
