"""A restarted controller finds its rotating Lidar disabled, so the head stands still until it enables the lidar.

webots-devices.md §3.2: a rotating lidar's ``rotatingHead`` is turned by −2π·f·dt per step (our reading, in
``webots/lidar_head.py``: while the lidar is enabled); §11.3/§11.4 and ``tests/webots/test_controller_restart.py``:
a restart (``Node.restartController()``, a new ``controller`` field) ends the running controller and starts a
fresh one, which finds none of the robot's devices enabled. Before, the former controller's lidar handle went on
driving the head after its controller had ended.

Hand values (basicTimeStep 10 ms, defaultFrequency 10 Hz: 0.1 turn = −36° per step while enabled): the supervisor
robot's controller ``lid`` enables its lidar at t = 0 and steps to 10, 20, 30 ms (head at −36°, −72°, −108°), then
restarts itself: its next step says -1 and a fresh ``lid`` starts at 30 ms. That one steps three times without
enabling the lidar (the head stays at −108°), then enables it and steps twice (−144°, −180°).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

CONTROLLER = """
    import math, os
    from controller import Supervisor
    ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    sup = Supervisor()
    lidar, head = sup.getDevice("lidar"), sup.getFromDef("HEAD")
    start = round(sup.getTime() * 1000)

    def angle():  # the head's turn about z, in degrees within (-180, 180]
        r = head.getOrientation()
        a = round(math.degrees(math.atan2(r[3], r[0])))
        return 180 if a == -180 else a

    with open(os.path.join(ROOT, f"lid_{start}.txt"), "w") as log:
        log.write(f"start {angle()} period {lidar.getSamplingPeriod()}\\n")
        if start == 0:
            lidar.enable(10)
        for i in range(5):
            if start > 0 and i == 3:
                lidar.enable(10)
            if sup.step(10) == -1:
                log.write("-1\\n")
                break
            log.write(f"{angle()}\\n")
            if start == 0 and i == 2:
                sup.getSelf().restartController()
"""
WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 10 }
Robot { controller "lid" supervisor TRUE children [
  Lidar { name "lidar" horizontalResolution 8 fieldOfView 6.283 numberOfLayers 1 maxRange 5 type "rotating"
          rotatingHead DEF HEAD Solid { translation 0 0 0.05 } } ] }
"""


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_a_restarted_controller_finds_its_rotating_lidar_disabled_and_the_head_still(
    tmp_path: Path, isolation: str
) -> None:
    folder = tmp_path / "controllers" / "lid"
    folder.mkdir(parents=True)
    (folder / "lid.py").write_text(textwrap.dedent(CONTROLLER))
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(WORLD)
    assert run_world(world, None, 0.1, isolation=isolation) == 0
    logs = {p.stem: p.read_text().splitlines() for p in sorted(tmp_path.glob("lid_*.txt"))}
    assert logs["lid_0"] == ["start 0 period 0", "-36", "-72", "-108", "-1"]
    assert logs["lid_30"] == ["start -108 period 0", "-108", "-108", "-108", "-144", "180"]
