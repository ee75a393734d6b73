"""Emitter/Receiver: in-process channels with Webots' filters, range, signal strength and timing."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot, Runtime
from dualtwin.webots.physics import Simulation
from tests.support.isolation_runs import assert_threads_print, run_in_both_modes


def _robots(
    emitter: str = "", receiver: str = "", rx_pose: str = "translation 2 0 0", wall: str = "", stepping: str = "b"
) -> tuple[Robot, Robot]:
    """Robot A (emitter at the origin) and robot B (receiver); only the ``stepping`` one's controller steps the
    simulation (the other's devices work, but nothing waits for its steps)."""
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 randomSeed 1 }}
{wall}
Robot {{ name "a" children [ Emitter {{ name "tx" {emitter} }} ] }}
Robot {{ name "b" {rx_pose} children [ Receiver {{ name "rx" {receiver} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    runtime = Runtime(sim)
    a = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    b = Robot(runtime=runtime, robot_node=sim.robots[1].node)
    (b if stepping == "a" else a).cleanup()
    return a, b


def test_packet_arrives_after_one_step_with_strength_and_direction() -> None:
    # B sits 2 m along +x, turned by +90° about z: the emitter is then along B's -y axis
    a, b = _robots(rx_pose="translation 2 0 0 rotation 0 0 1 1.5708")
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    rx.enable(8)
    tx.send("hello")
    tx.send([1.5, -2.0])
    tx.send([3, 4, True])
    assert rx.getQueueLength() == 0
    b.step(8)
    assert rx.getQueueLength() == 3
    assert rx.getString() == "hello" and rx.getDataSize() == 5
    assert rx.getSignalStrength() == pytest.approx(1 / 4)
    assert rx.getEmitterDirection() == pytest.approx([0.0, 1.0, 0.0], abs=1e-5)
    rx.nextPacket()
    assert rx.getFloats() == (1.5, -2.0)
    rx.nextPacket()
    assert rx.getInts() == (3, 4, 1)
    rx.nextPacket()
    assert rx.getQueueLength() == 0 and rx.getDataSize() == -1


@pytest.mark.parametrize(
    "emitter, receiver, arrives",
    [
        ("channel 3", "channel 3", True),
        ("channel 3", "channel 4", False),
        ("channel 3", "channel -1", True),  # a receiver on -1 hears every channel
        ("channel -1", "channel 7", True),
        ("range 1.9", "", False),  # 2 m apart
        ("range 2.1", "", True),
        ('type "serial"', "", False),  # the medium types must match
        ('type "serial"', 'type "serial"', True),
    ],
)
def test_channel_range_and_medium_filters(emitter: str, receiver: str, arrives: bool) -> None:
    a, b = _robots(emitter, receiver)
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    rx.enable(8)
    tx.send(b"x")
    b.step(8)
    assert rx.getQueueLength() == (1 if arrives else 0)


def test_set_range_channel_and_disabled_receiver() -> None:
    a, b = _robots("maxRange 5")
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    assert tx.getRange() == 5  # range -1 means maxRange
    tx.setRange(1.0)
    rx.enable(8)
    tx.send(b"far")
    b.step(8)
    assert rx.getQueueLength() == 0
    tx.setRange(100.0)
    assert tx.getRange() == 5  # clipped to maxRange
    tx.setChannel(2)
    rx.setChannel(2)
    tx.send(b"ok")
    b.step(8)
    assert rx.getBytes() == b"ok"
    rx.disable()
    tx.send(b"lost")  # nobody enabled to receive it when it leaves
    b.step(8)
    rx.enable(8)
    b.step(8)
    assert rx.getQueueLength() == 1


def test_buffers_and_baud_rate() -> None:
    # the emitter's controller steps: its baud budget grows with the steps it asks for (webots-devices.md §5.2
    # step 2, "per wb_robot_step")
    a, b = _robots("bufferSize 5 baudRate 800", "bufferSize 6", stepping="a")
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    rx.enable(8)
    tx.send(b"abcd")
    tx.send(b"ef")  # 6 bytes queued > bufferSize 5: refused
    # 800 bit/s at 8 bits per byte: 0.8 byte per 8 ms step; the 4-byte packet leaves with the 5th step
    for _ in range(4):
        a.step(8)
        assert rx.getQueueLength() == 0
    a.step(8)
    assert rx.getBytes() == b"abcd"
    tx.send(b"xyz")  # 4 + 3 > the receiver's 6 bytes: dropped on arrival
    for _ in range(5):
        a.step(8)
    assert rx.getQueueLength() == 1


BAUD_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "tx" controller "probe" children [ Emitter { name "tx" baudRate 8000 } ] }
Robot { translation 2 0 0 name "rx" controller "probe" children [ Receiver { name "rx" } ] }
"""
BAUD_SCRIPT = """
from controller import Robot
robot = Robot()
if robot.getName() == "tx":
    robot.getDevice("tx").send(b"x" * 30)
    robot.step(32)
    robot.step(32)
else:
    rx = robot.getDevice("rx")
    rx.enable(8)
    while robot.step(8) != -1:
        if rx.getQueueLength():
            print(f"arrived by {robot.getTime() * 1000:.0f} ms")
            break
"""


def test_the_baud_budget_grows_with_the_emitters_controller_step(tmp_path: Path) -> None:
    # webots-devices.md §5.2 step 2: "Per wb_robot_step: ... a byte budget grows by baudRate/byteSize/1000·step_ms
    # and whole packets go while they fit". 8000 bit/s at 8 bits a byte is 1 byte/ms: the emitter's step(32) gives
    # 32 bytes, so the 30-byte packet leaves with that step's first basic step and the receiver, sampling every
    # 8 ms, has it by 8 ms. (Granted per basic step, 8 bytes each, it left only with the 4th: by 32 ms.)
    runs = run_in_both_modes(tmp_path, BAUD_WORLD, BAUD_SCRIPT, duration_s=0.1)
    assert_threads_print(runs, "arrived by 8 ms\n")


def test_infra_red_needs_line_of_sight_and_aperture() -> None:
    wall = "Solid { translation 1 0 0 boundingObject Box { size 0.1 1 1 } }"
    for blocked, aperture, expected in ((True, -1, 0), (False, -1, 1), (False, 0.5, 1)):
        a, b = _robots(
            f'type "infra-red" aperture {aperture}', 'type "infra-red"', wall=wall if blocked else ""
        )
        tx, rx = a.getDevice("tx"), b.getDevice("rx")
        rx.enable(8)
        tx.send(b"ir")
        b.step(8)
        assert rx.getQueueLength() == expected
    # the receiver lies off the emitter's cone (+y instead of +x)
    a, b = _robots('type "infra-red" aperture 0.5', 'type "infra-red"', rx_pose="translation 0 2 0")
    rx = b.getDevice("rx")
    rx.enable(8)
    a.getDevice("tx").send(b"ir")
    b.step(8)
    assert rx.getQueueLength() == 0


def test_strength_noise_is_multiplicative() -> None:
    a, b = _robots("", "signalStrengthNoise 0.2")
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    rx.enable(8)
    values = []
    for _ in range(300):
        tx.send(b"n")
        b.step(8)
        values.append(rx.getSignalStrength())
        rx.nextPacket()
    mean = sum(values) / len(values)
    sd = math.sqrt(sum((v - mean) ** 2 for v in values) / len(values))
    assert mean == pytest.approx(0.25, rel=0.05) and sd == pytest.approx(0.05, rel=0.2)


def test_simulation_reset_clears_the_queues() -> None:
    a, b = _robots()
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    rx.enable(8)
    tx.send(b"one")
    b.step(8)
    tx.send(b"queued")
    assert rx.getQueueLength() == 1
    b.simulation.reset()
    assert rx.getQueueLength() == 0
    b.step(8)
    assert rx.getQueueLength() == 0  # the emitter's queue was cleared too
