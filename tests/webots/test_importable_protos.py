"""A supervisor imports a PROTO only if the world declares it ``IMPORTABLE EXTERNPROTO``, as Webots does.

Webots (R2023a on) refuses ``Field.importMFNodeFromString``/``importSFNodeFromString`` of a string naming a PROTO
that the world does not declare IMPORTABLE, with ``In order to import the PROTO 'X', first it must be declared in
the IMPORTABLE EXTERNPROTO list.``, and imports nothing; a plain EXTERNPROTO is not enough, even for a PROTO the
world already uses. PROTOs used inside the imported PROTO's own body come from its own declarations. Before, the
twin imported any PROTO it could find, so a supervisor that works here failed in Webots.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

CRATE = """#VRML_SIM R2023b utf8
PROTO Crate [ field SFVec3f translation 0 0 0 ]
{ Solid { translation IS translation children [ Shape { geometry Box { size 0.1 0.1 0.1 } } ] } }
"""
# a PROTO whose body uses another PROTO, declared in its own file
STACK = """#VRML_SIM R2023b utf8
EXTERNPROTO "Crate.proto"
PROTO Stack [ ]
{ Pose { children [ Crate { } Crate { translation 0 0 0.1 } ] } }
"""
REFUSAL = "In order to import the PROTO '{}', first it must be declared in the IMPORTABLE EXTERNPROTO list."


def _supervisor(tmp_path: Path, header: str) -> Supervisor:
    (tmp_path / "worlds").mkdir()
    (tmp_path / "protos").mkdir()
    (tmp_path / "protos" / "Crate.proto").write_text(CRATE)
    (tmp_path / "protos" / "Stack.proto").write_text(STACK)
    (tmp_path / "worlds" / "w.wbt").write_text(f"""#VRML_SIM R2023b utf8
{header}
WorldInfo {{ }}
Robot {{ supervisor TRUE children [ DEF SLOT Pose {{ }} DEF J HingeJoint {{ }} ] }}
DEF USED Crate {{ }}
""")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world(tmp_path / "worlds" / "w.wbt"))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _count(sup: Supervisor) -> int:
    return sup.getRoot().getField("children").getCount()


def test_a_proto_declared_only_as_externproto_is_not_imported(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path, 'EXTERNPROTO "../protos/Crate.proto"')  # used in the world, not IMPORTABLE
    before = _count(sup)
    sup.getRoot().getField("children").importMFNodeFromString(-1, "DEF NEW Crate { translation 1 0 0 }")
    err = capsys.readouterr().err
    assert REFUSAL.format("Crate") in err
    assert _count(sup) == before and sup.getFromDef("NEW") is None


def test_control_the_same_proto_declared_importable_is_imported(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path, 'IMPORTABLE EXTERNPROTO "../protos/Crate.proto"')
    before = _count(sup)
    sup.getRoot().getField("children").importMFNodeFromString(-1, "DEF NEW Crate { translation 1 0 0 }")
    assert "IMPORTABLE" not in capsys.readouterr().err
    assert _count(sup) == before + 1 and sup.getFromDef("NEW") is not None


def test_base_nodes_need_no_declaration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path, 'EXTERNPROTO "../protos/Crate.proto"')
    sup.getRoot().getField("children").importMFNodeFromString(
        -1, 'DEF NEW Solid { children [ Shape { geometry DEF B Box { size 1 1 1 } } ] boundingObject USE B '
            'name "a { b" }')  # a brace inside a string names no node
    assert capsys.readouterr().err == ""
    assert sup.getFromDef("NEW") is not None


def test_protos_inside_an_imported_proto_come_from_its_own_declarations(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path, 'EXTERNPROTO "../protos/Crate.proto"\nIMPORTABLE EXTERNPROTO "../protos/Stack.proto"')
    sup.getRoot().getField("children").importMFNodeFromString(-1, "DEF NEW Stack { }")
    assert "IMPORTABLE" not in capsys.readouterr().err
    assert sup.getFromDef("NEW") is not None


def test_a_proto_nested_in_the_imported_string_counts_too(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path, 'EXTERNPROTO "../protos/Crate.proto"')
    slot = sup.getFromDef("SLOT")
    assert slot is not None
    field = slot.getField("children")
    field.importMFNodeFromString(-1, "Pose { children [ Crate { } ] }")
    assert REFUSAL.format("Crate") in capsys.readouterr().err
    assert field.getCount() == 0


def test_an_sf_node_import_is_refused_alike(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor(tmp_path, 'EXTERNPROTO "../protos/Crate.proto"')
    joint = sup.getFromDef("J")
    assert joint is not None
    end_point = joint.getField("endPoint")
    end_point.importSFNodeFromString("Crate { }")
    assert REFUSAL.format("Crate") in capsys.readouterr().err
    assert end_point.getSFNode() is None
