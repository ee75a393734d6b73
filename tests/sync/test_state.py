"""State transfer between twins: exact round trips, name mapping errors, invalid states, motor holds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import RobotBinding
from dualtwin.twins import make_twin
from dualtwin.twins.base import MechanicalState, SyncError
from tests.support.sync_helpers import PIONEER_WHEELS, WHEELS, applied_state, drive, max_abs

# Generalised coordinates round-trip to floating-point precision on both twins (the Webots side through the
# supervisor API: translation/rotation, joint position fields, Node.setVelocity).
EXACT = 1e-9

ROBOTS = {"cartpole": (WHEELS, [5.0, 5.0, 5.0, 5.0], 0.2), "pioneer3at": (PIONEER_WHEELS, [5.0, 5.0, -2.0, -2.0], None)}


def _moving_state(name: str, robot: RobotBinding) -> MechanicalState:
    actuators, speeds, pole = ROBOTS[robot.name]
    twin = make_twin(name, robot)
    try:
        drive(twin, actuators, speeds, 20, pole)
        return twin.get_state()
    finally:
        twin.close()


def _largest(a: MechanicalState, b: MechanicalState) -> float:
    return max(abs(v) for v in a.difference(b).values())


@pytest.mark.parametrize("robot_name", ["cartpole", "pioneer3at"])
@pytest.mark.parametrize(("source", "target"), [("mujoco", "webots"), ("webots", "mujoco")])
def test_round_trip_between_twins(robot_name: str, source: str, target: str,
                                  request: pytest.FixtureRequest) -> None:
    robot: RobotBinding = request.getfixturevalue("cartpole" if robot_name == "cartpole" else "pioneer")
    state = _moving_state(source, robot)
    assert state.bodies and len(state.joint_positions) >= 4 and state.is_finite()
    b, a = make_twin(target, robot), make_twin(source, robot)
    try:
        b.set_state(state)
        there = applied_state(b)
        assert _largest(state, there) < EXACT
        a.set_state(there)
        back = applied_state(a)
        assert _largest(state, back) < EXACT
    finally:
        a.close()
        b.close()


@pytest.mark.parametrize("robot_name", ["cartpole", "pioneer3at"])
@pytest.mark.parametrize("name", ["mujoco", "webots"])
def test_write_read_on_the_same_twin(robot_name: str, name: str, request: pytest.FixtureRequest) -> None:
    robot: RobotBinding = request.getfixturevalue("cartpole" if robot_name == "cartpole" else "pioneer")
    state = _moving_state(name, robot)
    twin = make_twin(name, robot)
    try:
        twin.set_state(state)
        # Takes effect now from the caller's side: read back before any step, and the clock did not move.
        assert _largest(state, twin.get_state()) < EXACT and twin.time == 0.0
        assert _largest(state, applied_state(twin)) < EXACT
    finally:
        twin.close()


@pytest.mark.parametrize("name", ["mujoco", "webots"])
def test_the_next_step_evolves_from_the_written_state(name: str, cartpole: RobotBinding) -> None:
    a, b = make_twin(name, cartpole), make_twin(name, cartpole)
    try:
        drive(a, WHEELS, [5.0] * 4, 20)
        b.set_state(a.get_state())
        for wheel in WHEELS:
            b.command(wheel, "velocity", 5.0)
        a.step()
        b.step()
        error = _largest(a.get_state(), b.get_state())
        # MuJoCo: bit-for-bit up to rounding. Webots: ODE's constraint drift (bodies slightly off their joint
        # axes, up to ~0.4 mm on the falling pole) cannot be written through joint coordinates.
        assert error < (1e-12 if name == "mujoco" else 0.05)
    finally:
        a.close()
        b.close()


def test_a_joint_missing_in_one_twin_is_named(cartpole: RobotBinding) -> None:
    twin = make_twin("mujoco", cartpole)
    try:
        state = twin.get_state()
        extra = state.copy()
        extra.joint_positions["ghost_hinge"] = 0.0
        extra.joint_velocities["ghost_hinge"] = 0.0
        with pytest.raises(DualtwinError, match="ghost_hinge"):
            twin.set_state(extra)
        partial = state.copy()
        del partial.joint_positions["pole_hinge"], partial.joint_velocities["pole_hinge"]
        with pytest.raises(DualtwinError, match="lacks joint 'pole_hinge'"):
            twin.set_state(partial)
        twin.set_state(partial, partial=True)  # explicitly partial: the pole keeps its state
        with pytest.raises(DualtwinError, match="bodies only in"):
            state.difference(MechanicalState(0.0, {}, dict(state.joint_positions), dict(state.joint_velocities)))
    finally:
        twin.close()


@pytest.mark.parametrize("name", ["mujoco", "webots"])
def test_invalid_states_raise_sync_errors(name: str, cartpole: RobotBinding) -> None:
    twin = make_twin(name, cartpole)
    try:
        twin.step()
        before = twin.get_state()
        bad = before.copy()
        bad.joint_velocities["pole_hinge"] = math.nan
        with pytest.raises(SyncError) as info:
            twin.set_state(bad)
        assert info.value.reason == "nonfinite" and "pole_hinge" in str(info.value)
        sunk = before.copy()
        sunk.bodies["cart"].position[2] = -0.05  # chassis and wheels inside the floor
        with pytest.raises(SyncError) as info:
            twin.set_state(sunk)
        assert info.value.reason in ("penetration", "jump", "unstable")
        if name == "mujoco":
            assert _largest(before, twin.get_state()) == 0.0  # left as it was
    finally:
        twin.close()


@pytest.mark.parametrize("name", ["mujoco", "webots"])
def test_held_motors_hold_the_transferred_position(name: str, cartpole: RobotBinding) -> None:
    """Uncommanded wheels hold the source's hold target; commanded ones keep their command."""
    source = make_twin("mujoco", cartpole)
    twin = make_twin(name, cartpole)
    try:
        drive(source, ["wheel1"], [3.0], 10)  # wheel1 driven, wheels 2-4 held at 0 while the pole falls
        state = source.get_state()
        assert set(state.holds) == {"wheel2_hinge", "wheel3_hinge", "wheel4_hinge"}
        assert max_abs(list(state.holds.values())) == 0.0
        twin.set_state(state)
        # wheel1 was never commanded on this twin: it holds the written position (the state has no hold for it).
        assert twin.get_state().holds == {**state.holds, "wheel1_hinge": state.joint_positions["wheel1_hinge"]}
        shifted = state.copy()
        shifted.holds = {k: 0.5 for k in state.holds}  # a hold the robot is far from: the wheels turn to it
        twin.reset()
        twin.set_state(shifted)
        for _ in range(15):
            twin.step()
        assert twin.joint_position("wheel2_hinge") == pytest.approx(0.5 + state.joint_positions["wheel2_hinge"]
                                                                     - state.holds["wheel2_hinge"], abs=0.05)
    finally:
        source.close()
        twin.close()


