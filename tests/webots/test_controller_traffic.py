"""What a controller process exchanges with the simulation, as Webots' libController does: one message each way
per ``step`` (buffered commands out, the step's sensor values back), with readings identical to those of a
controller run as a thread of the simulation's process, bit for bit, even around supervisor edits.

Each test builds its own project (``worlds/w.wbt`` + ``controllers/c/c.py``) and runs it through
:func:`dualtwin.webots.runner.run_world` in both isolation modes.
"""

from __future__ import annotations

import os
import textwrap
import threading
from pathlib import Path

import pytest

from dualtwin.webots import controller_process
from dualtwin.webots.runner import run_world

ARM = """
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 anchor {x} 0 0 }}
      device [ RotationalMotor {{ name "arm::{i}" maxTorque 20 maxVelocity 5 multiplier {k} }}
               PositionSensor {{ name "sensor {i}" }} ]
      endPoint Solid {{
        translation {x} 0 -0.2
        children [ Shape {{ geometry Box {{ size 0.05 0.05 0.3 }} }} ]
        boundingObject Box {{ size 0.05 0.05 0.3 }}
        physics Physics {{ density -1 mass 0.5 }}
      }}
    }}"""

WORLD = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
DEF BOX Solid {{
  translation 2 0 0.5
  boundingObject Sphere {{ radius 0.1 }}
  physics Physics {{ density -1 mass 1 }}
}}
Robot {{
  translation 0 0 1
  rotation 0 0 1 0.4
  children [
    GPS {{ name "gps" }}
    InertialUnit {{ name "imu" }}
    {arms}
  ]
  boundingObject Box {{ size 0.2 0.2 0.1 }}
  physics Physics {{ density -1 mass 3 }}
  controller "c"
  controllerArgs [ "{steps}" ]
  supervisor TRUE
}}
"""


def _project(tmp_path: Path, script: str, steps: int = 40) -> Path:
    arms = "".join(ARM.format(i=i, x=0.15 * i, k=(1.0, -0.5)[i - 1]) for i in (1, 2))
    (tmp_path / "worlds").mkdir(parents=True, exist_ok=True)
    (tmp_path / "controllers" / "c").mkdir(parents=True, exist_ok=True)
    (tmp_path / "controllers" / "c" / "c.py").write_text(textwrap.dedent(script))
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(WORLD.format(arms=arms, steps=steps))
    return world


def _both(world: Path, capsys: pytest.CaptureFixture[str]) -> tuple[tuple[str, str], tuple[str, str]]:
    """(stdout, stderr) of the world run with controller processes, then with threads."""
    runs = []
    for isolation in ("process", "threads"):
        assert run_world(world, None, None, isolation=isolation) == 0
        captured = capsys.readouterr()
        runs.append((captured.out, captured.err))
    return runs[0], runs[1]


# ------------------------------------------------------------------ messages per step

LOOP = """
    import math, sys
    from controller import Supervisor
    robot = Supervisor()
    step = int(robot.getBasicTimeStep())
    motors = [robot.getDevice("arm::1"), robot.getDevice("arm::2")]
    sensors = [robot.getDevice("sensor 1"), robot.getDevice("sensor 2")]
    gps, imu = robot.getDevice("gps"), robot.getDevice("imu")
    for device in (*sensors, gps, imu):
        device.enable(step)
    for k in range(int(sys.argv[1])):
        motors[0].setPosition(0.5 * math.sin(0.1 * k))      # two motors set per step...
        motors[1].target_velocity = 1.0 + 0.01 * k
        robot.step(step)
        readings = (robot.getTime(), sensors[0].getValue(), sensors[1].value, gps.getValues(),
                    imu.getRollPitchYaw())                    # ...and four sensors and the clock read
    print("last", readings)
