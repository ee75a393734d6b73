"""Ray-based sensors on a robot that drives, aimed at targets that fall, in ENU and in NUE worlds.

Webots' order of a basic step (docs/reference/webots-on-ode.md §1.6): motor commands, ``dWorldStep``, then the
sensor rays are set from the bodies' *new* poses and collided, and the values sent to the controllers. So the
reading after step k is a function of the poses after step k: the sensor's (carried by the robot's body), the
targets' and the occluders'. Each test below drives a two-wheeled robot with Physics past static targets and
falling (Physics) ones and, at every step, derives what each device must read from the poses the supervisor
reports at that instant, with plain geometry written here (ray against box, angles, inverse square law), not
with the implementation's code. A control derives the same readings from the previous step's poses and
checks that they differ, so a device sampling stale poses, rays left behind by the robot, a falling target
that is not seen where it is, or the robot's own parts in its rays would all fail.

Every world is written in ENU; the NUE variant is the same scene turned so that y is up (gravity along -y),
and the derivations read its poses back in the ENU frame.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot, Runtime, Supervisor
from dualtwin.webots.physics import Simulation

STEP = 32  # ms, Webots' default basicTimeStep
WHEEL_SPEED = 20.0  # rad/s: the robot reaches about 0.5 m/s (wheel radius 0.025 m)

# ENU -> NUE: a quarter turn about x carries the ENU up axis (z) onto NUE's up axis (y)
_TO_NUE = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
FRAMES = {"ENU": np.eye(3), "NUE": _TO_NUE}


# ----------------------------------------------------------------------------------------------- world text


def _rot(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    x, y, z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    c, s, t = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return np.array([
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ])  # fmt: skip


def _axis_angle(R: np.ndarray) -> tuple[float, float, float, float]:
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2)))
    if angle < 1e-12:
        return (0.0, 0.0, 1.0, 0.0)
    if abs(angle - math.pi) < 1e-6:  # axis from the symmetric part
        axis = np.sqrt(np.maximum(np.diag(R) + 1, 0.0) / 2)
        i = int(np.argmax(axis))
        axis = (R[i] + R[:, i]) / (4 * axis[i])
        axis[i] = math.sqrt(max((R[i, i] + 1) / 2, 0.0))
    else:
        axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2 * math.sin(angle))
    return (*(float(v) for v in axis / np.linalg.norm(axis)), angle)


@dataclass
class Top:
    """A top-level node: its text with a ``{pose}`` slot, and its ENU pose."""

    text: str
    t: tuple[float, float, float] = (0.0, 0.0, 0.0)
    R: np.ndarray | None = None

    def render(self, frame: np.ndarray) -> str:
        R = frame @ (np.eye(3) if self.R is None else self.R)
        t = frame @ np.asarray(self.t, dtype=float)
        x, y, z, a = _axis_angle(R)
        pose = f"translation {t[0]:.9g} {t[1]:.9g} {t[2]:.9g} rotation {x:.12g} {y:.12g} {z:.12g} {a:.12g}"
        return self.text.replace("{pose}", pose)


def _wheel(side: str, y: float) -> str:
    return f"""HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 {y} 0 }}
      device [ RotationalMotor {{ name "{side} motor" maxVelocity 100 }} ]
      endPoint Solid {{ translation 0 {y} 0 rotation 1 0 0 1.5708
        children [ Shape {{ geometry Cylinder {{ radius 0.025 height 0.01 }} }} ]
        name "{side} wheel" boundingObject Cylinder {{ radius 0.025 height 0.01 }} physics Physics {{ density 500 }} }}
    }}"""


def rover(devices: str, name: str = "rover") -> Top:
    """The sensing robot: a 5 × 4 × 2 cm body on two wheels (radius 2.5 cm, axle along y) and two frictionless
    ball casters, facing +x, with Physics; ``devices`` are its children."""
    return Top(
        f"""DEF ROVER Robot {{ {{pose}}
  children [ Shape {{ geometry DEF BODY Box {{ size 0.05 0.04 0.02 }} }} {_wheel("left", 0.03)} {_wheel("right", -0.03)}
    {devices} ]
  name "{name}" supervisor TRUE contactMaterial "caster"
  boundingObject Group {{ children [ USE BODY
    Pose {{ translation 0.02 0 -0.015 children [ Sphere {{ radius 0.01 }} ] }}
    Pose {{ translation -0.02 0 -0.015 children [ Sphere {{ radius 0.01 }} ] }} ] }}
  physics Physics {{ density 500 }}
}}""",
        (0.0, 0.0, 0.025),
    )


def box(def_name: str, t: tuple[float, float, float], size: tuple[float, float, float], extra: str = "",
        physics: bool = False) -> Top:  # fmt: skip
    """A white box Solid (drawn and collided alike), with Physics when ``physics``."""
    sx, sy, sz = size
    return Top(
        f"""DEF {def_name} Solid {{ {{pose}}
  children [ Shape {{ appearance Appearance {{ material Material {{ diffuseColor 1 1 1 }} }}
    geometry DEF {def_name}_BOX Box {{ size {sx} {sy} {sz} }} }} ]
  name "{def_name.lower()}" boundingObject USE {def_name}_BOX {"physics Physics { density 500 }" if physics else ""}
  {extra}
}}""",
        t,
    )


def build(system: str, tops: list[Top]) -> Simulation:
    frame = FRAMES[system]
    floor = Top(
        'Solid { {pose} children [ Shape { geometry DEF FLOOR Plane { size 4 4 } } ] name "floor" '
        "boundingObject USE FLOOR }"
    )
    head = (
        f'#VRML_SIM R2023b utf8\nWorldInfo {{ coordinateSystem "{system}" basicTimeStep {STEP}\n'
        '  contactProperties [ ContactProperties { material2 "caster" coulombFriction [ 0 ] } ] }\n'
    )
    text = head + "\n".join(top.render(frame) for top in [floor, *tops]) + "\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world_text(text))


# ----------------------------------------------------------------------------------------------- geometry


@dataclass
class Frame:
    """A pose in the ENU frame of the scene: origin ``p``, axes as the columns of ``R``."""

    p: np.ndarray
    R: np.ndarray

    def then(self, t: tuple[float, float, float], R: np.ndarray | None = None) -> Frame:
        return Frame(self.p + self.R @ np.asarray(t, dtype=float), self.R if R is None else self.R @ R)

    def local(self, point: np.ndarray) -> np.ndarray:
        return self.R.T @ (point - self.p)


def pose_of(sup: Supervisor, def_name: str, system: str) -> Frame:
    node = sup.getFromDef(def_name)
    frame = FRAMES[system]
    R = np.array(node.getOrientation(), dtype=float).reshape(3, 3)
    return Frame(frame.T @ np.array(node.getPosition(), dtype=float), frame.T @ R)


def ray_hit(
    origin: np.ndarray, direction: np.ndarray, box_pose: Frame, size: tuple[float, ...]
) -> tuple[float, np.ndarray]:
    """Distance along the ray to the box's surface (slab method in the box frame; inf when it misses) and the
    world normal of the face it enters."""
    o, d, h = box_pose.local(origin), box_pose.R.T @ direction, np.asarray(size) / 2
    near, far, face = -math.inf, math.inf, 0
    for k in range(3):
        if abs(d[k]) < 1e-15:
            if abs(o[k]) > h[k]:
                return math.inf, np.zeros(3)
            continue
        t1, t2 = (-h[k] - o[k]) / d[k], (h[k] - o[k]) / d[k]
        if min(t1, t2) > near:
            near, face = min(t1, t2), k
        far = min(far, max(t1, t2))
    if not (near <= far and near >= 0):
        return math.inf, np.zeros(3)
    normal = np.zeros(3)
    normal[face] = -math.copysign(1.0, d[face])
    return near, box_pose.R @ normal


def ray_box(origin: np.ndarray, direction: np.ndarray, box_pose: Frame, size: tuple[float, ...]) -> float:
    return ray_hit(origin, direction, box_pose, size)[0]


def floor_hit(origin: np.ndarray, direction: np.ndarray) -> tuple[float, np.ndarray]:
    return (-origin[2] / direction[2] if direction[2] < 0 else math.inf), np.array([0.0, 0.0, 1.0])


def segment_blocked(a: np.ndarray, b: np.ndarray, box_pose: Frame, size: tuple[float, ...]) -> bool:
    d = b - a
    length = float(np.linalg.norm(d))
    return ray_box(a, d / length, box_pose, size) < length


def lut(table: list[tuple[float, float]], x: float) -> float:
    for (x0, y0), (x1, y1) in zip(table, table[1:], strict=False):
        if x0 <= x <= x1:
            return y0 + (x - x0) * (y1 - y0) / (x1 - x0)
    return table[-1][1] if x > table[-1][0] else table[0][1]


def start_driving(sup: Supervisor) -> None:
    for side in ("left", "right"):
        motor = sup.getDevice(f"{side} motor")
        motor.setPosition(math.inf)
        motor.setVelocity(WHEEL_SPEED)


Derive = Callable[[dict[str, Frame]], dict[str, Any]]


def drive_and_check(sup: Supervisor, system: str, defs: list[str], read: Callable[[], dict[str, Any]],
                    derive: Derive, steps: int, close: Callable[[Any, Any], bool]) -> tuple[list, list]:  # fmt: skip
    """Drive ``steps`` steps; after each, the readings must equal what ``derive`` makes of the poses *now*.
    Returns, per step, the readings and what the previous step's poses would give (the stale control)."""
    start_driving(sup)
    previous = {d: pose_of(sup, d, system) for d in defs}
    readings, stale = [], []
    for k in range(steps):
        sup.step(STEP)
        now = {d: pose_of(sup, d, system) for d in defs}
        got, want = read(), derive(now)
        for name, value in want.items():
            assert close(got[name], value), f"step {k + 1}, {name}: read {got[name]}, poses now give {value}"
        readings.append(got)
        stale.append(derive(previous))
        previous = now
    return readings, stale


