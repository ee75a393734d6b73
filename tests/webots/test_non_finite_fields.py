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
