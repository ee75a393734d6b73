"""Supervisor field edits meeting PROTOs and DEF/USE: an edit through a PROTO instance's interface field reaches the
device or motor its body links to it with ``IS`` (also through a nested PROTO), and a DEF node of a PROTO body reached
with ``getFromProtoDef`` is one node with its USEs in that instance's body, as a world's DEF is with its USEs.

S = shared/reference/webots-on-ode.md (§7.1: IS binds a body field to the interface field; "a .proto file is its own
DEF scope. USE is a copy of the DEF'd node", USE of geometries fine), D = webots-devices.md. The twin's rule for a
world's DEF/USE (docs/webots-coverage.md, Solid and Pose rows: an edit of a DEF reaches its USE copies) applies in a
PROTO body's scope. Expected values are hand computations; each test has its control."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

STEP = 8
# a wall whose near face is the plane x = 0.5, in front of a sensor (axis +x) at the robot's origin
WALL = "Solid { translation 0.6 0 0.1 boundingObject Box { size 0.2 4 4 } }"

PROTOS = {
    # a DistanceSensor whose table is an interface field
    "Ranger": """
        #VRML_SIM R2023b utf8
        PROTO Ranger [
          field SFString name "ds"
          field MFVec3f table [ 0 0 0, 0.1 1000 0 ]
        ]
        { DistanceSensor { name IS name lookupTable IS table } }
    """,
    # a Solid holding a Ranger (nested: its table IS this PROTO's) and an Emitter whose channel is an interface field
    "Pod": """
        #VRML_SIM R2023b utf8
        EXTERNPROTO "Ranger.proto"
        PROTO Pod [
          field MFVec3f rangerTable [ 0 0 0, 0.1 1000 0 ]
          field SFInt32 channel 0
        ]
        { Solid { children [ Ranger { name "pod ds" table IS rangerTable } Emitter { name "tx" channel IS channel } ] } }
    """,
    # a box Solid whose boundingObject is a USE of the visual Box DEF'd in its body
    "Crate": """
        #VRML_SIM R2023b utf8
        PROTO Crate [
          field SFVec3f translation 0 0 0
        ]
        {
          Solid {
            translation IS translation
            children [ Shape { geometry DEF CRATE_BOX Box { size 0.2 0.2 0.2 } } ]
            boundingObject USE CRATE_BOX
          }
        }
    """,
}


def _world(tmp_path: Path, body: str) -> Supervisor:
    for name, text in PROTOS.items():
        (tmp_path / f"{name}.proto").write_text(textwrap.dedent(text).lstrip(), encoding="utf-8")
    header = "".join(f'EXTERNPROTO "{name}.proto"\n' for name in PROTOS)
    return quiet_supervisor(f"#VRML_SIM R2023b utf8\n{header}WorldInfo {{ basicTimeStep {STEP} gravity 0 }}\n{body}",
                            tmp_path / "w.wbt")


def _sensing_robot(tmp_path: Path, children: str) -> tuple[Supervisor, Any]:
    sup = _world(tmp_path, f"{WALL}\nRobot {{ translation 0 0 0.1 supervisor TRUE children [ {children} ] }}\n")
    return sup, sup.getSelf()


def _set_rows(field: Any, rows: list[list[float]]) -> None:
    while field.getCount():
        field.removeMF(0)
    for row in rows:
        field.insertMFVec3f(-1, row)


@pytest.mark.parametrize("edit", [True, False])
def test_an_interface_table_edit_reaches_the_sensor_through_plain_and_nested_protos(tmp_path: Path, edit: bool) -> None:
    # D §1.4: the default table [0 0 0, 0.1 1000 0] reaches 0.1 m, short of the wall at 0.5 m: no hit reads 1000;
    # [0 0 0, 1 3000 0] written through the instance's field reads 0.5·3000 = 1500, and getMaxValue 3000
    sup, _ = _sensing_robot(tmp_path, 'DEF R Ranger { } DEF P Pod { }')
    sensors = [sup.getDevice("ds"), sup.getDevice("pod ds")]
    for sensor in sensors:
        sensor.enable(STEP)
    assert sup.step(STEP) != -1
    if edit:
        _set_rows(sup.getFromDef("R").getField("table"), [[0.0, 0.0, 0.0], [1.0, 3000.0, 0.0]])
        _set_rows(sup.getFromDef("P").getField("rangerTable"), [[0.0, 0.0, 0.0], [1.0, 3000.0, 0.0]])
    assert sup.step(STEP) != -1
    for sensor in sensors:
        assert sensor.getValue() == pytest.approx(1500.0 if edit else 1000.0)
        assert sensor.getMaxValue() == (3000.0 if edit else 1000.0)


@pytest.mark.parametrize("edit", [True, False])
def test_an_interface_channel_edit_reaches_the_emitter(tmp_path: Path, edit: bool) -> None:
    sup, _ = _sensing_robot(tmp_path, "DEF P Pod { }")
    tx = sup.getDevice("tx")
    assert sup.step(STEP) != -1
    if edit:
        sup.getFromDef("P").getField("channel").setSFInt32(5)
    assert sup.step(STEP) != -1
    assert tx.getChannel() == (5 if edit else 0)


@pytest.mark.parametrize("edit", [True, False])
def test_a_proto_body_def_edited_through_get_from_proto_def_resizes_its_use(tmp_path: Path, edit: bool) -> None:
    # two Crates 1 m ahead of two sensors whose table maps distance to itself: the 0.2 m box's near face reads
    # 1 - 0.1 = 0.9. The first crate's DEF Box (the visual) written 1 m long: its boundingObject, a USE of it, reads
    # 1 - 0.5 = 0.5; the second crate, whose body has a DEF of the same name, keeps 0.9
    sensors = "".join(f'DistanceSensor {{ name "s{i}" translation 0 {2 * i} 0 lookupTable [ 0 0 0, 2 2 0 ] }} '
                      for i in range(2))
    sup = _world(tmp_path, f"Robot {{ supervisor TRUE children [ {sensors} ] }}\n"
                           "DEF A Crate { translation 1 0 0 }\nDEF B Crate { translation 1 2 0 }\n")
    s0, s1 = sup.getDevice("s0"), sup.getDevice("s1")
    s0.enable(STEP)
    s1.enable(STEP)
    assert sup.step(STEP) != -1
    assert (s0.getValue(), s1.getValue()) == (pytest.approx(0.9), pytest.approx(0.9))
    if edit:
        sup.getFromDef("A").getFromProtoDef("CRATE_BOX").getField("size").setSFVec3f([1.0, 0.2, 0.2])
    assert sup.step(STEP) != -1
    assert s0.getValue() == pytest.approx(0.5 if edit else 0.9)
    assert s1.getValue() == pytest.approx(0.9)
