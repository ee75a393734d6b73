"""The Webots coverage registry matches the code, and the docs page is its rendering (issue 16.4)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text, schema
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.coverage import CATEGORIES, REGISTRY, STATUSES, render_markdown
from dualtwin.webots.devices import device_class
from dualtwin.webots.physics import JOINT_TYPES, SOLID_TYPES, Simulation

DOC = Path(__file__).resolve().parents[2] / "docs" / "webots-coverage.md"
WORKS = ("supported", "partial")
# devices that are used without reading a value (their behaviour has its own tests)
NO_READING = {"Emitter", "Receiver", "Display", "Pen"}

GEOMETRY_SAMPLES = {
    "Box": "Box { size 0.1 0.1 0.1 }",
    "Sphere": "Sphere { radius 0.1 }",
    "Capsule": "Capsule { radius 0.1 height 0.2 }",
    "Cylinder": "Cylinder { radius 0.1 height 0.2 }",
    "Plane": "Plane { size 1 1 }",
    "IndexedFaceSet": "IndexedFaceSet { coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0, 0 0 1 ] } "
                      "coordIndex [ 0 2 1 -1 0 1 3 -1 0 3 2 -1 1 2 3 -1 ] }",
    "ElevationGrid": "ElevationGrid { xDimension 2 yDimension 2 xSpacing 1 ySpacing 1 height [ 0 0 0 0 ] }",
    "Mesh": 'Mesh { url [ "hull.obj" ] }',  # HULL_OBJ, written beside the world
    "Cone": "Cone { bottomRadius 0.1 height 0.2 }",
    "IndexedLineSet": "IndexedLineSet { coord Coordinate { point [ 0 0 0, 1 0 0 ] } coordIndex [ 0 1 -1 ] }",
    "PointSet": "PointSet { coord Coordinate { point [ 0 0 0 ] } }",
}
HULL_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
# parts of other geometries, not geometries of their own
GEOMETRY_PARTS = {"Coordinate", "Normal", "TextureCoordinate"}

JOINT_SAMPLES = {
    "HingeJoint": "HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 } endPoint {end} }",
    "SliderJoint": "SliderJoint { jointParameters JointParameters { axis 0 0 1 } endPoint {end} }",
    "Hinge2Joint": "Hinge2Joint { endPoint {end} }",
    "BallJoint": "BallJoint { endPoint {end} }",
    "SolidReference": 'HingeJoint { endPoint SolidReference { solidName "<static environment>" } }',
}
END = "Solid { translation 0.2 0 0 boundingObject Sphere { radius 0.05 } physics Physics { } }"


def _entries(category: str) -> list[str]:
    return [c.name for c in REGISTRY if c.category == category]


def _status(name: str) -> str:
    return next(c.status for c in REGISTRY if c.name == name)


def _sim(body: str, path: Path | None = None) -> Simulation:
    text = f'#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep 8 }}\nDEF GROUND Solid {{ name "ground" }}\n{body}\n'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world_text(text) if path is None else load_world_text(text, path))


def test_every_node_the_parser_knows_has_one_entry() -> None:
    names = [c.name for c in REGISTRY]
    assert len(names) == len(set(names))
    assert {c.name for c in REGISTRY if c.node} == set(schema.BASE_NODES)
    assert all(c.status in STATUSES and c.category in CATEGORIES and c.reason for c in REGISTRY)


def test_docs_page_is_the_registry_rendering() -> None:
    assert DOC.read_text(encoding="utf-8") == render_markdown(), (
        "docs/webots-coverage.md is stale: run python -m dualtwin.webots.coverage")


def test_devices_marked_working_have_a_reader_and_the_others_none() -> None:
    for name in _entries("device"):
        working = _status(name) in WORKS
        assert (device_class(name) is not None) == working, name


def test_device_readings_follow_the_registry() -> None:
    solid_devices = [n for n in _entries("device") if n in SOLID_TYPES]
    children = " ".join(f'{n} {{ name "{n}" }}' for n in solid_devices)
    sim = _sim(f"Robot {{ children [ {children} ] supervisor TRUE }}")
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    devices = {n: sup.getDevice(n) for n in solid_devices}
    for dev in devices.values():
        if dev is not None and hasattr(dev, "enable"):
            dev.enable(8)
    sup.step(16)
    for name, dev in devices.items():
        if name in NO_READING:
            continue
        if name == "InertialUnit":
            values = dev.getRollPitchYaw()
        elif name == "TouchSensor":
            values = [dev.getValue()]  # a bumper by default: getValues is for force-3d only
        elif hasattr(dev, "getRangeImage"):
            # nothing in range reads +inf: a reading is any non-NaN image
            values = [0.0 if math.isinf(v) else v for v in dev.getRangeImage()] or [math.nan]
        elif hasattr(dev, "getImage"):
            values = [float(v) for v in dev.getImage()] or [math.nan]  # an empty world: a black frame
        elif hasattr(dev, "getNumberOfTargets"):
            values = [float(dev.getNumberOfTargets())]  # an empty world: no target is a reading
        elif hasattr(dev, "getPresence"):
            values = [float(dev.getPresence())]
        elif name == "LED":
            values = [float(dev.get())]
        elif hasattr(dev, "getValues"):
            values = dev.getValues()
        else:
            values = [dev.getValue()] if hasattr(dev, "getValue") else [math.nan]
        finite = all(math.isfinite(v) for v in values)
        assert finite == (_status(name) in WORKS), name
    sim.close()


@pytest.mark.parametrize("name", sorted(GEOMETRY_SAMPLES))
def test_geometry_status_matches_collision_geoms(name: str, tmp_path: Path) -> None:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hull.obj").write_text(HULL_OBJ)
    sim = _sim(f"Solid {{ boundingObject {GEOMETRY_SAMPLES[name]} }}", tmp_path / "worlds" / "w.wbt")
    assert (len(sim.geoms) == 1) == (_status(name) in WORKS), name
    sim.close()


def test_geometry_samples_cover_the_registry() -> None:
    assert set(_entries("geometry")) == set(GEOMETRY_SAMPLES) | GEOMETRY_PARTS


@pytest.mark.parametrize("name", sorted(JOINT_SAMPLES))
def test_joint_status_matches_ode_joints(name: str) -> None:
    joint = JOINT_SAMPLES[name].replace("{end}", END)
    sim = _sim(f"Robot {{ children [ {joint} ] boundingObject Box {{ size 0.1 0.1 0.1 }} physics Physics {{ }} }}")
    built = [j for j in sim.joints if j.ptr]  # an ODE joint (a SolidReference end point has no child Solid)
    assert (len(built) == 1) == (_status(name) in WORKS), name
    sim.close()


def test_every_joint_type_is_registered() -> None:
    assert set(_entries("joint")) >= JOINT_TYPES
