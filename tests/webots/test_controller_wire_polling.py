"""The controller channel's polling wait (``Wire.spin``): frames arrive whole and in order as with a sleeping
read, the end of the channel is still seen, polling stops while the waits outlast its budget, and the budget
comes from the machine (or ``DUALTWIN_CONTROLLER_SPIN_US``). A run gives the same output either way."""

from __future__ import annotations

import os
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.webots import controller_host, controller_process
from dualtwin.webots.runner import run_world


def _pipe_wires(spin_us: float) -> tuple[controller_process.Wire, controller_process.Wire, int, int]:
    read_fd, write_fd = os.pipe()
    reader = controller_process.Wire(read_fd, write_fd)
    reader.spin(spin_us)
    return controller_process.Wire(read_fd, write_fd), reader, read_fd, write_fd


def test_a_polling_wire_passes_frames_whole_and_in_order_and_sees_the_end() -> None:
    writer, reader, read_fd, write_fd = _pipe_wires(2_000)
    big = bytes(range(256)) * 4096  # 1 MiB: many reads, the pipe full in between
    frames = [b"a", big, b"b" * 70_000, b"", b"c"]
    delays = [0.0, 0.0, 0.01, 0.0005, 0.02]  # inside and beyond the 2 ms budget

    def write() -> None:
        for frame, delay in zip(frames, delays, strict=True):
            time.sleep(delay)
            writer.send(frame)
        time.sleep(0.01)
        os.close(write_fd)

    thread = threading.Thread(target=write)
    thread.start()
    received = [reader.receive() for _ in frames]
    end = reader.receive()
    thread.join(timeout=30)
    os.close(read_fd)
    assert received == frames
    assert end is None  # the writer closed: the polling read sees the end as the sleeping one does


def test_polling_stops_while_the_waits_outlast_the_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    """The first long waits are polled for up to the budget; once the waits measured are longer than the budget
    the reader sleeps at once, so a slow world or controller burns no core. Counted by the reads each wait makes
    (the real ``readv``, counted on the way): a sleeping wait makes two (one before sleeping, one after), a polled
    one more. CPU time would not tell on a busy machine, where the polling thread yields its core to the others."""
    budget_s = 0.03
    writer, reader, read_fd, write_fd = _pipe_wires(budget_s * 1e6)
    rounds = 8
    go = [threading.Event() for _ in range(rounds)]
    reads = [0]
    real_readv = os.readv

    def counting_readv(fd: int, buffers: Any) -> int:
        if fd == read_fd:
            reads[0] += 1
        return real_readv(fd, buffers)

    def write() -> None:
        for event in go:
            event.wait(30)
            time.sleep(3 * budget_s)
            writer.send(b"x")

    monkeypatch.setattr(controller_process.os, "readv", counting_readv)
    thread = threading.Thread(target=write)
    thread.start()
    per_wait: list[int] = []
    for event in go:
        reads[0] = 0
        event.set()
        assert reader.receive() == b"x"
        per_wait.append(reads[0])
    thread.join(timeout=30)
    os.close(read_fd)
    os.close(write_fd)
    # the waits are 90 ms (more on a busy machine); their running mean starts at 0, moves an eighth of the way to
    # each new one and passes the 30 ms budget after the third or fourth: polled waits, then sleeping ones only
    polled = [n > 2 for n in per_wait]
    assert polled[0] and not any(polled[-4:]), per_wait
    assert polled == sorted(polled, reverse=True), per_wait  # once asleep, it stays asleep


def test_a_sleeping_wire_spends_no_cpu_waiting() -> None:
    """The control: a budget of 0 sleeps at once, as the channel did before polling."""
    writer, reader, read_fd, write_fd = _pipe_wires(0)
    thread = threading.Thread(target=lambda: (time.sleep(0.05), writer.send(b"x")))
    thread.start()
    start = time.thread_time()
    assert reader.receive() == b"x"
    spent = time.thread_time() - start
    thread.join(timeout=30)
    os.close(read_fd)
    os.close(write_fd)
    assert spent < 0.01, spent


def test_a_wire_on_one_descriptor_never_polls() -> None:
    """Polling makes the read descriptor non-blocking; on a socket that also carries the writes, a full buffer
    would then fail a write, so such a wire keeps sleeping reads."""
    import socket

    left, right = socket.socketpair()
    try:
        wire = controller_process.Wire(left.fileno())
        wire.spin(250)
        assert os.get_blocking(left.fileno())
        controller_process.Wire(right.fileno()).send(b"x")
        assert wire.receive() == b"x"
    finally:
        left.close()
        right.close()


