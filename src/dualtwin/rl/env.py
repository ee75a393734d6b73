"""A Gymnasium env over any twin, with the task kept apart from the twin (dm_control's Physics/Task split).

The twin is physics only. A :class:`Task` reads the robot through its binding's channel names (on-board sensors
and the supervisor's ground truth, :class:`dualtwin.twins.io.RobotIO`) and turns that into observations,
rewards and terminations; :class:`TwinEnv` only orchestrates reset, action and step. So one task runs
unchanged on every twin, and the env's I/O contract (:meth:`TwinEnv.io_contract`) is the same on all of them.

Time limits come from the Gymnasium registry (``TimeLimit``), as for every Gymnasium env:
``gym.make(id, max_episode_steps=2000)`` changes the default of 1000 control periods.
"""

from __future__ import annotations

import math
import numbers
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.rl.actions import batch_box_actions, batch_discrete_actions, box_action, discrete_action
from dualtwin.rl.randomize import check_knob_names
from dualtwin.robots.binding import RobotBinding, resolve_robot
from dualtwin.twins import make_twin
from dualtwin.twins.base import Twin
from dualtwin.twins.io import RobotIO

Source = Literal["onboard", "privileged"]


@dataclass(frozen=True)
class ObservationTerm:
    """One entry of the observation vector, and where the robot gets it from."""

    name: str
    unit: str
    source: Source
    channel: str
    description: str = ""


class Task(ABC):
    """Observation, reward, termination and action semantics, written once against the twin contract."""

    observation_terms: tuple[ObservationTerm, ...]
    _io: RobotIO | None = None

    @property
    def io(self) -> RobotIO:
        """The robot this task was bound to."""
        if self._io is None:
            raise RuntimeError("task is not bound to a robot")
        return self._io

    @abstractmethod
    def bind(self, io: RobotIO) -> None:
        """Resolve the binding's names once, before the first episode."""

    @abstractmethod
    def action_space(self) -> spaces.Space[Any]: ...

    @abstractmethod
    def action_contract(self) -> dict[str, Any]:
        """Names, units and scaling of the action, for the I/O contract."""

    @abstractmethod
    def initialize_episode(self, rng: np.random.Generator) -> None:
        """Put the robot in this episode's initial state (the twin has just been reset)."""

    @abstractmethod
    def apply_action(self, action: Any) -> None: ...

    @abstractmethod
    def sample(self) -> None:
        """Read the robot once after a control period; the getters below use this sample."""

    @abstractmethod
    def observation(self) -> np.ndarray: ...

    @abstractmethod
    def reward(self) -> float: ...

    @abstractmethod
    def terminated(self) -> bool: ...

    def info(self) -> dict[str, Any]:
        return {}

    def contract(self) -> dict[str, Any]:
        return {}