# ----------------------------------------------------------------------------------------------- distance sensors

FRONT_LUT = [(0.0, 0.0), (1.0, 1000.0)]  # 1000 per metre
SIDE_LUT = [(0.0, 500.0), (0.1, 0.0)]  # the Webots test's table: 0.04 m reads 300, nothing reads 0
WALL_SIZE = (0.1, 1.0, 0.2)
SIDE_BOX = (0.06, 0.02, 0.04)
FALLING_BOX = (0.06, 0.02, 0.06)
QUARTER = _rot((0, 0, 1), math.pi / 2)


def _ds(name: str, t: str, rotation: str, table: list[tuple[float, float]], kind: str) -> str:
    rows = ", ".join(f"{x} {y} 0" for x, y in table)
    return (
        f'DistanceSensor {{ name "{name}" translation {t} rotation {rotation} type "{kind}" '
        f"lookupTable [ {rows} ] }}"
    )


DS_DEVICES = " ".join([
    *(_ds(f"front {k}", "0.03 0 0", "0 0 1 0", FRONT_LUT, k) for k in ("generic", "sonar", "laser", "infra-red")),
    # backwards through the robot's own body: generic rays skip the own robot, infra-red sees its Shapes
    _ds("back generic", "0.03 0 0", "0 0 1 3.14159265358979", FRONT_LUT, "generic"),
    _ds("back infra-red", "0.03 0 0", "0 0 1 3.14159265358979", FRONT_LUT, "infra-red"),
    *(_ds(f"left {k}", "0 0.05 0.001", "0 0 1 1.5707963267949", SIDE_LUT, k) for k in ("generic", "infra-red")),
    *(_ds(f"right {k}", "0 -0.05 0.001", "0 0 1 -1.5707963267949", SIDE_LUT, k) for k in ("generic", "infra-red")),
])  # fmt: skip


