"""Keyboard, step() results, argument conversion and EXTERNPROTO declarations: one test per fact of
webots-devices.md §11-§13 that no other test pinned.

Line numbers (D:n) cite /work/shared/reference/webots-devices.md; expected values come from it or from hand
computation, never from running this code.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Keyboard, Supervisor
from dualtwin.webots.physics import Simulation
from dualtwin.webots.proto_cache import cache_key, webots_assets_dir

TS = 8

WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
DEF ME Robot { supervisor TRUE children [
  HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 }
    device [ RotationalMotor { name "m" } ]
    endPoint Solid { translation 0.2 0 0 physics Physics { mass 1 } boundingObject Sphere { radius 0.05 } } }
  Display { name "d" width 4 height 4 }
  Emitter { name "tx" }
] }
DEF BALL Solid { translation 0 0 3 physics Physics { mass 1 } boundingObject Sphere { radius 0.1 } }
"""


def _sup() -> Supervisor:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(WORLD))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


# ------------------------------------------------------------------------------------------ §11.1 Keyboard


def test_get_keyboard_returns_the_robots_keyboard_created_disabled() -> None:
    # D:384-385: robot.getKeyboard() returns a Keyboard created disabled (Keyboard(0))
    sup = _sup()
    kb = sup.getKeyboard()
    assert kb is sup.keyboard and isinstance(kb, Keyboard) and kb.getSamplingPeriod() == 0


def test_keyboard_key_codes_and_modifier_bits() -> None:
    # D:386-389
    assert (Keyboard.END, Keyboard.HOME, Keyboard.LEFT, Keyboard.UP, Keyboard.RIGHT, Keyboard.DOWN) == (
        312, 313, 314, 315, 316, 317)
    assert (Keyboard.PAGEUP, Keyboard.PAGEDOWN) == (366, 367)
    assert (Keyboard.NUMPAD_HOME, Keyboard.NUMPAD_LEFT, Keyboard.NUMPAD_UP, Keyboard.NUMPAD_RIGHT,
            Keyboard.NUMPAD_DOWN, Keyboard.NUMPAD_END) == (375, 376, 377, 378, 379, 382)
    assert (Keyboard.KEY, Keyboard.SHIFT, Keyboard.CONTROL, Keyboard.ALT) == (0xFFFF, 0x10000, 0x20000, 0x40000)
    assert (Keyboard.SHIFT | Keyboard.ALT | ord("A")) & Keyboard.KEY == ord("A")  # mask with KEY strips modifiers


def test_a_disabled_keyboard_read_is_minus_one_with_an_error_every_time(capfd: pytest.CaptureFixture[str]) -> None:
    # D:391: "Disabled -> -1 + stderr error" (each call, as every other disabled-device read, D:27)
    kb = _sup().keyboard
    capfd.readouterr()
    for _ in range(3):
        assert kb.getKey() == -1
        assert "Error" in capfd.readouterr().err


# ------------------------------------------------------------------------------------------ §11.4 step()


def test_step_of_a_synchronous_robot_returns_zero() -> None:
    sup = _sup()  # D:411: 0 for synchronous robots
    assert sup.step(TS) == 0 and sup.step() == 0


def test_step_after_simulation_quit_returns_minus_one() -> None:
    sup = _sup()  # D:411-412: -1 when Webots is about to terminate the controller (quit)
    sup.simulationQuit(0)
    assert sup.step(TS) == -1


# ------------------------------------------------------------------------------------------ §12 arguments


@pytest.mark.parametrize("value", [2, True, 2.0, np.float64(2.0), np.float32(2.0), np.int64(2), np.array(2.0)],
                         ids=["int", "bool", "float", "float64", "float32", "int64", "0-d array"])
def test_float_setters_take_what_c_double_takes(value: object) -> None:
    # D:428-430: c_double(v) accepts int, bool, float, np.float64/float32, np.int64, 0-d arrays
    sup = _sup()
    motor = sup.getDevice("m")
    motor.setPosition(math.inf)
    motor.setVelocity(value)
    sup.getDevice("tx").setRange(value)
    assert motor.getVelocity() == float(value) and sup.getDevice("tx").getRange() == float(value)


