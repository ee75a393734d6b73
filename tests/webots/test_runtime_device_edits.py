"""A supervisor's edit of a device's fields acts from the device's next sample or step and its getters follow, as
Webots' device ``update*`` slots make it (WbDistanceSensor's lookup table and ray set-up, WbEmitter/WbReceiver's
channel and range); ``simulationReset`` restores the fields and the devices read them again.

D = shared/reference/webots-devices.md. Expected values are hand computations from D's rules (each test shows
it), never runs of this code; each test has its control (the same run without the edit)."""

from __future__ import annotations

import math
import warnings
from typing import Any

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot, Runtime, Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.multi_worlds import run_multi
from tests.support.sensor_worlds import sensor_world, unit_noise

STEP = 8
# a wall whose near face is the plane x = 0.5, in front of the sensor (axis +x) at the robot's origin
WALL = "Solid { translation 0.6 0 0.1 boundingObject Box { size 0.2 4 4 } }"


def _distance_sensor(fields: str = "") -> tuple[Supervisor, Any, Any]:
    sup = sensor_world(f'DEF DS DistanceSensor {{ name "ds" {fields} }}', WALL, step=STEP)
    ds = sup.getDevice("ds")
    ds.enable(STEP)
    return sup, ds, sup.getFromDef("DS")


def _set_table(node: Any, rows: list[list[float]]) -> None:
    table = node.getField("lookupTable")
    while table.getCount():
        table.removeMF(0)
    for row in rows:
        table.insertMFVec3f(-1, row)


@pytest.mark.parametrize("edit", [True, False])
def test_distance_sensor_lookup_table_edit_sets_range_values_and_getters(edit: bool) -> None:
    # D §1.4: the default table [0 0 0, 0.1 1000 0] reaches 0.1 m, short of the wall: no hit reads the last
    # output, 1000. Edited to [0 0 0, 1 3000 0] the ray (1 m long, the last input) reaches the wall at 0.5 m:
    # 0.5·3000 = 1500; getMaxValue = the largest output, 3000 (D §0.3)
    sup, ds, node = _distance_sensor()
    sup.step(STEP)
    assert ds.getValue() == pytest.approx(1000.0)
    if edit:
        _set_table(node, [[0.0, 0.0, 0.0], [1.0, 3000.0, 0.0]])
    sup.step(STEP)
    assert ds.getValue() == pytest.approx(1500.0 if edit else 1000.0, rel=1e-6)
    assert ds.getMaxValue() == (3000.0 if edit else 1000.0)
    assert ds.getLookupTable() == ([0.0, 0.0, 0.0, 1.0, 3000.0, 0.0] if edit else [0.0, 0.0, 0.0, 0.1, 1000.0, 0.0])


@pytest.mark.parametrize("edit", [True, False])
def test_distance_sensor_number_of_rays_and_aperture_edit_lays_the_rays_again(edit: bool) -> None:
    # D §1.2: 3 rays lie at (0, 1), (2π/3, 1), (−2π/3, 1), each θ = k·aperture/2 = 0.5 rad off the axis for an
    # aperture of 1: each meets the plane x = 0.5 at 0.5/cos 0.5, with equal weights; table [0 0 0, 1 1000 0]
    # reads 1000·0.5/cos(0.5) = 569.77. The control keeps one ray on the axis: 500
    sup, ds, node = _distance_sensor("lookupTable [ 0 0 0, 1 1000 0 ]")
    sup.step(STEP)
    assert ds.getValue() == pytest.approx(500.0, rel=1e-6)
    if edit:
        node.getField("numberOfRays").setSFInt32(3)
        node.getField("aperture").setSFFloat(1.0)
    sup.step(STEP)
    assert ds.getValue() == pytest.approx(1000.0 * 0.5 / math.cos(0.5) if edit else 500.0, rel=1e-6)
    assert ds.getAperture() == (1.0 if edit else 1.5708)


def test_distance_sensor_resolution_edit_rounds_the_next_sample() -> None:
    # D §0.4: discretize(500, 300) = int(500/300 + 0.5)·300 = 600
    sup, ds, node = _distance_sensor("lookupTable [ 0 0 0, 1 1000 0 ]")
    sup.step(STEP)
    node.getField("resolution").setSFFloat(300.0)
    sup.step(STEP)
    assert ds.getValue() == pytest.approx(600.0)


