"""Each robot/environment contact takes the ContactProperties of its own two contactMaterials (on-ODE §2.1-2.3),
whatever other materials the world holds. MuJoCo mixes a contact's parameters from its two geoms (the larger
friction, the mean solref and solimp), so the converter gives each geom the values of one pair; for a pair that
mixing does not reproduce it now writes an explicit MuJoCo ``<pair>`` with that pair's values. Before, a robot geom
took its pair with the first environment material in the file: a default-material wall listed before an icy floor
gave the robot on the ice the default friction 1 instead of 0.05.

Hand computation: a 1 kg box sliding at 1 m/s on the ice (coulombFriction 0.05) decelerates at 0.05 g =
0.4905 m/s^2 and after 0.8 s has gone 1 x 0.8 - 0.4905 x 0.8^2 / 2 = 0.643 m (it stops only after 2.04 s); 1 cm
is allowed for the two contact models. With friction 1 it would stop within 5 cm.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from dualtwin.convert import convert_world_text
from tests.support.converted_twins import converted_twins, world_text

ICE = world_text(
    'DEF WALL Solid { translation 5 0 0.5 name "wall" boundingObject Box { size 0.1 1 1 } }\n'
    'DEF R Robot { controller "<extern>" translation 0 0 0.05 linearVelocity 1 0 0 contactMaterial "rubber" '
    'physics Physics { density -1 mass 1 } boundingObject Box { size 0.1 0.1 0.1 } children [ GPS { name "gps" } ] }\n'
    'DEF FLOOR Solid { name "floor" contactMaterial "ice" boundingObject Plane { size 10 10 } }',
    'basicTimeStep 4 contactProperties [ ContactProperties { material1 "rubber" material2 "ice" '
    "coulombFriction [ 0.05 ] bounce 0 } ]")


def test_the_robot_touches_the_ice_with_the_ice_pairs_friction() -> None:
    model = convert_world_text(ICE, "ice.wbt").compile()
    data = mujoco.MjData(model)
    data.qpos[2] -= 1e-3  # sink 1 mm so that the box touches the floor
    mujoco.mj_forward(model, data)
    floor = {model.geom("FLOOR").id, model.geom("R").id}
    touching = [c for c in data.contact[:data.ncon] if {c.geom1, c.geom2} == floor]
    assert touching
    assert [c.friction[0] for c in touching] == pytest.approx([0.05] * len(touching))


def test_both_twins_slide_the_box_as_far_on_the_ice(tmp_path: Path) -> None:
    with converted_twins(ICE, tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(100):  # 0.8 s
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("R")[0] == pytest.approx(0.643, abs=0.01)
        assert mujoco_twin.body_position("R")[0] == pytest.approx(0.643, abs=0.01)


def test_a_geoms_friction_knob_reaches_its_pairs(tmp_path: Path) -> None:
    # The MuJoCo twin's knob geom.R.friction sets the robot geom's friction (nominal 1: its pair with the wall's
    # default material); the ice pair follows by the factor MuJoCo's mix of the two geoms changed, max(2, 0.05) /
    # max(1, 0.05) = 2: 0.05 x 2 = 0.1. Setting no knob puts it back.
    with converted_twins(ICE, tmp_path, 0.008) as (_, _webots, mujoco_twin):
        model = mujoco_twin.model  # type: ignore[attr-defined]
        assert model.npair == 1
        assert mujoco_twin.knobs()["geom.R.friction"].nominal == pytest.approx(1.0)
        mujoco_twin.set_knobs({"geom.R.friction": 2.0})
        assert model.pair_friction[0, :2] == pytest.approx([0.1, 0.1])
        mujoco_twin.set_knobs({})
        assert model.pair_friction[0, :2] == pytest.approx([0.05, 0.05])


LOOSE = world_text(
    'DEF R Robot { controller "<extern>" translation 0 2 0.05 contactMaterial "rubber" '
    'physics Physics { density -1 mass 1 } boundingObject Box { size 0.1 0.1 0.1 } children [ GPS { name "gps" } ] }\n'
    'DEF BOX Solid { translation 0 0 0.05 name "box" linearVelocity 1 0 0 physics Physics { density -1 mass 1 } '
    "boundingObject Box { size 0.1 0.1 0.1 } }\n"
    'DEF FLOOR Solid { name "floor" boundingObject Plane { size 10 10 } }',
    'basicTimeStep 4 contactProperties [ ContactProperties { material1 "rubber" material2 "default" '
    "coulombFriction [ 0.05 ] bounce 0 } ContactProperties { coulombFriction [ 0.3 ] bounce 0 } ]")


def test_a_loose_object_slides_on_its_own_materials_pair(tmp_path: Path) -> None:
    # A loose 1 kg box (material "default") thrown at 1 m/s on the default floor: their pair's friction is 0.3, so it
    # stops after 1 / (0.3 x 9.81) = 0.34 s, having gone 1^2 / (2 x 0.3 x 9.81) = 0.170 m. Before, its geoms carried
    # the robot's pair with the floor (rubber/default, 0.05) and it would have gone 0.643 m in 0.8 s.
    with converted_twins(LOOSE, tmp_path, 0.008) as (_, webots, mujoco_twin):
        for _ in range(100):  # 0.8 s
            webots.step()
            mujoco_twin.step()
        assert webots.body_position("BOX")[0] == pytest.approx(0.170, abs=0.01)
        assert mujoco_twin.body_position("BOX")[0] == pytest.approx(0.170, abs=0.01)


def test_explicit_pairs_are_capped_the_largest_first() -> None:
    # MuJoCo tests every explicit pair at every step, outside its broad phase: a world of many objects would pay for
    # pairs that never touch (56,725 of them made a 29 us step 321 us). The ice world with 1,000 icy stones listed
    # before its floor needs 1,001 pairs (the robot against each "ice" geom: its own friction, from its pair with
    # the wall's default material listed first, mixes to 1 where the rubber/ice pair says 0.05; the wall needs
    # none): the converter writes MAX_EXPLICIT_PAIRS of them, the floor's (a plane, the largest) first, and says how
    # many keep MuJoCo's mixing.
    from dualtwin.convert.contacts import MAX_EXPLICIT_PAIRS

    stones = "\n".join(f'Solid {{ translation {3 + (k % 40) * 0.3} {(k // 40) * 0.3 - 4} 0.05 name "stone{k}" '
                       'contactMaterial "ice" boundingObject Box { size 0.1 0.1 0.1 } }' for k in range(1000))
    text = ICE.replace("DEF FLOOR Solid", f"{stones}\nDEF FLOOR Solid")
    conversion = convert_world_text(text, "stones.wbt")
    model = conversion.compile()
    assert model.npair == MAX_EXPLICIT_PAIRS
    assert {model.geom(int(model.pair_geom1[0])).name, model.geom(int(model.pair_geom2[0])).name} == {"R", "FLOOR"}
    warnings = [w for w in conversion.warnings if "explicit pairs" in w]
    assert len(warnings) == 1 and warnings[0].startswith("1001 geom pairs")
    assert f": {1001 - MAX_EXPLICIT_PAIRS} (the first" in warnings[0]