def test_a_str_for_a_float_setter_is_a_type_error() -> None:
    # D:430: c_double raises TypeError for str
    with pytest.raises(TypeError):
        _sup().getDevice("m").setVelocity("1.0")


def test_vector_setters_take_numpy_arrays_of_any_numeric_dtype_and_tuples() -> None:
    # D:427, D:432: "(c_double*n)(*arr) accepts NumPy arrays of any numeric dtype and tuples" (Node.setVelocity)
    sup = _sup()
    ball = sup.getFromDef("BALL")
    ball.setVelocity(np.array([1, 0, 0, 0, 0, 0], dtype=np.int32))
    sup.step(TS)
    assert ball.getVelocity()[0] == pytest.approx(1.0, abs=1e-9)
    ball.setVelocity((0.0, 2.0, 0.0, 0.0, 0.0, 0.0))
    sup.step(TS)
    assert ball.getVelocity()[1] == pytest.approx(2.0, abs=1e-9)


def test_set_sf_float_takes_a_numpy_float64() -> None:
    # D:438: setSFFloat needs a float; np.float64 passes (it subclasses float)
    sup = _sup()
    field = sup.getFromDef("BALL").getField("physics").getSFNode().getField("mass")
    field.setSFFloat(np.float64(2.5))
    assert field.getSFFloat() == 2.5 and type(field.getSFFloat()) is float  # D:442: getters return Python types


def test_display_drawing_casts_numpy_coordinates_with_int() -> None:
    # D:436-437: Display drawing methods call int() first, so floats and NumPy values are fine
    d = _sup().getDevice("d")
    d.drawPixel(np.float32(1.9), np.int64(2))
    assert d.pixels[2, 1, 3] == 255 and int(d.pixels.sum()) == 4 * 255


# ------------------------------------------------------------------------------------------ §13 EXTERNPROTO


def test_cache_file_name_is_the_sha1_of_the_exact_url() -> None:
    # D:477-480: the example computed in the reference
    url = ("https://raw.githubusercontent.com/cyberbotics/webots/R2023b/projects/objects/backgrounds/protos/"
           "TexturedBackground.proto")
    assert cache_key(url) == "33f8b97a46f8139c858a8c8650e56cf7b99301ef"
    assert cache_key(url + " ") == hashlib.sha1((url + " ").encode()).hexdigest() != cache_key(url)


def test_webots_asset_cache_lies_under_the_linux_cache_location(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    # D:476: Linux ~/.cache/Cyberbotics/Webots/assets/ (QStandardPaths::CacheLocation honours XDG_CACHE_HOME)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert webots_assets_dir() == tmp_path / "Cyberbotics" / "Webots" / "assets"


def _box_proto(folder: Path, solid_name: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "Thing.proto").write_text(
        f'#VRML_SIM R2023b utf8\nPROTO Thing [ ]\n{{\n  Solid {{ name "{solid_name}" }}\n}}\n', encoding="utf-8")


def test_two_urls_for_one_proto_name_are_ambiguous_and_the_first_wins(tmp_path: Path) -> None:
    # D:459-460: "two URLs for one name -> 'ambiguous', first wins"
    _box_proto(tmp_path / "one", "first")
    _box_proto(tmp_path / "two", "second")
    world = load_world_text(
        '#VRML_SIM R2023b utf8\nEXTERNPROTO "one/Thing.proto"\nEXTERNPROTO "two/Thing.proto"\nThing { }\n',
        tmp_path / "w.wbt")
    assert world.nodes[0]["name"] == "first"
    assert any("ambiguous" in w for w in world.warnings)


def test_two_urls_for_one_proto_name_inside_a_proto_first_wins_too(tmp_path: Path) -> None:
    # D:459-460 for the declarations of a PROTO file
    _box_proto(tmp_path / "one", "first")
    _box_proto(tmp_path / "two", "second")
    (tmp_path / "Outer.proto").write_text(
        '#VRML_SIM R2023b utf8\nEXTERNPROTO "one/Thing.proto"\nEXTERNPROTO "two/Thing.proto"\n'
        "PROTO Outer [ ]\n{\n  Thing { }\n}\n", encoding="utf-8")
    world = load_world_text('#VRML_SIM R2023b utf8\nEXTERNPROTO "Outer.proto"\nOuter { }\n', tmp_path / "w.wbt")
    assert world.nodes[0]["name"] == "first"