def _distance_world(system: str) -> Supervisor:
    sim = build(system, [
        rover(DS_DEVICES),
        box("WALL", (0.45, 0.0, 0.1), WALL_SIZE),  # its face at x = 0.40, ahead
        box("BACK_WALL", (-0.30, 0.0, 0.1), WALL_SIZE),  # its face at x = -0.25, behind
        box("SIDE_BOX", (0.12, 0.10, 0.025), SIDE_BOX),  # on the left, face at y = 0.09, x in [0.09, 0.15]
        box("FALLING_BOX", (0.05, -0.10, 0.12), FALLING_BOX, physics=True),  # on the right, falls onto the floor
    ])  # fmt: skip
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _distance_readings(poses: dict[str, Frame]) -> dict[str, float]:
    robot = poses["ROVER"]
    out = {}
    statics = [(poses["WALL"], WALL_SIZE), (poses["BACK_WALL"], WALL_SIZE), (poses["SIDE_BOX"], SIDE_BOX),
               (poses["FALLING_BOX"], FALLING_BOX)]  # fmt: skip

    def nearest(sensor: Frame, own: list[tuple[Frame, tuple[float, ...]]] = ()) -> tuple[float, np.ndarray]:  # type: ignore[assignment]
        o, d = sensor.p, sensor.R[:, 0]
        hits = [floor_hit(o, d), *(ray_hit(o, d, p, s) for p, s in [*statics, *own])]
        return min(hits, key=lambda h: h[0])

    front = robot.then((0.03, 0.0, 0.0))
    t, normal = nearest(front)
    for kind in ("generic", "laser", "infra-red"):
        out[f"front {kind}"] = lut(FRONT_LUT, min(t, 1.0))
    # a sonar echo returns only from a surface within pi/8 of facing the ray; the nearest hit decides
    facing = math.acos(max(-1.0, min(1.0, -float(front.R[:, 0] @ normal)))) < math.pi / 8
    out["front sonar"] = lut(FRONT_LUT, min(t, 1.0) if facing else 1.0)
    back = robot.then((0.03, 0.0, 0.0), _rot((0, 0, 1), math.pi))
    out["back generic"] = lut(FRONT_LUT, min(nearest(back)[0], 1.0))
    body = robot.then((0.0, 0.0, 0.0))  # the body Shape's face at x = 0.025, 5 mm behind the sensor
    out["back infra-red"] = lut(FRONT_LUT, min(nearest(back, [(body, (0.05, 0.04, 0.02))])[0], 1.0))
    for side, y, turn in (("left", 0.05, QUARTER), ("right", -0.05, QUARTER.T)):
        sensor = robot.then((0.0, y, 0.001), turn)
        value = lut(SIDE_LUT, min(nearest(sensor)[0], 0.1))
        out[f"{side} generic"] = out[f"{side} infra-red"] = value
    return out


