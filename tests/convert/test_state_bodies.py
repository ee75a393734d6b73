"""Which free bodies are state, in both twins of a converted world. The Webots twin's state holds its robot and the
world's top-level Solids with a DEF and a body (twins/webots_state.StateStructure); a loose Solid without a DEF, or one
inside a top-level Group, is scenery there. The converter names every body (by DEF, else by ``name``), so the MuJoCo
twin used to count those as state too, and the Webots twin refused its state ("no body ..."). The converted model now
lists them (``webots_scenery``) and the MuJoCo twin's state leaves them out; a DEF'd top-level loose box stays state
in both (the control)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.converted_twins import converted_twins, world_text

FLOOR = "DEF FLOOR Solid { boundingObject Plane { size 10 10 } }\n"
ROBOT = ('DEF R Robot { translation 0 0 0.1 controller "<extern>" children [ GPS { name "gps" } ] boundingObject Box { size 0.2 0.2 0.2 } '
         "physics Physics { density -1 mass 1 } }\n")


def _box(x: float, head: str = "") -> str:
    return (f"{head}Solid {{ translation {x} 0 0.05 name \"crate{x:g}\" boundingObject Box {{ size 0.1 0.1 0.1 }} "
            "physics Physics { density -1 mass 0.5 } }\n")


@pytest.mark.parametrize(("scene", "state"), [
    (_box(1.0, "DEF BOX "), {"R", "BOX"}),                       # control: a top-level DEF'd box is state in both
    (_box(1.0), {"R"}),                                          # no DEF: scenery
    ("Group { children [ " + _box(1.0, "DEF INNER ") + "] }\n", {"R"}),  # DEF'd, but not at the top level
    (_box(1.0, "DEF BOX ") + _box(2.0), {"R", "BOX"}),
])
def test_both_twins_hold_the_same_free_bodies_and_take_each_others_state(tmp_path: Path, scene: str,
                                                                          state: set[str]) -> None:
    with converted_twins(world_text(FLOOR + ROBOT + scene, "basicTimeStep 4"), tmp_path, 0.02, robot="R") as (
            _, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        states = webots.get_state(), mujoco_twin.get_state()
        assert [set(s.bodies) for s in states] == [state, state]
        webots.set_state(states[1])
        mujoco_twin.set_state(states[0])


DOOR = ("DEF FRAME Solid { translation 2 0 0 children [ DEF HINGE HingeJoint { jointParameters HingeJointParameters "
        "{ axis 0 0 1 } endPoint DEF DOOR Solid { translation 0.3 0 0.5 boundingObject Box { size 0.6 0.05 1 } "
        "physics Physics { density -1 mass 2 } } } ] boundingObject Box { size 0.1 0.1 0.1 } }\n")


def test_a_door_hinged_in_the_environment_is_no_joint_of_either_twins_state(tmp_path: Path) -> None:
    # the Webots twin's state holds its robot's joints only; the door's HINGE (a joint of the static environment, no
    # robot's) was a state joint of the MuJoCo twin, which made the Webots twin refuse its state. Control: R's own
    # state, which both twins hold alike, passes
    with converted_twins(world_text(FLOOR + ROBOT + DOOR, "basicTimeStep 4"), tmp_path, 0.02, robot="R") as (
            _, webots, mujoco_twin):
        webots.step()
        mujoco_twin.step()
        states = webots.get_state(), mujoco_twin.get_state()
        assert [set(s.joint_positions) for s in states] == [set(), set()]
        assert [set(s.bodies) for s in states] == [{"R"}, {"R"}]
        webots.set_state(states[1])
        mujoco_twin.set_state(states[0])