def test_distance_sensor_reset_restores_the_load_table() -> None:
    sup, ds, node = _distance_sensor()
    sup.step(STEP)
    _set_table(node, [[0.0, 0.0, 0.0], [1.0, 3000.0, 0.0]])
    sup.step(STEP)
    sup.simulationReset()
    sup.step(STEP)
    sup.step(STEP)
    assert ds.getMaxValue() == 1000.0
    assert ds.getValue() == pytest.approx(1000.0)


# ------------------------------------------------------------------------------------------ other sensors


@pytest.mark.parametrize("edit", [True, False])
def test_accelerometer_lookup_table_edit_maps_the_next_sample(edit: bool) -> None:
    # a static robot's accelerometer reads R^T·(a − g) = (0, 0, 9.81) through its table (empty: the identity,
    # D §0.3); edited to [−100 −200 0, 100 200 0] it doubles: 19.62
    sup = sensor_world('DEF ACC Accelerometer { name "acc" }', "", step=STEP)
    acc = sup.getDevice("acc")
    acc.enable(STEP)
    sup.step(STEP)
    assert acc.getValues() == pytest.approx([0.0, 0.0, 9.81], abs=1e-9)
    if edit:
        _set_table(sup.getFromDef("ACC"), [[-100.0, -200.0, 0.0], [100.0, 200.0, 0.0]])
    sup.step(STEP)
    assert acc.getValues()[2] == pytest.approx(19.62 if edit else 9.81, rel=1e-9)
    assert acc.getLookupTable() == ([-100.0, -200.0, 0.0, 100.0, 200.0, 0.0] if edit else [])


@pytest.mark.parametrize("edit", [True, False])
def test_touch_sensor_lookup_table_and_resolution_edits(edit: bool) -> None:
    # a force sensor without Physics reads lookup(0) (the first output, D §0.3): 3 with [0 3 0, 10 13 0]; edited to
    # [0 7.3 0, 10 17 0] and resolution 0.5: discretize(7.3, 0.5) = int(14.6 + 0.5)·0.5 = 7.5 (D §0.4)
    sup = sensor_world('DEF T TouchSensor { name "t" type "force" lookupTable [ 0 3 0, 10 13 0 ] }', "", step=STEP)
    touch = sup.getDevice("t")
    touch.enable(STEP)
    sup.step(STEP)
    assert touch.getValue() == 3.0
    if edit:
        _set_table(sup.getFromDef("T"), [[0.0, 7.3, 0.0], [10.0, 17.0, 0.0]])
        sup.getFromDef("T").getField("resolution").setSFFloat(0.5)
    sup.step(STEP)
    assert touch.getValue() == pytest.approx(7.5 if edit else 3.0)
    assert touch.getLookupTable()[1] == (7.3 if edit else 3.0)


@pytest.mark.parametrize("edit", [True, False])
def test_position_sensor_resolution_and_noise_edits(edit: bool) -> None:
    # S §5.4 (webots-on-ode.md): value + N(0, noise²), then the resolution. A joint at 0.26 with resolution 0.1
    # reads int(2.6 + 0.5)·0.1 = 0.3; with noise 0.02 and every Gaussian draw +1 (unit_noise) it reads
    # discretize(0.28, 0.1) = 0.3 too, so the noise is checked alone: 0.26 + 0.02 = 0.28
    sup = sensor_world('HingeJoint { jointParameters HingeJointParameters { position 0.26 } '
                       'device [ DEF PS PositionSensor { name "ps" } ] endPoint Solid { } }', "", step=STEP)
    unit_noise(sup)
    ps = sup.getDevice("ps")
    ps.enable(STEP)
    sup.step(STEP)
    assert ps.getValue() == pytest.approx(0.26)
    node = sup.getFromDef("PS")
    if edit:
        node.getField("resolution").setSFFloat(0.1)
    sup.step(STEP)
    assert ps.getValue() == pytest.approx(0.3 if edit else 0.26)
    node.getField("resolution").setSFFloat(-1.0)
    if edit:
        node.getField("noise").setSFFloat(0.02)
    sup.step(STEP)
    assert ps.getValue() == pytest.approx(0.28 if edit else 0.26)


# ------------------------------------------------------------------------------------------ depth devices, camera

# the wall with a visual Shape: Lidar and RangeFinder rays hit what Webots renders (D §3.2)
SEEN_WALL = ("Solid { translation 0.6 0 0.1 children [ Shape { geometry Box { size 0.2 4 4 } } ] "
             "boundingObject Box { size 0.2 4 4 } }")


