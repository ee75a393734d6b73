"""Robot bindings: the declarative map from a suite's words onto each twin.

A binding file (YAML) names the robot's models for every twin and maps:

* initial-condition keys (``initial_angle``) to joint positions/velocities or body positions;
* action keys (``wheel_velocity``) to actuators, with a control mode and a scale;
* logged channels to on-board sensors (the TestRobot log) or privileged ground truth (the TestOrchestrator log);
* failure keys (``failure_pole_angle_rad``) to thresholds on ground-truth channels;
* optionally, cameras (pose, vertical field of view, resolution) for perception and rendering.

Entity names are shared by both twins (the converter preserves Webots names). A twin section may alias a
name when a user's models disagree (``aliases: {pole_hinge: POLE_JOINT}``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from dualtwin.artifacts import resolved
from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel

ControlMode = Literal["velocity", "position", "torque"]
Quantity = Literal["position", "velocity"]


class TwinModel(FrozenModel):
    """Where one twin's model lives, relative to the binding file."""

    model: str = Field(min_length=1, description="MJCF file (mujoco) or .wbt world (webots)")
    robot: str | None = Field(default=None, description="webots: DEF name of the robot node")
    aliases: dict[str, str] = Field(default_factory=dict)

    @field_validator("model")
    @classmethod
    def _a_path(cls, value: str) -> str:
        # The OS functions resolving it raise ValueError ("embedded null byte") on a NUL, past the validation.
        if "\x00" in value:
            raise ValueError("a file path cannot contain a NUL character")
        return value


class InitialCondition(FrozenModel):
    joint: str | None = None
    body: str | None = None
    quantity: Quantity = "position"
    axis: Literal["x", "y", "z"] | None = None
    unit: str = ""

    @model_validator(mode="after")
    def _one_target(self) -> InitialCondition:
        if (self.joint is None) == (self.body is None):
            raise ValueError("give exactly one of 'joint' or 'body'")
        if self.body is not None and self.axis is None:
            raise ValueError("a body initial condition needs an 'axis'")
        return self


class Action(FrozenModel):
    actuators: list[str] = Field(min_length=1)
    mode: ControlMode = "velocity"
    scale: float = 1.0
    unit: str = ""


class Channel(FrozenModel):
    """One logged column. Exactly one source: sensors, a joint or a body."""

    sensors: list[str] = Field(default_factory=list)
    joint: str | None = None
    body: str | None = None
    quantity: Quantity = "position"
    axis: Literal["x", "y", "z", "roll", "pitch", "yaw"] | None = Field(
        default=None, description="body channels: a world coordinate of the body frame's origin (x, y, z), or "
        "an angle of its orientation as Z-Y-X Euler angles (R = Rz(yaw) Ry(pitch) Rx(roll)); velocity channels "
        "take x, y or z")
    scale: float = 1.0
    unit: str = ""
    resolution: float | None = Field(
        default=None, gt=0, description="smallest meaningful difference, in the channel's unit; differences at "
        "or below it never rank and raise no sign or scale finding (default by unit: 1 mm for m, 1 mrad for rad, "
        "see dualtwin.divergence.metrics.DEFAULT_RESOLUTION_BY_UNIT)")

    @model_validator(mode="after")
    def _one_source(self) -> Channel:
        sources = [bool(self.sensors), self.joint is not None, self.body is not None]
        if sum(sources) != 1:
            raise ValueError("give exactly one of 'sensors', 'joint' or 'body'")
        if self.body is not None and self.axis is None:
            raise ValueError("a body channel needs an 'axis' (x, y, z, roll, pitch or yaw)")
        if self.axis in ("roll", "pitch", "yaw") and self.quantity != "position":
            raise ValueError(f"axis {self.axis!r} is an orientation angle: it has no 'velocity' quantity")
        return self


class Camera(FrozenModel):
    """A pinhole camera for perception and rendering; ``pos``/``lookat`` are in ``body``'s frame when set."""

    pos: tuple[float, float, float]
    lookat: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fovy_deg: float = Field(default=45.0, ge=1, le=170, description="vertical field of view, degrees")
    width: int = Field(default=64, ge=1)
    height: int = Field(default=64, ge=1)
    body: str | None = None


