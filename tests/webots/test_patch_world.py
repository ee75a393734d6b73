"""Writing fitted Webots-twin knobs back into a .wbt: the edited world loads with the new values."""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.robots.binding import BUNDLED
from dualtwin.webots import load_world
from dualtwin.webots.writer import patch_webots_world

WORLD = BUNDLED / "cartpole" / "cartpole.wbt"


def test_patched_world_carries_the_knob_values(tmp_path: Path) -> None:
    knobs = {"joint.pole_hinge.damping": 0.07, "body.pole.mass": 0.25, "motor.wheel2.max_torque": 3.0,
             "contact.default:default.friction": 0.8, "contact.default:default.soft_cfm": 0.002,
             "world.erp": 0.3, "motor.wheel1.gain": -1.0}
    out = tmp_path / "cartpole.wbt"
    out.write_text(patch_webots_world(WORLD, knobs))
    world = load_world(out)
    assert world.find_def("pole_hinge")["jointParameters"]["dampingConstant"] == 0.07
    assert world.find_def("pole")["physics"]["mass"] == 0.25
    info = world.world_info()
    assert info is not None and info["ERP"] == 0.3
    contact = info["contactProperties"][0]
    assert contact["coulombFriction"] == [0.8] and contact["softCFM"] == 0.002
    motors = [n for top in world.nodes for n in top.walk() if n.type_name == "RotationalMotor"]
    assert {m["name"]: m["maxTorque"] for m in motors}["wheel2"] == 3.0
    original = WORLD.read_text().splitlines()
    patched = out.read_text().splitlines()
    assert len(set(patched) - set(original)) <= 12, "only the edited fields change"


def test_unknown_knob_field_is_an_error() -> None:
    with pytest.raises(ValueError, match="no .wbt field"):
        patch_webots_world(WORLD, {"sensor.pole sensor.noise": 0.1})
