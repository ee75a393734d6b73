"""Faithfulness of a converted model: run it and a reference twin through one suite, before any alignment.

The reference is the Webots twin (``make_twin("webots", ...)``) running the original world, or, for a robot that
also has a hand-written MJCF, that MJCF in MuJoCo. Both runs use :class:`dualtwin.suite.runner.SuiteRun` and
are compared with :func:`dualtwin.divergence.compare_runs` (optionally an HTML report by ``write_report``).
The headline number is the difference of the passive joints' crossing times (``*_angle_rad`` at 0.99 rad).

Bundled suites for the Webots fixture worlds (:data:`FIXTURE_SUITES`): the skid-steer ``four_wheels`` robot
drives forward, turns and holds; the ``inverted_pendulum`` falls freely and gets a horizontal force push.
"""

from __future__ import annotations

import copy
import importlib
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from dualtwin.artifacts import write_text
from dualtwin.convert.conversion import Conversion
from dualtwin.convert.webots_to_mjcf import convert_loaded
from dualtwin.convert.world_robots import select_robot
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding, load_binding
from dualtwin.webots import schema
from dualtwin.webots.nodes import Node
from dualtwin.webots.protos import load_world
from dualtwin.webots.writer import write_world

#: Suites for the fixture worlds, keyed by world stem; keys refer to the converter's generated binding.
FIXTURE_SUITES: dict[str, dict[str, Any]] = {
    "four_wheels": {
        "suite_name": "four_wheels_skid_faithfulness",
        "global_settings": {"TIME_STEP": 16},
        "scenarios": [
            {"name": "Drive_Forward", "duration_s": 3.0, "wheel_velocity": 5.0},
            {"name": "Turn_In_Place", "duration_s": 2.0, "rear_right_wheel_velocity": -4.0,
             "front_right_wheel_velocity": -4.0, "rear_left_wheel_velocity": 4.0, "front_left_wheel_velocity": 4.0},
            {"name": "Ramp_Then_Hold", "duration_s": 3.0,
             "wheel_velocity": {"kind": "table", "interpolation": "linear",
                              "points": [[0.0, 0.0], [1.0, 8.0], [2.0, 8.0], [2.01, 0.0]]}},
        ],
    },
    "inverted_pendulum": {
        "suite_name": "inverted_pendulum_faithfulness",
        "global_settings": {"TIME_STEP": 32},
        "scenarios": [
            {"name": "Free_Fall", "duration_s": 3.0, "hip_position": 0.05},
            {"name": "Force_Push", "duration_s": 3.0, "hip_position": 0.01,
             "horizontal_motor_force": {"kind": "impulse", "at_s": 0.2, "duration_s": 0.3, "value": 20.0,
                                        "base": 0.0}},
        ],
    },
}

#: Robot chosen in each fixture world.
FIXTURE_ROBOTS: dict[str, str | None] = {"four_wheels": "FOUR_WHEELS", "inverted_pendulum": None}


def webots_twin_available() -> bool:
    """True once ``dualtwin.twins.webots`` (the ODE-backed Webots twin) can be imported."""
    try:
        importlib.import_module("dualtwin.twins.webots")
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class CrossingDiff:
    """Crossing times (s) of one channel in one scenario; ``diff_s`` = B - A."""

    scenario: str
    channel: str
    a_s: float | None
    b_s: float | None
    diff_s: float | None


@dataclass
class FaithfulnessReport:
    """Two runs of one suite compared (A = reference, B = converted model)."""

    robot: str
    label_a: str
    label_b: str
    out_dir: Path
    comparison: Any  # dualtwin.divergence.RunComparison
    report_html: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def crossings(self) -> list[CrossingDiff]:
        out = []
        for sc in self.comparison.scenarios:
            for name, ch in sc.channels.items():
                if ch.threshold is not None and (ch.crossing_a_s is not None or ch.crossing_b_s is not None):
                    out.append(CrossingDiff(sc.id, name, ch.crossing_a_s, ch.crossing_b_s, ch.crossing_diff_s))
        return out

    def max_crossing_diff(self) -> float | None:
        """Largest |crossing time difference| over scenarios where both runs cross (None if none does)."""
        diffs = [abs(c.diff_s) for c in self.crossings if c.diff_s is not None]
        return max(diffs) if diffs else None

    def one_sided_crossings(self) -> list[CrossingDiff]:
        return [c for c in self.crossings if (c.a_s is None) != (c.b_s is None)]

    def to_dict(self) -> dict[str, Any]:
        return {
            "robot": self.robot, "label_a": self.label_a, "label_b": self.label_b,
            "summary_score": self.comparison.summary_score,
            "max_crossing_diff_s": self.max_crossing_diff(),
            "crossings": [c.__dict__ for c in self.crossings],
            "report_html": str(self.report_html) if self.report_html else None,
            "notes": self.notes,
        }