"""


def test_a_control_loop_costs_one_round_trip_per_step(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Setting 2 motors and reading 4 sensors and the clock per step: exactly one message answered per step
    (counted on the simulation's side: every answer is one write of its channel)."""
    sent: list[int] = []
    real_send = controller_process.Wire.send

    def counting_send(wire: controller_process.Wire, data: bytes) -> None:
        sent.append(len(data))
        real_send(wire, data)

    monkeypatch.setattr(controller_process.Wire, "send", counting_send)
    counts = []
    for steps in (30, 90):
        sent.clear()
        world = _project(tmp_path / str(steps), LOOP, steps)
        assert run_world(world, None, None) == 0
        assert "last (" in capsys.readouterr().out
        counts.append(len(sent))
    assert counts[1] - counts[0] == 60, counts  # 60 more steps, 60 more answers
    assert counts[0] < 30 + 30, counts  # start-up (the devices, enable, the first reads) takes a few


# ------------------------------------------------------------------ same readings as a thread

EDITS = """
    import math, sys
    from controller import Supervisor
    robot = Supervisor()
    step = int(robot.getBasicTimeStep())
    m1, m2 = robot.getDevice("arm::1"), robot.getDevice("arm::2")
    s1, s2 = robot.getDevice("sensor 1"), robot.getDevice("sensor 2")
    gps, imu = robot.getDevice("gps"), robot.getDevice("imu")
    for device in (s1, s2, gps, imu):
        device.enable(step)
    box = robot.getFromDef("BOX")
    where = box.getField("translation")
    me = robot.getSelf()

    def show(tag, scene=True):  # devices first: a stale motor target is read before anything else
        print(tag, repr(m2.getTargetPosition()), repr(m2.getVelocity()), repr(m1.getTargetPosition()),
              repr(s1.getValue()), repr(s2.getValue()), gps.getValues(), imu.getRollPitchYaw(),
              imu.getQuaternion(), s2.getSamplingPeriod())
        if scene:
            print(tag, repr(robot.getTime()), box.getPosition(), me.getVelocity(), repr(m2.target_velocity),
                  repr(m1.target_position), repr(s2.value))  # properties served as their getters

    for k in range(int(sys.argv[1])):
        m1.setPosition(0.4 * math.sin(0.3 * k))   # coupled: arm::2 follows at once (multiplier -0.5)
        show("set")
        if k % 2:
            m2.setVelocity(2.0 + k % 3)
        else:
            m2.target_velocity = 2.5 + k % 3     # a settable property: the same buffered command
        show("velocity")
        if k % 7 == 3:                             # a supervisor edit between two reads
            where.setSFVec3f([2.0, 0.05 * k, 0.5])
            show("moved")
        if k % 11 == 5:                            # disabling and re-enabling a sensor between reads
            s2.disable()
            show("disabled")
            s2.enable(2 * step)
            show("enabled")
        if k % 13 == 8:
            box.setVelocity([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
            show("pushed")
        if k == 25:
            robot.simulationReset()
        robot.step(step)
        show("step", scene=k % 2 == 0)
"""


def test_readings_equal_those_of_a_thread_bit_for_bit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Sensor readings, the clock, node poses and motor targets read around buffered commands (a coupled
    motor's target follows its sibling's before any step), supervisor edits, sensor enable/disable and a
    simulation reset: the same text, to the last bit of every float, in a process and in a thread."""
    world = _project(tmp_path, EDITS, 40)
    (process_out, process_err), (thread_out, thread_err) = _both(world, capsys)
    assert process_out.count("\n") == 2 * (40 * 3 + 6 + 4 * 2 + 3) - 20
    assert process_out == thread_out
    assert process_err == thread_err


ORDER = """
    import sys
    from controller import Robot
    robot = Robot()
    motor = robot.getDevice("arm::2")
    motor.setVelocity(1.0)
    robot.step(8)
    print("before", file=sys.stderr)
    motor.setVelocity(1e6)                 # over maxVelocity: Webots warns, here at the call's place
    print("after", file=sys.stderr)
    robot.step(8)
    motor.setVelocity(2e6)
