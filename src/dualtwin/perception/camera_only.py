"""Camera-only observation contract (Pattern 3 without a pole encoder).

A policy exported by :func:`dualtwin.rl.export_policy` declares where each observation comes from: ``onboard``
(the robot's own sensors) or ``privileged`` (the supervisor). On the CartPole its on-board terms include the
pole hinge encoder. *Camera-only* deployment keeps exactly one kind of on-board sensor, the **wheel odometry**,
and takes everything else from the camera through the perception model:

* ``cart_position`` = mean of the four wheel position sensors (rad) × wheel radius (m). The binding's
  ``onboard.cart_pos_m`` channel is that average with ``scale`` = the wheel radius (0.04 m on the bundled
  CartPole); the wheels' PositionSensors are incremental encoders, which every wheeled robot has.
* ``cart_velocity`` = the change of ``cart_position`` over the last control period ÷ the control period
  (the task's ``cart_velocity: odometry`` option; its channel is ``cart_pos_m`` too).
* ``pole_angle``, ``pole_angular_velocity``: the perception model from camera frames (``source: camera``).
  The rate comes from the estimator's Kalman filter on the newest-frame angle, not from an encoder.

Decision: a term stays on board only if its channel is wheel odometry (:data:`WHEEL_ODOMETRY_CHANNELS`) *and*,
when the robot's binding is at hand, that channel reads only position sensors of the wheels the action drives
with ``scale`` equal to the action's wheel radius. Everything else (including a ground-truth cart velocity,
if a policy was trained on one) must be estimated by the perception model, or the contract is refused: the
served policy then reads nothing but the wheel odometry and the camera. The policy network itself is
unchanged (it takes the same quantities in the same units); only where they come from changes, and the
rewritten contract records it (``observation_mode: camera_only``, ``odometry``, each term's ``source``).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

from dualtwin.artifacts import atomic_open, write_json
from dualtwin.errors import DualtwinError

OBSERVATION_MODE = "camera_only"
#: The source of a term estimated from camera frames in a camera-only contract.
CAMERA_SOURCE = "camera"
#: Binding channels that are wheel odometry (mean wheel encoder angle × wheel radius). The CartPole task
#: derives both its cart position and its odometry cart velocity from this one channel.
WHEEL_ODOMETRY_CHANNELS = ("cart_pos_m",)


def is_camera_only(contract: dict[str, Any]) -> bool:
    """True for a policy contract already rewritten by :func:`camera_only_contract`."""
    return contract.get("observation_mode") == OBSERVATION_MODE


def odometry_spec(contract: dict[str, Any]) -> dict[str, Any]:
    """How the wheel odometry is computed for this policy's robot, from its binding (documented in the contract).

    Raises:
        DualtwinError: the binding's odometry channel does not read the driven wheels' position sensors, or its
            scale is not the wheel radius the action uses.
    """
    action = contract.get("action") or {}
    radius = action.get("wheel_radius_m")
    actuators = [str(a) for a in action.get("actuators") or []]
    spec: dict[str, Any] = {
        "channels": list(WHEEL_ODOMETRY_CHANNELS), "wheel_radius_m": radius, "wheel_actuators": actuators,
        "cart_position": "mean wheel position-sensor angle (rad) x wheel_radius_m",
        "cart_velocity": "(cart_position now - cart_position one control period earlier) / control period",
    }
    robot_name = contract.get("robot")
    if not robot_name:
        return spec
    from dualtwin.robots.binding import resolve_robot

    try:
        robot = resolve_robot(str(robot_name))
    except DualtwinError:
        return spec  # not a robot this installation knows: the channel names are all there is to go on
    for name in WHEEL_ODOMETRY_CHANNELS:
        channel = robot.spec.onboard.get(name)
        if channel is None:
            continue
        sensors = list(channel.sensors)
        # A wheel's position sensor is named after its motor in Webots ("wheel1" -> "wheel1 sensor").
        not_wheels = [s for s in sensors if not any(s.startswith(a) for a in actuators)]
        if not sensors or not_wheels:
            raise DualtwinError(f"robot {robot_name!r}: onboard channel {name!r} reads {not_wheels or 'no sensors'}, "
                                f"not the position sensors of the driven wheels {actuators}: it is not wheel "
                                "odometry, so camera-only deployment cannot use it")
        if radius is not None and abs(float(channel.scale) - float(radius)) > 1e-9:
            raise DualtwinError(f"robot {robot_name!r}: onboard channel {name!r} has scale {channel.scale}, not the "
                                f"wheel radius {radius} m of the action: it is not wheel odometry")
        spec["sensors"] = sensors
    return spec


def camera_only_contract(contract: dict[str, Any], estimated: list[str]) -> dict[str, Any]:
    """A copy of a policy contract in which only wheel odometry is on board and the rest comes from the camera.

    Args:
        contract: the exported policy's ``policy_contract.json`` (a camera-only contract is returned as is,
            after the same checks).
        estimated: the quantities the perception model estimates (its contract's state names).

    Raises:
        DualtwinError: a term that is not wheel odometry is not estimated by the perception model.
    """
    out = copy.deepcopy(contract)
    terms = out.get("observation")
    if not isinstance(terms, list) or not all(isinstance(t, dict) and "name" in t for t in terms):
        raise DualtwinError("policy contract: 'observation' must list terms with a 'name'")
    odometry = odometry_spec(out)
    missing = []
    for term in terms:
        if term.get("source") == "onboard" and term.get("channel") in WHEEL_ODOMETRY_CHANNELS:
            term["source"] = "onboard"
            term["sensor"] = "wheel odometry"
            continue
        if term["name"] not in estimated:
            missing.append(term["name"])
            continue
        if term.get("source") != CAMERA_SOURCE:
            term["description"] = (f"estimated from camera frames by the perception model (trained with: "
                                   f"{term.get('source')}, {term.get('description') or term.get('channel')})")
        term["source"] = CAMERA_SOURCE
    if missing:
        raise DualtwinError(f"camera-only: the policy observes {missing}, which are neither wheel odometry nor "
                            f"estimated by the perception model (it estimates {estimated})")
    out["observation_mode"] = OBSERVATION_MODE
    out["odometry"] = odometry
    out["camera_only"] = {
        "onboard": [t["name"] for t in terms if t.get("source") == "onboard"],
        "camera": [t["name"] for t in terms if t.get("source") == CAMERA_SOURCE],
        "not_used": "pole hinge encoder, supervisor state",
    }
    return out


def export_camera_only(policy_dir: Path | str, perception_dir: Path | str, out_dir: Path | str) -> Path:
    """Write a camera-only policy folder: the same ``policy.onnx`` with a rewritten ``policy_contract.json``.

    Served with the perception model, it makes the RobotServer ask for wheel odometry and a frame only.
    """
    from dualtwin.perception.estimator import StateEstimator
    from dualtwin.perception.onnx_policy import POLICY_CONTRACT, POLICY_FILE, OnnxPolicy

    policy = OnnxPolicy.load_exported(policy_dir)
    perception = StateEstimator.load(perception_dir)
    contract = camera_only_contract(policy.contract, perception.names)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / POLICY_FILE, "wb") as handle:
        handle.write((policy.directory / POLICY_FILE).read_bytes())
    write_json(out / POLICY_CONTRACT, contract)
    return out
