"""Webots ``Camera`` headless: the world's Shapes drawn by the same offscreen renderer as perception.

Our runtime has no renderer of its own, so a Camera device draws the world's visual scene
(:class:`~dualtwin.webots.visual_scene.WebotsVisualScene`: one mocap body per Solid with visible Shapes, posed
from the simulation) with :class:`~dualtwin.webots.render.FrameRenderer`, from the Camera Solid's own frame.
Webots' cameras look along their +x axis with +z up, and ``fieldOfView`` is horizontal.

What follows Webots (``camera.c`` and ``camera.py`` of its controller library, and the Camera reference page):

* the image is **BGRA**, 8 bits per channel, ``4·width·height`` bytes, row-major from the top-left pixel;
  alpha is 255;
* ``noise`` adds, per channel, Gaussian noise of standard deviation ``noise × 255`` (clipped to 0..255), drawn
  from the simulation's sensor-noise generator (seeded from ``WorldInfo.randomSeed``), so a seeded run is
  reproducible;
* sampling follows the sensor protocol (``enable(T)`` then ``step(T)`` yields an image); reading a disabled
  camera prints Webots' error on stderr and raises ``ValueError``, which is what Webots' Python wrapper raises
  when the C library returns a NULL image (our reading of its code, not observed); an enabled camera before
  its first sample returns a black image (Webots' buffer before the first frame is not documented);
* ``getImageArray()`` is indexed ``[x][y]`` and holds ``[r, g, b]`` lists, as Webots' Python documents it;
  ``imageGetRed/Green/Blue`` read bytes +2/+1/+0 at ``4·(y·width + x)``; ``imageGetGray`` is their mean, a
  float (Webots' Python wrapper divides with ``/``);
* ``saveImage(filename, quality)`` writes a real PNG (or a JPEG through Pillow when the name ends in
  ``.jpg``/``.jpeg``) and returns 0, or -1 on failure;
* ``near`` sets the near clipping plane, ``far`` (when > 0) the far one; ``antiAliasing TRUE`` renders at twice
  the size and averages 2×2 blocks.

Decisions: an image is rendered lazily, at the first ``getImage`` after a sample became due (a camera that is
enabled but never read costs nothing); the scene is built at the first frame and again after a supervisor changed the
scene tree (nodes imported or removed, a Pose among a Solid's children moved, a geometry resized). The sky is the
world's Background colour (its first ``skyColor``, as Webots shows it where the Background has no cube-map
texture; textures are not drawn). Not simulated: spherical and cylindrical projections (drawn planar, with a
warning), exposure, lens distortion, motion blur, bloom, ambient occlusion and textures (a Shape is drawn in its
flat ``baseColor``/``diffuseColor``, a textured Background in its ``skyColor``).

Recognition (a Recognition node in the ``recognition`` field): ``recognitionEnable(T)`` samples, with the
sensor protocol and its own period, the Solids with ``recognitionColors`` that the camera sees, as
:class:`~dualtwin.webots.recognition.CameraRecognitionObject` records (id, pose and size in the camera frame,
box on the image, colours, model); with ``segmentation TRUE`` and ``enableRecognitionSegmentation()``,
``getRecognitionSegmentationImage()`` is a BGRA image of the camera's size where recognisable objects have
their first colour and the rest is black, drawn by MuJoCo's segmentation pass of the same scene. The
computation, and which choices are our reading of Webots' documentation, are in
:mod:`dualtwin.webots.camera_recognition`.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.artifacts import write_bytes
from dualtwin.webots.api_args import as_float, as_int, warn
from dualtwin.webots.camera_recognition import (
    CameraView,
    RecognitionSampler,
    segmentation_colours,
    segmentation_image,
)
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.display import png_bytes
from dualtwin.webots.image_edits import SIZE_FIELDS, edited_image_size
from dualtwin.webots.recognition import CameraRecognitionObject

__all__ = ["Camera", "CameraModel", "bgra_from_rgb"]


def bgra_from_rgb(rgb: np.ndarray) -> np.ndarray:
    """An (h, w, 3) RGB uint8 frame as Webots' (h, w, 4) BGRA buffer with opaque alpha."""
    h, w, _ = rgb.shape
    out = np.empty((h, w, 4), dtype=np.uint8)
    out[..., 0] = rgb[..., 2]
    out[..., 1] = rgb[..., 1]
    out[..., 2] = rgb[..., 0]
    out[..., 3] = 255
    return out