class CartPoleBalance(Task):
    """Keep the pole up on the wheeled cart (the paper's reward: +1 per control period with |pole| <= 0.3 rad,
    counted only while the chassis is upright, within ``upright_angle`` of level).

    Observation (float32): cart position and cart velocity (wheel odometry, on-board), pole angle (pole
    encoder, on-board), pole angular velocity (supervisor, privileged). The episode does not end when the pole
    falls (the reward counts balanced steps) unless ``terminate_on_fall``; it ends when the cart leaves
    ``|x| <= x_limit`` (ground truth).
    Actions are cart speeds, sent to every wheel as angular velocity = speed / wheel radius.

    ``cart_velocity="ground_truth"`` uses the supervisor's cart velocity instead. It is not the default: it
    carries the tyres' creep under load, which a memoryless policy cannot separate from the command. (With
    episodes that ran on after a fall PPO did not learn with it within 10 minutes; with ``terminate_on_fall``
    it reached 950 of 1000 after 61 k steps on seed 0, bench/bench_rl.py.)
    """

    GROUND_TRUTH_TERMS = (
        ObservationTerm("cart_position", "m", "onboard", "cart_pos_m", "mean wheel encoder angle x wheel radius"),
        ObservationTerm("cart_velocity", "m/s", "privileged", "cart_vel_m_s", "supervisor ground truth"),
        ObservationTerm("pole_angle", "rad", "onboard", "pole_angle_rad", "pole hinge encoder"),
        ObservationTerm("pole_angular_velocity", "rad/s", "privileged", "pole_velocity_rad_s",
                        "supervisor ground truth"),
    )
    ODOMETRY_VELOCITY = ObservationTerm(
        "cart_velocity", "m/s", "onboard", "cart_pos_m",
        "wheel odometry: change of cart_position over the last control period / control period")

    def __init__(self, *, continuous: bool = False, max_cart_speed: float = 1.5, x_limit: float = 2.4,
                 balance_angle: float = 0.3, initial_angle: float = 0.05, action_key: str = "wheel_velocity",
                 pole_joint: str = "pole_hinge",
                 cart_velocity: Literal["ground_truth", "odometry"] = "odometry",
                 upright_angle: float = 0.5, terminate_on_fall: bool = False,
                 max_wheel_speed: float | None = None, observation_ranges: list[float] | None = None) -> None:
        # initial_angle is the half-width of a uniform draw: 1e308 overflowed numpy's uniform() (a traceback)
        if min(max_cart_speed, x_limit, balance_angle, upright_angle) <= 0 or not 0 <= initial_angle <= math.pi:
            raise DualtwinError("CartPoleBalance: max_cart_speed, x_limit, balance_angle and upright_angle must "
                                "be > 0, initial_angle from 0 to pi")
        # The paper's published controller (and Gymnasium's CartPole) end the episode when the pole leaves the
        # band. Without it a fallen pole rests on its stiff stops at +-1 rad for the rest of the 1000 steps: most
        # of every early rollout is zero-reward samples from states the policy can never recover from.
        self.terminate_on_fall = bool(terminate_on_fall)
        # The paper's published controller commands wheel speed (+-5 rad/s), not cart speed: with it the cart
        # speed follows from the binding's wheel radius (0.04 m on the bundled CartPole: +-0.2 m/s).
        if max_wheel_speed is not None and max_wheel_speed <= 0:
            raise DualtwinError("CartPoleBalance: max_wheel_speed must be > 0")
        self.max_wheel_speed = None if max_wheel_speed is None else float(max_wheel_speed)
        # Fixed observation scaling (the published controller divides each term by a range and clips to +-1).
        self.observation_ranges: np.ndarray | None = None
        if observation_ranges is not None:
            ranges = np.asarray(observation_ranges, dtype=np.float64).reshape(-1)
            if ranges.shape != (4,) or not (np.isfinite(ranges).all() and (ranges > 0).all()):
                raise DualtwinError("CartPoleBalance: observation_ranges must be 4 positive numbers (cart "
                                    "position, cart velocity, pole angle, pole angular velocity)")
            self.observation_ranges = ranges
        self.continuous = continuous
        self.max_cart_speed = float(max_cart_speed)
        self.x_limit = float(x_limit)
        self.balance_angle = float(balance_angle)
        self.initial_angle = float(initial_angle)
        self.action_key = action_key
        self.pole_joint = pole_joint
        self.upright_angle = float(upright_angle)
        self._tilt = 0.0
        if cart_velocity not in ("ground_truth", "odometry"):
            raise DualtwinError(f"CartPoleBalance: cart_velocity must be 'ground_truth' or 'odometry', "
                                f"got {cart_velocity!r}")
        # Odometry velocity is what the wheels (and so the velocity servos) do; the supervisor's cart velocity
        # also carries the tyres' creep under load, which a memoryless policy cannot separate from the command.
        self.odometry_velocity = cart_velocity == "odometry"
        terms = list(self.GROUND_TRUTH_TERMS)
        if self.odometry_velocity:
            terms[1] = self.ODOMETRY_VELOCITY
        if self.observation_ranges is not None:
            terms = [ObservationTerm(t.name, f"{t.unit} / {r:g}", t.source, t.channel,
                                     f"{t.description}; divided by {r:g} {t.unit} and clipped to [-1, 1]")
                     for t, r in zip(terms, self.observation_ranges, strict=True)]
        self.observation_terms = tuple(terms)
        self._previous_odometry = 0.0
        self._odometry_index = 0
        self._onboard = np.zeros(0)
        self._truth = np.zeros(0)

    def bind(self, io: RobotIO) -> None:
        spec = io.robot.spec
        for term in self.observation_terms:
            table = spec.onboard if term.source == "onboard" else spec.ground_truth
            if term.channel not in table:
                where = "onboard" if term.source == "onboard" else "ground_truth"
                raise DualtwinError(f"{io.robot.path}: task cartpole_balance needs {where} channel "
                                    f"{term.channel!r} (the binding has: {', '.join(sorted(table))})")
        for channel in ("pole_angle_rad", "cart_pos_m"):
            if channel not in spec.ground_truth:
                raise DualtwinError(f"{io.robot.path}: task cartpole_balance needs ground_truth channel {channel!r}")
        action = spec.actions.get(self.action_key)
        if action is None or action.mode != "velocity":
            raise DualtwinError(f"{io.robot.path}: task cartpole_balance needs a velocity action "
                                f"{self.action_key!r} (the binding has: {', '.join(sorted(spec.actions))})")
        # Wheel odometry is encoder angle x radius, so the odometry channel's scale is the wheel radius.
        self.wheel_radius = float(spec.onboard["cart_pos_m"].scale)
        if self.max_wheel_speed is not None:
            self.max_cart_speed = self.max_wheel_speed * self.wheel_radius
        self.actuators = list(action.actuators)
        self._io = io
        onboard, truth = io.onboard_names, io.ground_truth_names
        self._obs_index = [(0 if t.source == "onboard" else 1,
                            (onboard if t.source == "onboard" else truth).index(t.channel))
                           for t in self.observation_terms]
        self._odometry_index = onboard.index("cart_pos_m")
        self.cart_body = spec.ground_truth["cart_pos_m"].body or "cart"
        self._period = io.twin.control_period
        self._true_angle = truth.index("pole_angle_rad")
        self._true_x = truth.index("cart_pos_m")

    def action_space(self) -> spaces.Space[Any]:
        if self.continuous:
            return spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        return spaces.Discrete(2)

    def speed_table(self) -> list[float]:
        return [-self.max_cart_speed, self.max_cart_speed]

    def action_contract(self) -> dict[str, Any]:
        common = {
            "names": ["cart_velocity"], "unit": "m/s",
            "actuators": self.actuators, "actuator_mode": "velocity", "actuator_unit": "rad/s",
            "wheel_radius_m": self.wheel_radius,
            "to_actuator": "wheel angular velocity = cart velocity / wheel_radius_m, same for every actuator",
        }
        if self.continuous:
            return {"type": "box", "shape": [1], "low": [-1.0], "high": [1.0], "dtype": "float32",
                    "scaling": f"cart velocity = clip(action, -1, 1) * {self.max_cart_speed}",
                    "scale": self.max_cart_speed, **common}
        return {"type": "discrete", "n": 2, "speed_table": self.speed_table(),
                "scaling": "cart velocity = speed_table[action]", **common}

    def contract(self) -> dict[str, Any]:
        return {"name": "cartpole_balance", "cart_velocity": "odometry" if self.odometry_velocity else "ground_truth",
                "x_limit_m": self.x_limit, "balance_angle_rad": self.balance_angle,
                "initial_angle_rad": self.initial_angle, "upright_angle_rad": self.upright_angle,
                "reward": f"+1 per control period while |pole hinge angle| <= {self.balance_angle} rad and the "
                f"chassis is within {self.upright_angle} rad of upright (ground truth), else 0; no termination "
                "on the pole angle",
                "termination": f"|cart x| > {self.x_limit} m (ground truth)"
                + (f" or |pole hinge angle| > {self.balance_angle} rad or chassis tilt > {self.upright_angle} rad"
                   if self.terminate_on_fall else ""),
                "terminate_on_fall": self.terminate_on_fall, "max_wheel_speed_rad_s": self.max_wheel_speed,
                "observation_ranges": None if self.observation_ranges is None else self.observation_ranges.tolist()}

    def initialize_episode(self, rng: np.random.Generator) -> None:
        io = self.io
        angle = float(rng.uniform(-self.initial_angle, self.initial_angle))
        io.twin.set_joint_state(self.pole_joint, position=angle, velocity=0.0)
        # One control period with the wheels held at zero speed: a Webots supervisor's teleport only shows in
        # the sensors after the next physics step, so this makes the first observation mean the same on all twins.
        self._command(0.0)
        self.sample()
        io.twin.step()
        self.sample()

    def _command(self, cart_speed: float) -> None:
        wheel = cart_speed / self.wheel_radius
        twin = self.io.twin
        for actuator in self.actuators:
            twin.command(actuator, "velocity", wheel)

    def cart_speed(self, action: Any) -> float:
        if self.continuous:
            value = float(box_action(action, 1, "cartpole_balance")[0])
            return value * self.max_cart_speed
        return self.speed_table()[discrete_action(action, 2, "cartpole_balance")]

    def apply_action(self, action: Any) -> None:
        self._command(self.cart_speed(action))

    def sample(self) -> None:
        io = self.io
        if len(self._onboard):
            self._previous_odometry = float(self._onboard[self._odometry_index])
        self._onboard = np.asarray(io.sample_onboard(), dtype=np.float64)
        self._truth = np.asarray(io.sample_ground_truth(), dtype=np.float64)
        # Angle between the chassis' up axis and the world's: 0 on four wheels, pi upside down.
        up = float(io.twin.body_orientation(self.cart_body)[2, 2])
        self._tilt = math.acos(max(-1.0, min(1.0, up)))
        if not math.isfinite(self._previous_odometry):
            # Webots sensors read NaN until their first physics step (just after a reset): report zero speed.
            self._previous_odometry = float(self._onboard[self._odometry_index])

    def observation(self) -> np.ndarray:
        rows = (self._onboard, self._truth)
        values = [rows[r][i] for r, i in self._obs_index]
        if self.odometry_velocity:
            values[1] = (self._onboard[self._odometry_index] - self._previous_odometry) / self._period
        if self.observation_ranges is not None:
            return np.clip(np.asarray(values) / self.observation_ranges, -1.0, 1.0).astype(np.float32)
        return np.array(values, dtype=np.float32)

    def reward(self) -> float:
        # The pole angle is measured at the hinge, relative to the chassis: a cart lying on its back or side can
        # hold the hinge within the band with nothing balanced (PPO finds that in MuJoCo). So the chassis must
        # be upright too; 0.5 rad leaves room for the pitch of full-traction starts (about 0.13 rad).
        upright = self._tilt <= self.upright_angle
        return 1.0 if upright and abs(self._truth[self._true_angle]) <= self.balance_angle else 0.0

    def terminated(self) -> bool:
        if self.terminate_on_fall and (abs(self._truth[self._true_angle]) > self.balance_angle
                                       or self._tilt > self.upright_angle):
            return True
        return bool(abs(self._truth[self._true_x]) > self.x_limit)

    def info(self) -> dict[str, Any]:
        return {"true_pole_angle": float(self._truth[self._true_angle]),
                "true_cart_position": float(self._truth[self._true_x]), "true_cart_tilt": self._tilt}

    # ---- many envs at once (dualtwin.rl.vector_env): the arithmetic above, in the same order, on one column
    # per channel, so that a batch of envs is bit-identical to envs stepped one by one (tests/rl/test_vector_env.py).
    def last_odometry(self) -> float:
        """The wheel odometry of the last sample (the batch carries it into the next odometry velocity)."""
        return float(self._onboard[self._odometry_index])

    def batch_channels(self) -> tuple[list[int], list[int]]:
        """Indices of the on-board and ground-truth channels that the batch methods read."""
        onboard = {i for r, i in self._obs_index if r == 0} | {self._odometry_index}
        truth = {i for r, i in self._obs_index if r == 1} | {self._true_angle, self._true_x}
        return sorted(onboard), sorted(truth)

    def batch_wheel_speeds(self, actions: Any) -> np.ndarray:
        """:meth:`apply_action`'s wheel speed (rad/s, every actuator) for each row of ``actions``."""
        n = np.asarray(actions).shape[0]
        if self.continuous:
            value = batch_box_actions(actions, n, 1, "cartpole_balance")[:, 0]
            return value * self.max_cart_speed / self.wheel_radius
        index = batch_discrete_actions(actions, n, 2, "cartpole_balance")
        low, high = self.speed_table()
        return np.where(index == 1, high, low) / self.wheel_radius

    def batch_outcome(self, onboard: np.ndarray, truth: np.ndarray, tilt: np.ndarray,
                      previous_odometry: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any], np.ndarray]:
        """Observations, rewards, terminations and infos of samples (n, channels) taken after a period, and
        the odometry that the next period's odometry velocity starts from."""
        rows = (onboard, truth)
        columns = [rows[r][:, i] for r, i in self._obs_index]
        if self.odometry_velocity:
            columns[1] = (onboard[:, self._odometry_index] - previous_odometry) / self._period
        values = np.stack(columns, axis=1)
        if self.observation_ranges is not None:
            obs = np.clip(values / self.observation_ranges, -1.0, 1.0).astype(np.float32)
        else:
            obs = values.astype(np.float32)
        angle, x = truth[:, self._true_angle], truth[:, self._true_x]
        upright = tilt <= self.upright_angle
        reward = np.where(upright & (np.abs(angle) <= self.balance_angle), 1.0, 0.0)
        terminated = np.abs(x) > self.x_limit
        if self.terminate_on_fall:
            terminated |= (np.abs(angle) > self.balance_angle) | (tilt > self.upright_angle)
        info = {"true_pole_angle": angle.copy(), "true_cart_position": x.copy(), "true_cart_tilt": tilt}
        return obs, reward, terminated, info, onboard[:, self._odometry_index].copy()


