"""A controller run in its own process (the default) sees the same controller API as one run in a thread: every
class, every public name of the same kind (a write-only property stays write-only, a read-only one read-only),
the same parameters and defaults. ``test_api_surface`` holds the thread classes to Webots' table; this holds the
generated classes of a controller process to the thread classes."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

from dualtwin.webots import controller as api
from dualtwin.webots.runner import run_world
from tests.support.api_shape import class_shape

ROOT = Path(__file__).resolve().parents[2]

#: Names whose difference is by design, with the reason.
BY_DESIGN = {
    # value objects: these are fields each instance carries (Webots' ctypes structure fields); the thread class
    # shows its dataclass defaults
    ("CameraRecognitionObject", "id"), ("CameraRecognitionObject", "number_of_colors"),
    # Webots' "first Robot of this process": each process has its own (test_controller_processes checks it)
    ("Robot", "created"), ("Supervisor", "created"),
    # the in-process handle on the simulation (not Webots API): a controller process has none
    ("Robot", "simulation"), ("Supervisor", "simulation"),
}


def test_a_controller_process_sees_the_thread_api(tmp_path: Path) -> None:
    out = tmp_path / "shape.json"
    script = f"""
        import json, sys
        sys.path.insert(0, {str(ROOT)!r})
        import controller
        from tests.support.api_shape import class_shape
        shapes = {{n: class_shape(getattr(controller, n)) for n in controller.__all__
                   if isinstance(getattr(controller, n), type)}}
        with open({str(out)!r}, "w") as f:
            json.dump(shapes, f)
    """
    folder = tmp_path / "controllers" / "dump"
    folder.mkdir(parents=True)
    (folder / "dump.py").write_text(textwrap.dedent(script))
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text('#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\nRobot { controller "dump" }\n')
    assert run_world(world, None, 0.016) == 0
    child = json.loads(out.read_text())
    differences = []
    for name in api.__all__:
        cls = getattr(api, name)
        if not isinstance(cls, type):
            continue
        assert name in child, f"controller.{name} is missing in a controller process"
        mine = class_shape(cls)
        for member in sorted(set(mine) | set(child[name])):
            if (name, member) not in BY_DESIGN and mine.get(member) != child[name].get(member):
                differences.append(f"{name}.{member}: thread {mine.get(member)}, process {child[name].get(member)}")
    assert not differences, "\n".join(differences)