#: (field, CameraModel attribute, default) of the fields a supervisor's edit changes at run time
_EDITABLE = (("fieldOfView", "fov", 0.7854), ("near", "near", 0.01), ("far", "far", 0.0), ("noise", "noise", 0.0),
             ("exposure", "exposure", 1.0))
_EDITABLE_NAMES = (*(name for name, _, _ in _EDITABLE), *SIZE_FIELDS)


class CameraModel:
    """A Camera node's fields (Webots' defaults where a field is absent), read at load and, for those of
    :data:`_EDITABLE`, again after a supervisor's edit (:meth:`follow`)."""

    def __init__(self, fields: dict[str, Any]) -> None:
        self.width = max(1, int(fields.get("width", 64)))
        self.height = max(1, int(fields.get("height", 64)))
        self.fov = float(fields.get("fieldOfView", 0.7854))
        self.near = float(fields.get("near", 0.01))
        self.far = float(fields.get("far", 0.0))
        self.noise = float(fields.get("noise", 0.0))
        self.exposure = float(fields.get("exposure", 1.0))
        self.anti_aliasing = bool(fields.get("antiAliasing", False))
        self.projection = str(fields.get("projection", "planar"))
        if self.projection != "planar":
            warn(f"Camera: the {self.projection} projection is drawn as planar")

    def follow(self, fields: dict[str, Any], changed: frozenset[str], name: str) -> None:
        """Take the edited fields of ``changed`` (Webots' update slots: from the next image on, the getters too),
        the image size as :mod:`.image_edits` says."""
        for field, attr, default in _EDITABLE:
            if field in changed:
                setattr(self, attr, float(fields.get(field, default)))
        if changed & {"width", "height"}:
            self.width, self.height = edited_image_size(fields, (self.width, self.height), "Camera", name)

    def fovy_degrees(self) -> float:
        """The vertical field of view (degrees) of a horizontal ``fov`` at this aspect ratio."""
        return math.degrees(2.0 * math.atan(math.tan(self.fov / 2.0) * self.height / self.width))


class _RootView:
    """What :class:`WebotsVisualScene` needs from a supervisor (``getRoot``), for a camera on any robot."""

    def __init__(self, robot: Any) -> None:
        self._robot = robot

    def getRoot(self) -> Any:
        from dualtwin.webots.nodes import Node as SceneNode
        from dualtwin.webots.scene_api import Node

        root = Node(self._robot, SceneNode("Group", {"children": list(self._robot._sim.world.nodes)}))
        root._is_root = True
        return root


def _visual_scene(robot: Any) -> Any:
    """The simulation's visual scene, built at the first camera frame and shared by every camera; built again
    from the scene tree when a supervisor changed it (the geometry version moved: nodes imported or removed,
    a frame among a Solid's children moved, a geometry resized)."""
    sim = robot._sim
    scene = sim.extensions.get("visual_scene")
    if scene is None or scene.geometry_version != sim.geometry_version:
        from dualtwin.webots.visual_scene import WebotsVisualScene

        scene = sim.extensions["visual_scene"] = WebotsVisualScene(_RootView(robot), allow_empty=True,
                                                                   background=True)
        scene.geometry_version = sim.geometry_version
        # what the images leave out (a mesh file not read, a Background's textures), once per simulation
        shown: set[str] = sim.extensions.setdefault("visual_scene_warned", set())
        for line in scene.warnings:
            if line not in shown:
                shown.add(line)
                warn(f"Camera: {line}")
    return scene