@pytest.mark.parametrize("system", ["ENU", "NUE"])
def test_distance_sensors_follow_the_driving_robot_and_see_the_falling_box(system: str) -> None:
    sup = _distance_world(system)
    names = list(_distance_readings({d: Frame(np.zeros(3), np.eye(3)) for d in
                                     ("ROVER", "WALL", "BACK_WALL", "SIDE_BOX", "FALLING_BOX")}))  # fmt: skip
    devices = {n: sup.getDevice(n) for n in names}
    for dev in devices.values():
        dev.enable(STEP)
    defs = ["ROVER", "WALL", "BACK_WALL", "SIDE_BOX", "FALLING_BOX"]
    readings, stale = drive_and_check(
        sup,
        system,
        defs,
        lambda: {n: d.getValue() for n, d in devices.items()},
        _distance_readings,
        18,
        lambda got, want: got == pytest.approx(want, abs=0.01),  # 10 µm (the drawn floor is 1 µm thick)
    )
    # control: the robot moves enough each step for a reading from the previous poses to be wrong
    moved = [
        k for k in range(len(readings)) if abs(readings[k]["front generic"] - stale[k]["front generic"]) > 1.0
    ]
    assert len(moved) >= 12
    # the side boxes come into view and leave it as the robot passes (a ray left at the start would not)
    for side in ("left generic", "right generic", "right infra-red"):
        seen = [r[side] > 0 for r in readings]
        assert any(seen) and not all(seen), side
    # the falling box is seen where it is at the end of the step, not where it was before it
    assert any(
        abs(r["right generic"] - s["right generic"]) > 1.0 for r, s in zip(readings, stale, strict=True)
    )
    # the own body, 5 mm behind the sensors: invisible to the generic ray, seen by the infra-red one however the
    # robot pitches (it rears up by some 30 degrees as it starts)
    assert all(r["back generic"] > 50 for r in readings)
    assert all(r["back infra-red"] == pytest.approx(5.0, abs=1e-6) for r in readings)


# ----------------------------------------------------------------------------------------------- radar

TARGET = (0.02, 0.02, 0.02)
SCREEN = (0.04, 0.005, 0.1)  # a thin upright plate without radarCrossSection: it only hides
RADAR_FOV = (1.5, 0.1)  # horizontal, vertical (rad)
RADAR_RANGE = (0.01, 0.3)


def _radar(name: str, y: float, turn: str, extra: str = "") -> str:
    return (
        f'Radar {{ name "{name}" translation 0 {y} 0 rotation 0 0 1 {turn} horizontalFieldOfView {RADAR_FOV[0]} '
        f"minRange {RADAR_RANGE[0]} maxRange {RADAR_RANGE[1]} {extra} }}"
    )


RADAR_DEVICES = " ".join([
    _radar("radar left", 0.05, "1.5707963267949"),
    _radar("radar left occlusion", 0.05, "1.5707963267949", "occlusion TRUE"),
    _radar("radar right", -0.05, "-1.5707963267949"),
    _radar("radar right occlusion", -0.05, "-1.5707963267949", "occlusion TRUE"),
])  # fmt: skip
RADAR_MOUNTS = {"left": (0.05, QUARTER), "right": (-0.05, QUARTER.T)}


