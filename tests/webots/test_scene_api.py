"""The supervisor's scene API as Webots has it (issue 23): every MF getter/setter, insertion and removal, nodes
imported from VRML text and removed, PROTO interface and internal fields, saveState/loadState, and worlds saved,
loaded and reloaded in one run."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from dualtwin.webots import load_world
from dualtwin.webots.controller import Field, Node, Supervisor
from dualtwin.webots.physics import Simulation

PROTO = """#VRML_SIM R2023b utf8
PROTO Crate [
  field SFVec3f translation 0 0 0
  field SFFloat side 0.2
]
{
  Solid {
    translation IS translation
    name "crate"
    children [ DEF CRATE_SHAPE Shape { geometry Box { size 0.2 0.2 0.2 } } ]
    boundingObject Box { size 0.2 0.2 0.2 }
    physics Physics { mass 1 }
  }
}
"""

WORLD = """#VRML_SIM R2023b utf8
EXTERNPROTO "../protos/Crate.proto"
WorldInfo { basicTimeStep 8 }
Solid { name "floor" boundingObject Plane { size 20 20 } }
DEF BOX Solid { translation 0 0 1 name "box" boundingObject Box { size 0.1 0.1 0.1 } physics Physics { mass 1 } }
DEF CRATE Crate { translation 1 0 0.1 }
DEF MESH Solid {
  translation 3 0 0 name "mesh"
  children [ Shape { geometry IndexedFaceSet { coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] } } } ]
}
DEF SUP Robot {
  controller "ctl"
  controllerArgs [ "a" "b" ]
  battery [ 10 20 0 ]
  supervisor TRUE
  customData "init"
}
"""


def _project(tmp_path: Path, script: str = "") -> Path:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "protos").mkdir()
    (tmp_path / "controllers" / "ctl").mkdir(parents=True)
    (tmp_path / "protos" / "Crate.proto").write_text(PROTO)
    (tmp_path / "worlds" / "w.wbt").write_text(WORLD)
    (tmp_path / "controllers" / "ctl" / "ctl.py").write_text(textwrap.dedent(script))
    return tmp_path / "worlds" / "w.wbt"


def _supervisor(tmp_path: Path) -> Supervisor:
    sim = Simulation(load_world(_project(tmp_path)))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def test_mf_getters_setters_insertion_and_removal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path)
    args = sup.getSelf().getField("controllerArgs")
    assert args.type == Field.MF_STRING and args.getTypeName() == "MFString" and args.count == 2
    assert [args.getMFString(0), args.getMFString(-1)] == ["a", "b"]  # a negative index counts from the end
    args.setMFString(1, "B")
    args.insertMFString(-1, "z")  # -1 appends
    args.insertMFString(0, "first")
    assert [args.getMFString(i) for i in range(args.getCount())] == ["first", "a", "B", "z"]
    args.removeMF(1)
    assert [args.getMFString(i) for i in range(args.getCount())] == ["first", "B", "z"]
    battery = sup.getSelf().getField("battery")
    battery.setMFFloat(0, 5.5)
    assert battery.getMFFloat(0) == 5.5 and battery.type == Field.MF_FLOAT
    point = sup.getFromDef("MESH").getField("children").getMFNode(0).getField("geometry").getSFNode()
    coord = point.getField("coord").getSFNode().getField("point")
    coord.setMFVec3f(2, [0.0, 2.0, 0.5])
    coord.insertMFVec3f(3, [1.0, 1.0, 1.0])
    assert coord.getMFVec3f(2) == [0.0, 2.0, 0.5] and coord.getMFVec3f(-1) == [1.0, 1.0, 1.0]
    assert coord.getCount() == 4
    # wrong index or value: Webots' error on stderr, nothing changes
    capsys.readouterr()
    coord.setMFVec3f(9, [0.0, 0.0, 0.0])
    coord.setMFVec3f(0, [0.0, 0.0])
    assert coord.getCount() == 4 and coord.getMFVec3f(0) == [0.0, 0.0, 0.0]
    assert capsys.readouterr().err.count("Field.setMFVec3f") == 2


def test_imported_nodes_join_the_tree_get_ids_and_go_at_reset(tmp_path: Path) -> None:
    sup = _supervisor(tmp_path)
    children = sup.getRoot().getField("children")
    count = children.getCount()
    children.importMFNodeFromString(-1, "DEF NEW Pose { translation 0.1 0.2 0.3 }")
    children.importMFNodeFromString(0, "DEF FIRST Group { }")
    assert children.getCount() == count + 2
    assert children.getMFNode(0).getDef() == "FIRST" and children.getMFNode(-1).getDef() == "NEW"
    new = sup.getFromDef("NEW")
    assert new is not None and new.getField("translation").getSFVec3f() == [0.1, 0.2, 0.3]
    assert new.getId() > 0 and sup.getFromId(new.getId()) == new and new.getType() == 26  # Pose
    assert new.getParentNode().getId() == 0  # the root
    box = sup.getFromDef("BOX")
    bounding = box.getField("boundingObject")
    bounding.removeSF()
    assert bounding.getSFNode() is None
    bounding.importSFNodeFromString("Sphere { radius 0.05 }")
    assert bounding.getSFNode().getTypeName() == "Sphere"
    sup.simulationReset()
    sup.step(8)
    assert sup.getFromDef("NEW") is None and children.getCount() == count  # Webots removes added nodes


def test_removed_solid_leaves_the_physics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path)
    box = sup.getFromDef("BOX")
    for _ in range(10):
        sup.step(8)
    falling = box.getPosition()[2]
    assert falling < 1.0
    box.remove()
    assert sup.getFromDef("BOX") is None
    for _ in range(10):
        sup.step(8)
    capsys.readouterr()
    assert all(math.isnan(v) for v in box.getPosition())  # Webots: a deleted node's handle reads NaN
    assert "no longer in the scene" in capsys.readouterr().err


def test_proto_interface_and_internal_fields(tmp_path: Path) -> None:
    sup = _supervisor(tmp_path)
    crate = sup.getFromDef("CRATE")
    assert crate.isProto() and crate.getTypeName() == "Crate" and crate.getBaseTypeName() == "Solid"
    assert [crate.getFieldByIndex(i).getName() for i in range(crate.getNumberOfFields())] == ["translation", "side"]
    assert crate.getField("side").getSFFloat() == 0.2 and crate.getField("boundingObject") is None
    assert crate.getProtoField("boundingObject").getSFNode().getTypeName() == "Box"
    assert crate.getProtoField("name").getSFString() == "crate"
    assert crate.getFromProtoDef("CRATE_SHAPE").getType() == Node.SHAPE
    assert sup.getFromDef("BOX").getProtoField("name") is None  # not a PROTO instance
    crate.getField("translation").setSFVec3f([2.0, 0.0, 0.5])  # the interface field drives the Solid's
    sup.step(8)
    assert crate.getPosition()[0] == pytest.approx(2.0, abs=1e-3)


def test_save_and_load_state_restore_pose_and_velocity(tmp_path: Path) -> None:
    sup = _supervisor(tmp_path)
    box = sup.getFromDef("BOX")
    for _ in range(5):
        sup.step(8)
    saved_z, saved_v = box.getPosition()[2], box.getVelocity()[2]
    box.saveState("mid-air")
    for _ in range(20):
        sup.step(8)
    assert box.getPosition()[2] < saved_z - 0.01
    box.loadState("mid-air")
    sup.step(8)
    # back where it was, with its velocity, then one more step of fall
    assert box.getPosition()[2] == pytest.approx(saved_z + saved_v * 0.008, abs=2e-3)
    box.loadState("__init__")
    sup.step(8)
    assert box.getPosition()[2] == pytest.approx(1.0, abs=2e-3)


def test_field_value_property_and_type_names(tmp_path: Path) -> None:
    sup = _supervisor(tmp_path)
    data = sup.getSelf().getField("customData")
    assert data.value == "init" and data.type == Field.SF_STRING and data.name == "customData"
    data.value = "changed"
    # a field write reaches the robot's own library with the next step's answer (webots-python-api.md: "Supervisor
    # field setters take effect at the next step"); until then getCustomData keeps what the last step brought
    assert data.value == "changed" and sup.getCustomData() == "init"
    sup.step(8)
    assert sup.getCustomData() == "changed"
    with pytest.raises(AttributeError):
        data.count = 3  # type: ignore[misc]
    assert sup.getSelf().getField("controllerArgs").value is None  # MF fields have no single value


SAVE_AND_LOAD = """
import os
from controller import Supervisor
sup = Supervisor()
here = os.path.dirname(os.path.abspath(__file__))
saved = os.path.join(here, "..", "..", "worlds", "saved.wbt")
if sup.getCustomData() == "init":
    root = sup.getRoot().getField("children")
    root.importMFNodeFromString(-1, "DEF P Pose { }")
    sup.getFromDef("P").getField("translation").setSFVec3f([0.1, 1e-300, 123456789012345.0])
    sup.setCustomData("saved")
    sup.step(8)
    assert sup.worldSave(saved) == 1
    sup.worldLoad(saved)
    print("step after worldLoad:", sup.step(8), flush=True)
