"""Composite: a Camera's image of a white box lit by a light the robot carries, or by an LED's light.

In Webots a light is a child like any other: a PointLight inside a Solid has its ``location`` in the Solid's frame
and moves with it (PointLight reference page), and an LED switches the lights among its children: off while the
LED is off (``set(0)``, its state at start), on in the colour its value selects otherwise (LED reference page).
The twin's camera drew only the world's top-level lights, and its PointLights (MuJoCo "point" lights, which
MuJoCo's renderer draws as nothing) not at all.

Expected values are relative: every image is compared with a control world drawn by the same renderer, the
same light at top level at the world place worked out by hand (the same pixel), or no light (MuJoCo's headlight
alone, the darker pixel).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dualtwin.webots.camera import Camera
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.led import LED
from dualtwin.webots.physics import Simulation
from dualtwin.webots.protos import load_world_text

# The robot at (0.5, 0, 0) turned a quarter turn about z: its x axis (the camera's view) is the world's +y, its y
# axis the world's -x. The white box's near face is at y = 1.9, straight ahead of the camera.
ROBOT_AT = "0.5 0 0"
# Dim lamps (attenuation 1/d²) so that the box stays below white: a brighter pixel means more light.
LAMP = "attenuation 0 0 1 intensity 0.05"
# location 1.5 -0.2 0.3 in the robot's frame is the world point (0.5, 0, 0) + (0.2, 1.5, 0.3) = (0.7, 1.5, 0.3)
CARRIED = f"PointLight {{ location 1.5 -0.2 0.3 {LAMP} }}"
SAME_AT_TOP = f"PointLight {{ location 0.7 1.5 0.3 {LAMP} }}"
# a spot 0.4 m in front of the face's centre, pointing at it: location 1.5 0 0 is the world point (0.5, 1.5, 0),
# direction 1 0 0 (the robot's x axis) the world's +y
DIM = "attenuation 0 0 1 intensity 0.01"
CARRIED_SPOT = f"SpotLight {{ location 1.5 0 0 direction 1 0 0 {DIM} }}"
SPOT_AT_TOP = f"SpotLight {{ location 0.5 1.5 0 direction 0 1 0 {DIM} }}"


def _world(top: str, carried: str, robot_at: str = ROBOT_AT) -> str:
    return f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 }}
{top}
Solid {{ translation 0.5 2 0 children [ Shape {{ geometry Box {{ size 1 0.2 1 }} }} ] }}
DEF ROBOT Robot {{
  translation {robot_at} rotation 0 0 1 1.5707963267948966
  children [ Camera {{ name "cam" width 16 height 16 }} {carried} ]
  controller "<extern>"
  supervisor TRUE
}}
"""


def _open(text: str) -> tuple[Supervisor, Camera]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    cam = sup.getDevice("cam")
    assert isinstance(cam, Camera)
    cam.enable(16)
    return sup, cam


def _centre_bgr(cam: Camera) -> np.ndarray:
    """The mean B, G, R bytes of the image's centre (on the box's near face)."""
    image = np.frombuffer(cam.getImage(), dtype=np.uint8).reshape(16, 16, 4)
    return np.asarray(image[6:10, 6:10, :3], dtype=float).mean(axis=(0, 1))


def _box_bgr(sup: Supervisor, cam: Camera) -> np.ndarray:
    """:func:`_centre_bgr` after one more step."""
    sup.step(16)
    return _centre_bgr(cam)


def _pixel(text: str) -> np.ndarray:
    return _box_bgr(*_open(text))


def test_a_point_light_lights_the_box() -> None:
    # at top level, 0.4 m in front of the face's centre: the pixel brighter than by MuJoCo's headlight alone
    dark = _pixel(_world("", ""))
    lit = _pixel(_world(f"PointLight {{ location 0.5 1.5 0 {DIM} }}", ""))
    assert (lit > dark + 5).all(), (lit, dark)


@pytest.mark.parametrize(("carried", "at_top"), [(CARRIED, SAME_AT_TOP), (CARRIED_SPOT, SPOT_AT_TOP)],
                         ids=["PointLight", "SpotLight"])
