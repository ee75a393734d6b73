"""Emitter/Receiver and Display: one test per fact of webots-devices.md §5-§6 that no other test pinned.

Line numbers (D:n) cite /work/shared/reference/webots-devices.md; expected values come from it or from hand
computation, never from running this code.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Display, Robot, Runtime, Supervisor
from dualtwin.webots.physics import Simulation

TS = 8


def _sim(body: str) -> Simulation:
    text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {TS} randomSeed 1 gravity 0 }}\n{body}\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Simulation(load_world_text(text))


def _pair(emitter: str = "", receiver: str = "", rx_pose: str = "translation 2 0 0",
          extra: str = "", a_children: str = "", b_children: str = "") -> tuple[Robot, Robot]:
    """Robot A (emitter 'tx' at the origin) and robot B (receiver 'rx'); only B's controller steps."""
    sim = _sim(
        f"{extra}\n"
        f'Robot {{ name "a" children [ Emitter {{ name "tx" {emitter} }} {a_children} ] }}\n'
        f'Robot {{ name "b" {rx_pose} children [ Receiver {{ name "rx" {receiver} }} {b_children} ] }}'
    )
    runtime = Runtime(sim)
    a = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    a.cleanup()  # A's devices work, only B's controller waits for steps
    b = Robot(runtime=runtime, robot_node=sim.robots[1].node)
    return a, b


def _heard(emitter: str = "", receiver: str = "", **kw: str) -> int:
    a, b = _pair(emitter, receiver, **kw)
    rx = b.getDevice("rx")
    rx.enable(TS)
    a.getDevice("tx").send(b"x")
    b.step(TS)
    return int(rx.getQueueLength())


# ------------------------------------------------------------------------------------------ §5.1 fields


def test_emitter_field_defaults_range_infinite_channel_0_buffer_unlimited() -> None:
    # D:225-227: range -1 (infinite), maxRange -1, channel 0, bufferSize -1
    a, _ = _pair()
    tx = a.getDevice("tx")
    assert (tx.getRange(), tx.getChannel(), tx.getBufferSize()) == (-1, 0, -1)


def test_receiver_default_channel_is_0() -> None:
    _, b = _pair()  # D:229: Receiver channel 0
    assert b.getDevice("rx").getChannel() == 0


def test_emitter_aperture_counts_for_infra_red_only() -> None:
    # D:225: aperture is "infra-red only": a radio emitter with a narrow cone still reaches a receiver behind it
    assert _heard("aperture 0.1", "", rx_pose="translation -2 0 0") == 1


# ------------------------------------------------------------------------------------------ §5.2 pipeline


def test_a_packet_keeps_the_channel_current_when_it_was_sent() -> None:
    # D:235-236: "queued with the current channel": changing the channel after send does not re-route it
    a, b = _pair("channel 1", "channel 1")
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    rx.enable(TS)
    tx.send(b"on one")
    tx.setChannel(2)
    b.step(TS)
    assert rx.getQueueLength() == 1 and rx.getBytes() == b"on one"


def test_an_empty_packet_is_not_sent() -> None:
    # D:235: "send (controller): size >= 1"
    a, b = _pair()
    rx = b.getDevice("rx")
    rx.enable(TS)
    a.getDevice("tx").send(b"")
    b.step(TS)
    assert rx.getQueueLength() == 0


def test_a_robot_never_hears_its_own_emitter() -> None:
    # D:239-241: receivers must belong to another robot, never to the sender's robot
    sim = _sim('Robot { children [ Emitter { name "tx" } Receiver { name "rx" translation 1 0 0 } ] }')
    robot = Robot(simulation=sim, robot_node=sim.robots[0].node)
    rx = robot.getDevice("rx")
    rx.enable(TS)
    robot.getDevice("tx").send(b"self")
    robot.step(TS)
    assert rx.getQueueLength() == 0


def test_radio_and_infra_red_are_different_media() -> None:
    # D:240: same medium type required
    assert _heard('type "infra-red"', "") == 0
    assert _heard("", 'type "infra-red"') == 0
    assert _heard('type "infra-red"', 'type "infra-red"') == 1  # control


def test_infra_red_needs_the_receiver_in_its_own_aperture_cone() -> None:
    # D:243-245: both apertures are x-axis cones. Receiver B at x = 2: unturned, its x axis points away from
    # the emitter (which lies along its -x); turned by pi about z, it faces the emitter
    ir = 'type "infra-red"'
    assert _heard(ir, f"{ir} aperture 0.5") == 0
    assert _heard(ir, f"{ir} aperture 0.5", rx_pose="translation 2 0 0 rotation 0 0 1 3.14159") == 1


def test_infra_red_is_not_blocked_by_the_emitting_robots_own_solids() -> None:
    # D:243-244: "any hit Solid not of the emitting robot blocks it"; a box of robot A sits on the beam
    box = 'Solid { translation 1 0 0 boundingObject Box { size 0.1 1 1 } }'
    assert _heard('type "infra-red"', 'type "infra-red"', a_children=box) == 1


def test_infra_red_is_not_blocked_by_the_receiving_robots_solids() -> None:
    # D:244: "receiver's robot excluded by the same-robot rule"; B's box (B at x=2) lies at x=1 on the beam
    box = 'Solid { translation -1 0 0 boundingObject Box { size 0.1 1 1 } }'
    assert _heard('type "infra-red"', 'type "infra-red"', b_children=box) == 1


def test_infra_red_packets_obey_the_range_too() -> None:
    # D:245: "then both apertures ... and range are checked" (2 m apart)
    assert _heard('type "infra-red" range 1.5', 'type "infra-red"') == 0
    assert _heard('type "infra-red" range 2.5', 'type "infra-red"') == 1