def _corners(pose: Frame, size: tuple[float, ...]) -> list[np.ndarray]:
    h = np.asarray(size) / 2
    return [pose.p + pose.R @ (h * np.array(s)) for s in np.ndindex(2, 2, 2) for s in [np.array(s) * 2 - 1]]


def _radar_view(radar: Frame, target: Frame) -> bool | None:
    """Whether the target box overlaps the radar's field of view (None: within 5 mrad of an edge, or partly
    behind the radar: not decided here)."""
    local = [radar.local(c) for c in _corners(target, TARGET)]
    if any(c[0] <= 0 for c in local):
        return None
    margins = []
    for axis, half in ((1, RADAR_FOV[0] / 2), (2, RADAR_FOV[1] / 2)):
        angles = [math.atan2(c[axis], c[0]) for c in local]
        margins.append(min(half - min(angles), max(angles) + half))  # > 0: the angular spans overlap
    margin = min(margins)
    return None if abs(margin) < 5e-3 else margin > 0


def _radar_expectations(poses: dict[str, Frame]) -> dict[str, Any]:
    robot = poses["ROVER"]
    out: dict[str, Any] = {}
    for side, target in (("left", "TARGET"), ("right", "FALLING_TARGET")):
        y, turn = RADAR_MOUNTS[side]
        radar = robot.then((0.0, y, 0.0), turn)
        delta = poses[target].p - radar.p
        distance = float(np.linalg.norm(delta))
        view = _radar_view(radar, poses[target])
        seen = None if view is None else (view and RADAR_RANGE[0] <= distance <= RADAR_RANGE[1])
        others = [
            (poses["SCREEN"], SCREEN),
            (poses["TARGET" if side == "right" else "FALLING_TARGET"], TARGET),
        ]
        blocked = any(segment_blocked(radar.p, poses[target].p, p, s) for p, s in others)
        local = radar.local(poses[target].p)
        detail = (distance, math.atan2(local[1], local[0]))
        out[f"radar {side}"] = None if seen is None else ((1, detail) if seen else (0, None))
        out[f"radar {side} occlusion"] = (
            None if seen is None else ((1, detail) if seen and not blocked else (0, None))
        )
    return out


UNDECIDED: list[tuple[int, Any]] = []  # readings at a field-of-view edge, not checked (kept to count them)


def _same_targets(got: tuple[int, Any], want: tuple[int, Any] | None) -> bool:
    if want is None:
        UNDECIDED.append(got)
        return True
    if got[0] != want[0]:
        return False
    return want[1] is None or np.allclose(got[1], want[1], atol=1e-9)


@pytest.mark.parametrize("system", ["ENU", "NUE"])
def test_radars_follow_the_driving_robot_see_the_falling_target_and_the_screen_hides(system: str) -> None:
    sim = build(system, [
        rover(RADAR_DEVICES),
        box("TARGET", (0.15, 0.20, 0.025), TARGET, "radarCrossSection 1"),
        box("SCREEN", (0.10, 0.12, 0.025), SCREEN),  # between the left radar's path and its target
        box("FALLING_TARGET", (0.10, -0.15, 0.10), TARGET, "radarCrossSection 1", physics=True),
    ])  # fmt: skip
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    radars = {
        n: sup.getDevice(n)
        for n in ("radar left", "radar left occlusion", "radar right", "radar right occlusion")
    }
    for radar in radars.values():
        radar.enable(STEP)
    UNDECIDED.clear()

    def read() -> dict[str, tuple[int, Any]]:
        out = {}
        for name, radar in radars.items():
            targets = radar.getTargets()
            assert radar.getNumberOfTargets() == len(targets)
            out[name] = (
                len(targets),
                (targets[0].distance, targets[0].azimuth) if len(targets) == 1 else None,
            )
        return out

    readings, stale = drive_and_check(sup, system, ["ROVER", "TARGET", "SCREEN", "FALLING_TARGET"], read,
                                      _radar_expectations, 20, _same_targets)  # fmt: skip
    assert len(UNDECIDED) <= 20  # of 80 readings (the robot pitches: the 0.1 rad beam swings over targets)
    for name in radars:  # each radar sees its target during part of the drive only
        counts = [r[name][0] for r in readings]
        assert 0 in counts and 1 in counts, name
    # the screen hides the target from the occlusion radar while the plain radar still sees it
    assert any(r["radar left"][0] == 1 and r["radar left occlusion"][0] == 0 for r in readings)
    # control: distances read from the previous poses would be off by millimetres
    off = [
        abs(r["radar left"][1][0] - s["radar left"][1][0])
        for r, s in zip(readings, stale, strict=True)
        if r["radar left"][0] == 1 and s["radar left"] and s["radar left"][0] == 1
    ]
    assert off and min(off) > 1e-5  # a thousand times the tolerance of the check above