def test_a_light_the_robot_carries_lights_the_box_as_the_same_light_at_its_world_place(carried: str,
                                                                                     at_top: str) -> None:
    dark = _pixel(_world("", ""))
    control = _pixel(_world(at_top, ""))
    assert (control > dark + 5).all(), (control, dark)  # the control light does light the box
    lit = _pixel(_world("", f"Pose {{ children [ {carried} ] }}"))
    np.testing.assert_allclose(lit, control, atol=1.0)
    # the fields read as world coordinates would be another place (the point light 1.7 m from the face, the spot
    # pointing along +x, away from it)
    elsewhere = _pixel(_world(carried, ""))
    assert (np.abs(elsewhere - lit) > 5).all(), (elsewhere, lit)
    # a carried light switched off by its own field lights nothing
    kind = carried.split(" ")[0]
    off = _pixel(_world("", carried.replace(f"{kind} {{", f"{kind} {{ on FALSE")))
    np.testing.assert_allclose(off, dark, atol=1.0)


def test_a_carried_point_light_moves_with_the_robot() -> None:
    sup, cam = _open(_world("", CARRIED))
    _box_bgr(sup, cam)
    robot = sup.getFromDef("ROBOT")
    assert robot is not None
    robot.getField("translation").setSFVec3f([0.2, 0.0, 0.0])
    moved = _box_bgr(sup, cam)
    # control: the robot loaded there, the light at top level at (0.2, 0, 0) + (0.2, 1.5, 0.3) = (0.4, 1.5, 0.3)
    control = _pixel(_world(f"PointLight {{ location 0.4 1.5 0.3 {LAMP} }}", "", robot_at="0.2 0 0"))
    np.testing.assert_allclose(moved, control, atol=1.0)
    # and not as a light left where it was loaded, (0.7, 1.5, 0.3)
    stuck = _pixel(_world(SAME_AT_TOP, "", robot_at="0.2 0 0"))
    assert (np.abs(stuck - moved) > 5).all(), (stuck, moved)


def test_an_led_switches_its_light_and_gives_it_its_colour() -> None:
    dark = _pixel(_world("", ""))
    white = _pixel(_world(SPOT_AT_TOP, ""))
    assert (white > dark + 5).all(), (white, dark)
    led = f'LED {{ name "led" color [ 1 1 1, 0 0 1 ] children [ {CARRIED_SPOT} ] }}'
    sup, cam = _open(_world("", led))
    device = sup.getDevice("led")
    assert isinstance(device, LED)
    # off at start: the light's own `on TRUE` does not light it
    np.testing.assert_allclose(_box_bgr(sup, cam), dark, atol=1.0)
    sup.step(16)
    device.set(1)
    # the image of the step just done, read after the set: the value goes out with the next step request
    np.testing.assert_allclose(_centre_bgr(cam), dark, atol=1.0)
    np.testing.assert_allclose(_box_bgr(sup, cam), white, atol=1.0)
    device.set(2)  # blue: the image's B byte as with the white light, G and R as without light
    np.testing.assert_allclose(_box_bgr(sup, cam), [white[0], dark[1], dark[2]], atol=1.0)
    device.set(0)
    np.testing.assert_allclose(_box_bgr(sup, cam), dark, atol=1.0)


def test_a_gradual_led_gives_its_light_the_value_read_as_rgb() -> None:
    dark = _pixel(_world("", ""))
    white = _pixel(_world(SPOT_AT_TOP, ""))
    assert (white > dark + 5).all(), (white, dark)
    sup, cam = _open(_world("", f'LED {{ name "led" gradual TRUE color [] children [ {CARRIED_SPOT} ] }}'))
    device = sup.getDevice("led")
    assert isinstance(device, LED)
    device.set(0xFF0000)
    # red: R (the image's third byte) as with the white light, B and G as without light
    np.testing.assert_allclose(_box_bgr(sup, cam), [dark[0], dark[1], white[2]], atol=1.0)


def test_a_supervisor_switching_a_light_or_changing_its_colour_shows_at_the_next_image() -> None:
    # Webots' lights follow their edited fields (the PointLight page's `on`, `color`, `intensity`)
    dark = _pixel(_world("", ""))
    white = _pixel(_world(SPOT_AT_TOP, ""))
    assert (white > dark + 5).all(), (white, dark)
    sup, cam = _open(_world(f"DEF LAMP {SPOT_AT_TOP}", ""))
    np.testing.assert_allclose(_box_bgr(sup, cam), white, atol=1.0)
    lamp = sup.getFromDef("LAMP")
    assert lamp is not None
    lamp.getField("color").setSFColor([0.0, 1.0, 0.0])  # green: G as with white light, B and R as without light
    np.testing.assert_allclose(_box_bgr(sup, cam), [dark[0], white[1], dark[2]], atol=1.0)
    lamp.getField("on").setSFBool(False)
    np.testing.assert_allclose(_box_bgr(sup, cam), dark, atol=1.0)



