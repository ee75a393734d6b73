"""Several controllers, one result: robots are sampled and exchange packets in world order, not in the order
their controller processes happened to reach the simulation.

Every robot's noisy sensors draw from the simulation's one generator, and packets sent in the same step are
queued at a receiver one emitter after the other. Webots updates robots and their devices in scene-tree order,
so neither depends on how its controller processes are scheduled. Here each controller waits a given real time
(its ``customData``) before it enables its sensor or gets its emitter, so two runs differ only in which
controller registers first; both must print the same values, in world order.
"""

from __future__ import annotations

import contextlib
import io
import textwrap
from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

NOISY = """
    import time
    from controller import Robot
    robot = Robot()
    time.sleep(float(robot.getCustomData()))  # real time only: the simulation waits for every controller
    gps = robot.getDevice("gps")
    gps.enable(8)
    emitter = robot.getDevice("emitter")
    for _ in range(3):
        robot.step(8)
    print(f"{robot.getName()} {gps.getValues()[0]:.9f}")
    emitter.send(robot.getName())
    robot.step(8)
"""

LISTENER = """
    from controller import Robot
    robot = Robot()
    receiver = robot.getDevice("receiver")
    receiver.enable(8)
    for _ in range(6):
        robot.step(8)
    heard = []
    while receiver.getQueueLength():
        heard.append(receiver.getString())
        receiver.nextPacket()
    print("heard " + " ".join(heard))
"""


def _world(tmp_path: Path, delays: list[float]) -> Path:
    for name, script in (("noisy", NOISY), ("listener", LISTENER)):
        folder = tmp_path / "controllers" / name
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"{name}.py").write_text(textwrap.dedent(script))
    robots = "".join(
        f'Robot {{ translation {i} 0 0 name "r{i}" controller "noisy" customData "{delay}" '
        f'children [ GPS {{ accuracy 0.1 }} Emitter {{ }} ] }}\n'
        for i, delay in enumerate(delays)
    )
    listener = 'Robot { name "listener" controller "listener" children [ Receiver { } ] }\n'
    (tmp_path / "worlds").mkdir(exist_ok=True)
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 randomSeed 3 }\n" + robots + listener)
    return world


def _run(world: Path, isolation: str) -> list[str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert run_world(world, None, 0.2, isolation=isolation) == 0
    return out.getvalue().splitlines()


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_noise_and_packets_follow_world_order_not_controller_timing(tmp_path: Path, isolation: str) -> None:
    last_first = _run(_world(tmp_path / "a", [0.6, 0.3, 0.0]), isolation)  # r2 registers first, r0 last
    first_first = _run(_world(tmp_path / "b", [0.0, 0.3, 0.6]), isolation)  # r0 first
    readings = [line for line in last_first if line.startswith("r")]
    assert len(readings) == 3 and len({line.split()[1] for line in readings}) == 3  # three different draws
    assert sorted(last_first) == sorted(first_first)  # each robot's value, and what the listener heard
    assert "heard r0 r1 r2" in last_first
    if isolation == "process":  # and the output itself, in robot order at each synchronisation point
        assert last_first == first_first


RESET_NOISY = """
    import sys, time
    time.sleep(float(sys.argv[1]))            # before Robot(): the controllers join the run in another order
    from controller import Robot
    robot = Robot()
    gps = robot.getDevice("gps")
    gps.enable(8)
    for _ in range(8):
        robot.step(8)
        print(f"{robot.getName()} t={robot.getTime():.3f} {gps.getValues()[0]:.9f}")
"""

RESETTER = """
    from controller import Supervisor
    supervisor = Supervisor()
    for k in range(8):
        supervisor.step(8)
        if k == 3:
            supervisor.simulationReset()
"""


def test_after_a_reset_the_robots_resample_in_world_order(tmp_path: Path) -> None:
    """A reset samples every enabled sensor at once (Webots resets the sampling clocks); the robots do it in
    world order, whichever controller process joined the run first."""

    def world(folder: Path, delays: list[float]) -> Path:
        for name, script in (("noisy", RESET_NOISY), ("resetter", RESETTER)):
            (folder / "controllers" / name).mkdir(parents=True)
            (folder / "controllers" / name / f"{name}.py").write_text(textwrap.dedent(script))
        robots = "".join(f'Robot {{ translation {i} 0 0 name "r{i}" controller "noisy" controllerArgs [ "{d}" ] '
                         f"children [ GPS {{ accuracy 0.1 }} ] }}\n" for i, d in enumerate(delays))
        (folder / "worlds").mkdir()
        path = folder / "worlds" / "w.wbt"
        path.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 randomSeed 5 }\n" + robots
                        + 'Robot { name "resetter" controller "resetter" supervisor TRUE }\n')
        return path

    late = _run(world(tmp_path / "a", [0.5, 0.25, 0.0]), "process")
    early = _run(world(tmp_path / "b", [0.0, 0.25, 0.5]), "process")
    assert any("t=0.000" in line for line in late)  # the step that carries the reset returns at t = 0
    assert late == early
