"""A binding's channels read for every simulation of a TwinBatch at once (ChannelColumns) are, bit for bit, what
each twin's getters return after the same period (RobotIO's readers), for every kind of channel: single and
averaged sensors, joint positions and velocities, body positions, velocities and Z-Y-X angles, with scales."""

from __future__ import annotations

import numpy as np
import pytest

from dualtwin.robots.binding import Channel, resolve_robot
from dualtwin.twins import make_twin
from dualtwin.twins.io import channel_reader
from dualtwin.twins.mujoco_batch import ChannelColumns, TwinBatch

# Channels beyond each binding's own: other axes, angles and negative or odd scales.
EXTRA = {
    "cartpole": [Channel(body="cart", axis="z", scale=-2.5), Channel(body="cart", axis="y", quantity="velocity"),
                 Channel(body="cart", axis="z", quantity="velocity", scale=3.0), Channel(body="wheel1", axis="pitch"),
                 Channel(body="pole", axis="roll", scale=-1.0), Channel(body="cart", axis="yaw", scale=0.1),
                 Channel(joint="pole_hinge", scale=-0.3), Channel(sensors=["wheel2 sensor", "pole sensor"], scale=7.0)],
    "arm": [Channel(body="wrist_3_link", axis="x", quantity="velocity", scale=0.5),
            Channel(sensors=["elbow sensor"], scale=-1.0), Channel(joint="wrist_2", quantity="velocity", scale=-2.0)],
}
KNOBS = {
    "cartpole": [{}, {"body.pole.mass": 0.15, "joint.pole_hinge.damping": 0.2}, {"physics.substeps": 8.0}],
    "arm": [{}, {"body.wrist_3_link.mass": 3.0, "joint.elbow.damping": 1.0}, {"physics.substeps": 4.0}],
}


def _bits(values: list[float]) -> bytes:
    return np.asarray(values, dtype=np.float64).tobytes()  # signed zeros and NaN payloads count


@pytest.mark.parametrize("robot_name", ["cartpole", "arm"])
def test_columns_are_the_getters_values(robot_name: str) -> None:
    robot = resolve_robot(robot_name)
    spec = robot.spec
    section = spec.twins.get("mujoco")
    channels = [*spec.ground_truth.values(), *spec.onboard.values(), *EXTRA[robot_name]]
    twins = [make_twin("mujoco", robot, 0.032) for _ in KNOBS[robot_name]]
    for twin, knobs in zip(twins, KNOBS[robot_name], strict=True):
        twin.set_knobs(knobs)
        twin.reset(0)
    batch = TwinBatch(twins, nthread=2)
    columns = ChannelColumns.build(batch, dict(section.aliases) if section else {}, channels)
    assert columns is not None and columns.width == len(channels)
    readers = [[channel_reader(twin, c) for c in channels] for twin in twins]
    actions = list(spec.actions)
    seen = set()
    for period in range(12):
        ids = [0, 1, 2] if period % 3 else [0, 2]  # a subset steps too
        for k, twin in enumerate(twins):  # commands that differ per twin and period
            key = actions[(period + k) % len(actions)]
            for actuator in spec.actions[key].actuators:
                twin.command(actuator, spec.actions[key].mode, 0.3 * (k + 1) * (-1) ** period)
        assert batch.step(ids) == [None] * len(ids)
        table = columns.read(np.asarray(ids))
        assert table.shape == (len(ids), len(channels))
        for row, i in zip(table.tolist(), ids, strict=True):
            expected = [read() for read in readers[i]]
            assert _bits(row) == _bits(expected), (period, i, row, expected)
            seen.add(tuple(row))
    assert len(seen) > 12  # the twins and periods differ: the comparison is not of constants


def test_unknown_channel_names_build_nothing() -> None:
    robot = resolve_robot("cartpole")
    batch = TwinBatch([make_twin("mujoco", robot, 0.032) for _ in range(2)], nthread=1)
    assert ChannelColumns.build(batch, {}, [Channel(sensors=["no such sensor"])]) is None
    assert ChannelColumns.build(batch, {}, [Channel(body="nobody", axis="x")]) is None
