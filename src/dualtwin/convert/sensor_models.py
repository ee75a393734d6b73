"""Webots sensor value models in a converted model: ``resolution`` and ``lookupTable`` as numerics per sensor.

Resolution: ``<numeric name="webots_sensor.<sensor>" data="resolution"/>``. Webots quantises a sensor's output
with ``WbMathsUtilities::discretize``, int(v/r + 0.5)·r truncated toward zero, after its lookup table and noise
(``docs/reference/webots-devices.md`` §0.4, on-ode §5.4); ``-1`` (any r <= 0) disables it. MuJoCo sensors have no
resolution, so the converter writes it as a numeric per sensor and the MuJoCo twin applies the rule to its readings
(:func:`dualtwin.twins.mujoco_state.sensor_resolutions`). Written for the devices whose converted MuJoCo reading,
after the lookup table below, is Webots' value before quantisation: PositionSensor (joint position), GPS
(position, its ``accuracy`` being the MuJoCo sensor's noise), Gyro, Accelerometer, Compass and DistanceSensor. Not
for InertialUnit (a quaternion where Webots gives angles) and TouchSensor (lookup table not converted): there the
quantisation step would apply to another quantity.

Lookup table: ``<numeric name="webots_sensor_lut.<sensor>" data="in out noise in out noise ..."/>``, the rows of
the device's ``lookupTable`` (§0.3), applied by the MuJoCo twin to the physical value MuJoCo reads, before the
resolution (:mod:`dualtwin.twins.sensor_tables`). A Gyro, Accelerometer or Compass gets it only when its table
is not empty (an empty table is Webots' identity: nothing is written and the model is as before); each component
goes through it. A DistanceSensor always has one (Webots' default is ``[0 0 0, 0.1 1000 0]``); its rangefinder's
``cutoff`` is the last input D, Webots' ray length, and the twin reads ``lookup(min(d, D))``, a miss reading
``lookup(D)``. An empty DistanceSensor table reads 0 in Webots (§1.4), written as the one row ``0 0 0``.

Rays: the rangefinder is one ray along the sensor's axis that also hits visual geoms and the robot's other
bodies (MuJoCo's ray excludes only the sensor's own body and invisible geoms, and the rangefinder has no geom
filter). The converter therefore also writes what Webots casts,
``<numeric name="webots_distance.<sensor>" data="type group own D rays aperture gaussianWidth redColorSensitivity">``
(:func:`add_distance_rays`, read by :mod:`dualtwin.twins.mujoco_rays`): the geom group the rays hit (generic, sonar
and laser: the collision geoms, as Webots' ODE rays hit boundingObjects only, §1.3; infra-red: the visual geoms,
as Webots intersects its rays with the Shapes, §1.4), whether the sensor's robot is hidden from it (generic, sonar,
laser: all of it unless ``selfCollision``; infra-red: its Shapes that enclose the sensor), the ray length D and the
fields that give Webots' ray layout and Gaussian weights (§1.2), normalised as Webots does at load (the layout
itself is not written: the MJCF file keeps 6 significant digits, the twin computes it exactly from these fields,
as the Webots twin does). The MuJoCo twin reads such a sensor from those rays (generic: the weighted mean, a miss
counting D; sonar: the nearest hit whose surface faces the ray within π/8; laser: its ray; infra-red: the weighted
mean corrected by the weighted reflection factor) and plain MuJoCo programs still have the rangefinder. A world
with an infra-red sensor also gets each Shape's reflection factor, ``0.2 + 0.8·red·(1 − 0.5·roughness)`` of its
appearance (:func:`dualtwin.webots.visual_rays.infra_red_reflection`), as
``<numeric name="webots_reflection.<visual geom>" data="f">`` (:func:`add_reflections`).

A GPS reads the world position of its origin plus ``WorldInfo.gpsReference`` (the world origin in the GPS
coordinate system; Webots' WorldInfo page, :func:`dualtwin.webots.world_frame.gps_position`); MuJoCo's ``framepos``
reads the site's world position. A converted GPS in a world with a reference is therefore measured from the
world-fixed site :data:`GPS_REFERENCE_SITE` at -gpsReference, with the world's axes (``framepos`` relative to it:
the position plus the reference, exactly). A ``gpsCoordinateSystem "WGS84"`` world's GPS reads latitude and
longitude in Webots, which MuJoCo cannot: the converted GPS reads metres, and the conversion says so.

An Accelerometer, Gyro, Compass or InertialUnit with ``xAxis``, ``yAxis`` or ``zAxis`` FALSE reads NaN for that
component (angle) in Webots (their reference pages; the Webots twin does so); a MuJoCo sensor has no such switch
and reads it, so the conversion says so.

A Compass reads the world's north (the axis ``WorldInfo.coordinateSystem`` names N: +y in ENU, +x in NUE, +z in
EUN) as a unit vector in its frame (the Webots twin's ``webots.compass``); MuJoCo's ``magnetometer`` reads the
model's magnetic field in its site frame, by default (0, -0.5, 0), which read -0.5 times Webots' vector in ENU. A
converted world with a Compass gets ``<option magnetic>`` = that north, so the two read the same vector.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco

from dualtwin.twins.mujoco_rays import GENERIC, INFRA_RED, LASER, RAYS_NUMERIC, REFLECTION_NUMERIC, SONAR
from dualtwin.twins.mujoco_state import SENSOR_NUMERIC
from dualtwin.twins.sensor_tables import LUT_NUMERIC
from dualtwin.webots.lut import table_from_field
from dualtwin.webots.visual_rays import infra_red_reflection

__all__ = ["AXED", "GPS_REFERENCE_SITE", "QUANTISED", "TABLED", "RayTargets", "add_distance_rays", "add_gps_reference",
           "add_lookup_table", "add_reflections", "add_resolution", "add_sensor_model", "disabled_axes_notes",
           "distance_notes", "north"]

#: The devices whose ``resolution`` the converter writes (see the module docstring).
QUANTISED = frozenset({"PositionSensor", "GPS", "Gyro", "Accelerometer", "Compass", "DistanceSensor"})
#: The devices whose ``lookupTable`` the converter writes (see the module docstring).
TABLED = frozenset({"Gyro", "Accelerometer", "Compass", "DistanceSensor"})
#: The devices whose ``xAxis``/``yAxis``/``zAxis`` FALSE turn a component off (module docstring).
AXED = frozenset({"Accelerometer", "Gyro", "Compass", "InertialUnit"})
#: The world-fixed site a converted GPS is measured from when the world has a ``gpsReference`` (module docstring).
GPS_REFERENCE_SITE = "webots_gps_reference"
#: Webots' DistanceSensor types (case-insensitive; any other string is a sonar, as in Webots).
DISTANCE_TYPES = {"generic": "generic", "infra-red": "infra-red", "infrared": "infra-red", "laser": "laser"}


def add_resolution(spec: mujoco.MjSpec, sensor: str, device: Any) -> None:
    """Write ``device``'s ``resolution`` for the MuJoCo sensor ``sensor`` when it is one of :data:`QUANTISED` and
    the resolution is positive (Webots' default -1, or any value <= 0: no quantisation, nothing written)."""
    if device.type_name in QUANTISED and float(device.get("resolution", -1.0)) > 0:
        spec.add_numeric(name=SENSOR_NUMERIC + sensor, data=[float(device["resolution"])])


def north(world_info: Mapping[str, Any]) -> list[float]:
    """The world's north for its ``coordinateSystem`` (ENU when absent or unknown): the axis named ``N``."""
    system = str(world_info.get("coordinateSystem", "ENU")).upper()
    system = system if system in ("ENU", "NUE", "EUN") else "ENU"
    axis = [0.0, 0.0, 0.0]
    axis[system.index("N")] = 1.0
    return axis


def add_lookup_table(spec: mujoco.MjSpec, sensor: Any, device: Any) -> None:
    """Write ``device``'s ``lookupTable`` for the MuJoCo sensor ``sensor`` (an ``MjsSensor``) and, for a
    DistanceSensor, set the rangefinder's cutoff to the table's last input (module docstring)."""
    if device.type_name not in TABLED:
        return
    rows = table_from_field(device.get("lookupTable"))
    if device.type_name == "DistanceSensor":
        rows = rows or [(0.0, 0.0, 0.0)]  # Webots: an empty table reads 0 (no ray)
        if rows[-1][0] > 0:
            sensor.cutoff = rows[-1][0]
    if rows:
        spec.add_numeric(name=LUT_NUMERIC + sensor.name, data=[v for row in rows for v in row])


def distance_notes(device: Any) -> list[str]:
    """What of a DistanceSensor's value model the converted model does not reproduce (empty: nothing)."""
    if DISTANCE_TYPES.get(str(device.get("type", "generic")).lower(), "sonar") != "infra-red":
        return []
    return ["infra-red reflection is read from each Shape's colour and roughness: textures, occlusion maps and "
            "Pen paint at the hit point are not (as in the Webots twin)"]


class RayTargets:
    """What a converted DistanceSensor's rays may hit: the ``collision`` group's geoms (generic, sonar, laser) or
    the ``visual`` group's (infra-red), the sensor being on the converted ``robot`` or not, which has
    ``self_collision`` or not."""

    def __init__(self, collision: int, visual: int, *, robot: bool, self_collision: bool) -> None:
        self.collision, self.visual, self.robot, self.self_collision = collision, visual, robot, self_collision


def add_distance_rays(spec: mujoco.MjSpec, sensor: str, device: Any, targets: RayTargets) -> None:
    """Write Webots' rays of the DistanceSensor ``device`` for the MuJoCo rangefinder ``sensor`` (module
    docstring); nothing for an empty lookup table (which reads 0, no ray)."""
    kind = DISTANCE_TYPES.get(str(device.get("type", "generic")).lower(), "sonar")
    rows = table_from_field(device.get("lookupTable"))
    if not rows or rows[-1][0] <= 0:
        return
    # Webots' load-time normalisation (webots-devices §1.1): at least one ray, a laser one, one if no aperture.
    rays = max(int(device.get("numberOfRays", 1)), 1)
    aperture = abs(float(device.get("aperture", 1.5708)))
    width = float(device.get("gaussianWidth", 1.0))
    rays = 1 if kind == "laser" or aperture == 0.0 else rays
    code = {"generic": GENERIC, "infra-red": INFRA_RED, "sonar": SONAR, "laser": LASER}[kind]
    if kind == "infra-red":  # the Shapes, its robot's too except those enclosing it (§1.4)
        group, own = targets.visual, targets.robot
    else:  # boundingObjects, not its robot's unless selfCollision (§1.3)
        group, own = targets.collision, targets.robot and not targets.self_collision
    spec.add_numeric(name=RAYS_NUMERIC + sensor, data=[
        float(code), float(group), float(own), float(rows[-1][0]), float(rays), aperture,
        width if width > 0 else 1.0, abs(float(device.get("redColorSensitivity", 1.0)))])


def add_reflections(spec: mujoco.MjSpec, shapes: Mapping[str, Any]) -> None:
    """Write the infra-red reflection factor of each visual geom's Shape (``shapes``: geom name -> Shape) when the
    model has an infra-red DistanceSensor (module docstring); nothing otherwise."""
    if any(n.name.startswith(RAYS_NUMERIC) and int(n.data[0]) == INFRA_RED for n in spec.numerics):
        for geom, shape in shapes.items():
            spec.add_numeric(name=REFLECTION_NUMERIC + geom, data=[infra_red_reflection(shape)])


def disabled_axes_notes(device: Any) -> list[str]:
    """A note when ``device`` (one of :data:`AXED`) has an axis turned off (module docstring), else nothing."""
    off = [axis for axis in ("xAxis", "yAxis", "zAxis") if device.type_name in AXED and not device.get(axis, True)]
    if not off:
        return []
    return [f"{' and '.join(off)} FALSE not converted: Webots reads NaN for that component, MuJoCo reads it"]


def add_gps_reference(spec: mujoco.MjSpec, sensor: Any, world_info: Mapping[str, Any]) -> list[str]:
    """Measure the converted GPS ``sensor`` (a ``framepos``) from the world's ``gpsReference`` (module docstring);
    what the model cannot reproduce of it (a WGS84 world), as notes."""
    if str(world_info.get("gpsCoordinateSystem", "local")) == "WGS84":
        return ['WorldInfo gpsCoordinateSystem "WGS84": the converted GPS reads metres in the world frame, not '
                "latitude, longitude and altitude (MuJoCo has no geodetic sensor)"]
    reference = [float(v) for v in world_info.get("gpsReference", (0.0, 0.0, 0.0))]
    if any(reference):
        if spec.site(GPS_REFERENCE_SITE) is None:
            spec.worldbody.add_site(name=GPS_REFERENCE_SITE, pos=[-v for v in reference], group=4)
        sensor.reftype = mujoco.mjtObj.mjOBJ_SITE
        sensor.refname = GPS_REFERENCE_SITE
    return []


def add_sensor_model(spec: mujoco.MjSpec, sensor: Any, device: Any, world_info: Mapping[str, Any],
                     targets: RayTargets | None = None) -> list[str]:
    """What the MuJoCo sensor ``sensor`` (an ``MjsSensor``) of the Webots ``device`` needs besides itself: its
    ``noise`` (a GPS's ``accuracy``) as MuJoCo's sensor noise, its lookup table (:func:`add_lookup_table`), its
    resolution (:func:`add_resolution`), a DistanceSensor's rays (:func:`add_distance_rays`, hitting ``targets``),
    a GPS's reference (:func:`add_gps_reference`) and, for a Compass, the model's magnetic field set to the
    world's north. Returns what of the device the model does not reproduce, as notes."""
    noise = float(device.get("noise", 0.0) or 0.0)
    if noise > 0:
        sensor.noise = noise
    if device.type_name == "GPS" and float(device.get("accuracy", 0.0)) > 0:
        sensor.noise = float(device["accuracy"])
    add_lookup_table(spec, sensor, device)
    add_resolution(spec, sensor.name, device)
    if device.type_name == "DistanceSensor":
        if len(sensor.intprm) and int(sensor.intprm[0]) == 0:
            sensor.intprm[0] = 1  # MuJoCo >= 3.4 rangefinder data spec: distance only (the XML default)
        if targets is not None:
            add_distance_rays(spec, sensor.name, device, targets)
    if device.type_name == "Compass":
        spec.option.magnetic = north(world_info)
    notes = disabled_axes_notes(device)
    if device.type_name == "GPS":
        notes += add_gps_reference(spec, sensor, world_info)
    return notes
