"""Cameras and headless offscreen rendering shared by both twins.

Rendering uses MuJoCo's OpenGL renderer offscreen. The backend comes from ``MUJOCO_GL`` (``egl`` for Mesa's
EGL, ``osmesa`` for the pure-CPU OSMesa), read by MuJoCo at import; library code never sets it (the CLI and
the tests default it to ``egl``). No GPU and no display are needed.

A :class:`CameraSpec` describes a camera independently of any simulator (world pose, or a pose in a body
frame, and a vertical field of view), so the same camera renders the MuJoCo twin's model and the Webots
twin's visual scene (:mod:`dualtwin.webots.visual_scene`). :class:`FrameRenderer` draws one ``MjModel``/``MjData``
pair from such a camera with the costly effects (shadows, reflections, skybox, MSAA) off: on Mesa's
software rasteriser 4x MSAA and the 4096² shadow map cost 10-70 ms a frame, so anti-aliasing is done by
rendering at ``supersample`` times the size and averaging pixel blocks instead (a few ms). Visual
randomisation (:class:`Appearance`) edits the built ``mjvScene`` (lights, geom colours), never the model.

Camera specs per robot come from the binding's ``cameras:`` section (see :func:`robot_cameras`)::

    cameras:
      perception: {pos: [0, -2.0, 0.6], lookat: [0, 0, 0.6], fovy_deg: 38, width: 64, height: 64}
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualtwin.errors import DualtwinError

# The renderer moved down to the Webots runtime (its Camera device draws with it); re-exported here.
from dualtwin.webots.render import PLANE_GRID_M, Appearance, FrameRenderer, ResolvedCamera  # noqa: F401

if TYPE_CHECKING:
    from dualtwin.robots.binding import RobotBinding
    from dualtwin.twins.base import Twin

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class CameraSpec:
    """A pinhole camera: where it is, where it looks, its vertical field of view and default resolution.

    ``pos``/``lookat``/``up`` are world coordinates, or coordinates in ``body``'s frame when ``body`` is set
    (a camera mounted on the robot moves with it).
    """

    name: str
    pos: Vec3
    lookat: Vec3
    up: Vec3 = (0.0, 0.0, 1.0)
    fovy_deg: float = 45.0
    width: int = 64
    height: int = 64
    body: str | None = None

    def __post_init__(self) -> None:
        if not 1.0 <= self.fovy_deg <= 170.0:
            raise DualtwinError(f"camera {self.name!r}: fovy_deg must be in [1, 170], got {self.fovy_deg}")
        if self.width < 1 or self.height < 1:
            raise DualtwinError(f"camera {self.name!r}: width and height must be >= 1")
        forward = np.subtract(self.lookat, self.pos)
        if np.linalg.norm(forward) < 1e-9 or np.linalg.norm(np.cross(forward, self.up)) < 1e-9:
            raise DualtwinError(f"camera {self.name!r}: lookat must differ from pos and not be along up")

    @classmethod
    def from_dict(cls, name: str, data: dict[str, Any]) -> CameraSpec:
        allowed = {"pos", "lookat", "up", "fovy_deg", "width", "height", "body"}
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise DualtwinError(f"camera {name!r}: unknown keys {unknown} (allowed: {sorted(allowed)})")
        try:
            kwargs: dict[str, Any] = {k: tuple(float(x) for x in v) if k in ("pos", "lookat", "up") else v
                                      for k, v in data.items()}
            for key in ("pos", "lookat", "up"):
                if key in kwargs and len(kwargs[key]) != 3:
                    raise ValueError(f"{key} needs 3 numbers")
            return cls(name=name, **kwargs)
        except (TypeError, ValueError) as exc:
            raise DualtwinError(f"camera {name!r}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    def with_size(self, width: int, height: int) -> CameraSpec:
        return replace(self, width=int(width), height=int(height))

    def jittered(self, rng: np.random.Generator, pos_m: float, lookat_m: float, fovy_deg: float) -> CameraSpec:
        """The camera moved by small uniform offsets: a real mount is never exactly where the model says."""
        pos = np.add(self.pos, rng.uniform(-pos_m, pos_m, 3))
        lookat = np.add(self.lookat, rng.uniform(-lookat_m, lookat_m, 3))
        fovy = self.fovy_deg + float(rng.uniform(-fovy_deg, fovy_deg))
        return replace(self, pos=_vec(pos), lookat=_vec(lookat), fovy_deg=fovy)


def _vec(values: Any) -> Vec3:
    a, b, c = (float(v) for v in values)
    return (a, b, c)




def resolve_camera(spec: CameraSpec, twin: Twin | None = None) -> ResolvedCamera:
    """World pose of ``spec`` now (a body-mounted camera reads the body's pose through the Twin API)."""
    if spec.body is None:
        return ResolvedCamera.look(spec.pos, spec.lookat, spec.up, spec.fovy_deg)
    if twin is None:
        raise DualtwinError(f"camera {spec.name!r} is mounted on body {spec.body!r}: a twin is needed to place it")
    origin = twin.body_position(spec.body)
    rotation = twin.body_orientation(spec.body)
    return ResolvedCamera.look(origin + rotation @ np.asarray(spec.pos), origin + rotation @ np.asarray(spec.lookat),
                               rotation @ np.asarray(spec.up), spec.fovy_deg)



# ------------------------------------------------------------------------------------------ camera specs

#: Cameras of the bundled robots, used until a binding declares its own ``cameras:`` section.
#: ``perception`` frames the cart-pole from the side: the pole (z 0.12-1.12 m) fills most of the image height,
#: about 46 pixels per metre at 64x64, so the 2 cm pole is about a pixel wide and a 0.02 rad tilt moves its tip
#: by about 0.9 pixel; the cart stays in view for |x| up to about 0.5 m (64x64) or 0.7 m (128x96).
#: ``side`` is the MJCF's own ``side`` camera (pos 0 -3 0.6, looking along +y, fovy 45).
DEFAULT_CAMERA = "perception"


def robot_cameras(robot: RobotBinding) -> dict[str, CameraSpec]:
    """The robot's cameras, from its binding's ``cameras:`` section."""
    return {name: CameraSpec.from_dict(name, value.model_dump(exclude_none=True))
            for name, value in robot.spec.cameras.items()}


@functools.lru_cache(maxsize=64)
def bundled_camera_for_model(model_path: str | Path, name: str) -> CameraSpec | None:
    """The camera ``name`` of the bundled robot whose model (either twin's) is ``model_path``, if any.

    Lets a twin that only knows its model file (the Webots twin's ``render("side", ...)``) find the cameras
    declared for its robot.
    """
    from dualtwin.robots.binding import bundled_robots, resolve_robot

    target = Path(model_path).resolve()
    for robot_name in bundled_robots():
        robot = resolve_robot(robot_name)
        paths = [(robot.root / section.model).resolve() for section in robot.spec.twins.values()]
        if target in paths:
            return robot_cameras(robot).get(name)
    return None


def camera_for(robot: RobotBinding, name: str | None = None) -> CameraSpec:
    cameras = robot_cameras(robot)
    key = name or DEFAULT_CAMERA
    if key not in cameras:
        known = ", ".join(sorted(cameras)) or "none"
        raise DualtwinError(f"robot {robot.name!r} has no camera {key!r} (cameras: {known}); add a 'cameras:' "
                            "section to its binding")
    return cameras[key]
