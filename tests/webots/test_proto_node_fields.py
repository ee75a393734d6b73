"""A supervisor's node edit of a PROTO instance's node-valued interface field reaches the scene tree and the physics.

An instance's ``MFNode``/``SFNode`` interface fields hold its parameters; the body's fields written ``IS`` them hold
copies, and those copies are what is in the scene (webots-on-ode.md §7.1: ``IS`` binds a node field to an interface
field; webots-python-api.md Field: ``importMFNodeFromString``/``importSFNodeFromString``/``removeMF``/``removeSF``).
Adding a Solid to a PROTO robot's extension slot this way is the common use. Before this change the interface list
changed but the body did not follow in the physics: an imported Solid was copied into the body without joining the
physics (with a warning that it was "under the scene root"), and a removed one stayed, with its mass and geoms.

``Cradle.proto``: a Solid (1 kg at its origin, inertia 0.01) whose ``children IS extras`` and ``boundingObject IS bounds``.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

HERE = Path(__file__).parent / "proto_links"
STEP = 8
# 1 kg at its origin, its inertia given (§3.2 CUSTOM_INERTIA_MATRIX: no boundingObject needed for the mass)
PART = "Solid { translation 0 0 0.1 physics Physics { density -1 mass 1 centerOfMass [ 0 0 0 ] inertiaMatrix [ 0.01 0.01 0.01, 0 0 0 ] } }"


def _supervisor(body: str) -> Supervisor:
    text = (f'#VRML_SIM R2023b utf8\nEXTERNPROTO "Cradle.proto"\nEXTERNPROTO "Crate.proto"\nWorldInfo {{ basicTimeStep {STEP} gravity 0 }}\n'
            'Robot { supervisor TRUE children [ DistanceSensor { name "s0" lookupTable [ 0 0 0, 2 2 0 ] } ] }\n'
            f"{body}")
    return quiet_supervisor(text, HERE / "cradle.wbt")


def test_a_solid_imported_into_a_proto_extension_field_is_merged_into_the_proto_solid(
        capsys: pytest.CaptureFixture[str]) -> None:
    sup = _supervisor("DEF A Cradle { place 1 0 0 }\n")
    cradle = sup.getFromDef("A")
    sup.step(STEP)
    assert cradle.getCenterOfMass() == pytest.approx([1.0, 0.0, 0.0])
    capsys.readouterr()
    cradle.getField("extras").importMFNodeFromString(-1, PART)
    sup.step(STEP)
    # §3.3: a Solid without a joint is merged into its parent's body: CoM of 1 kg at z 0 and 1 kg at z 0.1 = 0.05
    assert cradle.getCenterOfMass() == pytest.approx([1.0, 0.0, 0.05])
    assert cradle.getField("extras").getCount() == 1
    assert cradle.getProtoField("children").getCount() == 1
    assert "takes no part in the physics" not in capsys.readouterr().err
    sup.simulationReset()  # the added node goes with the reset: the Solid is alone again
    sup.step(STEP)
    assert cradle.getCenterOfMass() == pytest.approx([1.0, 0.0, 0.0])


def test_a_solid_removed_from_a_proto_extension_field_leaves_the_physics() -> None:
    sup = _supervisor(f"DEF B Cradle {{ place 0 3 0 extras [ {PART} ] }}\n")
    cradle = sup.getFromDef("B")
    sup.step(STEP)
    assert cradle.getCenterOfMass() == pytest.approx([0.0, 3.0, 0.05])  # (0 + 0.1) / 2, as above
    cradle.getField("extras").removeMF(-1)
    sup.step(STEP)
    assert cradle.getCenterOfMass() == pytest.approx([0.0, 3.0, 0.0])
    assert cradle.getProtoField("children").getCount() == 0


def test_a_bounding_object_imported_into_and_removed_from_a_proto_node_field_reaches_the_rays() -> None:
    sup = _supervisor("DEF A Cradle { place 1 0 0 }\n")
    sensor = sup.getDevice("s0")
    sensor.enable(STEP)
    bounds = sup.getFromDef("A").getField("bounds")
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(2.0)  # nothing on the ray: the table's last output
    bounds.importSFNodeFromString("Box { size 0.2 0.2 0.2 }")
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)  # the box centred 1 m ahead: 1 - 0.2 / 2
    bounds.removeSF()
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(2.0)


def test_a_node_read_through_a_proto_node_field_is_the_one_in_the_scene() -> None:
    """``getMFNode``/``getSFNode`` on the interface field name the node the body's ``IS`` field holds: its pose is
    the physics', a write of its fields reaches the physics, and the instance is saved with its state. The handle
    named the parameter outside the scene: its pose read NaN and its writes moved nothing."""
    hinge = ("HingeJoint { jointParameters HingeJointParameters { axis 0 0 1 } endPoint Solid { translation 0.2 0 0 "
             "boundingObject Sphere { radius 0.02 } physics Physics { mass 1 } } }")
    sup = _supervisor(f"DEF B Cradle {{ place 0 0 1 extras [ {hinge} ] }}\n")
    cradle = sup.getFromDef("B")
    joint = cradle.getField("extras").getMFNode(0)
    bob = joint.getField("endPoint").getSFNode()
    assert bob.getPosition() == pytest.approx([0.2, 0.0, 1.0])
    joint.getField("jointParameters").getSFNode().getField("position").setSFFloat(0.5)
    sup.step(STEP)
    # §4.1: the endPoint turned 0.5 rad about z around the anchor (the Cradle's origin): 0.2 (cos 0.5, sin 0.5)
    turned = [0.2 * math.cos(0.5), 0.2 * math.sin(0.5), 1.0]
    assert bob.getPosition() == pytest.approx(turned)
    # the parameter is written as the scene holds it (not as loaded: no position, translation 0.2 0 0)
    written = {line.split()[0]: [float(v) for v in line.split()[1:]]
               for line in cradle.exportString().splitlines() if line.split()[0] in ("position", "translation")}
    assert written["position"] == pytest.approx([0.5])
    assert written["translation"] == pytest.approx(turned[:2] + [0.0])  # in the Cradle's frame


def test_a_node_removed_through_its_own_handle_leaves_the_proto_node_field_too() -> None:
    """``Node.remove()`` of a node an extension slot holds: the interface field no longer counts it (the body's copy
    and the parameter are one node, §7.1), and the Solid leaves the physics."""
    sup = _supervisor(f"DEF B Cradle {{ place 0 3 0 extras [ {PART} ] }}\n")
    cradle = sup.getFromDef("B")
    extras = cradle.getField("extras")
    extras.getMFNode(0).remove()
    sup.step(STEP)
    assert extras.getCount() == 0
    assert cradle.getCenterOfMass() == pytest.approx([0.0, 3.0, 0.0])  # the Cradle's 1 kg alone


def test_a_node_imported_into_a_node_field_a_template_reads_regenerates_the_instance_with_it() -> None:
    """``Crate.proto``'s template reads ``extras``: Webots expands the instance again with the new node in its slot
    (the box 0.1 m longer), and the node read through the field is the regenerated body's."""
    sup = _supervisor("DEF C Crate { place 1 0 0 }\n")
    sensor = sup.getDevice("s0")
    sensor.enable(STEP)
    crate = sup.getFromDef("C")
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)  # a 0.2 m box centred 1 m ahead: 1 - 0.2 / 2
    crate.getField("extras").importMFNodeFromString(-1, PART)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.85)  # 0.2 + 0.1 = 0.3 m long: 1 - 0.3 / 2
    assert crate.getCenterOfMass() == pytest.approx([1.0, 0.0, 0.05])  # merged 1 kg at z 0.1, as above
    assert crate.getField("extras").getMFNode(0).getPosition() == pytest.approx([1.0, 0.0, 0.1])
    crate.getField("extras").removeMF(0)
    sup.step(STEP)
    assert sensor.getValue() == pytest.approx(0.9)
    assert crate.getCenterOfMass() == pytest.approx([1.0, 0.0, 0.0])
