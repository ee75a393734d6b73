"""The step order with several supervisors (webots-on-ode.md §6, §1.6 step 1): the translation/rotation writes
of a step are "queued and executed at the beginning of the next step (before the physics step), in scene-tree
order of supervisors", however the supervisors' controller processes are scheduled. Two supervisors write the
same Solid's translation in the same step: the one later in the scene tree writes last, so its value is the one
the Solid has after the step, whichever controller made its call first.

Each supervisor waits a given real time (its ``customData``) before its write, so the two runs differ only in which
write reaches the simulation first (no timing is asserted: the waits only order the calls)."""

from __future__ import annotations

import contextlib
import io
import textwrap
from pathlib import Path

import pytest

from dualtwin.webots.runner import run_world

WRITER = """
    import time
    from controller import Supervisor
    supervisor = Supervisor()
    supervisor.step(8)
    time.sleep(float(supervisor.getCustomData()))  # real time only: the simulation waits for every controller
    box = supervisor.getFromDef("BOX")
    box.getField("translation").setSFVec3f([float(supervisor.getName()[1:]), 0.0, 0.0])
    supervisor.step(8)
    print(f"{supervisor.getName()} sees x={box.getPosition()[0]:g}")
"""


def _world(folder: Path, delays: list[float]) -> Path:
    (folder / "controllers" / "writer").mkdir(parents=True)
    (folder / "controllers" / "writer" / "writer.py").write_text(textwrap.dedent(WRITER))
    robots = "".join(f'Robot {{ name "s{i + 1}" controller "writer" supervisor TRUE customData "{delay}" }}\n'
                     for i, delay in enumerate(delays))
    (folder / "worlds").mkdir()
    world = folder / "worlds" / "w.wbt"
    world.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 gravity 0 }\n" + robots
                     + "DEF BOX Solid { }\n")
    return world


@pytest.mark.parametrize("isolation", ["process", "threads"])
def test_translation_writes_of_one_step_are_executed_in_the_supervisors_scene_tree_order(
        tmp_path: Path, isolation: str) -> None:
    for name, delays in (("first_writes_first", [0.0, 0.4]), ("last_writes_first", [0.4, 0.0])):
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert run_world(_world(tmp_path / name, delays), None, 0.05, isolation=isolation) == 0
        # s1 is first in the scene tree and writes x = 1, s2 writes x = 2 after it: the box ends at x = 2
        assert sorted(out.getvalue().splitlines()) == ["s1 sees x=2", "s2 sees x=2"], name