"""


def test_a_buffered_command_warns_in_the_scripts_order(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A command sent with the next step still warns between what the script printed before and after it."""
    world = _project(tmp_path, ORDER)
    (_, process_err), (_, thread_err) = _both(world, capsys)
    lines = [line.split(":")[0] for line in process_err.splitlines()]
    # the load's warning (the coupled motors' limits harmonised) first, then two coupled motors' per command
    assert lines == ["Warning", "before", "Warning", "Warning", "after", "Warning", "Warning"], process_err
    assert "limits set from" in process_err.splitlines()[0]
    assert process_err == thread_err


def test_a_command_refused_at_the_call_raises_there(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Arguments a buffered command does not take as they are (a string, a keyword, a wrong count) go to the
    simulation at once, so the error is raised at the call, as in a thread."""
    refused = """
        from controller import Robot
        robot = Robot()
        motor, led = robot.getDevice("arm::1"), robot.getDevice("arm::2")
        for call in (lambda: motor.setPosition("far"), lambda: motor.setPosition(position=1.0),
                     lambda: motor.setPosition(1.0, 2.0), lambda: motor.setControlPID(1.0, 2.0)):
            try:
                call()
                print("accepted")
            except TypeError as error:
                print("TypeError")
            robot.step(8)
    """
    world = _project(tmp_path, refused)
    (process_out, _), (thread_out, _) = _both(world, capsys)
    assert process_out == thread_out
    assert process_out.split() == ["TypeError", "accepted", "TypeError", "TypeError"]


def test_step_answers_do_not_grow_with_handles_got_anew_each_step(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``robot.getSelf()`` gives a new node handle at each call: reading its position every step subscribes a
    new getter every step, and the subscriptions not read any more are dropped, so a step's answer (which
    carries every subscribed value) stays small however long the run."""
    sizes: list[int] = []
    real_send = controller_process.Wire.send

    def recording_send(wire: controller_process.Wire, data: bytes) -> None:
        sizes.append(len(data))
        real_send(wire, data)

    monkeypatch.setattr(controller_process.Wire, "send", recording_send)
    anew = """
        import sys
        from controller import Supervisor
        robot = Supervisor()
        for k in range(int(sys.argv[1])):
            robot.step(8)
            position = robot.getSelf().getPosition()
        print("last", position)
    """
    world = _project(tmp_path, anew, 400)
    assert run_world(world, None, None) == 0
    assert "last [" in capsys.readouterr().out
    assert len(sizes) > 3 * 400  # each step: getSelf() and the new handle's first read go to the simulation
    # after the API's description: at most two sweeps' worth of positions (all 400 would be about 12 kB)
    assert max(sizes[1:]) < 8_000, max(sizes[1:])


# ------------------------------------------------------------------ the channel itself


def test_a_frame_crosses_whole_when_the_kernel_takes_it_in_parts(monkeypatch: pytest.MonkeyPatch) -> None:
    """A frame (length and payload go out in one ``writev``) larger than a pipe holds, whose first write the
    kernel cuts short (as a signal can), still arrives whole and in order, followed by the next frame."""
    read_fd, write_fd = os.pipe()
    writer, reader = controller_process.Wire(read_fd, write_fd), controller_process.Wire(read_fd, write_fd)
    real_writev = os.writev
    cut: list[int] = []

    def short_writev(fd: int, buffers: list[bytes]) -> int:
        cut.append(fd)
        return real_writev(fd, [bytes(buffers[0])[:2]])  # two bytes of the length, nothing more

    monkeypatch.setattr(controller_process.os, "writev", short_writev)
    big = bytes(range(256)) * 4096  # 1 MiB: sixteen times what a pipe holds
    received: list[bytes | None] = []
    thread = threading.Thread(target=lambda: received.extend((reader.receive(), reader.receive())))
    thread.start()
    writer.send(big)
    writer.send(b"next")
    thread.join(timeout=30)
    os.close(read_fd)
    os.close(write_fd)
    assert cut == [write_fd, write_fd]
    assert received == [big, b"next"]