# ----------------------------------------------------------------------------------------------- light sensors

LAMP_BOX = (0.03, 0.03, 0.03)
SPOT = {"beam": 0.2, "cut": 0.8}


def _light(name: str, y: float, turn: str, extra: str = "") -> str:
    return (
        f'LightSensor {{ name "{name}" translation 0 {y} 0.001 rotation 0 0 1 {turn} '
        f"lookupTable [ 0 0 0, 1000 1000 0 ] {extra} }}"
    )


LIGHT_DEVICES = " ".join([
    _light("light left", 0.05, "1.5707963267949"),
    _light("light left occlusion", 0.05, "1.5707963267949", "occlusion TRUE"),
    _light("light right", -0.05, "-1.5707963267949"),
    _light("light right occlusion", -0.05, "-1.5707963267949", "occlusion TRUE"),
])  # fmt: skip


def _irradiance(sensor: Frame, poses: dict[str, Frame], occlusion: bool) -> float:
    """Sum over the two lights of spot · max(0, cos θ) / d² (attenuation 0 0 1, intensity 1, white)."""
    total = 0.0
    lights = [
        ("LAMP", None),
        ("FALLING_LAMP", np.array([0.0, 1.0, 0.0])),
    ]  # the spot shines along its Solid's +y
    for name, spot_axis in lights:
        delta = poses[name].p - sensor.p
        d = float(np.linalg.norm(delta))
        cos = float(sensor.R[:, 0] @ delta) / d
        if cos <= 0:
            continue
        factor = 1.0
        if spot_axis is not None:
            alpha = math.acos(max(-1.0, min(1.0, float(poses[name].R @ spot_axis @ (-delta / d)))))
            factor = 0.0 if alpha > SPOT["cut"] else 1.0 if alpha <= SPOT["beam"] else (SPOT["cut"] - alpha) / (
                SPOT["cut"] - SPOT["beam"])  # fmt: skip
        # obstacles: the screen and the falling lamp's box, unless that box carries this light
        obstacles = [(poses["SCREEN"], SCREEN)] + (
            [(poses["FALLING_LAMP"], LAMP_BOX)] if name == "LAMP" else []
        )
        below = poses[name].p[2] < 0  # the lamp sinks into the floor as it lands: the floor's plane hides it
        if occlusion and (below or any(segment_blocked(sensor.p, poses[name].p, p, s) for p, s in obstacles)):
            continue
        total += factor * cos / (d * d)
    return total


def _light_expectations(poses: dict[str, Frame]) -> dict[str, float]:
    robot = poses["ROVER"]
    out = {}
    for side, y, turn in (("left", 0.05, QUARTER), ("right", -0.05, QUARTER.T)):
        sensor = robot.then((0.0, y, 0.001), turn)
        out[f"light {side}"] = _irradiance(sensor, poses, False)
        out[f"light {side} occlusion"] = _irradiance(sensor, poses, True)
    return out


@pytest.mark.parametrize("system", ["ENU", "NUE"])
def test_light_sensors_follow_the_driving_robot_and_the_falling_spot_light(system: str) -> None:
    sim = build(system, [
        rover(LIGHT_DEVICES),
        Top('DEF LAMP Solid { {pose} children [ PointLight { attenuation 0 0 1 } ] name "lamp" }', (0.10, 0.20, 0.025)),
        box("SCREEN", (0.06, 0.12, 0.025), SCREEN),
        Top(f'DEF FALLING_LAMP Solid {{ {{pose}} children [ SpotLight {{ direction 0 1 0 attenuation 0 0 1 '
            f'beamWidth {SPOT["beam"]} cutOffAngle {SPOT["cut"]} }} ] name "falling lamp" '
            f"boundingObject Box {{ size {' '.join(map(str, LAMP_BOX))} }} physics Physics {{ density 500 }} }}",
            (0.06, -0.15, 0.12)),
    ])  # fmt: skip
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    sensors = {n: sup.getDevice(n) for n in _light_expectations({d: Frame(np.zeros(3) + 1, np.eye(3)) for d in
                                                                 ("ROVER", "LAMP", "SCREEN", "FALLING_LAMP")})}  # fmt: skip
    for sensor in sensors.values():
        sensor.enable(STEP)
    readings, stale = drive_and_check(
        sup, system, ["ROVER", "LAMP", "SCREEN", "FALLING_LAMP"], lambda: {n: s.getValue() for n, s in sensors.items()},
        _light_expectations, 20, lambda got, want: got == pytest.approx(want, rel=1e-9, abs=1e-9),
    )  # fmt: skip
    # the screen hides the lamp for part of the drive only
    hidden = [r["light left"] > 0 and r["light left occlusion"] == 0 for r in readings]
    assert any(hidden) and not all(hidden)
    # the falling lamp lights the right sensors; its own box, which the ray to the light always enters, does not
    # hide it
    assert sum(r["light right occlusion"] > 0 for r in readings) >= 5
    # control: the previous poses would give other values
    assert sum(abs(r["light right"] - s["light right"]) > 1e-3 * r["light right"] for r, s in
               zip(readings, stale, strict=True) if r["light right"] > 0) >= 5  # fmt: skip