# Task name -> constructor (keyword arguments: ``continuous`` and the task's own); task modules add theirs.
TASKS: dict[str, Callable[..., Task]] = {"cartpole_balance": CartPoleBalance}


def declared_options(factory: Any) -> dict[str, Any]:
    """The keyword parameters of ``factory`` (a class's ``__init__`` or a function) with their annotated types
    (``Any`` where a parameter has none)."""
    import inspect
    import typing

    function = factory.__init__ if inspect.isclass(factory) else factory
    hints = typing.get_type_hints(function)
    return {name: hints.get(name, Any) for name, p in inspect.signature(function).parameters.items()
            if name != "self" and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}


def check_option(where: str, value: Any, hint: Any) -> Any:
    """``value`` checked against the annotation ``hint``: strict (a JSON string is not a number, 1 is not True)
    and finite (NaN and infinities refused, also inside lists and objects the annotation leaves open).

    Raises:
        DualtwinError: ``"{where}: <reason> (got <value>)"``, one line.
    """
    from pydantic import ConfigDict, TypeAdapter, ValidationError

    try:
        adapter = TypeAdapter(hint, config=ConfigDict(allow_inf_nan=False))
    except Exception:  # noqa: BLE001 - an annotation pydantic cannot check: accept plain JSON scalars only
        if value is None or isinstance(value, bool | int | float | str) and _all_finite(where, value):
            return value
        raise DualtwinError(f"{where}: expected a plain value, got {type(value).__name__}") from None
    try:
        checked = adapter.validate_python(value, strict=True)
    except ValidationError as exc:
        raise DualtwinError(f"{where}: {exc.errors()[0]['msg']} (got {value!r:.80})") from None
    _all_finite(where, checked)
    return checked


