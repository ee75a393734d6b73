"""The twin contract, run over every registered twin (like Gymnasium's test over every registered env)."""

from __future__ import annotations

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import resolve_robot
from dualtwin.twins import TWINS, Twin, make_twin

WHEELS = ["wheel1", "wheel2", "wheel3", "wheel4"]


#: The bundled CartPoles the contract runs on: pole stop (rad), the cart's direction for a positive wheel
#: command (the paper's world drives the other way, see docs/robots.md), and how far ODE itself overshoots the
#: stop when the pole falls onto it from 0.1 rad before it (further at 1.3 rad, where gravity pulls harder).
CARTPOLES = {"cartpole": (1.0, 1.0, 0.003), "cartpole_paper": (1.3, -1.0, 0.006)}
_FACTS: dict[int, tuple[float, float, float]] = {}


@pytest.fixture(params=[(t, r) for r in CARTPOLES for t in sorted(TWINS)], ids=lambda p: f"{p[0]}-{p[1]}")
def twin(request: pytest.FixtureRequest) -> Twin:
    name, robot = request.param
    t = make_twin(name, resolve_robot(robot), 0.032)
    _FACTS[id(t)] = CARTPOLES[robot]
    yield t
    _FACTS.pop(id(t), None)
    t.close()


def trajectory(twin: Twin, steps: int = 40, velocity: float = 6.0) -> np.ndarray:
    twin.reset(seed=3)
    twin.set_joint_state("pole_hinge", position=0.05)
    for w in WHEELS:
        twin.command(w, "velocity", velocity)
    rows = []
    for _ in range(steps):
        twin.step()
        rows.append([twin.time, twin.joint_position("pole_hinge"), *twin.body_position("cart"),
                     twin.joint_velocity("wheel1_hinge"), twin.sensor("pole sensor")])
    return np.array(rows)


def test_time_advances_by_control_period(twin: Twin) -> None:
    twin.reset()
    for k in range(1, 6):
        twin.step()
        assert twin.time == pytest.approx(0.032 * k)


def test_same_inputs_same_outputs_after_reset(twin: Twin) -> None:
    first = trajectory(twin)
    second = trajectory(twin)
    assert np.array_equal(first, second)


def test_reset_restores_the_initial_state(twin: Twin) -> None:
    twin.reset()
    start = (twin.body_position("cart").copy(), twin.joint_position("pole_hinge"))
    trajectory(twin, steps=20)
    twin.reset()
    assert twin.time == 0.0
    assert np.allclose(twin.body_position("cart"), start[0])
    assert twin.joint_position("pole_hinge") == pytest.approx(start[1])


def test_joint_teleport(twin: Twin) -> None:
    twin.reset()
    twin.set_joint_state("pole_hinge", position=0.3)
    twin.step()
    assert twin.joint_position("pole_hinge") == pytest.approx(0.3, abs=0.02)


def test_a_loaded_stop_holds_like_a_webots_stop(twin: Twin) -> None:
    # Webots stops are hard (ODE ERP 0.2, CFM 1e-5): the pole falling onto its stop (+1 rad; the paper's
    # +1.3 rad) barely overshoots and then rests on it. A default MuJoCo limit would rest 2.3 mrad past it.
    stop, _, overshoot = _FACTS[id(twin)]
    twin.reset()
    twin.set_joint_state("pole_hinge", position=stop - 0.1)
    angles = []
    for _ in range(40):
        twin.step()
        angles.append(twin.joint_position("pole_hinge"))
    assert max(angles) < stop + overshoot
    assert angles[-1] == pytest.approx(stop, abs=2e-4)


def test_initial_hold_keeps_wheels_braked(twin: Twin) -> None:
    """Webots motors hold their initial position until commanded, even while the pole falls."""
    twin.reset()
    twin.set_joint_state("pole_hinge", position=0.2)
    for _ in range(40):
        twin.step()
    assert abs(twin.joint_position("wheel1_hinge")) < 0.05
    assert abs(twin.body_position("cart")[0]) < 0.01


def test_velocity_command_reaches_target(twin: Twin) -> None:
    rows = trajectory(twin, steps=30, velocity=6.0)
    assert rows[-1, 5] == pytest.approx(6.0, rel=0.02)
    # 6 rad/s on 0.04 m wheels moves the cart at about 0.24 m/s along +x (the paper's world: along -x).
    speed = (rows[-1, 2] - rows[-11, 2]) / (rows[-1, 0] - rows[-11, 0])
    assert speed == pytest.approx(0.24 * _FACTS[id(twin)][1], rel=0.1)


def test_velocity_is_torque_limited(twin: Twin) -> None:
    twin.reset()
    twin.set_knobs({f"motor.{w}.max_torque": 0.002 for w in WHEELS})
    for w in WHEELS:
        twin.command(w, "velocity", 40.0)
    twin.step()
    assert twin.joint_velocity("wheel1_hinge") < 10.0, "0.002 N*m cannot reach 40 rad/s in 32 ms"
    twin.set_knobs({})


def test_position_control_converges(twin: Twin) -> None:
    twin.reset()
    twin.command("wheel1", "position", 1.0)
    for _ in range(40):
        twin.step()
    assert twin.joint_position("wheel1_hinge") == pytest.approx(1.0, abs=0.02)


def test_knobs_apply_from_nominal(twin: Twin) -> None:
    knobs = twin.knobs()
    assert "joint.pole_hinge.damping" in knobs
    baseline = trajectory(twin)
    twin.set_knobs({"joint.pole_hinge.damping": 0.5})
    twin.set_knobs({"joint.pole_hinge.damping": 0.5})
    damped = trajectory(twin)
    assert not np.array_equal(baseline, damped)
    assert damped[-1, 1] < baseline[-1, 1] or abs(damped[-1, 1]) < abs(baseline[-1, 1]) + 1e-9
    twin.set_knobs({})
    assert np.array_equal(trajectory(twin), baseline)


def test_unknown_names_are_clear_errors(twin: Twin) -> None:
    with pytest.raises(DualtwinError, match="no joint named 'nope'"):
        twin.joint_position("nope")
    with pytest.raises(DualtwinError, match="nope"):
        twin.command("nope", "velocity", 1.0)
    with pytest.raises(DualtwinError, match="unknown knobs"):
        twin.set_knobs({"joint.nope.damping": 1.0})