def test_the_budget_comes_from_the_cores_or_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DUALTWIN_CONTROLLER_SPIN_US", raising=False)
    monkeypatch.setattr(controller_host.os, "sched_getaffinity", lambda pid: {0, 1})
    assert controller_host.spin_budget_us(1) == controller_process.SPIN_US > 0
    # a second controller on 2 cores: while the simulation steps, two polling controllers would take both cores
    assert controller_host.spin_budget_us(2) == 0
    monkeypatch.setattr(controller_host.os, "sched_getaffinity", lambda pid: set(range(16)))
    assert controller_host.spin_budget_us(15) == controller_process.SPIN_US
    assert controller_host.spin_budget_us(16) == 0
    monkeypatch.setattr(controller_host.os, "sched_getaffinity", lambda pid: {0})
    assert controller_host.spin_budget_us(1) == 0  # one core: a polling side would hold the core the other needs
    monkeypatch.setenv("DUALTWIN_CONTROLLER_SPIN_US", "40")
    assert controller_host.spin_budget_us(1) == controller_host.spin_budget_us(8) == 40
    for bad in ("fast", "-1", "nan", "1e9"):
        monkeypatch.setenv("DUALTWIN_CONTROLLER_SPIN_US", bad)
        with pytest.raises(DualtwinError, match="DUALTWIN_CONTROLLER_SPIN_US"):
            controller_host.spin_budget_us(1)


WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot {
  name "r"
  children [
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 1 0 }
      device [ RotationalMotor { name "m" maxTorque 5 } PositionSensor { name "s" } ]
      endPoint Solid { translation 0.2 0 0 boundingObject Sphere { radius 0.05 } physics Physics { } }
    }
  ]
  controller "c"
}
"""

CONTROLLER = """
from controller import Robot
robot = Robot()
motor, sensor = robot.getDevice("m"), robot.getDevice("s")
sensor.enable(8)
for k in range(200):
    motor.setPosition(0.01 * k)
    robot.step(8)
    print(k, repr(sensor.getValue()), robot.getTime())
"""


@pytest.mark.parametrize("budget", ["0", "250"])
def test_a_run_prints_the_same_whether_the_channel_polls_or_sleeps(
    budget: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str],
) -> None:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "w.wbt").write_text(WORLD)
    (tmp_path / "controllers" / "c").mkdir(parents=True)
    (tmp_path / "controllers" / "c" / "c.py").write_text(textwrap.dedent(CONTROLLER))
    outputs = []
    for isolation, spin in (("threads", "0"), ("process", budget)):
        monkeypatch.setenv("DUALTWIN_CONTROLLER_SPIN_US", spin)
        assert run_world(tmp_path / "worlds" / "w.wbt", None, None, isolation=isolation) == 0
        outputs.append(capfd.readouterr().out)
    assert len(outputs[0].splitlines()) == 200
    assert outputs[1] == outputs[0]


IMPORTING = """
from controller import Supervisor
sup = Supervisor()
children = sup.getRoot().getField("children")
for i in range(10):
    sup.step(8)
    if i == 2:
        children.importMFNodeFromString(-1, 'Robot { name "new" controller "child" }')
print("supervisor done", round(sup.getTime(), 3))
"""
CHILD = """
from controller import Robot
robot = Robot()
while robot.step(8) != -1:
    pass
"""


def test_a_controller_imported_beyond_the_cores_stops_the_polling(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str],
) -> None:
    """On 2 cores one controller polls; a supervisor that imports a Robot with a controller makes two, and the
    simulation's side stops polling on every wire from then on (the new one starts sleeping)."""
    monkeypatch.delenv("DUALTWIN_CONTROLLER_SPIN_US", raising=False)
    monkeypatch.setattr(controller_host.os, "sched_getaffinity", lambda pid: {0, 1})
    budgets: list[float] = []
    real_spin = controller_process.Wire.spin

    def recording_spin(wire: controller_process.Wire, microseconds: float) -> None:
        budgets.append(microseconds)
        real_spin(wire, microseconds)

    monkeypatch.setattr(controller_process.Wire, "spin", recording_spin)
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "w.wbt").write_text(
        '#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\nRobot { name "sup" controller "sup" supervisor TRUE }\n')
    for name, script in (("sup", IMPORTING), ("child", CHILD)):
        (tmp_path / "controllers" / name).mkdir(parents=True)
        (tmp_path / "controllers" / name / f"{name}.py").write_text(script)
    assert run_world(tmp_path / "worlds" / "w.wbt", None, 0.2) == 0
    assert "supervisor done 0.08" in capfd.readouterr().out
    # the supervisor's wire at its start, then lowered for every wire when the import made two controllers,
    # then the new controller's wire at its start
    assert budgets == [controller_process.SPIN_US, 0.0, 0.0], budgets