else:
    print("loaded at t =", sup.getTime(), sup.getFromDef("P").getField("translation").getSFVec3f(), flush=True)
    counter = os.path.join(here, "reloads")
    if not os.path.exists(counter):
        open(counter, "w").close()
        sup.worldReload()
        sup.step(8)
    else:
        print("reloaded from disk:", sup.getCustomData(), flush=True)
"""


def test_world_save_load_and_reload_in_one_run(tmp_path: Path) -> None:
    world = _project(tmp_path, SAVE_AND_LOAD)
    result = subprocess.run([sys.executable, "-m", "dualtwin.cli", "webots", "run", str(world), "--duration", "1"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert "step after worldLoad: -1" in lines
    values = "[0.1, 1e-300, 123456789012345.0]"
    assert lines.count(f"loaded at t = 0.0 {values}") == 2  # the saved world, then its reload
    assert "reloaded from disk: saved" in lines
    text = (tmp_path / "worlds" / "saved.wbt").read_text()
    assert "translation 0.1 1e-300 123456789012345" in text and 'customData "saved"' in text


def test_world_save_writes_proto_instances_as_proto_nodes_and_solids_where_they_are(tmp_path: Path) -> None:
    sup = _supervisor(tmp_path)
    crate = sup.getFromDef("CRATE")
    crate.getField("side").setSFFloat(0.3)  # an edited interface field is written; the untouched ones are not
    crate.getField("translation").setSFVec3f([1.0, 0.0, 0.5])  # dropped from 0.5 m: it falls
    for _ in range(20):
        sup.step(8)
    box_z, crate_z = sup.getFromDef("BOX").getPosition()[2], crate.getPosition()[2]
    assert box_z < 0.9 and crate_z < 0.45  # both fell since the world was loaded
    saved = tmp_path / "worlds" / "saved.wbt"
    assert sup.worldSave(str(saved)) == 1
    text = saved.read_text()
    assert "DEF CRATE Crate {" in text and "side 0.3" in text
    assert 'name "crate"' not in text and "CRATE_SHAPE" not in text  # the body is not expanded into the file
    assert 'EXTERNPROTO "../protos/Crate.proto"' in text
    again = Simulation(load_world(saved))  # the saved world loads back to the same instance
    node = next(n for n in again.world.nodes if n.def_name == "CRATE")
    assert node.proto_name == "Crate" and node.type_name == "Solid" and node.fields["name"] == "crate"
    assert node.proto_fields is not None and node.proto_fields["side"] == 0.3
    assert node.proto_fields["translation"][2] == pytest.approx(crate_z)  # its pose now, through its IS link
    box = next(n for n in again.world.nodes if n.def_name == "BOX")
    assert box.fields["translation"][2] == pytest.approx(box_z)  # Webots saves where the physics has it
    again.close()
