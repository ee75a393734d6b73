"""A joint axis with no direction (0 0 0, or not finite) in a world we did not write: ODE normalises every axis
it is given and aborts the whole process on such a one (SIGABRT: "assertion !bSafeNormalize3Fault"), so the
world gets the joint's default axis and one warning instead, and the run goes on.

The worlds run through ``dualtwin webots run`` in a child process, so an abort fails the test instead of ending
pytest. The control runs the same world with the default axis written out: its pendulum must swing exactly as
the degenerate one's."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.world_runs import run_world_cli

# A pendulum on each kind of joint, tilted so that gravity swings it about the default axis; the supervisor
# prints where each bob is after 20 steps.
WORLD = """#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 }}
Robot {{
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis {hinge} position 0.3 }}
      endPoint DEF HINGE_BOB Solid {{
        translation 0 -0.2955 0.0955 rotation 1 0 0 0.3
        children [ Shape {{ geometry DEF S Sphere {{ radius 0.05 }} }} ]
        boundingObject USE S physics Physics {{ density -1 mass 1 }}
      }}
    }}
    SliderJoint {{
      jointParameters JointParameters {{ axis {slider} }}
      endPoint DEF SLIDER_BOB Solid {{
        translation 1 0 0
        children [ Shape {{ geometry USE S }} ]
        boundingObject USE S physics Physics {{ density -1 mass 1 }}
        name "slider bob"
      }}
    }}
    Hinge2Joint {{
      jointParameters HingeJointParameters {{ axis 1 0 0 }}
      jointParameters2 JointParameters {{ axis {hinge2} }}
      endPoint DEF HINGE2_BOB Solid {{
        translation 2 0.1 -0.3
        children [ Shape {{ geometry USE S }} ]
        boundingObject USE S physics Physics {{ density -1 mass 1 }}
        name "hinge2 bob"
      }}
    }}
  ]
  controller "<extern>"
  supervisor TRUE
}}
"""

CONTROLLER = """from controller import Supervisor
s = Supervisor()
for _ in range(20):
    s.step(8)
for name in ("HINGE_BOB", "SLIDER_BOB", "HINGE2_BOB"):
    print(name, " ".join(repr(v) for v in s.getFromDef(name).getPosition()))
"""


@pytest.mark.parametrize("degenerate", ["0 0 0", "nan 0 0", "0 inf 0"])
def test_a_joint_axis_without_direction_takes_the_default_with_a_warning(tmp_path: Path,
                                                                         degenerate: str) -> None:
    bad = run_world_cli(tmp_path, "bad", WORLD.format(hinge=degenerate, slider=degenerate, hinge2=degenerate), CONTROLLER)
    assert bad.returncode == 0, bad.stderr
    # a zero axis is the joint's to judge; nan and inf are caught as the world is read (any field's number)
    said = "has no direction" if degenerate == "0 0 0" else "holds a non-finite number"
    warnings = [line for line in bad.stderr.splitlines() if said in line]
    assert len(warnings) == 3 and all(line.startswith("Warning: ") for line in warnings), bad.stderr
    if degenerate == "0 0 0":
        assert "using the default 1 0 0" in warnings[0] and "using the default 0 0 1" in warnings[1], warnings
    control = run_world_cli(tmp_path, "control", WORLD.format(hinge="1 0 0", slider="0 0 1", hinge2="0 0 1"), CONTROLLER)
    assert control.returncode == 0 and "has no direction" not in control.stderr, control.stderr
    assert bad.stdout == control.stdout and bad.stdout.count("BOB") == 3, (bad.stdout, control.stdout)
    # the joints are not stuck: the hinge's bob swung down about x, the slider's fell along z (a Hinge2Joint on a
    # body without Physics is kinematic: its bob stays where its motors put it)
    moved = {line.split()[0]: [float(v) for v in line.split()[1:]] for line in bad.stdout.splitlines()}
    assert moved["HINGE_BOB"][2] < 0.0955 - 0.01 and moved["SLIDER_BOB"][2] < -0.01, moved
