"""Cameras on both twins: headless frames, the same state looks alike, and rendering leaves the model alone."""

from __future__ import annotations

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import resolve_robot
from dualtwin.twins import make_twin
from dualtwin.twins.camera import CameraSpec, camera_for
from dualtwin.twins.render import TwinCamera

pytestmark = pytest.mark.usefixtures("headless")
ROBOT = resolve_robot("cartpole")
SPEC = camera_for(ROBOT)


def pose(twin_name: str, angle: float, x: float = 0.0) -> object:
    twin = make_twin(twin_name, ROBOT)
    twin.reset(seed=0)
    twin.set_joint_state("pole_hinge", position=angle, velocity=0.0)
    if x:
        twin.set_body_position("cart", 0, x)
    twin.step()  # Webots applies a teleport at the next physics step
    return twin


def pole_angle_from_image(frame: np.ndarray, horizon_row: int) -> float:
    """A classical estimate: fit a line through the orange (red minus blue) pixels above the horizon."""
    score = frame[..., 0].astype(float) - frame[..., 2].astype(float)
    rows, xs = [], []
    for y in range(2, horizon_row):
        row = np.clip(score[y] - 20.0, 0.0, None)
        if row.sum() > 10.0:
            rows.append(y)
            xs.append(float((row * np.arange(len(row))).sum() / row.sum()))
    slope = np.polyfit(rows, xs, 1)[0]  # pixels of x per pixel of y (y grows downwards)
    return float(-slope)


@pytest.mark.parametrize("twin_name", ["mujoco", "webots"])
@pytest.mark.parametrize("size", [(64, 64), (128, 96)])
def test_renders_headless(twin_name: str, size: tuple[int, int]) -> None:
    twin = pose(twin_name, 0.2)
    camera = TwinCamera(twin, SPEC, *size)
    frame = camera.render()
    assert frame.shape == (size[1], size[0], 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # not a blank image
    np.testing.assert_array_equal(camera.render(), frame)  # deterministic
    camera.close()
    twin.close()


def test_twins_look_alike_for_the_same_state() -> None:
    width, height = 128, 96
    frames = {}
    for name in ("mujoco", "webots"):
        twin = pose(name, 0.25, x=0.3)
        frames[name] = TwinCamera(twin, SPEC, width, height).render().astype(float)
        twin.close()
    # The pole against the sky and the cart on the floor: nearly the same pixels. (Between them lies the floor's
    # far edge, which differs: the MJCF floor is infinite, the Webots Floor 20 m wide.)
    for rows in (slice(5, 45), slice(60, 80)):
        a, b = frames["mujoco"][rows, 30:110].ravel(), frames["webots"][rows, 30:110].ravel()
        assert np.corrcoef(a, b)[0, 1] > 0.95
    # And the pole's angle is recovered from either frame: tip offset / pole length in pixels.
    estimates = [pole_angle_from_image(f.astype(np.uint8), 45) for f in frames.values()]
    ratio = np.tan(0.25)
    for estimate in estimates:
        assert estimate == pytest.approx(ratio, abs=0.06)
    assert abs(estimates[0] - estimates[1]) < 0.03


def test_body_mounted_camera_follows_the_cart() -> None:
    spec = CameraSpec("onboard", pos=(0.0, -1.2, 0.5), lookat=(0.0, 0.0, 0.5), fovy_deg=60.0, body="cart")
    twin = pose("mujoco", 0.0)
    camera = TwinCamera(twin, spec, 48, 48)
    before = camera.render()
    twin.set_body_position("cart", 0, 0.5)
    twin.step()
    after = camera.render()
    # The camera moved with the cart: the (symmetric, upright) view barely changes.
    assert np.abs(before.astype(int) - after.astype(int)).mean() < 8


def test_rendering_leaves_the_physics_model_alone() -> None:
    twin = make_twin("mujoco", ROBOT)
    model = twin.model
    saved = (model.vis.quality.offsamples, model.geom_size.copy(), model.geom_rgba.copy(), model.light_diffuse.copy())
    from dualtwin.twins.camera import Appearance

    TwinCamera(twin, SPEC, 32, 32).render(Appearance.sample(np.random.default_rng(0)))
    assert model.vis.quality.offsamples == saved[0]
    np.testing.assert_array_equal(model.geom_size, saved[1])
    np.testing.assert_array_equal(model.geom_rgba, saved[2])
    np.testing.assert_array_equal(model.light_diffuse, saved[3])


def test_webots_twin_render_method() -> None:
    twin = pose("webots", 0.1)
    frame = twin.render(SPEC, 64, 64)
    assert frame.shape == (64, 64, 3)
    side = twin.render("side", 64, 48)  # the robot's declared camera, as the MJCF twin has it
    assert side.shape == (48, 64, 3) and side.std() > 5
    viewpoint = twin.render("viewpoint", 64, 48)
    assert viewpoint.shape == (48, 64, 3) and viewpoint.std() > 5
    with pytest.raises(DualtwinError, match="no camera 'nope'"):
        twin.render("nope", 64, 64)


def test_camera_spec_validation() -> None:
    with pytest.raises(DualtwinError, match="fovy_deg"):
        CameraSpec("c", pos=(0, -1, 0), lookat=(0, 0, 0), fovy_deg=0.0)
    with pytest.raises(DualtwinError, match="lookat"):
        CameraSpec("c", pos=(0, 0, 0), lookat=(0, 0, 1))
    with pytest.raises(DualtwinError, match="unknown keys"):
        CameraSpec.from_dict("c", {"pos": [0, -1, 0], "lookat": [0, 0, 0], "zoom": 2})
    with pytest.raises(DualtwinError, match="no camera"):
        camera_for(ROBOT, "missing")


def test_webots_scene_draws_proto_instances_from_their_base_node() -> None:
    # The Floor is a PROTO instance: getField answers its interface (size, ...), so its Shape is reached through
    # the base node's children; a walk through getField alone leaves the floor out of every frame.
    import mujoco

    from dualtwin.webots.visual_scene import WebotsVisualScene

    twin = pose("webots", 0.0)
    scene = WebotsVisualScene(twin.sup)
    planes = [i for i in range(scene.model.ngeom) if scene.model.geom_type[i] == mujoco.mjtGeom.mjGEOM_PLANE]
    assert [scene.model.geom_size[i][:2].tolist() for i in planes] == [[10.0, 10.0]]  # Floor { size 20 20 }
    twin.close()