# ----------------------------------------------------------------------------------------------- emitter / receiver

LINK_RANGE = 0.2
APERTURE = 1.0  # rad, infra-red emitters and receivers alike
EMITTER_BOX = (0.03, 0.03, 0.03)


def _receivers() -> str:
    out = []
    for side, y, turn, channel in (
        ("left", 0.02, "1.5707963267949", 1),
        ("right", -0.02, "-1.5707963267949", 2),
    ):
        pose = f"translation 0 {y} 0 rotation 0 0 1 {turn} channel {channel}"
        out.append(f'Receiver {{ name "radio {side}" {pose} }}')
        out.append(f'Receiver {{ name "infra-red {side}" type "infra-red" aperture {APERTURE} {pose} }}')
    return " ".join(out)


def _emitter_robot(
    def_name: str, channel: int, t: tuple[float, float, float], facing: float, physics: bool
) -> Top:
    """A robot holding a radio and an infra-red emitter at its origin, its x axis turned by ``facing`` about z."""
    body = (
        f"boundingObject Box {{ size {' '.join(map(str, EMITTER_BOX))} }} physics Physics {{ density 500 }}"
    )
    return Top(
        f'''DEF {def_name} Robot {{ {{pose}} name "{def_name.lower()}" children [
  Emitter {{ name "radio" range {LINK_RANGE} channel {channel} }}
  Emitter {{ name "infra-red" type "infra-red" range {LINK_RANGE} aperture {APERTURE} channel {channel} }} ]
  {body if physics else ""} }}''',
        t,
        _rot((0, 0, 1), facing),
    )


def _within(axis: np.ndarray, toward: np.ndarray) -> float:
    """Aperture margin (rad): positive inside the cone of half-angle APERTURE/2 about ``axis``."""
    return APERTURE / 2 - math.acos(max(-1.0, min(1.0, float(axis @ toward) / float(np.linalg.norm(toward)))))


def _link_expectations(poses: dict[str, Frame]) -> dict[str, Any]:
    robot = poses["ROVER"]
    out: dict[str, Any] = {}
    for side, y, turn, source, other in (("left", 0.02, QUARTER, "BEACON", "FALLER"),
                                         ("right", -0.02, QUARTER.T, "FALLER", "BEACON")):  # fmt: skip
        rx, tx = robot.then((0.0, y, 0.0), turn), poses[source]
        delta = tx.p - rx.p
        d = float(np.linalg.norm(delta))
        direction = tuple(rx.R.T @ delta / d)
        margin = LINK_RANGE - d
        out[f"radio {side}"] = None if abs(margin) < 1e-6 else ((1, direction) if margin > 0 else (0, None))
        # infra-red: range, both cones, and a clear line (the two robots themselves do not block it)
        margin = min(margin, _within(tx.R[:, 0], -delta), _within(rx.R[:, 0], delta))
        obstacles = [(poses["SCREEN"], SCREEN)] + (
            [(poses["FALLER"], EMITTER_BOX)] if other == "FALLER" else []
        )
        clear = not any(segment_blocked(tx.p, rx.p, p, s) for p, s in obstacles) and min(tx.p[2], rx.p[2]) > 0
        out[f"infra-red {side}"] = None if abs(margin) < 1e-6 else (
            (1, direction) if margin > 0 and clear else (0, None))  # fmt: skip
    return out


