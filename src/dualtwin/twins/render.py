"""Render any twin from a :class:`~dualtwin.twins.camera.CameraSpec` (the twins' camera capability).

* MuJoCo twin: the twin's own model and data, drawn by :class:`~dualtwin.twins.camera.FrameRenderer`.
* Webots twin: its visual scene (:class:`~dualtwin.webots.visual_scene.WebotsVisualScene`), posed from the
  supervisor each frame, drawn by the same renderer, so the two twins' frames are comparable pixel for pixel.

Both need ``MUJOCO_GL=egl`` or ``osmesa`` on a headless machine (read from the environment).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.twins.base import Twin
from dualtwin.twins.camera import (
    Appearance,
    CameraSpec,
    FrameRenderer,
    ResolvedCamera,
    bundled_camera_for_model,
    resolve_camera,
)

#: Render at this multiple of the output size and average blocks: anti-aliasing for the thin pole.
SUPERSAMPLE = 2


def _visual_scene(twin: Any) -> Any:
    """The Webots twin's visual scene, built once per twin and kept on it."""
    scene = getattr(twin, "_dualtwin_visual_scene", None)
    if scene is None:
        from dualtwin.webots.visual_scene import WebotsVisualScene

        scene = WebotsVisualScene(twin.sup)
        twin._dualtwin_visual_scene = scene
    return scene


class TwinCamera:
    """One camera on one twin at one resolution; keeps its GL context between frames.

    Args:
        twin: a MuJoCo or Webots twin.
        camera: where to look from (a spec, or for the MuJoCo twin the name of a model camera).
        width, height: resolution (default: the spec's).
        supersample: anti-aliasing factor (see :class:`FrameRenderer`).
        effects: keep shadows/reflections/skybox (slow without a GPU).
    """

    def __init__(self, twin: Twin, camera: CameraSpec | str, width: int | None = None, height: int | None = None,
                 *, supersample: int = SUPERSAMPLE, effects: bool = False) -> None:
        self.twin = twin
        self.camera = camera
        default_w, default_h = (camera.width, camera.height) if isinstance(camera, CameraSpec) else (64, 64)
        self.width, self.height = int(width or default_w), int(height or default_h)
        if twin.name == "mujoco":
            self._model: Any = twin.model  # type: ignore[attr-defined]
            self._scene = None
        elif twin.name == "webots":
            self._scene = _visual_scene(twin)
            self._model = self._scene.model
        else:
            raise DualtwinError(f"twin {twin.name!r} has no perception renderer (mujoco and webots do)")
        self.renderer = FrameRenderer(self._model, self.width, self.height, supersample=supersample,
                                      effects=effects)

    def resolve(self, camera: CameraSpec | str | None = None) -> ResolvedCamera:
        camera = camera if camera is not None else self.camera
        if isinstance(camera, CameraSpec):
            return resolve_camera(camera, self.twin)
        if self._scene is not None:
            try:
                return self._scene.named_camera(camera, self.width, self.height)
            except DualtwinError:
                # Not a Camera device of the world: a camera declared for this robot (e.g. the MJCF's "side").
                spec = bundled_camera_for_model(getattr(self.twin, "_origin", ""), camera)
                if spec is None:
                    raise
                return resolve_camera(spec, self.twin)
        return _mujoco_model_camera(self._model, self.twin.data, camera)  # type: ignore[attr-defined]

    def render(self, appearance: Appearance | None = None, camera: CameraSpec | str | None = None) -> np.ndarray:
        """The twin's current state as an RGB frame (height, width, 3) uint8."""
        resolved = self.resolve(camera)
        return self.renderer.render(self._current_data(), resolved, appearance)

    def labels(self, bodies: list[str], camera: CameraSpec | str | None = None) -> np.ndarray:
        """Per-pixel coverage (uint8) of each named body's visual geoms: [height, width, len(bodies)]."""
        resolved = self.resolve(camera)
        return self.renderer.render_labels(self._current_data(), resolved, [self._geoms(body) for body in bodies])

    def _current_data(self) -> Any:
        """MjData holding the twin's current state: its own, or the Webots twin's scene synced to it."""
        if self._scene is not None:
            self._scene.sync()
            return self._scene.data
        return self.twin.data  # type: ignore[attr-defined]

    def _geoms(self, body: str) -> np.ndarray:
        import mujoco

        model = self._model
        index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        if index < 0:
            raise DualtwinError(f"twin {self.twin.name!r}: no visual body {body!r} to label")
        return np.flatnonzero(model.geom_bodyid == index)

    def close(self) -> None:
        self.renderer.close()


def _mujoco_model_camera(model: Any, data: Any, name: str) -> ResolvedCamera:
    import mujoco

    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
    if cam < 0:
        known = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam)]
        raise DualtwinError(f"the MuJoCo model has no camera {name!r} (cameras: {', '.join(filter(None, known)) or 'none'})")
    # MuJoCo cameras look along -z with +y up (cam_xmat columns are the camera axes in the world).
    R = np.asarray(data.cam_xmat[cam], dtype=float).reshape(3, 3)
    pos = np.asarray(data.cam_xpos[cam], dtype=float)
    return ResolvedCamera.look(pos, pos - R[:, 2], R[:, 1], float(model.cam_fovy[cam]))


def render_webots(twin: Twin, camera: CameraSpec | str, width: int, height: int) -> np.ndarray:
    """``WebotsTwin.render``: one frame, with a renderer cached per (camera, size) on the twin."""
    cache: dict[Any, TwinCamera] | None = getattr(twin, "_dualtwin_cameras", None)
    if cache is None:
        cache = {}
        twin._dualtwin_cameras = cache  # type: ignore[attr-defined]
    key = (width, height)
    camera_renderer = cache.get(key)
    if camera_renderer is None:
        camera_renderer = cache[key] = TwinCamera(twin, camera, width, height)
    return camera_renderer.render(camera=camera)
