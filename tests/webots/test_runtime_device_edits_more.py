"""A supervisor's edit of the fields of the devices ``test_runtime_device_edits`` leaves out: a Lidar's image size,
frequencies and type (the choices of :mod:`dualtwin.webots.image_edits`, where D is silent on run-time edits),
Recognition, Battery, and the devices that read their fields live (Connector, VacuumGripper, Compass, GPS, ...).

D = shared/reference/webots-devices.md. Expected values are hand computations from D's rules (each test shows
it), never runs of this code; each test has its control (the same run without the edit)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tests.support.multi_worlds import run_multi
from tests.support.sensor_worlds import sensor_world

STEP = 8
# a wall with a visual Shape whose near face is the plane x = 0.5: Lidar rays hit what Webots renders (D §3.2)
SEEN_WALL = ("Solid { translation 0.6 0 0.1 children [ Shape { geometry Box { size 0.2 4 4 } } ] "
             "boundingObject Box { size 0.2 4 4 } }")
# one column, one layer, straight ahead: the ray meets the wall at 0.5 m
ONE_RAY = 'DEF L Lidar { name "l" horizontalResolution 1 numberOfLayers 1 fieldOfView 0.1 }'


def _lidar(node: str = ONE_RAY) -> tuple:  # type: ignore[type-arg]
    sup = sensor_world(node, SEEN_WALL, step=STEP)
    lidar = sup.getDevice("l")
    lidar.enable(STEP)
    sup.step(STEP)
    return sup, lidar, sup.getFromDef("L")


# ------------------------------------------------------------------------------------------------------ Lidar


@pytest.mark.parametrize("edit", [True, False])
def test_lidar_horizontal_resolution_edit_sizes_the_next_scan(edit: bool) -> None:
    # D §3.2: fixed lidar θ_j = fov/2 − (j+½)·fov/W; W = 2, fov 0.1: θ = ±0.025, each ray (elevation 0) meets the
    # plane x = 0.5 at the Euclidean distance 0.5/cos(0.025). Layer check (D §3.1): 1 ≤ 0.2·2/0.1 = 4, kept.
    # The control keeps W = 1: [0.5]
    sup, lidar, node = _lidar()
    assert lidar.getRangeImage() == pytest.approx([0.5])
    if edit:
        node.getField("horizontalResolution").setSFInt32(2)
    sup.step(STEP)
    expected = [0.5 / math.cos(0.025)] * 2 if edit else [0.5]
    assert lidar.getHorizontalResolution() == (2 if edit else 1)
    assert lidar.getRangeImage() == pytest.approx(expected, rel=1e-9)
    assert lidar.getRangeImageArray() == [pytest.approx(expected, rel=1e-9)]
    sup.simulationReset()  # the load's horizontalResolution again (the restored field read again)
    sup.step(STEP)
    sup.step(STEP)
    assert lidar.getHorizontalResolution() == 1
    assert lidar.getRangeImage() == pytest.approx([0.5])


def test_lidar_horizontal_resolution_beyond_the_image_side_keeps_the_size(capsys: pytest.CaptureFixture[str]) -> None:
    # a side of 10^9 columns (a typo) would cast 10^9 rays: as a Camera's side, one outside 1..16384 keeps the
    # current size with one warning line (image_edits' choice; the load takes the default for such a side)
    sup, lidar, node = _lidar()
    capsys.readouterr()
    node.getField("horizontalResolution").setSFInt32(10**9)
    sup.step(STEP)
    assert lidar.getHorizontalResolution() == 1
    assert lidar.getRangeImage() == pytest.approx([0.5])
    assert "Lidar 'l': horizontalResolution 1000000000 is not in 1..16384; it stays 1" in capsys.readouterr().err


@pytest.mark.parametrize("edit", [True, False])
def test_lidar_number_of_layers_edit_sizes_the_next_scan_with_the_load_check(
    edit: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    # D §3.1/§3.2: layers φ_i = vfov/2 − i·vfov/(L−1); L = 2, vfov 0.2: φ = ±0.1, the ray straight ahead in
    # azimuth meets x = 0.5 at 0.5/cos(0.1). The layer check at load: L ≤ vfov·W/fov = 0.2·1/0.1 = 2, so a 5
    # written is cut to 2 with a warning as at load (image_edits' choice for a run-time edit)
    sup, lidar, node = _lidar()
    capsys.readouterr()
    if edit:
        node.getField("numberOfLayers").setSFInt32(5)
    sup.step(STEP)
    warned = capsys.readouterr().err
    assert ("numberOfLayers 5 is more than" in warned) == edit
    assert lidar.getNumberOfLayers() == (2 if edit else 1)
    expected = [0.5 / math.cos(0.1)] * 2 if edit else [0.5]
    assert lidar.getRangeImage() == pytest.approx(expected, rel=1e-9)
    assert len(lidar.getRangeImageArray()) == (2 if edit else 1)


@pytest.mark.parametrize("edit", [True, False])
def test_rotating_lidar_horizontal_resolution_edit_sizes_its_turning_image(edit: bool) -> None:
    # a rotating lidar's image spans 2π (D §3.1), cast column by column as its head turns (D §3.2); at 10 Hz and
    # 8 ms per step the head turns 0.08 turn a step, so 13 steps (1.04 turns) cast every column. W = 16 instead
    # of 8: 16 ranges, none 0 (the wall or +inf beyond maxRange 1)
    sup, lidar, node = _lidar('DEF L Lidar { name "l" type "rotating" horizontalResolution 8 numberOfLayers 1 }')
    if edit:
        node.getField("horizontalResolution").setSFInt32(16)
    for _ in range(13):
        sup.step(STEP)
    image = lidar.getRangeImage()
    assert lidar.getHorizontalResolution() == len(image) == (16 if edit else 8)
    assert all(v > 0.0 for v in image)
    assert len(lidar.getPointCloud()) == 0  # the cloud is off: a warning and no point, whatever the size


@pytest.mark.parametrize("edit", [True, False])
def test_lidar_frequency_field_edits_set_its_bounds_and_frequency(edit: bool) -> None:
    # D §3.1/§3.3: defaults 1/25 Hz, defaultFrequency 10; setFrequency outside [min, max] is refused (error).
    # maxFrequency 8 written: the bounds are [1, 8] and the current 10 is clamped to 8 (image_edits' choice);
    # setFrequency(9) is then refused. defaultFrequency 5 written: the frequency is 5, replacing what the
    # controller set (6)
    sup, lidar, node = _lidar()
    if edit:
        node.getField("maxFrequency").setSFFloat(8.0)
    sup.step(STEP)
    assert lidar.getMaxFrequency() == (8.0 if edit else 25.0)
    assert lidar.getFrequency() == (8.0 if edit else 10.0)
    lidar.setFrequency(9.0)
    assert lidar.getFrequency() == (8.0 if edit else 9.0)
    lidar.setFrequency(6.0)
    if edit:
        node.getField("defaultFrequency").setSFFloat(5.0)
    sup.step(STEP)
    assert lidar.getFrequency() == (5.0 if edit else 6.0)
    assert lidar.getMinFrequency() == 1.0
    sup.simulationReset()  # the load's bounds and frequency again (the restored fields read again)
    sup.step(STEP)
    assert (lidar.getMaxFrequency(), lidar.getFrequency()) == ((25.0, 10.0) if edit else (25.0, 6.0))


@pytest.mark.parametrize("edit", [True, False])
def test_lidar_type_edit_is_named_and_not_applied(edit: bool, capsys: pytest.CaptureFixture[str]) -> None:
    # a fixed lidar's type written "rotating": the image keeps the fixed lidar's fieldOfView span (one ray ahead,
    # 0.5) and one warning line says the edit is not applied (image_edits' choice; D is silent)
    sup, lidar, node = _lidar()
    capsys.readouterr()
    if edit:
        node.getField("type").setSFString("rotating")
    sup.step(STEP)
    sup.step(STEP)
    assert lidar.getFov() == 0.1
    assert lidar.getRangeImage() == pytest.approx([0.5])
    warned = capsys.readouterr().err
    assert warned.count("a run-time edit of type is not applied") == (1 if edit else 0)


# ------------------------------------------------------------------------------------ RangeFinder, Camera


@pytest.mark.parametrize("edit", [True, False])
def test_range_finder_width_edit_sizes_the_next_image(edit: bool, capsys: pytest.CaptureFixture[str]) -> None:
    # D §3.2: a planar range is the perpendicular depth to the image plane, 0.5 for every pixel that sees the
    # plane x = 0.5 (3 columns span ±tan(fov/2)·2/3 = ±0.276 sideways, well inside the 4 m wall). A width of 0
    # written afterwards keeps 3 with a warning (image_edits' choice)
    sup = sensor_world('DEF RF RangeFinder { name "rf" width 1 height 1 }', SEEN_WALL, step=STEP)
    rf = sup.getDevice("rf")
    rf.enable(STEP)
    sup.step(STEP)
    node = sup.getFromDef("RF")
    if edit:
        node.getField("width").setSFInt32(3)
    sup.step(STEP)
    size = 3 if edit else 1
    assert (rf.getWidth(), rf.getHeight()) == (size, 1)
    assert rf.getRangeImage() == pytest.approx([0.5] * size, rel=1e-9)
    capsys.readouterr()
    if edit:
        node.getField("width").setSFInt32(0)
    sup.step(STEP)
    assert rf.getWidth() == size
    assert ("width 0 is not in 1..16384; it stays 3" in capsys.readouterr().err) is edit
    sup.simulationReset()  # the load's width again
    sup.step(STEP)
    sup.step(STEP)
    assert rf.getWidth() == 1 and len(rf.getRangeImage()) == 1


@pytest.mark.parametrize("edit", [True, False])
def test_camera_size_edit_sizes_the_next_image(edit: bool) -> None:
    # D §4: the image is BGRA, 4·width·height bytes; width 6, height 2 written: 48 bytes from the next sample
    sup = sensor_world('DEF C Camera { name "c" width 4 height 4 }', SEEN_WALL, step=STEP)
    camera = sup.getDevice("c")
    camera.enable(STEP)
    sup.step(STEP)
    assert len(camera.getImage()) == 4 * 4 * 4
    if edit:
        node = sup.getFromDef("C")
        node.getField("width").setSFInt32(6)
        node.getField("height").setSFInt32(2)
    sup.step(STEP)
    width, height = (6, 2) if edit else (4, 4)
    assert (camera.getWidth(), camera.getHeight()) == (width, height)
    image = camera.getImage()
    assert len(image) == 4 * width * height
    assert set(image[3::4]) == {255}  # drawn (opaque), not the black zeros of an image not sampled yet
    assert len(camera.getImageArray()) == width and len(camera.getImageArray()[0]) == height
    sup.simulationReset()  # the load's 4×4 again (the restored fields read again)
    sup.step(STEP)
    sup.step(STEP)
    assert (camera.getWidth(), camera.getHeight(), len(camera.getImage())) == (4, 4, 64)


# ------------------------------------------- devices that read their fields at every sample (guards, live already)


def _sensor(node: str, enable: str = "enable") -> tuple:  # type: ignore[type-arg]
    sup = sensor_world(node, "", step=STEP)
    device = sup.getDevice("s")
    getattr(device, enable)(STEP)
    sup.step(STEP)
    return sup, device, sup.getFromDef("S")


@pytest.mark.parametrize("edit", [True, False])
def test_compass_resolution_edit_rounds_the_next_sample(edit: bool) -> None:
    # ENU: north is +y; an unrotated compass reads [0, 1, 0]; resolution 0.3 rounds 1 to int(1/0.3 + 0.5)·0.3 = 0.9
    # (D §0.4)
    sup, compass, node = _sensor('DEF S Compass { name "s" }')
    assert compass.getValues() == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    if edit:
        node.getField("resolution").setSFFloat(0.3)
    sup.step(STEP)
    assert compass.getValues() == pytest.approx([0.0, 0.9 if edit else 1.0, 0.0], abs=1e-12)


@pytest.mark.parametrize("edit", [True, False])
def test_gps_and_altimeter_resolution_edit_rounds_the_next_sample(edit: bool) -> None:
    # the robot's origin is 0.1 m up: resolution 0.08 rounds 0.1 to int(0.1/0.08 + 0.5)·0.08 = 0.08 (D §0.4)
    sup = sensor_world('DEF G GPS { name "g" } DEF A Altimeter { name "a" }', "", step=STEP)
    gps, altimeter = sup.getDevice("g"), sup.getDevice("a")
    gps.enable(STEP)
    altimeter.enable(STEP)
    sup.step(STEP)
    if edit:
        sup.getFromDef("G").getField("resolution").setSFFloat(0.08)
        sup.getFromDef("A").getField("resolution").setSFFloat(0.08)
    sup.step(STEP)
    assert gps.getValues()[2] == pytest.approx(0.08 if edit else 0.1, abs=1e-12)
    assert altimeter.getValue() == pytest.approx(0.08 if edit else 0.1, abs=1e-12)


@pytest.mark.parametrize("edit", [True, False])
def test_inertial_unit_axis_edit_disables_the_roll(edit: bool) -> None:
    # xAxis FALSE: the roll reads NaN (the InertialUnit page); the unrotated unit's angles are 0
    sup, unit, node = _sensor('DEF S InertialUnit { name "s" }')
    if edit:
        node.getField("xAxis").setSFBool(False)
    sup.step(STEP)
    roll, pitch, yaw = unit.getRollPitchYaw()
    assert math.isnan(roll) is edit
    assert (pitch, yaw) == (pytest.approx(0.0, abs=1e-12), pytest.approx(0.0, abs=1e-12))


@pytest.mark.parametrize("edit", [True, False])
def test_led_color_list_edit_sets_the_values_it_takes(edit: bool) -> None:
    # a non-gradual LED takes 0..len(color) (the LED page): with one colour, set(2) is refused; a second colour
    # inserted makes 2 a valid value from the step that executes the write (webots-on-ode.md §6)
    sup = sensor_world('DEF S LED { name "s" color [ 1 0 0 ] }', "", step=STEP)
    led = sup.getDevice("s")
    if edit:
        sup.getFromDef("S").getField("color").insertMFColor(-1, [0.0, 1.0, 0.0])
    sup.step(STEP)
    led.set(2)
    sup.step(STEP)
    assert led.get() == (2 if edit else 0)


@pytest.mark.parametrize("edit", [True, False])
def test_battery_and_cpu_consumption_edits_drain_from_the_next_step(edit: bool) -> None:
    # each step takes dt·cpuConsumption: 0.008 s · 10 W = 0.08 J (the Robot page; no motor). The level written
    # 50 and cpuConsumption 20 W: 50 − 0.008·20 = 49.84 J after one step; the control 100 − 2·0.08 = 99.84 J
    sup = sensor_world("", "", robot_extra="battery [ 100, 100, 0 ] cpuConsumption 10", step=STEP)
    sup.batterySensorEnable(STEP)
    sup.step(STEP)
    assert sup.batterySensorGetValue() == pytest.approx(99.92)
    robot = sup.getSelf()
    if edit:
        robot.getField("battery").setMFFloat(0, 50.0)
        robot.getField("cpuConsumption").setSFFloat(20.0)
    sup.step(STEP)
    assert sup.batterySensorGetValue() == pytest.approx(49.84 if edit else 99.84)


@pytest.mark.parametrize("edit", [True, False])
def test_recognition_max_range_and_max_objects_edits_act_at_the_next_sample(edit: bool) -> None:
    # two recognisable 0.2 m cubes straight ahead of the camera (axis +x) at 2 m and 1 m, side by side: with
    # maxRange 1.5 only the near one is reported; maxRange 3 written adds the far one, and maxObjects 1 written
    # then keeps one (D §4: the Recognition fields maxRange, maxObjects)
    cube = ('Solid {{ translation {x} {y} 0.1 recognitionColors [ 1 0 0 ] children [ Shape {{ geometry Box '
            '{{ size 0.2 0.2 0.2 }} }} ] boundingObject Box {{ size 0.2 0.2 0.2 }} }}')
    walls = cube.format(x=2.0, y=0.3) + " " + cube.format(x=1.0, y=-0.3)
    sup = sensor_world('Camera { name "c" width 32 height 32 recognition DEF R Recognition { maxRange 1.5 } }',
                       walls, step=STEP)
    camera = sup.getDevice("c")
    camera.recognitionEnable(STEP)
    sup.step(STEP)
    assert camera.getRecognitionNumberOfObjects() == 1
    recognition = sup.getFromDef("R")
    if edit:
        recognition.getField("maxRange").setSFFloat(3.0)
    sup.step(STEP)
    assert camera.getRecognitionNumberOfObjects() == (2 if edit else 1)
    if edit:
        recognition.getField("maxObjects").setSFInt32(1)
    sup.step(STEP)
    assert camera.getRecognitionNumberOfObjects() == 1


@pytest.mark.parametrize("edit", [True, False])
def test_light_sensor_color_filter_edit_acts_at_the_next_sample(edit: bool) -> None:
    # a light sensor facing up (x axis turned to +z) under a DirectionalLight reads more than 0; a colorFilter of
    # 0 0 0 written filters every channel out: irradiance 0, read lookup(0) = 0 on the default table
    sup = sensor_world('DEF S LightSensor { name "s" rotation 0 1 0 -1.5708 }', "",
                       head="DirectionalLight { direction 0 0 -1 }", step=STEP)
    sensor = sup.getDevice("s")
    sensor.enable(STEP)
    sup.step(STEP)
    assert sensor.getValue() > 0.0
    if edit:
        sup.getFromDef("S").getField("colorFilter").setSFColor([0.0, 0.0, 0.0])
    sup.step(STEP)
    assert (sensor.getValue() == 0.0) is edit


@pytest.mark.parametrize("edit", [True, False])
def test_radar_max_range_edit_acts_at_the_next_sample(edit: bool) -> None:
    # a target (radarCrossSection > 0) 5 m ahead on the radar's x axis, inside [minRange 1, maxRange 50]: one
    # target; maxRange 3 written leaves it beyond the range (the Radar page)
    target = ("Solid { translation 5 0 0.1 radarCrossSection 1 children [ Shape { geometry Box { size 0.5 0.5 0.5 } } ] "
              "boundingObject Box { size 0.5 0.5 0.5 } }")
    sup = sensor_world('DEF S Radar { name "s" }', target, step=STEP)
    radar = sup.getDevice("s")
    radar.enable(STEP)
    sup.step(STEP)
    assert radar.getNumberOfTargets() == 1
    if edit:
        sup.getFromDef("S").getField("maxRange").setSFFloat(3.0)
    sup.step(STEP)
    assert radar.getNumberOfTargets() == (0 if edit else 1)


# ------------------------------------------------------------------------------------------ controller processes

PROCESS_WORLD = """
WorldInfo { basicTimeStep 8 }
Robot { name "a" controller "reader" children [
  DEF L Lidar { name "l" horizontalResolution 4 numberOfLayers 1 fieldOfView 0.4 }
  DEF C Camera { name "c" width 4 height 4 }
] }
Robot { name "b" supervisor TRUE controller "editor" }
"""

READER = """from controller import Robot
robot = Robot()
lidar, camera = robot.getDevice("l"), robot.getDevice("c")
lidar.enable(8)
camera.enable(8)
print("LOAD", lidar.getHorizontalResolution(), lidar.getMaxFrequency(), camera.getWidth())
for _ in range(3):
    robot.step(8)
