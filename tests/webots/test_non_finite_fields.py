"""A world (or PROTO) number that is nan or inf: the tokenizer reads them (a world saved from a diverged simulation
holds them), but no Webots field takes one, and ODE aborts the whole process (SIGABRT in ``dxNormalize4``) on a
non-finite anchor or centre of mass. The field keeps its default, with one warning naming where it is.

The runs go through ``dualtwin webots run`` in a child process, so an abort fails the test instead of ending
pytest. The control is the same world without the bad values: it must move exactly alike."""

from __future__ import annotations

from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from tests.support.world_runs import run_world_cli

WORLD = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
Robot {{
  rotation 0 0 1 0{rotation}
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ {anchor} }}
      device [ RotationalMotor {{ name "m" {torque} }} ]
      endPoint DEF BOB Solid {{
        translation 0 -0.2955 0.0955 rotation 1 0 0 0.3
        children [ Shape {{ geometry DEF S Sphere {{ radius 0.05 }} }} ]
        boundingObject USE S physics Physics {{ density -1 mass 1 {com} }}
      }}
    }}
  ]
  controller "<extern>"
  supervisor TRUE
}}
"""
BAD = {"rotation": " rotation nan 0 1 0", "anchor": "anchor nan 0 0", "torque": "maxTorque inf",
       "com": "centerOfMass [ 0 -inf 0 ]"}

CONTROLLER = """from controller import Supervisor
s = Supervisor()
for _ in range(20):
    s.step(8)
print("BOB", " ".join(repr(v) for v in s.getFromDef("BOB").getPosition()))
"""


@pytest.mark.parametrize("field", sorted(BAD))
def test_a_non_finite_number_keeps_the_fields_default_and_says_where(tmp_path: Path, field: str) -> None:
    bad = run_world_cli(tmp_path, "bad", WORLD.format(**{k: (BAD[k] if k == field else "") for k in BAD}), CONTROLLER)
    assert bad.returncode == 0, bad.stderr
    lines = [line for line in bad.stderr.splitlines() if "non-finite number" in line]
    assert len(lines) == 1 and lines[0].startswith("Warning: ") and "bad.wbt:" in lines[0], bad.stderr
    assert "using its default" in lines[0]
    control = run_world_cli(tmp_path, "control", WORLD.format(**dict.fromkeys(BAD, "")), CONTROLLER)
    assert control.returncode == 0 and "non-finite" not in control.stderr, control.stderr
    assert bad.stdout == control.stdout and bad.stdout.startswith("BOB "), (bad.stdout, control.stdout)


def test_the_warnings_defaults_and_a_non_finite_hidden_field() -> None:
    """In-process: one warning per bad field, their defaults kept, a saved hidden state that is not finite
    ignored (the node starts as if it had none), and the finite world unchanged (the control)."""
    world = load_world_text(WORLD.format(**BAD))
    params = world.nodes[1].fields["children"][0].fields["jointParameters"]
    assert params.fields["anchor"] == (0.0, 0.0, 0.0)
    assert world.nodes[1].fields["rotation"] == (0.0, 0.0, 1.0, 0.0)
    assert len([w for w in world.warnings if "non-finite" in w]) == len(BAD), world.warnings
    assert not load_world_text(WORLD.format(**dict.fromkeys(BAD, ""))).warnings
    hidden = load_world_text("#VRML_SIM R2023b utf8\nSolid { hidden translation_1 nan 0 1 hidden position_0_0 0.5 }")
    assert hidden.nodes[0].hidden == {"position_0_0": 0.5}
    assert [w for w in hidden.warnings if "hidden field 'translation_1' holds a non-finite number" in w]


EDITS = {
    "rotation axis inf": "box.getField('rotation').setSFRotation([inf, 0, 0, 1])",  # was SIGABRT in dxOrthogonalizeR
    "rotation axis overflow": "box.getField('rotation').setSFRotation([1e308, 1e308, 1e308, 1])",
    "rotation angle inf": "box.getField('rotation').setSFRotation([0, 0, 1, inf])",  # was 'math domain error'
    "translation inf": "box.getField('translation').setSFVec3f([inf, 0, 0])",  # was SimulationUnstable
    "anchor inf": "s.getFromDef('HJ').getField('jointParameters').getSFNode().getField('anchor')"
                  ".setSFVec3f([0, -inf, 0])",
    "joint position inf": "s.getFromDef('HJ').getField('jointParameters').getSFNode().getField('position')"
                          ".setSFFloat(inf)",
}

EDIT_WORLD = WORLD.format(rotation="", anchor="", torque="", com="").replace(
    "    HingeJoint {", "    DEF HJ HingeJoint {") + """DEF BOX Solid {
  translation 1 0 0.5
  children [ Shape { geometry DEF B Box { size 0.1 0.1 0.1 } } ]
  boundingObject USE B physics Physics { }
}
"""

EDIT_CONTROLLER = """from controller import Supervisor
inf = float("inf")
s = Supervisor()
box = s.getFromDef("BOX")
s.step(8)
EDIT
for _ in range(20):
    s.step(8)
