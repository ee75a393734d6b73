"""A visual-only MuJoCo scene of a Webots world, posed from the supervisor: how the Webots twin renders.

The runtime's ``Camera`` device draws this scene too, so it lives at the lowest layer.

Our headless Webots runtime has no renderer of its own, so the world's Shapes are drawn by the same MuJoCo
renderer as the MuJoCo twin (:class:`dualtwin.twins.camera.FrameRenderer`):

* every Solid (robot parts, static objects, Solid-derived devices) with visible Shapes becomes one **mocap
  body**; its Shapes (through Pose/Transform/Group, not through nested Solids) become geoms in the Solid's
  frame with the appearance's colour (PBR ``baseColor`` / Material ``diffuseColor``); an IndexedFaceSet, a
  Mesh and a CadShape are MuJoCo meshes of :func:`~dualtwin.webots.shapes.surface_triangles` (a CadShape in
  :data:`~dualtwin.webots.shapes.CAD_SHAPE_RGBA`: its file's materials are not read); a mesh file that cannot
  be read is not drawn (a line in :attr:`WebotsVisualScene.warnings`);
* DirectionalLight/PointLight/SpotLight become MuJoCo lights wherever they sit, as in Webots where a light is a
  child like any other: a Point/SpotLight inside a Solid (through Pose/Transform/Group) is a light of the Solid's
  body, its ``location``/``direction`` in that frame, so it moves with the Solid; a DirectionalLight's
  ``direction`` is a world direction wherever it sits (Webots' DirectionalLight page: "in the global coordinate
  system"; the LightSensor reads it so too: :mod:`.lights`). Each frame, :meth:`WebotsVisualScene.sync` sets
  them from their fields as the steps executed them (a supervisor's edit shows from the next step's image): on
  and colour from ``on``/``color``/``intensity``/``ambientIntensity``, or for the lights of an LED from the LED's
  state (:mod:`.led_lights`), and place from ``location``/``direction``/``attenuation``/``cutOffAngle``. MuJoCo's
  default headlight is kept, as in every MuJoCo model;
* the Background: with ``background=True`` (a ``Camera`` device's scene) the sky is the first Background's
  first ``skyColor``, as Webots draws it where no cube-map texture is set (the TexturedBackground PROTO says so
  of its ``skyColor``); its textures are not drawn (a line in :attr:`WebotsVisualScene.warnings`). It is a flat
  MuJoCo skybox, unlit, in bytes rounded to the nearest. Without it (the perception renderer) the background
  is MuJoCo's clear colour, black, as in the MJCF twin;
* each frame, :meth:`WebotsVisualScene.sync` copies every Solid's pose read through the supervisor API
  (``Node.getPosition``/``getOrientation``) into ``mocap_pos``/``mocap_quat`` and runs ``mj_forward``.

``supervisor`` is anything with ``getRoot()`` returning a scene handle: a Supervisor, or the root view a
``Camera`` device of a plain Robot builds (a camera sees the world whether or not its robot is a supervisor).

The structure is walked through the supervisor API (``getField``/``getMFNode``); only the geometry itself
is read from our runtime's scene tree (``Node.scene_node``). In a real Webots installation the world is
rendered by Webots itself: add a ``Camera`` device and read ``Camera.getImage()`` instead of this scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.geometry import mujoco_quat
from dualtwin.webots import _math3 as m3
from dualtwin.webots import schema
from dualtwin.webots.led_lights import light_state
from dualtwin.webots.mesh_files import MeshFileError
from dualtwin.webots.render import ResolvedCamera
from dualtwin.webots.shapes import CAD_SHAPE_RGBA, appearance_rgba, surface_triangles
from dualtwin.webots.solid_scale import holds_bodies, positive_scale, transform_factor

__all__ = ["VISUAL_GEOMETRY", "WebotsVisualScene"]

VISUAL_GEOMETRY = ("Box", "Sphere", "Cylinder", "Capsule", "Plane", "IndexedFaceSet", "Mesh")
_LIGHTS = ("DirectionalLight", "PointLight", "SpotLight")
_SPECULAR = 0.3  # the highlight of a white light (Webots' lights have no specular field)


#: (field, default) of a light that its MuJoCo light follows, besides on and color (light_state)
_LIGHT_FIELDS = (("intensity", 1.0), ("ambientIntensity", 0.0), ("location", (0.0, 0.0, 0.0)),
                 ("direction", (0.0, 0.0, -1.0)), ("attenuation", (1.0, 0.0, 0.0)), ("cutOffAngle", math.pi / 2))


@dataclass
class _Light:
    """A light drawn: its MuJoCo name, its node, the LED driving it (or None), its frame and scale in its body's
    frame, and what :meth:`WebotsVisualScene.sync` last set of it (None: nothing yet)."""

    name: str
    node: Any
    led: Any
    frame: np.ndarray
    scale: float
    shown: Any = None


@dataclass
class _Parts:
    """What a walk collects for one body (a Solid's, or the world's): geoms, and lights with their frame and
    scale in the body's frame; ``led``: the LED whose lights these are (the body is an LED's)."""

    geoms: list[dict[str, Any]] = field(default_factory=list)
    lights: list[tuple[Any, np.ndarray, float]] = field(default_factory=list)
    led: Any = None


def rotation_matrix(rotation: Any) -> np.ndarray:
    """Webots SFRotation (axis, angle; axis normalised) as a 3x3 array.

    Through the physics engine's own tuple math rather than :func:`dualtwin.geometry.axis_angle_matrix`: the two
    agree to rounding, and this keeps the scene's fixed poses bit for bit those of the ODE world it draws.
    """
    return np.asarray(m3.rot_axis_angle(rotation), dtype=float).reshape(3, 3)


def _drawn_factor(transform: Any) -> float:
    """The factor a Transform scales what it holds by in the drawing: above Solids or joints the physics' one
    factor (:mod:`dualtwin.webots.solid_scale`: a non-uniform scale's largest), above Shapes alone its x factor
    (a non-positive one reset to 1, as the physics does; the load warned about it)."""
    def quiet(_: str) -> None:
        return None

    if holds_bodies(transform):
        return transform_factor(transform, quiet)
    return positive_scale(transform, quiet)[0]


def _pose(fields: dict[str, Any], scale: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation_matrix(fields.get("rotation", (0.0, 0.0, 1.0, 0.0)))
    T[:3, 3] = np.asarray(fields.get("translation", (0.0, 0.0, 0.0)), dtype=float) * scale
    return T


def _rgba(shape: Any) -> list[float]:
    # Webots draws a Shape without appearance in white.
    return appearance_rgba(shape) or [1.0, 1.0, 1.0, 1.0]


def _children(handle: Any, field: str) -> list[Any]:
    # The scene draws the expanded tree: a PROTO instance's getField answers its interface (as Webots does), its
    # base node's children/endPoint come from getProtoField.
    f = handle.getProtoField(field) if handle.isProto() else handle.getField(field)
    if f is None:
        return []
    if f.getCount() < 0:  # an SF field
        node = f.getSFNode()
        return [node] if node is not None else []
    return [n for n in (f.getMFNode(i) for i in range(f.getCount())) if n is not None]


class WebotsVisualScene:
    """The visual scene of the world a Webots supervisor runs, as a MuJoCo model with one mocap body per Solid.

    ``allow_empty``: a world without any visible Shape gives an empty scene (a Camera then sees only the
    background) instead of an error (perception has nothing to learn from such a world). ``background``: draw
    the world's Background colour behind everything (:attr:`sky`; see the module docstring).
    """

    def __init__(self, supervisor: Any, *, allow_empty: bool = False, background: bool = False) -> None:
        self.sup = supervisor
        self.spec = mujoco.MjSpec()
        self.spec.compiler.degree = False
        self.warnings: list[str] = []
        self.geometry_version: int | None = None  # the simulation's, when its owner built it (camera.py)
        self._solids: list[tuple[Any, str]] = []
        self._cameras: dict[str, Any] = {}
        self._viewpoint: Any = None
        self._mesh_count = 0
        self._background: Any = None
        #: The sky's RGB bytes when the scene draws a Background colour (a skybox), else None (black).
        self.sky: tuple[int, int, int] | None = None
        self._world = _Parts()
        self._names: set[str] = set()
        self._lights: list[_Light] = []  # every light drawn
        root = supervisor.getRoot()
        if not hasattr(root, "scene_node"):
            raise DualtwinError("the Webots visual scene needs dualtwin's headless runtime; in real Webots add a "
                                "Camera device and use Camera.getImage()")
        self._sim = root._sim  # where an LED's state is (led_lights)
        for top in _children(root, "children"):
            self._top(top)
        for geom in self._world.geoms:
            self.spec.worldbody.add_geom(**geom)
        self._add_lights(self.spec.worldbody, self._world)
        if background and self._background is not None:
            self._sky(self._background)
        if not self._solids and not self._world.geoms and not allow_empty:
            raise DualtwinError("the Webots world has no visible Shape in any Solid: nothing to render")
        try:
            self.model = self.spec.compile()
        except ValueError as exc:
            raise DualtwinError(f"the Webots visual scene does not compile: {' '.join(str(exc).split())}") from None
        self.data = mujoco.MjData(self.model)
        self._mocap = [int(self.model.body_mocapid[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)])
                       for _, name in self._solids]
        self._light_ids = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_LIGHT, light.name) for light in self._lights]
        self.sync()

    # ------------------------------------------------------------------ building
    def _top(self, handle: Any) -> None:
        kind = handle.getBaseTypeName()
        node = handle.scene_node
        if kind == "Viewpoint":
            self._viewpoint = handle
        elif kind == "Background":
            # Webots uses the first Background of the world
            if self._background is None:
                self._background = node
        else:
            # Shapes and lights outside any Solid are static scenery, in the world frame.
            self._walk(handle, np.eye(4), 1.0, self._world)

    def _sky(self, node: Any) -> None:
        """The Background's first skyColor as a flat skybox (nothing for black, MuJoCo's clear colour)."""
        colours = node.get("skyColor", [])
        if any(node.get(f"{side}Url") for side in ("back", "bottom", "front", "left", "right", "top")):
            self.warnings.append(f"{node.location or 'Background'}: Background textures are not drawn; the sky is "
                                 "its skyColor")
        if not colours:
            return
        rgb = tuple(int(math.floor(min(max(float(c), 0.0), 1.0) * 255.0 + 0.5)) for c in colours[0][:3])
        if not any(rgb):
            return
        self.sky = (rgb[0], rgb[1], rgb[2])
        # a quarter of a byte above the value: MuJoCo truncates the flat texture's colour to bytes
        colour = [(b + 0.25) / 255.0 if b < 255 else 1.0 for b in rgb]
        self.spec.add_texture(name="webots_background", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                              builtin=mujoco.mjtBuiltin.mjBUILTIN_FLAT, rgb1=colour, rgb2=colour, width=4, height=4)

    def _add_lights(self, body: Any, parts: _Parts) -> None:
        """Add the Point/SpotLights of ``parts`` to ``body`` (their frames are in its frame) and its
        DirectionalLights to the world (a world direction wherever they sit). Every light is added, on or not:
        :meth:`sync` sets it from its fields (switched, coloured, placed)."""
        for node, T, scale in parts.lights:
            name = f"webots_light{len(self._lights)}"
            if node.type_name == "DirectionalLight":
                light = self.spec.worldbody.add_light(name=name, type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                                      pos=[0.0, 0.0, 10.0])
            else:
                # A PointLight is a spot of cone 180°, OpenGL's uniform point light (GL_SPOT_CUTOFF): MuJoCo's
                # renderer draws its own "point" lights as nothing.
                light = body.add_light(name=name, type=mujoco.mjtLightType.mjLIGHT_SPOT)
            light.castshadow = False
            self._lights.append(_Light(name, node, parts.led, T, scale))

    def _walk(self, handle: Any, T: np.ndarray, scale: float, parts: _Parts | None) -> None:
        """Visit ``handle``: Solids get their own body; Shapes and lights add to ``parts`` (the enclosing
        Solid's)."""
        kind = handle.getBaseTypeName()
        node = handle.scene_node
        if schema.is_solid_type(kind):
            self._solid(handle, kind, scale)
        elif kind in ("Shape", "CadShape"):
            if parts is not None:
                geom = self._shape(node, T, scale)
                if geom is not None:
                    parts.geoms.append(geom)
        elif kind in _LIGHTS:
            if parts is not None:
                parts.lights.append((node, T, scale))
        elif kind in ("Pose", "Transform", "TrackWheel"):  # a TrackWheel: a Pose at (position.x, 0, position.y)
            inner = T @ _pose(node.fields, scale)
            for child in _children(handle, "children"):
                self._walk(child, inner, scale * _drawn_factor(node) if kind == "Transform" else scale, parts)
        elif kind == "Group":
            for child in _children(handle, "children"):
                self._walk(child, T, scale, parts)
        elif kind in schema.JOINT_TYPES or kind == "Slot":
            # The endPoint Solid moves on its own: it is a body of its own, posed by the supervisor.
            for child in _children(handle, "endPoint"):
                self._walk(child, np.eye(4), scale, None)

    def _solid(self, handle: Any, kind: str, scale: float) -> None:
        node = handle.scene_node
        # its Shapes at the factor the physics sizes and places the Solid with (the load's: a run-time edit of a
        # scale above it is not applied to it, physics/frame_edits.py), not the one the fields say now
        solid = handle._sim.solid_for(node)
        scale = solid.scale if solid is not None else scale
        if kind == "Camera":
            self._cameras[str(node.get("name", "camera"))] = handle
        # an LED drives the lights among its own children (Webots' LED page), not those of a Solid inside it
        parts = _Parts(led=node if kind == "LED" else None)
        for child in _children(handle, "children"):
            self._walk(child, np.eye(4), scale, parts)
        if kind == "Lidar":  # its rotatingHead Solid (webots-devices.md §3.1), a body of its own that the lidar turns
            for head in _children(handle, "rotatingHead"):
                self._walk(head, np.eye(4), scale, None)
        if not parts.geoms and all(light.type_name == "DirectionalLight" for light, _, _ in parts.lights):
            self._add_lights(self.spec.worldbody, parts)  # nothing that moves with the Solid: no body to pose
            return
        # Bodies are named after the Solid's DEF (else its name field), as the binding names bodies.
        base = node.def_name or str(node.get("name") or kind.lower())
        name, n = base, 1
        while name in self._names:
            name, n = f"{base}({n})", n + 1
        self._names.add(name)
        body = self.spec.worldbody.add_body(name=name, mocap=True)
        for geom in parts.geoms:
            body.add_geom(**geom)
        self._add_lights(body, parts)
        self._solids.append((handle, name))

    def _shape(self, shape: Any, T: np.ndarray, scale: float) -> dict[str, Any] | None:
        """The MuJoCo geom (keyword arguments) of a Shape (or CadShape) at frame T of its Solid, or None if not
        drawable."""
        if shape.type_name == "CadShape":  # a Shape whose geometry is its own file
            geometry, rgba = shape, list(CAD_SHAPE_RGBA)
        else:
            geometry, rgba = shape.get("geometry"), _rgba(shape)
        if geometry is None:
            return None
        kind = geometry.type_name
        if kind not in VISUAL_GEOMETRY and kind != "CadShape":
            self.warnings.append(f"{geometry.location}: visual {kind} not drawn")
            return None
        kwargs: dict[str, Any] = {"pos": [float(v) for v in T[:3, 3]], "quat": [float(v) for v in mujoco_quat(T[:3, :3])],
                                  "rgba": rgba, "contype": 0, "conaffinity": 0}
        if kind == "Box":
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_BOX, size=[float(v) * scale / 2 for v in geometry["size"]])
        elif kind == "Sphere":
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[float(geometry["radius"]) * scale, 0, 0])
        elif kind in ("Cylinder", "Capsule"):
            gtype = mujoco.mjtGeom.mjGEOM_CYLINDER if kind == "Cylinder" else mujoco.mjtGeom.mjGEOM_CAPSULE
            kwargs.update(type=gtype, size=[float(geometry["radius"]) * scale, float(geometry["height"]) * scale / 2, 0])
        elif kind == "Plane":
            sx, sy = (float(v) * scale for v in geometry["size"])
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[sx / 2, sy / 2, 1.0])
        else:
            try:
                points, faces = surface_triangles(geometry)
            except MeshFileError as exc:
                self.warnings.append(f"{kind} not drawn: {exc}")
                return None
            points = points * scale
            if len(faces) == 0 or len(points) < 4:
                return None
            self._mesh_count += 1
            mesh = self.spec.add_mesh(name=f"mesh{self._mesh_count}")
            mesh.uservert = points.reshape(-1).tolist()
            mesh.userface = faces.reshape(-1).tolist()
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            kwargs.update(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh.name)
        return kwargs

    def solid_geoms(self) -> list[tuple[Any, np.ndarray]]:
        """(scene-tree node, ids of its body's geoms) of every Solid drawn: what a segmentation pass maps back."""
        out = []
        for handle, name in self._solids:
            body = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
            start, count = int(self.model.body_geomadr[body]), int(self.model.body_geomnum[body])
            out.append((handle.scene_node, np.arange(start, start + count)))
        return out

    # ------------------------------------------------------------------ per frame
    def sync(self) -> None:
        """Copy every Solid's current supervisor pose into its mocap body, and every light's state (on, colour,
        intensities; an LED's state for its lights) into the model."""
        d = self.data
        for (handle, _), mocap in zip(self._solids, self._mocap, strict=True):
            d.mocap_pos[mocap] = handle.getPosition()
            R = np.asarray(handle.getOrientation(), dtype=float).reshape(3, 3)
            mujoco.mju_mat2Quat(d.mocap_quat[mocap], R.reshape(9))
        self._sync_lights()
        mujoco.mj_forward(self.model, d)

    def _sync_lights(self) -> None:
        """Each light as its fields (an LED's state for an LED's lights) are now, as the steps executed them (a
        camera draws the image of the step just done when its controller first reads it, maybe after a
        supervisor's write): set in the model when they changed since the last frame."""
        sim, m = self._sim, self.model
        for light, index in zip(self._lights, self._light_ids, strict=True):
            node = light.node
            fields: tuple[Any, ...] = tuple(
                tuple(v) if isinstance(v, list) else v
                for v in (sim.executed_value(node, name, default) for name, default in _LIGHT_FIELDS)
            )
            state = (light_state(sim, node, light.led), fields)
            if state == light.shown:
                continue
            light.shown = state
            (on, colour), (intensity, ambient, location, direction, attenuation, cutoff) = state
            rgb = np.asarray(colour, dtype=float)
            m.light_active[index] = on
            m.light_diffuse[index] = rgb * float(intensity)
            m.light_ambient[index] = rgb * float(ambient)
            # a highlight of the light's colour (a red LED's light leaves no white glint)
            m.light_specular[index] = rgb * _SPECULAR
            d = np.asarray(direction, dtype=float)
            d = d / max(float(np.linalg.norm(d)), 1e-9)
            if node.type_name == "DirectionalLight":
                m.light_dir[index] = d
                continue
            R, t = light.frame[:3, :3], light.frame[:3, 3]
            m.light_pos[index] = R @ (np.asarray(location, dtype=float) * light.scale) + t
            m.light_dir[index] = R @ d
            m.light_attenuation[index] = [float(v) for v in attenuation]
            m.light_cutoff[index] = 180.0 if node.type_name == "PointLight" else math.degrees(float(cutoff))

    def snapshot(self) -> tuple[np.ndarray, np.ndarray]:
        """The Solids' current poses (mocap positions and quaternions), to be drawn later by :meth:`restore`."""
        self.sync()
        return self.data.mocap_pos.copy(), self.data.mocap_quat.copy()

    def restore(self, poses: tuple[np.ndarray, np.ndarray]) -> None:
        """Pose the scene as at a :meth:`snapshot` of it."""
        self.data.mocap_pos[:], self.data.mocap_quat[:] = poses
        mujoco.mj_forward(self.model, self.data)

    def named_camera(self, name: str, width: int, height: int) -> ResolvedCamera:
        """A Camera device of the world by name, or ``viewpoint`` (Webots FLU: looks along +x, +z up)."""
        if name in self._cameras:
            handle = self._cameras[name]
            fov = float(handle.scene_node.get("fieldOfView", 0.785398))
        elif name == "viewpoint" and self._viewpoint is not None:
            handle = self._viewpoint
            fov = float(handle.scene_node.get("fieldOfView", 0.785398))
        else:
            known = ", ".join(sorted(self._cameras) + (["viewpoint"] if self._viewpoint is not None else []))
            raise DualtwinError(f"the Webots world has no camera {name!r} (Camera devices and the Viewpoint: "
                                f"{known or 'none'}); pass a CameraSpec instead")
        if handle is self._viewpoint:
            node = handle.scene_node
            R = rotation_matrix(node.get("orientation", (0.0, 0.0, 1.0, 0.0)))
            pos = np.asarray(node.get("position", (0.0, 0.0, 0.0)), dtype=float)
        else:
            R = np.asarray(handle.getOrientation(), dtype=float).reshape(3, 3)
            pos = np.asarray(handle.getPosition(), dtype=float)
        # Webots' fieldOfView is horizontal; the renderer wants the vertical one for this aspect ratio.
        fovy = math.degrees(2.0 * math.atan(math.tan(fov / 2.0) * height / width))
        return ResolvedCamera.look(pos, pos + R[:, 0], R[:, 2], fovy)
