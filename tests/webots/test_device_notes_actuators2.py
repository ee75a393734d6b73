"""The documented behaviours of Webots R2023b's Emitter/Receiver, Keyboard, Mouse and Motion that no other test
covers, one small test each (the first part, Robot and the joint devices, is test_device_notes_actuators.py).
References: R = /work/shared/reference/webots-python-api.md, D = .../webots-devices.md (line numbers as of this
writing)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Emitter, Keyboard, Motion, Mouse, Robot, Runtime
from dualtwin.webots.keyboard import KeyEvent, KeyScript
from dualtwin.webots.physics import Simulation

TS = 8


def _radio() -> tuple[Robot, Robot]:
    """Robot A (emitter) and robot B (receiver, whose controller steps), 2 m apart."""
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "a" children [ Emitter { name "tx" maxRange 5 } ] }
Robot { name "b" translation 2 0 0 children [ Receiver { name "rx" } ] }
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    runtime = Runtime(sim)
    a = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    a.cleanup()
    b = Robot(runtime=runtime, robot_node=sim.robots[1].node)
    b.getDevice("rx").enable(TS)
    return a, b


# ------------------------------------------------------------------ Emitter / Receiver


def test_send_returns_none() -> None:
    # D:256 send "returns None in Python (C result dropped)"
    a, _ = _radio()
    assert a.getDevice("tx").send(b"x") is None


def test_a_str_is_sent_cut_to_its_length_in_characters() -> None:
    # D:254-255 "str UTF-8-encoded but sent with len(str) characters (non-ASCII truncated — QUIRK)"; R:573
    a, b = _radio()
    a.getDevice("tx").send("hé")  # 3 UTF-8 bytes, 2 characters
    b.step(TS)
    rx = b.getDevice("rx")
    assert rx.getBytes() == "hé".encode()[:2] and rx.getDataSize() == 2


def test_bools_are_packed_as_ints() -> None:
    # D:255 "list/tuple packed d (floats) or i (ints; bools too — QUIRK)"
    a, b = _radio()
    a.getDevice("tx").send((True, False, True))
    b.step(TS)
    rx = b.getDevice("rx")
    assert rx.getDataSize() == 12 and rx.getInts() == (1, 0, 1)


def test_a_channel_below_broadcast_is_an_error_and_ignored(capfd: pytest.CaptureFixture[str]) -> None:
    # D:256 setChannel(c) "(c < −1 or not allowed → error)"; R:564 CHANNEL_BROADCAST=-1 is a channel
    a, b = _radio()
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    tx.setChannel(Emitter.CHANNEL_BROADCAST)
    rx.channel = 4
    capfd.readouterr()
    tx.setChannel(-2)
    rx.setChannel(-3)
    assert tx.getChannel() == -1 and rx.getChannel() == 4
    assert capfd.readouterr().err.count("\n") == 2


def test_set_range_minus_one_means_max_range() -> None:
    # D:257 "getRange/setRange(r) (−1 ⇒ maxRange; clipped to maxRange)"
    a, _ = _radio()
    tx = a.getDevice("tx")
    tx.setRange(1.0)
    assert tx.getRange() == 1.0
    tx.range = -1
    assert tx.getRange() == 5.0


def test_data_size_of_an_empty_queue_is_minus_one_with_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # D:260 "getDataSize() (−1 + error if empty)"
    _, b = _radio()
    capfd.readouterr()
    assert b.getDevice("rx").getDataSize() == -1
    assert capfd.readouterr().err != ""


def test_next_packet_on_an_empty_queue_does_nothing() -> None:
    # D:258 "nextPacket() (no-op if empty)"
    _, b = _radio()
    rx = b.getDevice("rx")
    rx.nextPacket()
    assert rx.getQueueLength() == 0


def test_next_packet_drops_the_head_packet() -> None:
    # R:591 nextPacket "drop the head packet"; R:582 "Packets queue; read the head packet, then nextPacket()"
    a, b = _radio()
    tx, rx = a.getDevice("tx"), b.getDevice("rx")
    tx.send("one")
    tx.send("two")
    b.step(TS)
    assert rx.getQueueLength() == 2 and rx.getString() == "one" and rx.getString() == "one"
    rx.nextPacket()
    assert rx.queue_length == 1 and rx.string == "two"


def test_get_data_is_the_deprecated_alias_of_get_string() -> None:
    # R:594 getData "str | DEPRECATED alias of getString"; D:259
    a, b = _radio()
    a.getDevice("tx").send("payload")
    b.step(TS)
    rx = b.getDevice("rx")
    assert rx.getData() == rx.getString() == "payload" and rx.data == "payload"


# ------------------------------------------------------------------ Keyboard, Mouse


def _robot() -> Robot:
    text = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { children [
  HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }
    device [ RotationalMotor { name "m" } PositionSensor { name "s" } ]
    endPoint Solid { translation 0.2 0 0 physics Physics { mass 1 } boundingObject Sphere { radius 0.05 } } }
] }
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return Robot(simulation=sim, robot_node=sim.robots[0].node)


def test_keyboard_none_enables_at_the_basic_time_step_and_zero_is_disabled() -> None:
    # R:398 Keyboard __init__ "0 = disabled (what Robot uses); None = basic step"
    robot = _robot()
    assert Keyboard().getSamplingPeriod() == TS and Keyboard(0).getSamplingPeriod() == 0
    assert robot.keyboard.getSamplingPeriod() == 0


def test_keys_come_one_by_one_then_minus_one_and_are_cleared_at_the_step_end() -> None:
    # D:390-391 "successive getKey() calls return them then −1; the list is cleared at each step end";
    # R:403 getKeyCode "same as getKey"
    robot = _robot()
    kb = robot.keyboard
    kb.enable(TS)
    kb._keys = [Keyboard.UP, Keyboard.SHIFT | ord("A")]
    assert kb.getKey() == Keyboard.UP and kb.getKeyCode() == Keyboard.SHIFT | ord("A") and kb.getKey() == -1
    kb._keys = [Keyboard.DOWN]
    robot.step(TS)
    assert kb.getKey() == -1


def test_a_sample_holds_at_most_seven_keys() -> None:
    # R:402 getKey "<= 7 per sample"; D:390 "Each sample delivers up to 7 simultaneously pressed keys"
    script = KeyScript([KeyEvent(0.0, ord("A") + i, None) for i in range(9)])
    assert len(script.keys_at(0.0)) == 7


def test_a_disabled_mouse_read_prints_an_error(capfd: pytest.CaptureFixture[str]) -> None:
    # R:36 shared semantics (the robot's Mouse is created disabled, R:62); D:27 "`Error: ...`"; R:843 x/y/z "NaN unless 3D position enabled"
    robot = _robot()
    capfd.readouterr()
    state = robot.mouse.getState()
    err = capfd.readouterr().err
    assert err.startswith("Error: ") and "called for a disabled device" in err
    assert math.isnan(state.x) and robot.mouse.is3dPositionEnabled() is False
    mouse = Mouse()
    assert mouse.getSamplingPeriod() == TS


# ------------------------------------------------------------------ Motion


def _motion(tmp_path: Path) -> tuple[Robot, Motion]:
    path = tmp_path / "turn.motion"
    path.write_text("#WEBOTS_MOTION,V1.0,m\n00:00:000,Pose1,0\n00:00:080,Pose2,0.8\n")
    robot = _robot()
    return robot, Motion(str(path))


def test_motion_duration_and_time_are_in_ms(tmp_path: Path) -> None:
    # R:908-909 getDuration "int | ms", getTime "int | ms"
    robot, motion = _motion(tmp_path)
    motion.play()
    for _ in range(3):
        robot.step(TS)
    assert motion.getDuration() == 80 and motion.getTime() == 24 and type(motion.getTime()) is int


def test_motion_stop_pauses_and_play_resumes(tmp_path: Path) -> None:
    # R:903-904 play/stop
    robot, motion = _motion(tmp_path)
    motion.play()
    robot.step(TS)
    motion.stop()
    for _ in range(3):
        robot.step(TS)
    assert motion.getTime() == TS and not motion.isOver()
    motion.play()
    robot.step(TS)
    assert motion.getTime() == 2 * TS


def test_motion_set_time_moves_the_playback_position(tmp_path: Path) -> None:
    # R:910 setTime; R:897 time is a settable property
    robot, motion = _motion(tmp_path)
    motion.setTime(40)
    assert motion.getTime() == 40
    motion.time = 80
    assert motion.time == 80 and motion.isOver()


def test_motion_in_reverse_runs_time_backwards_and_is_over_at_the_start(tmp_path: Path) -> None:
    # R:906 setReverse; R:907 isOver
    robot, motion = _motion(tmp_path)
    motion.setTime(80)
    motion.setReverse(True)
    motion.play()
    robot.step(TS)
    assert motion.getTime() == 80 - TS and not motion.isOver()
    for _ in range(20):
        robot.step(TS)
    assert motion.getTime() == 0 and motion.isOver()


def test_motion_in_a_loop_is_never_over(tmp_path: Path) -> None:
    # R:905 setLoop; R:907 isOver
    robot, motion = _motion(tmp_path)
    motion.setLoop(True)
    motion.play()
    times = []
    for _ in range(15):
        robot.step(TS)
        times.append(motion.getTime())
        assert not motion.isOver()
    assert max(times) <= 80 and times[-1] < times[8]  # it started again