def run_pair(binding_a: RobotBinding, twin_a: str, binding_b: RobotBinding, twin_b: str, suite: Path,
             out_dir: Path, *, labels: tuple[str, str] = ("A", "B"), report: bool = True) -> FaithfulnessReport:
    """Run ``suite`` on twin A (binding A) and twin B (binding B), then compare and optionally write a report."""
    from dualtwin.divergence import compare_runs
    from dualtwin.suite.runner import SuiteRun

    out_dir = Path(out_dir)
    run_a, run_b = out_dir / f"run_{labels[0].lower()}", out_dir / f"run_{labels[1].lower()}"
    SuiteRun(Path(suite), twin_a, binding_a, run_a).run()
    SuiteRun(Path(suite), twin_b, binding_b, run_b).run()
    comparison = compare_runs(run_a, run_b)
    html = None
    if report:
        from dualtwin.divergence import write_report

        html = write_report(comparison, out_dir / "report", labels[0], labels[1])
    result = FaithfulnessReport(binding_a.name, labels[0], labels[1], out_dir, comparison, html)
    write_text(out_dir / "faithfulness.json", json.dumps(result.to_dict(), indent=2) + "\n")
    return result


def write_converted(conv: Conversion, out_dir: Path, *, base_binding: Path | None = None,
                    webots_world: Path | None = None) -> RobotBinding:
    """Write the converted MJCF and a binding into ``out_dir``.

    With ``base_binding`` (a hand-written binding of the same robot) its channels and actions are kept and
    only the model paths change, so runs of the converted model compare 1:1 with runs of the original.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    xml_path = out_dir / f"{conv.model_name}.xml"
    binding_path = out_dir / "binding.yaml"
    world = Path(webots_world or conv.world_path).resolve()
    if base_binding is None:
        conv.write(xml_path, binding_path)
        return load_binding(binding_path)
    data = yaml.safe_load(Path(base_binding).read_text(encoding="utf-8"))
    data = copy.deepcopy(data)
    data.setdefault("twins", {})
    data["twins"]["mujoco"] = {**data["twins"].get("mujoco", {}), "model": xml_path.name}
    webots = dict(data["twins"].get("webots", {}))
    webots["model"] = os.path.relpath(world, out_dir.resolve())
    webots.setdefault("robot", conv.robot)
    data["twins"]["webots"] = webots
    write_text(xml_path, conv.xml)
    write_text(binding_path, yaml.safe_dump(data, sort_keys=False, width=110))
    return load_binding(binding_path)


def _identifier(text: str, used: set[str]) -> str:
    base = re.sub(r"[^A-Za-z0-9_]+", "_", text).strip("_") or "node"
    if not re.match(r"[A-Za-z_]", base):
        base = f"N_{base}"
    name, i = base, 1
    while name in used:
        name, i = f"{base}_{i}", i + 1
    used.add(name)
    return name


def prepare_world_for_twins(world_path: Path, out_path: Path, robot: str | None = None) -> Path:
    """A copy of the world that both twins can address by the same names.

    The Webots twin finds the robot, joints and bodies by DEF (devices by name); worlds like the Webots
    samples leave DEFs out and have motors without PositionSensors. The copy adds a DEF to the robot, to every
    joint (the converter's name: ``<motor>_joint``...) and endPoint Solid (its ``name``), a jointParameters
    node where missing, and a PositionSensor ``<motor> sensor`` to every motorised joint without one (the
    binding needs on-board sensors).
    """
    world = load_world(world_path)
    node, _ = select_robot(world, robot, str(world_path))
    used = {n.def_name for top in world.nodes for n in top.walk() if n.def_name}
    if not node.def_name:
        node.def_name = _identifier(str(node.get("name") or "robot"), used)
    params_type = {"HingeJoint": "HingeJointParameters", "SliderJoint": "JointParameters",
                   "Hinge2Joint": "HingeJointParameters", "BallJoint": "BallJointParameters"}
    for joint in list(node.walk()):
        if joint.type_name not in schema.JOINT_TYPES:
            continue
        devices = [d for d in joint.get("device", []) if d is not None]
        motors = [d for d in devices if d.type_name in ("RotationalMotor", "LinearMotor")]
        sensors = [d for d in devices if d.type_name == "PositionSensor"]
        if motors and not sensors:
            fields = schema.default_fields("PositionSensor")
            fields["name"] = f"{motors[0].get('name')} sensor"
            joint.fields["device"] = [*devices, Node("PositionSensor", fields)]
        if joint.get("jointParameters") is None:
            fields = schema.default_fields(params_type[joint.type_name])
            fields["position"] = float(joint.get("position", 0.0))
            joint.fields["jointParameters"] = Node(params_type[joint.type_name], fields)
        if not joint.def_name:
            label = motors[0].get("name") if motors else (sensors[0].get("name") if sensors else "joint")
            joint.def_name = _identifier(f"{label}_joint", used)
        end = joint.get("endPoint")
        if end is not None and schema.is_solid_type(end.type_name) and not end.def_name:
            end.def_name = _identifier(str(end.get("name") or "solid"), used)
    out_path = Path(out_path)
    write_text(out_path, write_world(world))
    return out_path


add_position_sensors = prepare_world_for_twins


def fixture_suite(stem: str, out_path: Path) -> Path:
    """Write the bundled suite for a fixture world (``four_wheels`` or ``inverted_pendulum``)."""
    if stem not in FIXTURE_SUITES:
        raise DualtwinError(f"no bundled faithfulness suite for {stem!r} (have: {', '.join(FIXTURE_SUITES)})")
    write_text(Path(out_path), json.dumps(FIXTURE_SUITES[stem], indent=1) + "\n")
    return Path(out_path)


def prepare_fixture(world_path: Path, out_dir: Path, robot: str | None = None,
                    proto_paths: Sequence[str | os.PathLike[str]] = ()) -> tuple[RobotBinding, Path]:
    """Convert a fixture world (adding position sensors) and write its binding and suite into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = Path(world_path).stem
    if robot is None:
        robot = FIXTURE_ROBOTS.get(stem)
    # The copy lives beside the original so relative PROTO paths and controllers still resolve.
    world_copy = out_dir / f"{stem}_sensors.wbt"
    prepare_world_for_twins(Path(world_path), world_copy, robot)
    conv = convert_loaded(load_world(world_copy, proto_paths), robot, world_path=str(world_copy))
    binding = write_converted(conv, out_dir)
    suite = fixture_suite(stem, out_dir / "suite.json")
    return binding, suite


def converted_vs_webots(world_path: Path, out_dir: Path, *, suite: Path | None = None, robot: str | None = None,
                        base_binding: Path | None = None, report: bool = True) -> FaithfulnessReport:
    """Converted MuJoCo model vs the Webots twin on the original world (A = Webots, B = converted MuJoCo).

    Raises:
        DualtwinError: the Webots twin is not available yet (``dualtwin.twins.webots`` missing).
    """
    if not webots_twin_available():
        raise DualtwinError("the Webots twin (dualtwin.twins.webots) is not available yet")
    out_dir = Path(out_dir)
    if suite is None and base_binding is None:
        binding, suite = prepare_fixture(Path(world_path), out_dir / "model", robot)
    else:
        conv = convert_loaded(load_world(world_path), robot, world_path=str(world_path))
        binding = write_converted(conv, out_dir / "model", base_binding=base_binding)
    if suite is None:
        raise DualtwinError("a suite is needed when a base binding is given")
    return run_pair(binding, "webots", binding, "mujoco", suite, out_dir, labels=("Webots", "MuJoCo"), report=report)


def converted_vs_mjcf(world_path: Path, reference_binding: Path, suite: Path, out_dir: Path, *,
                      robot: str | None = None, report: bool = True) -> FaithfulnessReport:
    """Converted model vs a hand-written MJCF of the same robot, both in MuJoCo (A = hand-written)."""
    out_dir = Path(out_dir)
    conv = convert_loaded(load_world(world_path), robot, world_path=str(world_path))
    converted = write_converted(conv, out_dir / "model", base_binding=reference_binding)
    reference = load_binding(Path(reference_binding))
    return run_pair(reference, "mujoco", converted, "mujoco", suite, out_dir, labels=("Handwritten", "Converted"),
                    report=report)