@pytest.mark.parametrize("system", ["ENU", "NUE"])
def test_receivers_on_the_driving_robot_hear_by_range_aperture_and_line_of_sight(system: str) -> None:
    sim = build(system, [
        rover(_receivers()),
        _emitter_robot("BEACON", 1, (0.10, 0.20, 0.025), -math.pi / 2, physics=False),  # facing the path
        box("SCREEN", (0.05, 0.12, 0.025), SCREEN),
        _emitter_robot("FALLER", 2, (0.03, -0.15, 0.10), math.pi / 2, physics=True),  # falls, facing the path
    ])  # fmt: skip
    runtime = Runtime(sim)
    emitters = []
    for node in sim.robots[1:]:
        robot = Robot(runtime=runtime, robot_node=node.node)
        robot.cleanup()  # its emitters work; only the rover's controller waits for steps
        emitters += [robot.getDevice("radio"), robot.getDevice("infra-red")]
    sup = Supervisor(runtime=runtime, robot_node=sim.robots[0].node)
    receivers = {
        n: sup.getDevice(n) for n in ("radio left", "infra-red left", "radio right", "infra-red right")
    }
    for rx in receivers.values():
        rx.enable(STEP)

    def read() -> dict[str, tuple[int, Any]]:
        out = {}
        for name, rx in receivers.items():
            n = rx.getQueueLength()
            out[name] = (n, tuple(rx.getEmitterDirection()) if n else None)
            while rx.getQueueLength():
                rx.nextPacket()
        for tx in emitters:  # one packet each before the next step
            tx.send(b"ping")
        return out

    for tx in emitters:
        tx.send(b"ping")
    readings, stale = drive_and_check(sup, system, ["ROVER", "BEACON", "SCREEN", "FALLER"], read,
                                      _link_expectations, 26, _same_targets)  # fmt: skip
    for name in receivers:  # every link is heard during part of the drive only
        heard = [r[name][0] for r in readings]
        assert 0 in heard and 1 in heard, name
    # the screen cuts the infra-red link while the radio one, through it, still arrives
    assert any(r["radio left"][0] == 1 and r["infra-red left"][0] == 0 for r in readings)
    # control: the direction from the previous poses differs
    assert sum(r["radio left"][0] == 1 and s["radio left"] is not None and s["radio left"][0] == 1 and
               not np.allclose(r["radio left"][1], s["radio left"][1], atol=1e-3)
               for r, s in zip(readings, stale, strict=True)) >= 5  # fmt: skip


def test_occlusion_rays_of_a_driving_robot_reuse_one_grouping_of_the_scene() -> None:
    # light, radar and infra-red occlusion rays ask the ray caster for the geoms they may hit at every sample; the
    # caster groups each list once, so a list built afresh each time would be regrouped and kept per sample
    devices = " ".join([_light("light", 0.05, "1.5707963267949", "occlusion TRUE"),
                        _radar("radar", 0.05, "1.5707963267949", "occlusion TRUE"),
                        'Receiver { name "infra-red" type "infra-red" channel 1 translation 0 0.05 0 }'])  # fmt: skip
    sim = build("ENU", [
        rover(devices),
        Top('Solid { {pose} children [ PointLight { attenuation 0 0 1 } ] name "lamp" }', (0.10, 0.20, 0.025)),
        box("TARGET", (0.15, 0.20, 0.025), TARGET, "radarCrossSection 1"),
        _emitter_robot("BEACON", 1, (0.10, 0.20, 0.025), -math.pi / 2, physics=False),
    ])  # fmt: skip
    runtime = Runtime(sim)
    beacon = Robot(runtime=runtime, robot_node=sim.robots[1].node)
    beacon.cleanup()
    sup = Supervisor(runtime=runtime, robot_node=sim.robots[0].node)
    for name in ("light", "radar", "infra-red"):
        sup.getDevice(name).enable(STEP)
    start_driving(sup)
    seen = set()
    for _ in range(40):
        beacon.getDevice("infra-red").send(b"ping")
        sup.step(STEP)
        seen |= {"radar"} if sup.getDevice("radar").getNumberOfTargets() else set()
        seen |= {"light"} if sup.getDevice("light").getValue() > 0 else set()
        seen |= {"infra-red"} if sup.getDevice("infra-red").getQueueLength() else set()
    assert seen == {"radar", "light", "infra-red"}  # every kind of occlusion ray was cast
    groupings = sim.extensions["rays"]._groups  # the caster's per-list work
    assert 1 <= len(groupings) <= 3