def _all_finite(where: str, value: Any) -> bool:
    """True, or a DualtwinError naming the first NaN or infinity inside ``value`` (an ``Any`` annotation lets
    them through pydantic, and they poison physics and JSON records alike)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise DualtwinError(f"{where}: must be finite, got {value!r}")
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list | tuple) else ()
    for key, item in items:
        _all_finite(f"{where}.{key}", item)
    return True


def check_task_kwargs(task: str, kwargs: Any, where: str | None = None) -> dict[str, Any]:
    """``kwargs`` checked against the task constructor's annotated parameters (:func:`check_option`: strict,
    finite numbers).

    Task arguments come from files (a PPO config, a run's ``run.json``, an export's contract) and go to the
    constructor and on to the physics engine unchecked otherwise: ``pole_joint: null`` reached MuJoCo's
    ``mj_name2id`` and killed the process with SIGSEGV, ``observation_ranges: "abc"`` and ``action_key: []``
    were tracebacks and ``x_limit: NaN`` was silently accepted (found by fuzzing ``gym.make``'s task_kwargs).
    """
    where = where or f"task {task!r}: task_kwargs"
    if kwargs is None:
        return {}
    if not isinstance(kwargs, dict):
        raise DualtwinError(f"{where}: expected an object of task {task!r}'s options, got {type(kwargs).__name__}")
    options = {name: hint for name, hint in declared_options(TASKS[task]).items() if name != "continuous"}
    for name, value in kwargs.items():
        if name not in options:
            raise DualtwinError(f"{where}.{name}: not an option of this task (options: {', '.join(options)})")
        check_option(f"{where}.{name}", value, options[name])
    return dict(kwargs)


def _knob_values(values: Any, where: str) -> dict[str, float]:
    """Knob values given to an env, as a dict of finite numbers: knobs="abc" was a ValueError in dict() and a
    value "abc" one in the twin's float(), NaN went into the model (found by fuzzing gym.make's knobs)."""
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise DualtwinError(f"{where} must be a mapping of knob name to value, got {type(values).__name__}")
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            raise DualtwinError(f"{where}: knob {name!r} must be a finite number, got {value!r:.80}")
    return dict(values)


class TwinEnv(gym.Env[np.ndarray, Any]):
    """A Gymnasium env: one twin (``mujoco``, ``webots``) running one task.

    Args:
        twin: twin name (:data:`dualtwin.twins.TWINS`).
        robot: bundled robot name or binding file.
        task: task name (:data:`TASKS`).
        continuous: Box([-1], [1]) actions instead of Discrete(2).
        control_period: seconds of simulation per ``step``.
        knobs: fixed knob values (from nominal) that define this env's physics; a reset's
            ``options={"knobs": {...}}`` adds to and overrides them for that episode.
        render_mode: ``"rgb_array"`` if the twin can render and the binding declares ``camera``.
        task_kwargs: extra task arguments (``x_limit``, ``max_cart_speed``...).
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 31}

    def __init__(self, twin: str = "mujoco", robot: str = "cartpole", task: str = "cartpole_balance", *,
                 continuous: bool = False, control_period: float = 0.032, knobs: dict[str, float] | None = None,
                 render_mode: str | None = None, camera: str = "side", render_size: tuple[int, int] = (480, 640),
                 task_kwargs: dict[str, Any] | None = None) -> None:
        if task not in TASKS:
            raise DualtwinError(f"unknown task {task!r} (available: {', '.join(sorted(TASKS))})")
        checked_kwargs = check_task_kwargs(task, task_kwargs)
        # Before the twin is built: control_period "abc" was a TypeError inside make_twin (found by fuzzing).
        period: Any = control_period  # typed float, but from untrusted config or caller: checked as it comes
        if isinstance(period, bool) or not isinstance(period, numbers.Real) or not 0 < float(period) <= 60:
            raise DualtwinError(f"control_period must be a number of seconds in (0, 60], got {control_period!r:.80}")
        knobs = _knob_values(knobs, "knobs")
        self.robot: RobotBinding = resolve_robot(robot)
        self.twin_name = twin
        self.robot_name = robot
        self.task_name = task
        self.twin: Twin = make_twin(twin, self.robot, control_period)
        # A check below can still refuse the arguments: the twin is closed then, not left to the process's end (a
        # Webots twin keeps its ODE world until then; nobody holds the half-built env to close it).
        try:
            self.io = RobotIO(self.robot, self.twin)
            try:
                self.task = TASKS[task](continuous=continuous, **checked_kwargs)
            except TypeError as exc:  # an argument the task does not take
                raise DualtwinError(f"task {task!r}: {exc}") from None
            self.task.bind(self.io)
            self.base_knobs = knobs
            self._check_knobs(self.base_knobs)
            # The camera must be declared in the binding so that every twin renders the same view.
            can_render = type(self.twin).render is not Twin.render and camera in self.robot.spec.cameras
            # Per instance: the frame rate follows the control period and only rendering twins offer rgb_array.
            self.metadata = {"render_modes": ["rgb_array"] if can_render else [],
                             "render_fps": int(round(1.0 / control_period))}
            if render_mode is not None and render_mode not in self.metadata["render_modes"]:
                raise DualtwinError(f"render_mode {render_mode!r} is not supported by twin {twin!r} with robot "
                                    f"{robot!r} and camera {camera!r} (supported: "
                                    f"{self.metadata['render_modes'] or 'none'}; cameras in the binding: "
                                    f"{', '.join(sorted(self.robot.spec.cameras)) or 'none'})")
            self.render_mode = render_mode
            self.camera = camera
            self.render_size = render_size
            self._frames: Any = None
            self.control_period = control_period
            self.observation_space = spaces.Box(-np.inf, np.inf, shape=(len(self.task.observation_terms),),
                                                dtype=np.float32)
            self.action_space = self.task.action_space()
            self.knob_values: dict[str, float] = {}
        except BaseException:
            self.twin.close()
            raise

    def _check_knobs(self, values: dict[str, float]) -> None:
        check_knob_names(list(values), self.twin.knobs(), f"twin {self.twin_name!r}")

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        overrides = _knob_values((options or {}).get("knobs"), 'reset options["knobs"]')
        knobs = {**self.base_knobs, **overrides}
        if overrides:
            self._check_knobs(overrides)
        # The twin's own noise stream is seeded from ours, so reset(seed=s) fixes the whole episode.
        self.twin.reset(int(self.np_random.integers(2**31 - 1)))
        # Every reset, from nominal: episode knobs never compound (mjlab #38).
        self.twin.set_knobs(knobs)
        self.knob_values = knobs
        self.task.initialize_episode(self.np_random)
        return self.task.observation(), self.task.info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.task.apply_action(action)
        try:
            self.twin.step()
        except SimulationUnstable as exc:
            # The episode cannot continue; report it rather than crash a long training run.
            info = {**self.task.info(), "unstable": str(exc)}
            return self.task.observation(), 0.0, True, False, info
        self.task.sample()
        return self.task.observation(), self.task.reward(), self.task.terminated(), False, self.task.info()

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        if self.render_mode != "rgb_array":
            return None
        if self._frames is None:
            # The perception renderer: no shadows, reflections or MSAA, 5-30x faster on a CPU than mujoco.Renderer.
            from dualtwin.twins.render import TwinCamera

            height, width = self.render_size
            self._frames = TwinCamera(self.twin, self.camera, width, height)
        return self._frames.render()

    def close(self) -> None:
        if self._frames is not None:
            self._frames.close()
            self._frames = None
        self.twin.close()

    def io_contract(self) -> dict[str, Any]:
        """What a policy trained here consumes and produces: compared on transfer, shipped with exports."""
        spec = self.spec
        return {
            "env_id": spec.id if spec is not None else None,
            "twin": self.twin_name,
            "robot": self.robot_name,
            "task": self.task.contract(),
            "control_period_s": self.control_period,
            "observation": {
                "shape": list(self.observation_space.shape or ()), "dtype": "float32",
                "terms": [{"index": i, **asdict(t)} for i, t in enumerate(self.task.observation_terms)],
            },
            "action": self.task.action_contract(),
        }


__all__ = ["TASKS", "CartPoleBalance", "ObservationTerm", "Task", "TwinEnv", "check_option", "check_task_kwargs",
           "declared_options"]