print("LATER", lidar.getHorizontalResolution(), len(lidar.getRangeImage()), lidar.getMaxFrequency(),
      camera.getWidth(), len(camera.getImage()))
"""

EDITOR = """from controller import Supervisor
sup = Supervisor()
sup.step(8)
sup.getFromDef("L").getField("horizontalResolution").setSFInt32(8)
sup.getFromDef("L").getField("maxFrequency").setSFFloat(20.0)
sup.getFromDef("C").getField("width").setSFInt32(2)
for _ in range(3):
    sup.step(8)
"""


def test_a_controller_process_reads_the_edited_sizes(tmp_path: Path) -> None:
    # the reader runs in its own process, as in Webots: before the edit (before its first step, which the
    # editor's edit follows) 4 columns, maxFrequency 25, a 4-pixel-wide camera; after its next steps 8 columns
    # (8 ranges), 20 Hz, a 2×4 camera (4·2·4 = 32 bytes)
    out = run_multi(tmp_path, PROCESS_WORLD, {"reader": READER, "editor": EDITOR}, "process", duration_s=0.1)
    lines = {line.split()[0]: line.split()[1:] for line in out if line[:4] in ("LOAD", "LATE")}
    assert [float(v) for v in lines["LOAD"]] == [4, 25.0, 4]
    assert [float(v) for v in lines["LATER"]] == [8, 8, 20.0, 2, 32]