class Camera(SolidSensor):
    """Webots ``Camera``; see the module docstring."""

    _image: np.ndarray | None  # the last image drawn (None: none since the last sample, reset or resize)

    def _model(self) -> CameraModel:
        fields = self._fields()
        changed = self._fields_changed(_EDITABLE_NAMES)
        model = getattr(self, "_model_cache", None)
        if model is None:
            model = self._model_cache = CameraModel(fields)
        elif changed:
            size = (model.width, model.height)
            model.follow(fields, changed, self._name)
            if (model.width, model.height) != size:  # a black image of the new size until the next sample
                self._image = None
                self.__dict__.pop("_segmentation_frame", None)
        return model

    def _invalidate(self) -> None:
        super()._invalidate()
        self._image = None
        self._pending = False

    def _read(self) -> None:
        self._pending = True  # rendered at the next getImage (see the module docstring)

    # -- rendering

    def _view(self, m: CameraModel) -> Any:
        """The camera's frame now, as the renderer's camera (Webots: looks along +x, +z up)."""
        from dualtwin.webots.render import ResolvedCamera

        pose = self._pose()
        R = np.asarray(pose.R, dtype=float).reshape(3, 3)
        pos = np.asarray(pose.t, dtype=float)
        return ResolvedCamera.look(pos, pos + R[:, 0], R[:, 2], m.fovy_degrees())

    def _renderer_for(self, purpose: str, scene: Any, supersample: int) -> Any:
        """The camera's renderer for ``purpose`` (the image, the segmentation) over ``scene``: made at the first
        frame, and again (the former one closed) when the visual scene was built again."""
        from dualtwin.webots.render import FrameRenderer

        renderers: dict[str, tuple[Any, Any, tuple[int, int]]] = self.__dict__.setdefault("_renderers", {})
        held = renderers.get(purpose)
        m = self._model()
        if held is not None and held[0] is scene and held[2] == (m.width, m.height):
            return held[1]
        if held is not None:  # the scene was built again, or a supervisor's edit resized the image
            held[1].close()
        renderer = FrameRenderer(scene.model, m.width, m.height, supersample=supersample,
                                 sky=purpose == "image" and scene.sky is not None)
        renderers[purpose] = (scene, renderer, (m.width, m.height))
        return renderer

    def _controller_ended(self) -> None:
        """Its controller's thread ends: the renderers it drew with are closed in that thread. An EGL context
        is current in the thread that made it, and Python's collector, freeing one later in another thread,
        failed (EGL_BAD_ACCESS, printed as an ignored exception with its traceback)."""
        for _, renderer, _ in self.__dict__.pop("_renderers", {}).values():
            renderer.close()

    def _render(self) -> np.ndarray:
        m = self._model()
        scene = _visual_scene(self._robot)
        renderer = self._renderer_for("image", scene, supersample=2 if m.anti_aliasing else 1)
        scene.sync()
        rgb = renderer.render(scene.data, self._view(m), near=m.near, far=m.far if m.far > 0 else None)
        image = bgra_from_rgb(rgb)
        if m.noise > 0.0:
            rng = np.random.default_rng(self._robot._sim.rng.getrandbits(64))
            noisy = image[..., :3] + rng.normal(0.0, m.noise * 255.0, size=image[..., :3].shape)
            image[..., :3] = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        return image

    def _current(self, method: str) -> np.ndarray:
        if self._period <= 0:
            print(f"Error: {method}() called for a disabled device! Please use: wb_camera_enable().",
                  file=sys.stderr)
            raise ValueError("NULL pointer access")
        if self._pending:
            self._pending = False
            self._image = self._render()
        if self._image is None:
            m = self._model()
            return np.zeros((m.height, m.width, 4), dtype=np.uint8)
        return self._image

    # -- image API

    def getImage(self) -> bytes:
        """BGRA bytes, ``4·width·height``, row-major from the top-left pixel."""
        return self._current("wb_camera_get_image").tobytes()

    def getImageArray(self) -> list[list[list[int]]]:
        """``[x][y] -> [r, g, b]``."""
        image = self._current("wb_camera_get_image")
        return image[..., 2::-1].transpose(1, 0, 2).tolist()

    @staticmethod
    def imageGetRed(image: bytes, width: int, x: int, y: int) -> int:
        return int(image[4 * (y * width + x) + 2])

    @staticmethod
    def imageGetGreen(image: bytes, width: int, x: int, y: int) -> int:
        return int(image[4 * (y * width + x) + 1])

    @staticmethod
    def imageGetBlue(image: bytes, width: int, x: int, y: int) -> int:
        return int(image[4 * (y * width + x)])

    @staticmethod
    def imageGetGray(image: bytes, width: int, x: int, y: int) -> float:
        i = 4 * (y * width + x)
        return (int(image[i]) + int(image[i + 1]) + int(image[i + 2])) / 3  # a float: Webots' wrapper divides with /

    imageGetGrey = imageGetGray

    def saveImage(self, filename: str, quality: Any) -> int:
        """Write the last image as PNG (or JPEG through Pillow); 0 on success, -1 on failure (as Webots)."""
        image = self._current("wb_camera_save_image")
        rgba = np.concatenate([image[..., 2::-1], image[..., 3:]], axis=2)
        path = Path(filename)
        suffix = path.suffix.lower()
        try:
            if suffix == ".png":
                write_bytes(path, png_bytes(np.ascontiguousarray(rgba)))
                return 0
            if suffix in (".jpg", ".jpeg"):
                import io

                from PIL import Image

                buffer = io.BytesIO()
                Image.fromarray(np.ascontiguousarray(rgba[..., :3])).save(
                    buffer, format="JPEG", quality=int(as_float(quality, "Camera.saveImage")))
                write_bytes(path, buffer.getvalue())
                return 0
        except (OSError, ImportError) as exc:
            warn(f"Camera.saveImage(): cannot write {filename}: {exc}")
            return -1
        warn(f"Camera.saveImage(): {filename}: only .png, .jpg and .jpeg are supported")
        return -1

    # -- parameters

    def getWidth(self) -> int:
        return self._model().width

    def getHeight(self) -> int:
        return self._model().height

    def getFov(self) -> float:
        return self._model().fov

    def setFov(self, f: Any) -> None:
        value = as_float(f, "Camera.setFov")
        low, high = self.getMinFov(), self.getMaxFov()
        if not 0.0 < value <= math.pi or not low <= value <= high:
            warn(f"Camera.setFov(): {value} is outside [{low}, {high}] (the Zoom node's range, or (0, pi])")
            return
        self._model().fov = value

    def _part(self, field: str) -> dict[str, Any] | None:
        node = self._record.node.fields.get(field)
        return node.fields if node is not None else None

    def getMinFov(self) -> float:
        zoom = self._part("zoom")
        return float(zoom["minFieldOfView"]) if zoom is not None else self._model().fov

    def getMaxFov(self) -> float:
        zoom = self._part("zoom")
        return float(zoom["maxFieldOfView"]) if zoom is not None else self._model().fov

    def _focus(self, name: str) -> float:
        focus = self._part("focus")
        return float(focus[name]) if focus is not None else 0.0

    def getFocalLength(self) -> float:
        return self._focus("focalLength")

    def getFocalDistance(self) -> float:
        return self._focus("focalDistance")

    def getMinFocalDistance(self) -> float:
        return self._focus("minFocalDistance")

    def getMaxFocalDistance(self) -> float:
        return self._focus("maxFocalDistance")

    def setFocalDistance(self, d: Any) -> None:
        """Kept for the getter (the headless image is drawn in focus); needs a Focus node, as in Webots."""
        value = as_float(d, "Camera.setFocalDistance")
        focus = self._part("focus")
        if focus is None:
            warn("Camera.setFocalDistance(): the camera has no Focus node")
        elif not self.getMinFocalDistance() <= value <= self.getMaxFocalDistance():
            warn(f"Camera.setFocalDistance(): {value} is outside [minFocalDistance, maxFocalDistance]")
        else:
            focus["focalDistance"] = value

    def getNear(self) -> float:
        return self._model().near

    def getFar(self) -> float:
        return self._model().far

    def getExposure(self) -> float:
        return self._model().exposure

    def setExposure(self, exposure: Any) -> None:
        value = as_float(exposure, "Camera.setExposure")
        if value < 0.0:
            warn(f"Camera.setExposure(): {value} is negative")
            return
        self._model().exposure = value  # kept for the getter; the headless image does not change with it

    # -- recognition (computed in camera_recognition.py)

    def hasRecognition(self) -> bool:
        return self._part("recognition") is not None

    def _recognizer(self) -> RecognitionSampler:
        sampler: RecognitionSampler | None = self.__dict__.get("_recognition_sampler")
        if sampler is None:
            def view() -> CameraView:
                m = self._model()
                return CameraView(m.width, m.height, m.fov, m.near)

            sampler = self.__dict__["_recognition_sampler"] = RecognitionSampler(
                self._binding(), view, lambda: self._robot._runtime.node_ids()[0], self._keep_segmentation_poses)
        return sampler

    def _keep_segmentation_poses(self) -> None:
        """At a recognition sample: the poses the segmentation image will be drawn from (at the next read)."""
        if self.isRecognitionSegmentationEnabled():
            scene = _visual_scene(self._robot)
            self.__dict__["_segmentation_poses"] = (scene, scene.snapshot(), self._view(self._model()))
        else:
            self.__dict__["_segmentation_poses"] = None

    def recognitionEnable(self, sampling_period: Any) -> None:
        period = as_int(sampling_period, "Camera.recognitionEnable")
        if not self.hasRecognition():
            warn("Camera.recognitionEnable(): this camera has no Recognition node")
            return
        self._recognizer().enable(period)

    def recognitionDisable(self) -> None:
        if self.hasRecognition():
            self._recognizer().disable()

    def getRecognitionSamplingPeriod(self) -> int:
        return self._recognizer().getSamplingPeriod() if self.hasRecognition() else 0

    def getRecognitionNumberOfObjects(self) -> int:
        return len(self.getRecognitionObjects())

    def getRecognitionObjects(self) -> list[CameraRecognitionObject]:
        """The objects of the last recognition sample, nearest first (none before the first, or disabled)."""
        if not self.getRecognitionSamplingPeriod():
            return []
        return list(self._recognizer().objects)

    def hasRecognitionSegmentation(self) -> bool:
        recognition = self._part("recognition")
        return bool(recognition.get("segmentation", False)) if recognition is not None else False

    def enableRecognitionSegmentation(self) -> None:
        if self.hasRecognitionSegmentation():
            self.__dict__["_segmentation"] = True
        else:
            warn("Camera.enableRecognitionSegmentation(): the Recognition node's segmentation is FALSE")

    def disableRecognitionSegmentation(self) -> None:
        self.__dict__["_segmentation"] = False

    def isRecognitionSegmentationEnabled(self) -> bool:
        return bool(self.__dict__.get("_segmentation", False))

    def _segmentation_image(self) -> np.ndarray | None:
        if not self.isRecognitionSegmentationEnabled() or not self.getRecognitionSamplingPeriod():
            return None
        sampler = self._recognizer()
        if sampler.pending:
            sampler.pending = False
            self.__dict__["_segmentation_frame"] = self._render_segmentation()
        frame: np.ndarray | None = self.__dict__.get("_segmentation_frame")
        if frame is None:  # enabled, not sampled yet: a black frame, as the image
            m = self._model()
            return np.zeros((m.height, m.width, 4), dtype=np.uint8)
        return frame

    def _render_segmentation(self) -> np.ndarray:
        m = self._model()
        scene = _visual_scene(self._robot)
        renderer = self._renderer_for("segmentation", scene, supersample=1)
        kept = self.__dict__.get("_segmentation_poses")
        if kept is not None and kept[0] is scene:
            scene.restore(kept[1])
            view = kept[2]
        else:  # enabled after the sample, or the scene rebuilt since: the poses now
            scene.sync()
            view = self._view(m)
        ids = renderer.render_geom_ids(scene.data, view, near=m.near, far=m.far if m.far > 0 else None)
        return segmentation_image(ids, scene.solid_geoms(),
                                  segmentation_colours(self._robot._sim, self._record.solid))

    def getRecognitionSegmentationImage(self) -> bytes | None:
        """BGRA: a recognisable object's pixels in its first recognition colour, black elsewhere; None while
        segmentation or recognition is disabled."""
        image = self._segmentation_image()
        return None if image is None else image.tobytes()

    def getRecognitionSegmentationImageArray(self) -> list[list[list[int]]] | None:
        """``[x][y] -> [r, g, b]``, as getImageArray."""
        image = self._segmentation_image()
        return None if image is None else image[..., 2::-1].transpose(1, 0, 2).tolist()

    def saveRecognitionSegmentationImage(self, filename: str, quality: Any) -> int:
        """Write the segmentation image as PNG; 0 on success, -1 when disabled or not written."""
        image = self._segmentation_image()
        if image is None:
            return -1
        as_int(quality, "Camera.saveRecognitionSegmentationImage")
        rgba = np.concatenate([image[..., 2::-1], image[..., 3:]], axis=2)
        try:
            write_bytes(Path(filename), png_bytes(np.ascontiguousarray(rgba)))
        except OSError as exc:
            warn(f"Camera.saveRecognitionSegmentationImage(): cannot write {filename}: {exc}")
            return -1
        return 0

    image = property(lambda self: self.getImage())
    segmentation_image = property(lambda self: self.getRecognitionSegmentationImage())
    focal_length = property(lambda self: self.getFocalLength())
    max_focal_distance = property(lambda self: self.getMaxFocalDistance())
    min_focal_distance = property(lambda self: self.getMinFocalDistance())
    height = property(lambda self: self.getHeight())
    width = property(lambda self: self.getWidth())
    min_fov = property(lambda self: self.getMinFov())
    max_fov = property(lambda self: self.getMaxFov())
    near = property(lambda self: self.getNear())
    exposure = property(lambda self: self.getExposure(), lambda self, exposure: self.setExposure(exposure))
    focal_distance = property(lambda self: self.getFocalDistance(), lambda self, d: self.setFocalDistance(d))
    fov = property(lambda self: self.getFov(), lambda self, f: self.setFov(f))

    def getProjection(self) -> str:
        return self._model().projection