@pytest.mark.parametrize("edit", [True, False])
def test_lidar_max_range_edit_sets_the_next_scan(edit: bool) -> None:
    # one column, one layer: a ray straight ahead (azimuth fov/2 − ½·fov = 0) meets the wall at 0.5 m, inside
    # [minRange 0.01, maxRange 1); with maxRange 0.4 it is beyond the range: +inf (D §3.2)
    sup = sensor_world('DEF L Lidar { name "l" horizontalResolution 1 numberOfLayers 1 fieldOfView 0.1 }',
                       SEEN_WALL, step=STEP)
    lidar = sup.getDevice("l")
    lidar.enable(STEP)
    sup.step(STEP)
    assert lidar.getRangeImage() == pytest.approx([0.5])
    if edit:
        sup.getFromDef("L").getField("maxRange").setSFFloat(0.4)
    sup.step(STEP)
    assert lidar.getRangeImage() == ([math.inf] if edit else pytest.approx([0.5]))
    assert lidar.getMaxRange() == (0.4 if edit else 1.0)
    sup.simulationReset()  # the load maxRange again (the restored field read again)
    sup.step(STEP)
    sup.step(STEP)
    assert lidar.getMaxRange() == 1.0
    assert lidar.getRangeImage() == pytest.approx([0.5])


@pytest.mark.parametrize("edit", [True, False])
def test_range_finder_min_range_edit_sets_the_next_image(edit: bool) -> None:
    # one pixel looking along +x: depth 0.5; a minRange of 0.6 leaves it short of the range: +inf (D §3.2)
    sup = sensor_world('DEF RF RangeFinder { name "rf" width 1 height 1 }', SEEN_WALL, step=STEP)
    rf = sup.getDevice("rf")
    rf.enable(STEP)
    sup.step(STEP)
    assert rf.getRangeImage() == pytest.approx([0.5])
    if edit:
        sup.getFromDef("RF").getField("minRange").setSFFloat(0.6)
    sup.step(STEP)
    assert rf.getRangeImage() == ([math.inf] if edit else pytest.approx([0.5]))
    assert rf.getMinRange() == (0.6 if edit else 0.01)
    assert rf.getWidth() == 1


def test_camera_field_of_view_edit_reaches_its_getter_and_keeps_other_settings() -> None:
    sup = sensor_world('DEF C Camera { name "c" width 4 height 4 }', "", step=STEP)
    cam = sup.getDevice("c")
    cam.setExposure(2.0)  # the controller's setting, which an edit of another field leaves as it is
    assert cam.getFov() == pytest.approx(0.7854)
    sup.getFromDef("C").getField("fieldOfView").setSFFloat(0.5)
    sup.step(STEP)
    assert (cam.getFov(), cam.getExposure(), cam.getWidth()) == (0.5, 2.0, 4)
    sup.getFromDef("C").getField("exposure").setSFFloat(3.0)
    sup.step(STEP)
    assert cam.getExposure() == 3.0


# ------------------------------------------------------------------------------------------ Emitter / Receiver


