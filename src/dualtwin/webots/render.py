"""Headless offscreen frames of a MuJoCo model from any camera pose: the renderer both twins share.

Moved here from ``dualtwin.twins.camera`` (which re-exports every name) so the Webots runtime's
``Camera`` device, at the lowest layer, draws with the same renderer as perception: one rendering path for
the Webots twin's perception frames and for a controller's ``Camera.getImage()``.

Rendering uses MuJoCo's OpenGL renderer offscreen. The backend comes from ``MUJOCO_GL`` (``egl`` for Mesa's
EGL, ``osmesa`` for the pure-CPU OSMesa), read by MuJoCo at import; library code never sets it. No GPU and no
display are needed. :class:`FrameRenderer` draws one ``MjModel``/``MjData`` pair with the costly effects
(shadows, reflections, skybox, MSAA) off: on Mesa's software rasteriser 4x MSAA and the 4096² shadow map cost
10-70 ms a frame, so anti-aliasing is done by rendering at ``supersample`` times the size and averaging pixel
blocks instead (a few ms). Visual randomisation (:class:`Appearance`) edits the built ``mjvScene`` (lights,
geom colours), never the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from dualtwin.errors import DualtwinError

if TYPE_CHECKING:
    import mujoco

__all__ = ["PLANE_GRID_M", "Appearance", "FrameRenderer", "ResolvedCamera"]

Vec3 = tuple[float, float, float]
#: Tessellation of rendered planes (m) when effects are off; see FrameRenderer.
PLANE_GRID_M = 1.0


def _vec(values: Any) -> Vec3:
    a, b, c = (float(v) for v in values)
    return (a, b, c)


@dataclass(frozen=True)
class ResolvedCamera:
    """A camera in world coordinates for one frame: position, unit forward and up, vertical fov (degrees)."""

    pos: np.ndarray
    forward: np.ndarray
    up: np.ndarray
    fovy_deg: float

    @staticmethod
    def look(pos: Any, lookat: Any, up: Any, fovy_deg: float) -> ResolvedCamera:
        p = np.asarray(pos, dtype=float)
        f = np.asarray(lookat, dtype=float) - p
        f /= np.linalg.norm(f)
        u = np.asarray(up, dtype=float)
        u = u - f * float(u @ f)  # orthogonalise: OpenGL needs up perpendicular to forward
        u /= np.linalg.norm(u)
        return ResolvedCamera(p, f, u, float(fovy_deg))


@dataclass(frozen=True)
class Appearance:
    """Visual randomisation of one episode, applied to the built scene (the model is never touched).

    ``light_gain`` scales the diffuse colour of the scene's own lights, ``headlight`` sets the camera-attached
    light's diffuse level, ``ambient`` is added to every light's ambient term, ``light_tilt`` tilts directional
    lights (added to their direction before normalising), and ``geom_gain`` multiplies the RGB of every geom
    (cycled by geom index, so one table serves scenes of any size).
    """

    light_gain: float = 1.0
    headlight: float | None = None
    ambient: float = 0.0
    light_tilt: Vec3 = (0.0, 0.0, 0.0)
    geom_gain: tuple[Vec3, ...] = field(default_factory=tuple)

    @staticmethod
    def sample(rng: np.random.Generator, colour: float = 0.15, n_gains: int = 32) -> Appearance:
        gains = rng.uniform(1.0 - colour, 1.0 + colour, size=(n_gains, 3))
        return Appearance(
            light_gain=float(rng.uniform(0.6, 1.3)),
            headlight=float(rng.uniform(0.3, 0.7)),
            ambient=float(rng.uniform(0.0, 0.15)),
            light_tilt=_vec(rng.uniform(-0.3, 0.3, 3) * np.array([1.0, 1.0, 0.0])),
            geom_gain=tuple(_vec(g) for g in gains),
        )

    def to_dict(self) -> dict[str, Any]:
        return {"light_gain": self.light_gain, "headlight": self.headlight, "ambient": self.ambient,
                "light_tilt": list(self.light_tilt), "n_geom_gains": len(self.geom_gain)}


class FrameRenderer:
    """Offscreen RGB frames of one model, from any :class:`ResolvedCamera`, with cheap settings.

    Args:
        model: the model to draw (a twin's physics model or a visual-only scene).
        width, height: output resolution.
        supersample: render ``supersample`` times larger and average blocks (anti-aliasing; 1 = off).
        effects: keep shadows, reflections and the skybox (slow on a CPU rasteriser; off for perception).
        sky: keep the skybox alone (a Webots Camera's Background colour: a flat skybox, about 1.5 ms a
            320x240 frame on a CPU rasteriser).
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, *, supersample: int = 2,
                 effects: bool = False, sky: bool = False) -> None:
        import mujoco

        if width < 1 or height < 1 or supersample < 1:
            raise DualtwinError(f"render size must be positive (got {width}x{height}, supersample {supersample})")
        self.model = model
        self.width, self.height, self.supersample = int(width), int(height), int(supersample)
        self.effects = effects
        w, h = self.width * self.supersample, self.height * self.supersample
        vis = model.vis
        saved = (vis.global_.offwidth, vis.global_.offheight, vis.quality.offsamples)
        planes = np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
        saved_grid = model.geom_size[planes, 2].copy()
        # The GL context is made from the model's visual settings: set them for this renderer only and restore
        # them. MSAA off unless effects (supersampling anti-aliases instead). Planes are tessellated into
        # quads of size[2] (a purely visual size) when the context is made; a fine grid (the MJCF floor's
        # 5 cm) costs more than the rest of the frame in software, so the context gets a coarse one.
        vis.global_.offwidth, vis.global_.offheight = max(w, saved[0]), max(h, saved[1])
        if not effects:
            vis.quality.offsamples = 0
            model.geom_size[planes, 2] = np.maximum(saved_grid, PLANE_GRID_M)
        try:
            self._renderer = mujoco.Renderer(model, h, w)
        except Exception as exc:  # noqa: BLE001 - any GL failure gets the same advice
            raise DualtwinError(
                f"offscreen rendering failed ({type(exc).__name__}: {exc}). Set MUJOCO_GL=egl (Mesa EGL: "
                "libegl1 libegl-mesa0 libgl1-mesa-dri) or MUJOCO_GL=osmesa (libosmesa6) before starting Python"
            ) from None
        finally:
            vis.global_.offwidth, vis.global_.offheight, vis.quality.offsamples = saved
            model.geom_size[planes, 2] = saved_grid
        self._free = mujoco.MjvCamera()
        self._free.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._option = mujoco.MjvOption()
        self._flags = [] if effects else [mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                                          *([] if sky else [mujoco.mjtRndFlag.mjRND_SKYBOX]),
                                          mujoco.mjtRndFlag.mjRND_FOG, mujoco.mjtRndFlag.mjRND_HAZE]
        self._geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        self._directional = int(mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)

    def render(self, data: mujoco.MjData, camera: ResolvedCamera, appearance: Appearance | None = None, *,
               near: float | None = None, far: float | None = None) -> np.ndarray:
        """One RGB frame (height, width, 3) uint8 of ``data`` (whose kinematics must be up to date).

        ``near``/``far`` (m) override the model's clipping planes (a Webots Camera's ``near`` and ``far``).
        """
        self._prepare(data, camera, appearance, near, far)
        image = self._renderer.render()
        s = self.supersample
        if s == 1:
            return image.copy()
        blocks = image.reshape(self.height, s, self.width, s, 3).astype(np.uint16).sum(axis=(1, 3))
        return ((blocks + (s * s) // 2) // (s * s)).astype(np.uint8)

    def render_labels(self, data: mujoco.MjData, camera: ResolvedCamera, groups: list[np.ndarray]) -> np.ndarray:
        """Per-pixel coverage (uint8 0..255) of each group of geom ids: [height, width, len(groups)].

        Drawn by MuJoCo's segmentation pass from the same camera; coverage is the fraction of the supersampled
        pixels that show the group, so a thin pole gets the same anti-aliased footprint as in the RGB frame.
        """
        geom = self.render_geom_ids(data, camera)
        s = self.supersample
        out = np.zeros((self.height, self.width, len(groups)), dtype=np.uint8)
        for i, group in enumerate(groups):
            hit = np.isin(geom, group).reshape(self.height, s, self.width, s).sum(axis=(1, 3))
            out[..., i] = np.round(hit * (255.0 / (s * s))).astype(np.uint8)
        return out

    def render_geom_ids(self, data: mujoco.MjData, camera: ResolvedCamera, *, near: float | None = None,
                        far: float | None = None) -> np.ndarray:
        """The geom id each rendered pixel shows (-1: none), at the rendered (supersampled) size.

        MuJoCo's segmentation pass from the same camera and clipping planes as :meth:`render`.
        """
        self._prepare(data, camera, None, near, far)
        renderer = self._renderer
        renderer.enable_segmentation_rendering()
        try:
            ids = renderer.render()
        finally:
            renderer.disable_segmentation_rendering()
        return np.where(ids[..., 1] == self._geom_type, ids[..., 0], -1)

    def _prepare(self, data: mujoco.MjData, camera: ResolvedCamera, appearance: Appearance | None,
                 near: float | None = None, far: float | None = None) -> None:
        renderer = self._renderer
        renderer.update_scene(data, camera=self._free, scene_option=self._option)
        scene = renderer.scene
        for flag in self._flags:
            scene.flags[flag] = 0
        # Override the GL camera and the headlight that follows it (what update_scene derives from a
        # model camera); the two stereo eyes coincide for a mono render.
        if near is None:
            near = float(scene.camera[0].frustum_near)
        top = near * math.tan(math.radians(camera.fovy_deg) / 2.0)
        for eye in (scene.camera[0], scene.camera[1]):
            eye.pos[:] = camera.pos
            eye.forward[:] = camera.forward
            eye.up[:] = camera.up
            eye.frustum_center = 0.0
            eye.frustum_width = 0.0
            eye.frustum_bottom = -top
            eye.frustum_top = top
            eye.frustum_near = near
            if far is not None:
                eye.frustum_far = far
            elif eye.frustum_far <= near:  # an empty scene has no extent to derive a far plane from
                eye.frustum_far = near * 1e4
        for i in range(scene.nlight):
            light = scene.lights[i]
            if light.headlight:
                light.pos[:] = camera.pos
                light.dir[:] = camera.forward
        if appearance is not None:
            self._apply(scene, appearance)

    def _apply(self, scene: Any, appearance: Appearance) -> None:
        for i in range(scene.nlight):
            light = scene.lights[i]
            if light.headlight:
                if appearance.headlight is not None:
                    light.diffuse[:] = appearance.headlight
            else:
                light.diffuse[:] = np.asarray(light.diffuse) * appearance.light_gain
                if light.type == self._directional:
                    d = np.asarray(light.dir, dtype=float) + np.asarray(appearance.light_tilt)
                    light.dir[:] = d / max(float(np.linalg.norm(d)), 1e-9)
            light.ambient[:] = np.asarray(light.ambient) + appearance.ambient
        gains = appearance.geom_gain
        if gains:
            for i in range(scene.ngeom):
                geom = scene.geoms[i]
                if geom.objtype == self._geom_type:
                    gain = gains[int(geom.objid) % len(gains)]
                    geom.rgba[:3] = np.clip(np.asarray(geom.rgba[:3]) * gain, 0.0, 1.0)

    def close(self) -> None:
        self._renderer.close()
