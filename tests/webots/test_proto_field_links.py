"""A supervisor's edit of a PROTO instance's field reaches the fields its body links to it with ``IS``.

Webots propagates a PROTO field's value to every body field written ``<field> IS <protoField>`` (through
nested and derived PROTOs), and those fields reach ODE at the next step like any field edit. The PROTOs in
``proto_links/`` name their interface fields differently from the base fields (``place`` -> ``translation``,
``extent`` -> ``size``, ``weight`` -> ``mass``), so only the recorded links can carry an edit. Before this
change the interface value read back but nothing else moved: rays saw the old box, the body kept its pose
and its mass.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

HERE = Path(__file__).parent / "proto_links"
STEP = 8


def _supervisor(body: str) -> Supervisor:
    text = (
        '#VRML_SIM R2023b utf8\nEXTERNPROTO "Slab.proto"\nEXTERNPROTO "Wall.proto"\nEXTERNPROTO "Post.proto"\n'
        'EXTERNPROTO "Bar.proto"\nEXTERNPROTO "Rover.proto"\nEXTERNPROTO "Rack.proto"\nEXTERNPROTO "Swing.proto"\n'
        f"WorldInfo {{ basicTimeStep {STEP} gravity 0 }}\n{body}"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text, HERE / "links.wbt"))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


def _sensors(*ys: float) -> str:
    # one ray along +x; the table maps distance to itself, so a box centred 1 m ahead reads 1 - half extent
    return "".join(
        f'DistanceSensor {{ name "s{i}" translation 0 {y} 0 lookupTable [ 0 0 0, 2 2 0 ] }} ' for i, y in enumerate(ys)
    )


def test_a_proto_size_field_reaches_the_rays_through_plain_nested_and_derived_protos() -> None:
    sup = _supervisor(
        f"Robot {{ supervisor TRUE children [ {_sensors(0, 2, 4)} ] }}\n"
        "DEF SLAB Slab { place 1 0 0 }\nDEF WALL Wall { at 1 2 0 }\nDEF POST Post { at 1 4 0 }\n"
    )
    sensors = [sup.getDevice(f"s{i}") for i in range(3)]
    for s in sensors:
        s.enable(STEP)
    sup.step(STEP)
    assert [s.getValue() for s in sensors] == pytest.approx([0.9, 0.9, 0.9])
    sup.getFromDef("SLAB").getField("extent").setSFVec3f([0.6, 0.2, 0.2])
    sup.getFromDef("WALL").getField("dims").setSFVec3f([1.0, 0.2, 0.2])
    sup.getFromDef("POST").getField("dims").setSFVec3f([0.4, 0.2, 0.2])
    sup.step(STEP)
    assert [s.getValue() for s in sensors] == pytest.approx([0.7, 0.5, 0.8])
    # the interface reads back the new value; the derived PROTO's inner Slab instance follows it too
    wall = sup.getFromDef("WALL")
    assert wall.getField("dims").getSFVec3f() == [1.0, 0.2, 0.2]
    box = next(n for n in wall.scene_node.walk() if n.type_name == "Box")
    assert box.fields["size"] == (1.0, 0.2, 0.2)


def test_a_proto_field_linked_to_translation_moves_the_body_at_the_next_step() -> None:
    sup = _supervisor("Robot { supervisor TRUE }\nDEF SLAB Slab { place 1 0 0 }\nDEF WALL Wall { at 0 3 0 }\n")
    slab, wall = sup.getFromDef("SLAB"), sup.getFromDef("WALL")
    sup.step(STEP)
    slab.getField("place").setSFVec3f([0.0, -2.0, 0.5])
    wall.getField("at").setSFVec3f([0.0, 5.0, 0.0])
    assert slab.getPosition() == pytest.approx([1.0, 0.0, 0.0])  # queued: applied before the next step
    sup.step(STEP)
    assert slab.getPosition() == pytest.approx([0.0, -2.0, 0.5])
    assert wall.getPosition() == pytest.approx([0.0, 5.0, 0.0])
    assert slab.getProtoField("translation").getSFVec3f() == [0.0, -2.0, 0.5]


def test_a_proto_field_linked_to_mass_changes_the_body_response_to_a_force() -> None:
    sup = _supervisor("Robot { supervisor TRUE }\nDEF A Slab { place 0 0 0 }\nDEF B Slab { place 0 2 0 }\n")
    a, b = sup.getFromDef("A"), sup.getFromDef("B")
    b.getField("weight").setSFFloat(4.0)  # B: 4 kg; A (control) keeps 1 kg
    sup.step(STEP)
    for node in (a, b):
        node.addForce([2.0, 0.0, 0.0], False)
    sup.step(STEP)
    dt = STEP / 1000
    assert a.getVelocity()[0] == pytest.approx(2.0 * dt / 1.0)
    assert b.getVelocity()[0] == pytest.approx(2.0 * dt / 4.0)


def test_a_procedural_proto_is_regenerated_when_a_template_field_changes(capsys: pytest.CaptureFixture[str]) -> None:
    """Webots expands the instance again from its fields: the ray sees the new box from the next step, the
    instance keeps its handle, DEF and id, and stays where physics had moved it."""
    sup = _supervisor(f"Robot {{ supervisor TRUE children [ {_sensors(0)} ] }}\nDEF BAR Bar {{ place 1 0 0 }}\n")
    sensor = sup.getDevice("s0")
    sensor.enable(STEP)
    bar = sup.getFromDef("BAR")
    ident = bar.getId()
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)
    capsys.readouterr()
    bar.getField("place").setSFVec3f([1.0, 0.0, 0.0])  # an IS-only field: followed, no regeneration
    bar.getField("length").setSFFloat(0.5)
    assert capsys.readouterr().err == ""
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.75)  # 1 - 0.5 / 2: the regenerated box (it was 0.9)
    assert bar.getField("length").getSFFloat() == 0.5 and bar.getId() == ident
    again = sup.getFromDef("BAR")
    assert again.getId() == ident and again.getPosition() == pytest.approx([1.0, 0.0, 0.0])
    assert "length 0.5" in bar.exportString() and bar.exportString().startswith("DEF BAR Bar {")
    sup.simulationReset()  # the reset puts the field back, and the node it fed
    sup.step(STEP)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)
    assert bar.getField("length").getSFFloat() == pytest.approx(0.2)


def test_a_field_that_reaches_a_procedural_proto_through_is_regenerates_the_instance() -> None:
    # Rack is a plain PROTO whose body is a Bar: its 'size' is Bar's 'length', read by Bar's template
    sup = _supervisor(f"Robot {{ supervisor TRUE children [ {_sensors(0)} ] }}\nDEF RACK Rack {{ at 1 0 0 }}\n")
    sensor = sup.getDevice("s0")
    sensor.enable(STEP)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)
    sup.getFromDef("RACK").getField("size").setSFFloat(0.5)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.75)


def test_a_procedural_proto_holding_or_inside_a_robot_is_not_regenerated_and_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    # the control: regenerating a Robot would restart its controller; its IS links are still followed
    sup = _supervisor('Robot { supervisor TRUE children [ DEF INNER Bar { place 0 0 1 } ] }\n'
                      'DEF ROVER Rover { place 1 0 0 }\n')
    rover = sup.getFromDef("ROVER")
    sup.step(STEP)
    capsys.readouterr()
    rover.getField("place").setSFVec3f([0.0, 1.0, 0.0])
    assert capsys.readouterr().err == ""
    sup.step(STEP)
    assert rover.getPosition() == pytest.approx([0.0, 1.0, 0.0])
    rover.getField("length").setSFFloat(0.5)
    err = capsys.readouterr().err
    assert "'length' is read by the template of a procedural PROTO in Rover" in err and err.count("\n") == 1
    assert rover.getField("length").getSFFloat() == 0.5
    sup.getFromDef("INNER").getField("length").setSFFloat(0.5)  # a part of a robot: its devices would go too
    assert "'length' is read by the template of a procedural PROTO in Bar" in capsys.readouterr().err


def test_simulation_reset_restores_a_proto_field_with_the_nodes_it_feeds() -> None:
    sup = _supervisor(f"Robot {{ supervisor TRUE children [ {_sensors(0)} ] }}\nDEF SLAB Slab {{ place 1 0 0 }}\n")
    sensor = sup.getDevice("s0")
    sensor.enable(STEP)
    extent = sup.getFromDef("SLAB").getField("extent")
    extent.setSFVec3f([0.6, 0.2, 0.2])
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.7)
    sup.simulationReset()
    sup.step(STEP)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)
    assert extent.getSFVec3f() == [0.2, 0.2, 0.2]  # the interface value is reset too, not only the Box


def test_a_regenerated_proto_that_a_supervisor_removed_stays_out_after_a_reset() -> None:
    # inside a parent's children, which the reset restores (the removal's own reset step then takes it out again)
    sup = _supervisor(f"Robot {{ supervisor TRUE children [ {_sensors(0)} ] }}\n"
                      "Solid { name \"shelf\" children [ DEF BAR Bar { place 1 0 0 } ] }\n")
    sensor = sup.getDevice("s0")
    sensor.enable(STEP)
    bar = sup.getFromDef("BAR")
    bar.getField("length").setSFFloat(0.5)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.75)
    bar.remove()
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(2.0)  # nothing in the ray: the table's far end
    sup.simulationReset()  # removed nodes stay removed: the reset must not rebuild its body either
    sup.step(STEP)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(2.0)
    assert sup.getFromDef("BAR") is None


def test_an_exported_proto_instance_carries_its_internal_state_to_its_copy() -> None:
    """Webots writes a PROTO instance's internal Solids, joints and velocities as ``hidden`` fields (worldSave,
    exportString), so importing the text of a swinging pendulum gives one in the same state, swinging alike. (The
    world declares the PROTO IMPORTABLE: Webots imports no PROTO that is not, test_importable_protos.py.)"""
    text = (
        '#VRML_SIM R2023b utf8\nIMPORTABLE EXTERNPROTO "Pendulum.proto"\nWorldInfo { basicTimeStep 8 }\n'
        "Robot { supervisor TRUE }\nDEF P Pendulum { place 0 0 1 }\n"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text, HERE / "links.wbt"))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    for _ in range(30):
        sup.step(STEP)
    exported = sup.getFromDef("P").exportString()
    assert "hidden position_0_0" in exported and "hidden angularVelocity_1" in exported
    copy_text = exported.replace("DEF P ", "DEF Q ").replace("place 0 0 1", "place 0 2 1")
    sup.getRoot().getField("children").importMFNodeFromString(-1, copy_text)
    hinges = [j for j in sim.joints if j.kind == "hinge"]
    assert len(hinges) == 2 and hinges[0].positions[0] > 0.5  # swinging
    for _ in range(10):
        sup.step(STEP)
        # alike, not bit for bit (3e-4 rad apart after 10 steps here); a copy at rest would be about 1.4 rad off
        assert hinges[1].positions[0] == pytest.approx(hinges[0].positions[0], abs=0.01)


def test_a_proto_field_bound_to_a_solid_translation_reads_where_the_physics_has_the_solid() -> None:
    """§7.1: ``IS`` binds the interface field to the Solid's field, which follows the physics (§6), so a supervisor
    reading a PROTO's ``translation``-bound field (``robot.getField("translation")`` on a PROTO robot) reads the
    current pose, through a derived PROTO too. It read the load-time value while the body moved."""
    sup = _supervisor("Robot { supervisor TRUE }\nDEF SLAB Slab { place 0 0 1 }\nDEF WALL Wall { at 0 2 1 }\n")
    slab, wall = sup.getFromDef("SLAB"), sup.getFromDef("WALL")
    for node in (slab, wall):
        node.setVelocity([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    for _ in range(10):
        sup.step(STEP)
    # no gravity, no damping: 1 m/s for 10 steps of 8 ms = 0.08 m along x
    assert slab.getField("place").getSFVec3f() == pytest.approx([0.08, 0.0, 1.0])
    assert wall.getField("at").getSFVec3f() == pytest.approx([0.08, 2.0, 1.0])
    # a write is read back at once (it reaches the body at the next step, §6)
    slab.getField("place").setSFVec3f([0.0, 0.0, 2.0])
    assert slab.getField("place").getSFVec3f() == [0.0, 0.0, 2.0]


def test_a_proto_field_bound_to_a_joint_position_reads_the_joint_angle() -> None:
    """The same binding for a joint's ``position`` (§4.1: the field is the joint's current position)."""
    sup = _supervisor("Robot { supervisor TRUE }\nDEF SWING Swing { }\n")
    swing = sup.getFromDef("SWING")
    # the bob turning at 1 rad/s about the hinge's y axis: v = ω × r = (0, 1, 0) × (0.2, 0, 0) = (0, 0, -0.2)
    swing.getFromProtoDef("BOB").setVelocity([0.0, 0.0, -0.2, 0.0, 1.0, 0.0])
    for _ in range(10):
        sup.step(STEP)
    assert swing.getField("angle").getSFFloat() == pytest.approx(0.08, abs=1e-4)  # 1 rad/s × 10 × 8 ms


def test_a_derived_proto_is_saved_where_the_physics_has_it() -> None:
    """exportString/worldSave write a PROTO instance's interface fields with the values of the fields ``IS`` binds
    them to (§7.1); a derived PROTO's position reaches its Solid through two links (Wall.at -> Slab.place ->
    translation) and was written as loaded, so the saved world put the moved body back where it started."""
    sup = _supervisor("Robot { supervisor TRUE }\nDEF WALL Wall { at 0 2 1 }\n")
    wall = sup.getFromDef("WALL")
    wall.setVelocity([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    for _ in range(10):
        sup.step(STEP)
    line = next(line.split() for line in wall.exportString().splitlines() if line.strip().startswith("at "))
    assert [float(v) for v in line[1:]] == pytest.approx([0.08, 2.0, 1.0])  # 1 m/s × 10 × 8 ms along x


TAGGED = """#VRML_SIM R2023b utf8
PROTO Tagged [ field SFString tag "a" ]
{ Solid { children [ DEF HOLDER Solid { name IS tag } ] } }
"""


def test_an_interface_field_reads_its_own_value_once_the_node_it_was_bound_to_is_removed(tmp_path: Path) -> None:
    # an interface field reads the base field IS bound to it (§7.1: one value); the base node gone, nothing binds
    # it and it reads what was written to it. Guards the reads' walk of the PROTO body, kept between reads until
    # the scene tree changes: kept past the removal, the read gave the removed node's "a"
    (tmp_path / "Tagged.proto").write_text(TAGGED, encoding="utf-8")
    text = 'EXTERNPROTO "Tagged.proto"\nRobot { supervisor TRUE }\nDEF T Tagged { }\n'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(f"#VRML_SIM R2023b utf8\n{text}", tmp_path / "w.wbt"))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    tagged = sup.getFromDef("T")
    tag = tagged.getField("tag")
    assert tag.getSFString() == "a"
    tagged.getFromProtoDef("HOLDER").remove()
    tag.setSFString("b")
    assert tag.getSFString() == "b"
    sup.step(STEP)
    assert tagged.getField("tag").getSFString() == "b"