class Failure(FrozenModel):
    """A failure key in ``global_settings`` becomes a threshold on |channel| in the ground-truth log."""

    channel: str


class Binding(FrozenModel):
    name: str
    description: str = ""
    control_period_ms: float = Field(default=32.0, gt=0)
    twins: dict[str, TwinModel]
    initial_conditions: dict[str, InitialCondition] = Field(default_factory=dict)
    actions: dict[str, Action] = Field(default_factory=dict)
    onboard: dict[str, Channel] = Field(min_length=1, description="TestRobot log: on-board sensors only")
    ground_truth: dict[str, Channel] = Field(min_length=1, description="TestOrchestrator log: privileged")
    failures: dict[str, Failure] = Field(default_factory=dict)
    cameras: dict[str, Camera] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _consistent(self) -> Binding:
        clash = set(self.initial_conditions) & set(self.actions)
        if clash:
            raise ValueError(f"keys are both initial conditions and actions: {sorted(clash)}")
        for key, channel in self.onboard.items():
            if not channel.sensors:
                raise ValueError(f"on-board channel {key!r} must read sensors; ground truth belongs in 'ground_truth'")
        for key, failure in self.failures.items():
            if failure.channel not in self.ground_truth:
                raise ValueError(f"failure {key!r} refers to unknown ground-truth channel {failure.channel!r}")
        return self


class RobotBinding:
    """A validated binding together with the folder its relative model paths are resolved from."""

    def __init__(self, binding: Binding, path: Path) -> None:
        self.spec = binding
        self.path = path
        self.root = path.parent

    @property
    def name(self) -> str:
        return self.spec.name

    def model_path(self, twin: str) -> Path:
        if twin not in self.spec.twins:
            raise DualtwinError(f"{self.path}: robot {self.name!r} has no model for twin {twin!r} "
                                f"(it has: {', '.join(sorted(self.spec.twins))})")
        path = resolved(self.root / self.spec.twins[twin].model)
        if not path.is_file():
            raise DualtwinError(f"{self.path}: model file for twin {twin!r} not found: {path}")
        return path

    def twin_name(self, twin: str, name: str) -> str:
        """The entity's name inside one twin (identity unless aliased)."""
        section = self.spec.twins.get(twin)
        return section.aliases.get(name, name) if section else name

    def files(self, twin: str) -> list[Path]:
        return [self.path, self.model_path(twin)]


def load_binding(path: Path) -> RobotBinding:
    from dualtwin.artifacts import read_yaml

    path = Path(path)
    data = read_yaml(path, "binding file")
    try:
        binding = Binding.model_validate(data)
    except ValidationError as exc:
        from dualtwin.models import validation_message

        raise DualtwinError(validation_message(path, exc)) from None
    return RobotBinding(binding, path)


BUNDLED = Path(__file__).parent


def bundled_robots() -> list[str]:
    return sorted(p.parent.name for p in BUNDLED.glob("*/binding.yaml"))


def resolve_robot(name_or_path: str) -> RobotBinding:
    """``cartpole`` names a bundled robot; anything else is a path to a user's binding file.

    As for suites (:func:`dualtwin.suite.loader.resolve_suite`), a bare word (no folder separator, no suffix) is
    always a bundled name, even when a file of that name exists in the working folder; write ``./mybot`` to mean
    such a file. A bare word that names no bundled robot is an error listing the bundled names.
    """
    text = str(name_or_path)
    if not ("/" in text or "\\" in text or Path(text).suffix or text in ("", ".", "..")):
        candidate = BUNDLED / text / "binding.yaml"
        if candidate.is_file():
            return load_binding(candidate)
        raise DualtwinError(f"unknown robot {text!r}: not a bundled robot ({', '.join(bundled_robots())}); "
                            f"to use a binding file of that name, write ./{text}")
    path = Path(text)
    if path.is_file():
        return load_binding(path)
    raise DualtwinError(f"unknown robot {text!r}: not a bundled robot ({', '.join(bundled_robots())}) "
                        "and not a binding file")