def test_a_supervisors_light_edit_is_not_in_the_image_of_the_step_before() -> None:
    # webots-on-ode.md §6: a supervisor's field write is "executed at the beginning of the next step"; Webots draws
    # a camera image during its step, so the image of the step just done, read after the write, shows the light
    # as it was. The twin draws an image when it is first read: it showed the write at once
    dark = _pixel(_world("", ""))
    white = _pixel(_world(SPOT_AT_TOP, ""))
    sup, cam = _open(_world(f"DEF LAMP {SPOT_AT_TOP}", ""))
    lamp = sup.getFromDef("LAMP")
    assert lamp is not None
    sup.step(16)
    lamp.getField("on").setSFBool(False)
    np.testing.assert_allclose(_centre_bgr(cam), white, atol=1.0)
    np.testing.assert_allclose(_box_bgr(sup, cam), dark, atol=1.0)  # control: the step executed it
    lamp.getField("on").setSFBool(True)
    sup.step(16)
    lamp.getField("ambientIntensity").setSFFloat(0.2)  # an ambient light of 0.2 everywhere: brighter
    np.testing.assert_allclose(_centre_bgr(cam), white, atol=1.0)
    assert (_box_bgr(sup, cam) > white + 5).all()


def test_a_supervisors_edit_of_an_leds_colours_is_not_in_the_image_of_the_step_before() -> None:
    # as above for an LED's color list, which gives its lights their colour (LED reference page)
    dark = _pixel(_world("", ""))
    white = _pixel(_world(SPOT_AT_TOP, ""))
    sup, cam = _open(_world("", f'DEF LED LED {{ name "led" color [ 1 1 1 ] children [ {CARRIED_SPOT} ] }}'))
    device = sup.getDevice("led")
    assert isinstance(device, LED)
    device.set(1)
    np.testing.assert_allclose(_box_bgr(sup, cam), white, atol=1.0)
    led = sup.getFromDef("LED")
    assert led is not None
    sup.step(16)
    led.getField("color").setMFColor(0, [0.0, 0.0, 1.0])
    np.testing.assert_allclose(_centre_bgr(cam), white, atol=1.0)
    # control: blue from the step that executed the edit (B as with white light, G and R as without light)
    np.testing.assert_allclose(_box_bgr(sup, cam), [white[0], dark[1], dark[2]], atol=1.0)


def test_a_supervisor_moving_or_turning_a_light_shows_at_the_next_image() -> None:
    # Webots' lights follow their edited location, direction, attenuation and cutOffAngle as their on/color (the
    # PointLight and SpotLight pages' fields; the LightSensor reads them so: light_sensor.py). Control worlds: the
    # same spot loaded where the edit puts it (0.1 m in front of the face's centre rather than 0.4 m), and the spot
    # turned away from the box (no light on the face: the no-light pixel)
    dark = _pixel(_world("", ""))
    closer = _pixel(_world(f"SpotLight {{ location 0.5 1.8 0 direction 0 1 0 {DIM} }}", ""))
    white = _pixel(_world(SPOT_AT_TOP, ""))
    assert (np.abs(closer - white) > 0.5).all(), (closer, white)
    sup, cam = _open(_world(f"DEF LAMP {SPOT_AT_TOP}", ""))
    lamp = sup.getFromDef("LAMP")
    assert lamp is not None
    np.testing.assert_allclose(_box_bgr(sup, cam), white, atol=0.1)
    lamp.getField("location").setSFVec3f([0.5, 1.8, 0.0])
    np.testing.assert_allclose(_box_bgr(sup, cam), closer, atol=0.1)
    lamp.getField("direction").setSFVec3f([0.0, -1.0, 0.0])
    np.testing.assert_allclose(_box_bgr(sup, cam), dark, atol=1.0)

def test_a_directional_light_in_a_turned_solid_shines_along_its_world_direction() -> None:
    # Webots' DirectionalLight page: its direction is "in the global coordinate system" wherever the node sits.
    # 0 1 0 shines onto the near face (its normal is -y); turned with the Solid (a quarter turn about z) it would
    # be -x, along the face, lighting nothing of it.
    dark = _pixel(_world("", ""))
    sun = "DirectionalLight { direction 0 1 0 intensity 0.1 }"
    control = _pixel(_world(sun, ""))
    assert (control > dark + 5).all(), (control, dark)
    lit = _pixel(_world(f"Solid {{ rotation 0 0 1 1.5707963267948966 children [ {sun} ] }}", ""))
    np.testing.assert_allclose(lit, control, atol=1.0)