def test_direction_noise_keeps_a_unit_direction() -> None:
    # D:247-248: noise added per component "before renormalising"
    a, b = _pair("", "directionNoise 0.3")
    rx = b.getDevice("rx")
    rx.enable(TS)
    for _ in range(20):
        a.getDevice("tx").send(b"d")
        b.step(TS)
        assert math.fsum(c * c for c in rx.getEmitterDirection()) == pytest.approx(1.0)
        rx.nextPacket()


def test_packets_reach_the_controller_at_the_receivers_sample() -> None:
    # D:249-250 with §0.1 (D:17-18): enable(24) at t=0 samples at t=24 ms, i.e. after the third 8 ms step
    a, b = _pair()
    rx = b.getDevice("rx")
    rx.enable(3 * TS)
    a.getDevice("tx").send(b"late")
    b.step(TS)
    b.step(TS)
    assert rx.getQueueLength() == 0
    b.step(TS)
    assert rx.getQueueLength() == 1


def test_packets_arrive_in_the_order_they_were_sent() -> None:
    # D:253: "Order preserved, packets atomic"
    a, b = _pair()
    rx = b.getDevice("rx")
    rx.enable(TS)
    for i in range(5):
        a.getDevice("tx").send(bytes([i]) * (i + 1))
    b.step(TS)
    got = []
    while rx.getQueueLength():
        got.append(rx.getBytes())
        rx.nextPacket()
    assert got == [bytes([i]) * (i + 1) for i in range(5)]


# ------------------------------------------------------------------------------------------ §5.3 API


def test_emitter_channel_outside_allowed_channels_is_refused(capfd: pytest.CaptureFixture[str]) -> None:
    # D:259: setChannel(c): c < -1 or not allowed -> error
    a, _ = _pair("channel 1 allowedChannels [1 3]")
    tx = a.getDevice("tx")
    capfd.readouterr()
    tx.setChannel(2)
    assert tx.getChannel() == 1 and capfd.readouterr().err != ""
    tx.setChannel(3)
    assert tx.getChannel() == 3


def test_receiver_channel_outside_allowed_channels_is_refused(capfd: pytest.CaptureFixture[str]) -> None:
    _, b = _pair("", "channel 1 allowedChannels [1 3]")  # D:231 Receiver allowedChannels; D:263 setChannel
    rx = b.getDevice("rx")
    capfd.readouterr()
    rx.setChannel(2)
    assert rx.getChannel() == 1 and capfd.readouterr().err != ""


def test_receiver_emitter_direction_is_a_list_of_three() -> None:
    a, b = _pair()  # D:263: getEmitterDirection()->list[3]
    rx = b.getDevice("rx")
    rx.enable(TS)
    a.getDevice("tx").send(b"x")
    b.step(TS)
    direction = rx.getEmitterDirection()
    assert type(direction) is list and direction == pytest.approx([-1.0, 0.0, 0.0])


def test_get_bools_unpacks_the_whole_packet() -> None:
    a, b = _pair()  # D:262: getFloats/getInts/getBools() unpack the whole packet
    rx = b.getDevice("rx")
    rx.enable(TS)
    a.getDevice("tx").send(bytes([1, 0, 1]))
    b.step(TS)
    assert list(rx.getBools()) == [True, False, True]


# ------------------------------------------------------------------------------------------ §6 Display


def _display(fields: str = "width 8 height 4") -> tuple[Supervisor, Display]:
    sim = _sim(f'Robot {{ supervisor TRUE children [ Display {{ name "d" {fields} }} ] }}')
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    return sup, sup.getDevice("d")


def test_display_image_format_constants() -> None:
    # D:290: RGB=3, RGBA=4, ARGB=5, BGRA=6, ABGR=7
    assert (Display.RGB, Display.RGBA, Display.ARGB, Display.BGRA, Display.ABGR) == (3, 4, 5, 6, 7)


def test_display_draw_polygon_is_closed() -> None:
    # D:288: drawPolygon(xs, ys) "auto-closed": the edge from the last point back to the first is drawn
    _, d = _display()
    d.drawPolygon([0, 3, 3], [0, 0, 3])  # closing edge (3,3) -> (0,0) is the diagonal
    px = d.pixels
    assert all(px[i, i, 3] == 255 for i in range(4))
    assert px[0, 1, 3] == 255 and px[2, 3, 3] == 255 and px[1, 0, 3] == 0


def test_display_image_new_reorders_argb_and_abgr() -> None:
    # D:290-291: imageNew(data, format, width, height); ARGB / ABGR byte orders
    _, d = _display()
    argb = d.imageNew(bytes([128, 10, 20, 30]), Display.ARGB, 1, 1)
    abgr = d.imageNew(bytes([128, 30, 20, 10]), Display.ABGR, 1, 1)
    d.imagePaste(argb, 0, 0, False)
    d.imagePaste(abgr, 1, 0, False)
    assert d.pixels[0, 0].tolist() == d.pixels[0, 1].tolist() == [10, 20, 30, 128]


def test_display_image_handles_are_ints_returned_at_once() -> None:
    # D:294: handles are created client-side (ids 1, 2, ...), so new/load/copy return immediately
    _, d = _display()
    first, second = d.imageCopy(0, 0, 2, 2), d.imageNew(bytes(4), Display.RGBA, 1, 1)
    assert type(first) is int and type(second) is int and 0 < first < second


def test_display_is_cleared_by_simulation_reset() -> None:
    # D:296: "Reset clears it"; D:402: reset matrix clears the Display
    sup, d = _display()
    d.fillRectangle(0, 0, 8, 4)
    sup.simulationReset()
    sup.step(TS)
    assert int(d.pixels.max()) == 0
