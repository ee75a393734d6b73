"""The Python-API part of the coverage page: how much of Webots R2023b's controller API matches, name for name, and
what the API answers differently from Webots (headless answers, Webots bugs we do not copy, what is still missing).

The figure is computed, not typed: ``tests/webots/test_api_surface.py`` holds Webots' surface as data (every class,
name, kind and signature) and its ``api_report()`` walks it against :mod:`dualtwin.webots.controller`. The page is
generated from a checkout, so the test file is read from there; without it the figure says so.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

__all__ = ["API_NOTES", "api_figure", "api_section"]

_TEST = Path(__file__).resolve().parents[3] / "tests" / "webots" / "test_api_surface.py"

#: (topic, what the API does headless or differently from Webots, and why)
API_NOTES: tuple[tuple[str, str, str], ...] = (
    # -- answers without a GUI (what Webots answers when no window, view or device exists)
    ("headless", "Mouse, MouseState", "no 3D view: the state never changes (u, v, x, y, z NaN; no button)"),
    ("headless", "Joystick", "never connected: 0 axes and POVs, getPressedButton() -1, model None"),
    ("headless", "Speaker", "no sound: nothing plays or is spoken; engine 'pico', language 'en-US'"),
    ("headless", "Skin", "the skeleton comes from a mesh Webots loads to render: 0 bones"),
    ("headless", "Pen", "no textures to paint: the ink settings are kept, nothing is drawn"),
    ("headless", "Robot.wwiSendText / wwiReceiveText", "no robot window: messages dropped, None received"),
    ("headless", "Robot.waitForUserInputEvent", "no user input: EVENT_NO_EVENT at once (Webots waits the timeout)"),
    ("headless", "Robot.setMode", "no remote-control plugin: an error, the robot stays in MODE_SIMULATION"),
    ("headless", "Supervisor.getSelected", "no scene-tree view: None"),
    ("headless", "Supervisor.setLabel", "no 3D view: checked, not drawn"),
    ("headless", "Supervisor.exportImage, movie*, animation*",
     "no 3D view: an error line, no file; movieFailed() True after a start"),
    ("headless", "Supervisor.virtualRealityHeadset*", "no headset: not used, NaN pose"),
    ("headless", "Node.moveViewpoint, Node.setVisibility", "no view to move or hide from: no effect"),
    ("headless", "Node.enablePoseTracking, Field.enableSFTracking, contact tracking",
     "accepted; every read is current, so streaming is not needed"),
    # -- Webots' own bugs: we do what Webots documents
    ("webots bug", "Node.addTorque", "Webots' wrapper calls the force function; ours applies the documented torque"),
    ("webots bug", "Node.addForceWithOffset",
     "Webots' wrapper loses the offset; ours applies the force at the offset (Solid frame)"),
    ("webots bug", "Speaker.setLanguage", "Webots' wrapper sets the engine; ours sets the language"),
    ("webots bug", "Keyboard.get_key", "Webots' helper spells Alt 'atl-'; ours writes 'alt-'"),
    # -- not Webots yet, or more permissive than Webots
    ("not yet", "Field.import*NodeFromString into a joint's device field",
     "the imported motor, sensor or brake is a device at once (see PositionSensor), but Robot.devices (the "
     "dictionary filled once when the Robot is made) does not list it; a removed sensor's handle keeps reading "
     "its axis"),
    ("not yet", "Field.importSFNodeFromString / removeSF of a Physics node",
     "the Solid's new body starts from rest, also when the Solid was moving as a kinematic joint's endPoint "
     "(what Webots gives it then is not checked)"),
    ("not yet", "Robot imported, or controller restarted, without a runner",
     "a Supervisor driven directly (no run_world) starts no controller (one warning at its next step) and a "
     "restarted one keeps running; 'dualtwin webots run' and run_world (processes or threads) start and restart "
     "them as Webots does"),
    ("not yet", "Supervisor.worldSave, Node.exportString",
     "Solids and joints are written where the physics has them, moving bodies with their velocities, and PROTO "
     "instances as PROTO nodes with the interface fields that differ from their defaults and their internal "
     "state as Webots' hidden fields (translation_N, rotation_N, linearVelocity_N, angularVelocity_N, "
     "position_N_M), which load back; not checked against files Webots wrote: it may leave out entries that "
     "did not change"),
    ("not yet", "Motion", "plays .motion files on the robot's motors (linear interpolation between poses)"),
    ("permissive", "Field.setSFBool/Int32/Float",
     "take any real scalar (Webots' isinstance checks refuse an int for setSFFloat and a NumPy integer for "
     "setSFInt32, with an error line); the SF vector setters take a list only, as Webots does"),
    ("permissive", "Robot.step, enable, setChannel...",
     "take floats and NumPy scalars (Webots raises ctypes.ArgumentError for them)"),
)


def api_figure() -> tuple[int, int] | None:
    """(names that match, names in Webots' table), or None when the test file is not in this checkout."""
    if not _TEST.is_file():
        return None
    spec = importlib.util.spec_from_file_location("_dualtwin_api_surface", _TEST)
    if spec is None or spec.loader is None:
        return None
    module = sys.modules.get(spec.name)
    if module is None:
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
        spec.loader.exec_module(module)
    matched, total, _problems = module.api_report()
    return int(matched), int(total)


def api_section() -> list[str]:
    """The page's lines about the Python API."""
    figure = api_figure()
    shown = f"**{figure[0]}/{figure[1]}**" if figure is not None else "not computed (no tests/ in this checkout)"
    lines = [
        "## Python controller API",
        "",
        "Names of Webots R2023b's Python `controller` API present with the same kind (method, plain attribute,",
        "read-only / settable / write-only property, constant) and the same parameters and defaults: "
        f"{shown} (`tests/webots/test_api_surface.py`, which walks the whole table).",
        "",
        "What the API answers differently from Webots: headless answers (what Webots answers without its GUI),",
        "Webots bugs we do not copy (we do what Webots documents), and what is not Webots yet.",
        "",
        "| kind | API | what it does here |",
        "|---|---|---|",
    ]
    lines += [f"| {kind} | `{name}` | {what.replace('|', '/')} |" for kind, name, what in API_NOTES]
    lines.append("")
    return lines