print("BOB", " ".join(repr(v) for v in s.getFromDef("BOB").getPosition()))
print("BOX", " ".join(repr(v) for v in box.getPosition()), box.getField("rotation").getSFRotation())
"""


@pytest.mark.parametrize("edit", sorted(EDITS))
def test_a_supervisor_setting_an_infinite_field_value_is_refused(tmp_path: Path, edit: str) -> None:
    """A Field setter given ±inf (or an axis whose length overflows) prints one warning and keeps the field, as
    for NaN: the run goes on exactly like the control run without the edit. Before, the value reached ODE:
    an infinite rotation axis aborted the whole process (SIGABRT), an infinite angle raised 'math domain
    error' at the call and an infinite translation made the next step raise SimulationUnstable."""
    bad = run_world_cli(tmp_path, "bad", EDIT_WORLD, EDIT_CONTROLLER.replace("EDIT", EDITS[edit]))
    assert bad.returncode == 0, bad.stderr
    lines = [line for line in bad.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "wrong type or length" in lines[0] and "ignored" in lines[0], bad.stderr
    control = run_world_cli(tmp_path, "control", EDIT_WORLD, EDIT_CONTROLLER.replace("EDIT", "pass"))
    assert control.returncode == 0 and not control.stderr.strip(), control.stderr
    assert bad.stdout == control.stdout and bad.stdout.startswith("BOB "), (bad.stdout, control.stdout)


def test_an_image_size_beyond_a_render_target_keeps_the_fields_default() -> None:
    """A device's image buffer is allocated from its width and height (a Lidar's from its resolution and
    layers): a world's ``Display { width 200000 height 200000 }`` asked for 149 GiB (MemoryError in the
    controller, or the machine out of memory). Beyond 16384 (OpenGL's usual texture limit, the most a Webots
    render target can be) the field keeps its default, with one warning naming where it is; 16384 itself is
    kept."""
    world = load_world_text("""#VRML_SIM R2023b utf8
Robot { children [
  Display { name "d" width 200000 height 200000 }
  Camera { name "c" width 16385 height 16384 }
  RangeFinder { name "r" width 20 height 1000000 }
  Lidar { name "l" horizontalResolution 100000000 numberOfLayers 100000 }
] }
""")
    display, camera, finder, lidar = (node.fields for node in world.nodes[0].fields["children"])
    assert (display["width"], display["height"]) == (64, 64)
    assert (camera["width"], camera["height"]) == (64, 16384)
    assert (finder["width"], finder["height"]) == (20, 64)
    assert (lidar["horizontalResolution"], lidar["numberOfLayers"]) == (512, 4)
    lines = [w for w in world.warnings if "is larger than 16384; using its default" in w]
    assert len(lines) == 6 and len(world.warnings) == 6, world.warnings
    assert any(":3:" in w and "Display.width 200000" in w for w in lines), lines