def _radio(emitter: str = "", receiver: str = "") -> tuple[Robot, Supervisor]:
    """Robot A (emitter at the origin) and the supervisor B 2 m away (receiver); only B steps the simulation."""
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {STEP} }}
Robot {{ name "a" children [ DEF TX Emitter {{ name "tx" {emitter} }} ] }}
Robot {{ name "b" translation 2 0 0 supervisor TRUE children [ DEF RX Receiver {{ name "rx" {receiver} }} ] }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    runtime = Runtime(sim)
    a = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    a.cleanup()  # A's devices work, but only B's controller waits for steps
    b = Supervisor(runtime=runtime, robot_node=sim.robots[1].node)
    b.getDevice("rx").enable(STEP)
    return a, b


def _heard(a: Robot, b: Supervisor) -> int:
    """How many packets of one sent now the receiver has after the next step."""
    rx = b.getDevice("rx")
    while rx.getQueueLength():
        rx.nextPacket()
    a.getDevice("tx").send(b"x")
    b.step(STEP)
    return int(rx.getQueueLength())


@pytest.mark.parametrize("edit", [True, False])
def test_emitter_channel_edit_sends_on_the_new_channel(edit: bool) -> None:
    # D §5.2 step 3: a packet reaches a receiver of the same channel only; both start on 3, B listens on 3
    a, b = _radio("channel 3", "channel 3")
    assert _heard(a, b) == 1
    if edit:
        b.getFromDef("TX").getField("channel").setSFInt32(4)
    b.step(STEP)
    assert a.getDevice("tx").getChannel() == (4 if edit else 3)
    assert _heard(a, b) == (0 if edit else 1)


@pytest.mark.parametrize("edit", [True, False])
def test_receiver_channel_edit_listens_on_the_new_channel(edit: bool) -> None:
    a, b = _radio("channel 4", "channel 3")
    assert _heard(a, b) == 0
    if edit:
        b.getFromDef("RX").getField("channel").setSFInt32(4)
    b.step(STEP)
    assert b.getDevice("rx").getChannel() == (4 if edit else 3)
    assert _heard(a, b) == (1 if edit else 0)


@pytest.mark.parametrize("edit", [True, False])
def test_emitter_range_edit_limits_the_next_packets(edit: bool) -> None:
    # D §5.2 step 4: a packet beyond the emitter's range (origin distance 2 m here) is dropped
    a, b = _radio("range 3")
    assert _heard(a, b) == 1
    if edit:
        b.getFromDef("TX").getField("range").setSFFloat(1.5)
    b.step(STEP)
    assert a.getDevice("tx").getRange() == (1.5 if edit else 3.0)
    assert _heard(a, b) == (0 if edit else 1)


def test_a_channel_the_controller_set_stays_until_the_channel_field_is_written() -> None:
    # the controller's setChannel is the emitter's channel until a supervisor writes that field; an edit of
    # another field (range) does not undo it
    a, b = _radio("channel 3", "channel 5")
    tx = a.getDevice("tx")
    tx.setChannel(5)
    b.getFromDef("TX").getField("range").setSFFloat(10.0)
    b.step(STEP)
    assert tx.getChannel() == 5 and tx.getRange() == 10.0
    assert _heard(a, b) == 1
    b.getFromDef("TX").getField("channel").setSFInt32(3)
    b.step(STEP)
    assert tx.getChannel() == 3
    assert _heard(a, b) == 0


def test_radio_reset_restores_the_load_channel() -> None:
    a, b = _radio("channel 3", "channel 3")
    b.getFromDef("TX").getField("channel").setSFInt32(4)
    b.step(STEP)
    b.simulationReset()
    b.step(STEP)
    assert a.getDevice("tx").getChannel() == 3
    assert _heard(a, b) == 1


# ------------------------------------------------------------------------------------------ controller processes

PROCESS_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "a" controller "reader" children [
  DEF TX Emitter { name "tx" channel 3 }
  DEF DS DistanceSensor { name "ds" }
  HingeJoint { device [ DEF M RotationalMotor { name "m" minPosition -1 maxPosition 1 } ]
               endPoint Solid { translation 0.2 0 0 physics Physics { } boundingObject Sphere { radius 0.01 } } }
] }
Robot { name "b" supervisor TRUE controller "editor" }
"""

READER = """from controller import Robot
robot = Robot()
tx, ds, m = robot.getDevice("tx"), robot.getDevice("ds"), robot.getDevice("m")
print("LOAD", tx.getChannel(), ds.getMaxValue(), m.getMaxPosition())
for _ in range(3):
    robot.step(8)
print("LATER", tx.getChannel(), ds.getMaxValue(), m.getMaxPosition())
"""

EDITOR = """from controller import Supervisor
sup = Supervisor()
sup.step(8)
sup.getFromDef("TX").getField("channel").setSFInt32(7)
sup.getFromDef("DS").getField("lookupTable").setMFVec3f(1, [0.1, 250.0, 0.0])
sup.getFromDef("M").getField("maxPosition").setSFFloat(0.5)
for _ in range(3):
    sup.step(8)
"""


def test_a_controller_process_reads_the_edited_configuration(tmp_path: Any) -> None:
    # the reader runs in its own process, as in Webots: its getters give the load values before the edit, the
    # edited ones (channel 7, the table's largest output 250, maxPosition 0.5) after its next steps
    out = run_multi(tmp_path, PROCESS_WORLD, {"reader": READER, "editor": EDITOR}, "process", duration_s=0.1)
    lines = {line.split()[0]: line.split()[1:] for line in out if line[:4] in ("LOAD", "LATE")}
    assert [float(v) for v in lines["LOAD"]] == [3.0, 1000.0, 1.0]
    assert [float(v) for v in lines["LATER"]] == [7.0, 250.0, 0.5]
