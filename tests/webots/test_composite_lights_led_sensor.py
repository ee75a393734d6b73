"""Composite: a LightSensor lit by an LED's PointLight, and by a lamp a supervisor moves.

Webots' LED reference page: the lights among an LED's children are off while the LED is off (``set(0)``, its
state at start) and on in the LED's colour otherwise, the ``color`` entry the value selects (1 the first), or for
a ``gradual`` LED the value read as 0xRRGGBB. The value reaches the world with the controller's next step request.

The LightSensor (its x axis up) reads ``1000·E`` through the default table ``[0 0 0, 1 1000 0]``, with
``E = intensity·cos θ/(a1 + a2·d + a3·d²)·(r·fr + g·fg + b·fb)/3`` (light_sensor.py, the LightSensor page's
irradiance with the colour weighted by the white default ``colorFilter``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.led import LED
from dualtwin.webots.light_sensor import LightSensor
from dualtwin.webots.physics import Simulation
from tests.support.isolation_runs import assert_threads_print, run_in_both_modes

UP = "rotation 0 1 0 -1.5707963267948966"  # the sensor's x axis points up, +z
# 1 m above the sensor, straight along its axis: d = 1, cos θ = 1, E = 0.5/1² = 0.5 for white light
LAMP = "PointLight { location 0 0 1 attenuation 0 0 1 intensity 0.5 }"


def _open(children: str, top: str = "") -> tuple[Supervisor, LightSensor]:
    text = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 }}
{top}
Robot {{ children [ LightSensor {{ name "ls" {UP} }} {children} ] controller "<extern>" supervisor TRUE }}
"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    sensor = sup.getDevice("ls")
    assert isinstance(sensor, LightSensor)
    sensor.enable(16)
    return sup, sensor


def _after_step(sup: Supervisor, sensor: LightSensor) -> float:
    sup.step(16)
    return float(sensor.getValue())


def _led(sup: Supervisor) -> LED:
    led = sup.getDevice("led")
    assert isinstance(led, LED)
    return led


def test_the_light_sensor_follows_the_led_driving_the_light() -> None:
    sup, sensor = _open(f'LED {{ name "led" color [ 1 0 0, 1 1 1 ] children [ Pose {{ children [ {LAMP} ] }} ] }}')
    led = _led(sup)
    assert _after_step(sup, sensor) == pytest.approx(0.0, abs=1e-9)  # off at start, whatever the light's `on`
    led.set(2)
    assert _after_step(sup, sensor) == pytest.approx(500.0, abs=1e-6)  # white: 1000·0.5·(1+1+1)/3
    led.set(1)
    assert _after_step(sup, sensor) == pytest.approx(500.0 / 3, abs=1e-6)  # red: 1000·0.5·(1+0+0)/3
    led.set(0)
    assert _after_step(sup, sensor) == pytest.approx(0.0, abs=1e-9)


def test_a_gradual_led_lights_with_its_value_as_rgb() -> None:
    sup, sensor = _open(f'LED {{ name "led" gradual TRUE color [] children [ {LAMP} ] }}')
    _led(sup).set(0x00FF00)
    # green 0xFF/255 = 1: 1000·0.5·(0+1+0)/3
    assert _after_step(sup, sensor) == pytest.approx(500.0 / 3, abs=1e-6)


def test_a_light_in_a_lamp_solid_is_read_where_a_supervisor_moved_it() -> None:
    # (a guard: the sensor read lights inside Solids at the Solid's current pose before the LED work)
    sup, sensor = _open("", top=f"DEF LAMP Solid {{ translation 0 0 0.5 children [ {LAMP} ] }}")
    # the light at (0, 0, 0.5) + (0, 0, 1): d = 1.5, E = 0.5/2.25
    assert _after_step(sup, sensor) == pytest.approx(1000 * 0.5 / 2.25, abs=1e-6)
    lamp = sup.getFromDef("LAMP")
    assert lamp is not None
    lamp.getField("translation").setSFVec3f([0.0, 0.0, 1.0])
    # now at (0, 0, 2): d = 2, E = 0.5/4
    assert _after_step(sup, sensor) == pytest.approx(125.0, abs=1e-6)


def test_a_controller_in_its_own_process_switches_the_led_light_with_its_step(tmp_path: Path) -> None:
    # LED.set is buffered in a controller process and goes with the step request, as in libController: the
    # readings are those of the thread mode, 0 (off at start), 500 (white), 500/3 (red), 0 as above
    world = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 16 gravity 0 }}
Robot {{
  children [ LightSensor {{ name "ls" {UP} }} LED {{ name "led" color [ 1 0 0, 1 1 1 ] children [ {LAMP} ] }} ]
  controller "probe"
}}
"""
    script = """
        from controller import Robot
        robot = Robot()
        sensor, led = robot.getDevice("ls"), robot.getDevice("led")
        sensor.enable(16)
        for value in (0, 2, 1, 0):
            led.set(value)
            robot.step(16)
            print(round(sensor.getValue(), 3))
    """
    assert_threads_print(run_in_both_modes(tmp_path, world, script, 0.064), "0.0\n500.0\n166.667\n0.0\n")