def test_state_vectors_and_dicts_round_trip(cartpole: RobotBinding) -> None:
    state = _moving_state("mujoco", cartpole)
    again = MechanicalState.from_vector(state.layout(), state.vector(), state.time, state.source)
    assert np.array_equal(again.vector(), state.vector()) and again.holds == state.holds
    assert np.array_equal(MechanicalState.from_dict(state.to_dict()).vector(), state.vector())
    assert set(state.difference(state).values()) == {0.0}
    assert len(state.diff_channels()) == len(state.difference(state))


def test_webots_set_velocity_waits_for_a_queued_teleport(cartpole: RobotBinding) -> None:
    """Webots runs a supervisor's requests in order before the next physics step: a velocity set after a
    joint teleport (which resets the endPoint's velocity) must survive it."""
    twin = make_twin("webots", cartpole)
    try:
        sup = twin.sup  # type: ignore[attr-defined]
        pole = sup.getFromDef("pole")
        sup.getFromDef("pole_hinge").getField("jointParameters").getSFNode().getField("position").setSFFloat(0.3)
        pole.setVelocity([0.0, 0.0, 0.0, 0.0, 2.0, 0.0])
        assert pole.getVelocity()[4] == 0.0  # still queued
        sup.simulation.apply_pending()
        assert pole.getVelocity()[4] == pytest.approx(2.0)
        assert twin.joint_position("pole_hinge") == pytest.approx(0.3)
        pole.setVelocity([0.0, 0.0, 0.0, 0.0, -1.0, 0.0])  # nothing queued: applies at once, as before
        assert pole.getVelocity()[4] == pytest.approx(-1.0)
    finally:
        twin.close()


@pytest.mark.parametrize("robot_name", ["cartpole", "pioneer3at"])
@pytest.mark.parametrize(("source", "target"), [("webots", "mujoco"), ("mujoco", "webots")])
def test_after_a_transfer_the_twins_agree(robot_name: str, source: str, target: str,
                                          request: pytest.FixtureRequest) -> None:
    """One period after a transfer the two simulators are about as close as their models allow (measured:
    normalised error 0.002-0.004 on the cart-pole, 0.06-0.08 on the skid-steered Pioneer), far closer than
    the same twin left where it was."""
    from dualtwin.divergence.channels import channel_scales, normalized_error

    robot: RobotBinding = request.getfixturevalue("cartpole" if robot_name == "cartpole" else "pioneer")
    actuators, speeds, pole = ROBOTS[robot.name]
    a, b, idle = make_twin(source, robot), make_twin(target, robot), make_twin(target, robot)
    try:
        drive(a, actuators, speeds, 20, pole)
        for twin in (b, idle):
            twin.reset(seed=1)
            for name, speed in zip(actuators, speeds, strict=True):
                twin.command(name, "velocity", speed)
        b.set_state(a.get_state())
        for twin in (a, b, idle):
            twin.step()
        reference = a.get_state()
        errors = []
        for twin in (b, idle):
            diff = reference.difference(twin.get_state())
            errors.append(normalized_error(diff, channel_scales(list(diff))))
        assert errors[0] < (0.01 if robot_name == "cartpole" else 0.15)
        assert errors[0] < 0.2 * errors[1]
    finally:
        for twin in (a, b, idle):
            twin.close()
