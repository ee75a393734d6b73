"""The twin contract over the test double (tests/support/fake_twin.py): the generic half of test_conformance
(the cartpole-specific physics there does not apply to two springs), plus the double's own physics against the
closed form, so the fast align/divergence/sync tests that use it stand on a twin that is itself checked."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from dualtwin.errors import DualtwinError, SimulationUnstable
from dualtwin.twins import TWINS, Twin, make_twin
from dualtwin.twins.base import SyncError
from tests.support.fake_twin import ENTRY, NAME, fake_robot, registered, step_rate


@pytest.fixture
def twin() -> Iterator[Twin]:
    with registered():
        t = make_twin(NAME, fake_robot(), 0.02)
    yield t
    t.close()


def free_swing(twin: Twin, steps: int = 100) -> np.ndarray:
    twin.reset(seed=3)
    twin.set_joint_state("j1", position=0.5)
    twin.command("m1", "torque", 0.0)
    rows = []
    for _ in range(steps):
        twin.step()
        rows.append([twin.time, twin.joint_position("j1"), twin.joint_velocity("j1"), twin.joint_position("j2")])
    return np.array(rows)


def test_registration_is_through_the_public_registry_and_undone() -> None:
    assert NAME not in TWINS
    with registered() as name:
        assert TWINS[name] == ENTRY
        assert make_twin(name, fake_robot()).control_period == pytest.approx(0.02)  # the binding's 20 ms
    assert NAME not in TWINS
    with pytest.raises(DualtwinError, match="unknown twin 'fake'"):
        make_twin(NAME, fake_robot())


def test_time_advances_by_control_period(twin: Twin) -> None:
    twin.reset()
    for k in range(1, 6):
        twin.step()
        assert twin.time == pytest.approx(0.02 * k)


def test_same_inputs_same_outputs_after_reset(twin: Twin) -> None:
    assert np.array_equal(free_swing(twin), free_swing(twin))


def test_reset_restores_the_initial_state(twin: Twin) -> None:
    free_swing(twin, 20)
    twin.reset()
    assert twin.time == 0.0
    assert twin.joint_position("j1") == 0.0 and twin.joint_velocity("j1") == 0.0


def test_a_free_spring_follows_the_closed_form(twin: Twin) -> None:
    # m q'' = -k q - c q' with m = 1, k = 4, c = 0.4: q = e^(-zeta w t) (q0 cos(wd t) + ...), started at rest.
    rows = free_swing(twin, 100)
    m, k, c, q0 = 1.0, 4.0, 0.4, 0.5
    w = math.sqrt(k / m)
    zeta = c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - zeta**2)
    t = rows[:, 0]
    exact = q0 * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    assert np.max(np.abs(rows[:, 1] - exact)) < 0.01  # semi-implicit Euler at 5 ms
    assert np.all(rows[:, 3] == 0.0), "the other joint is held by its uncommanded motor"


def test_an_uncommanded_motor_holds_and_a_commanded_one_does_not(twin: Twin) -> None:
    twin.reset()
    twin.set_joint_state("j2", position=0.3)
    for _ in range(50):
        twin.step()
    assert twin.joint_position("j2") == pytest.approx(0.3, abs=0.03)  # held against its spring
    twin.command("m2", "torque", 0.0)
    for _ in range(50):
        twin.step()
    assert abs(twin.joint_position("j2") - 0.3) > 0.1  # released


def test_velocity_and_position_commands_converge_and_torque_limits(twin: Twin) -> None:
    twin.reset()
    twin.command("m1", "velocity", 0.5)
    twin.command("m2", "position", 0.2)
    for _ in range(10):
        twin.step()
    assert twin.joint_velocity("j1") == pytest.approx(0.5, abs=0.05)
    for _ in range(100):
        twin.step()
    assert twin.joint_position("j2") == pytest.approx(0.2, abs=0.02)
    twin.set_knobs({"motor.m1.max_torque": 0.01})
    twin.reset()
    twin.command("m1", "velocity", 5.0)
    twin.step()
    assert twin.joint_velocity("j1") < 0.01, "0.01 N*m cannot reach 5 rad/s in 20 ms on 1 kg"
    twin.set_knobs({})


def test_knobs_apply_from_nominal(twin: Twin) -> None:
    knobs = twin.knobs()
    assert {"joint.j1.damping", "joint.j2.stiffness", "joint.j1.mass", "motor.m2.max_torque"} <= set(knobs)
    assert all(k.lower <= k.nominal <= k.upper for k in knobs.values())
    baseline = free_swing(twin)
    twin.set_knobs({"joint.j1.damping": 2.0})
    twin.set_knobs({"joint.j1.damping": 2.0})
    damped = free_swing(twin)
    assert np.abs(damped[-20:, 1]).max() < np.abs(baseline[-20:, 1]).max()
    twin.set_knobs({})
    assert np.array_equal(free_swing(twin), baseline), "knobs not named return to nominal"


def test_state_round_trip_and_holds(twin: Twin) -> None:
    free_swing(twin, 30)
    state = twin.get_state()
    assert set(state.joint_positions) == {"j1", "j2"} and state.holds == {"j2": 0.0}
    ahead = [twin.step() or twin.joint_position("j1") for _ in range(10)]
    twin.set_state(state)
    assert [twin.step() or twin.joint_position("j1") for _ in range(10)] == ahead
    bad = state.copy()
    bad.joint_positions["j1"] = math.nan
    with pytest.raises(SyncError):
        twin.set_state(bad)
    partial = state.copy()
    del partial.joint_positions["j2"], partial.joint_velocities["j2"]
    with pytest.raises(DualtwinError, match="lacks joint 'j2'"):
        twin.set_state(partial)
    twin.set_state(partial, partial=True)


def test_unknown_names_are_clear_errors(twin: Twin) -> None:
    with pytest.raises(DualtwinError, match="no joint named 'nope'"):
        twin.joint_position("nope")
    with pytest.raises(DualtwinError, match="no actuator named"):
        twin.command("nope", "velocity", 1.0)
    with pytest.raises(DualtwinError, match="no sensor named"):
        twin.sensor("nope")
    with pytest.raises(DualtwinError, match="unknown knobs joint.j9.damping"):
        twin.set_knobs({"joint.j9.damping": 1.0})


def test_blow_up_is_simulation_unstable(twin: Twin) -> None:
    twin.reset()
    twin.set_knobs({"joint.j1.stiffness": 1e12})
    twin.command("m1", "torque", 0.0)
    twin.set_joint_state("j1", position=0.1)
    with pytest.raises(SimulationUnstable):
        for _ in range(200):
            twin.step()
    twin.set_knobs({})


def test_it_is_fast(twin: Twin) -> None:
    # Microseconds per step is the point of the double: 5,000 periods per second is a loose floor.
    twin.reset()
    assert step_rate(twin, 2000) > 5000
