"""A sensor's ``lookupTable`` reaches the converted model (``webots_sensor_lut.<name>`` numeric) and the MuJoCo twin
reads what Webots computes (webots-devices §0.3, §1.4): the table's output of the physical value, clamped to its first
and last rows and interpolated between them, its noise multiplicative; a DistanceSensor's distance capped at the
last input D (its ray length), nothing in range reading ``lookup(D)``; then the resolution (§0.4).

Expected values are hand computations of those rules; the dual-twin tests read the Webots twin on the same world.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualtwin.convert import convert_world_text
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

PERIOD = 0.008
FALLING = "0 1000 0, 0.2 0 0"  # 1000 at contact, 0 at 0.2 m: 5000 per metre
RISING = "0 0 0, 0.3 300 0"  # 1000 per metre up to 0.3 m


def _world(devices: str, *, wall: float | None = None, yaw: float = 0.0) -> str:
    """A welded robot at the origin (yawed by ``yaw``) carrying ``devices``, and a wall whose near face is ``wall``
    metres ahead along +x (none: nothing to see). A GPS and a held hinge 1 m below give the robot a binding."""
    scene = (f'DEF R Robot {{ rotation 0 0 1 {yaw} controller "<extern>" children [ GPS {{ name "gps" }} '
             f"{devices} DEF H HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 0 1 }}\n"
             '  device [ PositionSensor { name "s" } RotationalMotor { name "m" } ]\n'
             "  endPoint DEF E Solid { translation 0 0 -1 physics Physics { } "
             "boundingObject Box { size 0.1 0.1 0.1 } } } ] }")
    if wall is not None:
        scene += f"\nSolid {{ name \"wall\" translation {wall + 0.01} 0 0 boundingObject Box {{ size 0.02 1 1 }} }}"
    return world_text(scene, "basicTimeStep 2 gravity 0")


def _ds(fields: str) -> str:
    return f'DistanceSensor {{ name "ds" {fields} }}'


def _mujoco(text: str) -> MuJoCoTwin:
    return MuJoCoTwin(convert_world_text(text, "t.wbt").spec, PERIOD)


@pytest.mark.parametrize(("table", "wall", "reading"), [
    (FALLING, 0.05, 750.0),  # 1000·(1 - 0.05/0.2)
    (FALLING, 0.5, 0.0),  # beyond D = 0.2: the distance is D, the last output
    (FALLING, None, 0.0),  # nothing in range: D, not MuJoCo's -1
    (RISING, 0.05, 50.0),
    (RISING, 0.5, 300.0),  # not the true 0.5 m
    (RISING, None, 300.0),
])
def test_a_distance_sensor_reads_its_lookup_table(table: str, wall: float | None, reading: float) -> None:
    twin = _mujoco(_world(_ds(f"lookupTable [ {table} ]"), wall=wall))
    assert twin.sensor("ds") == pytest.approx(reading, abs=1e-6)


def test_the_table_and_its_range_are_in_the_model() -> None:
    conv = convert_world_text(_world(_ds(f"lookupTable [ {RISING} ]")), "t.wbt")
    m = conv.compile()
    assert [float(v) for v in m.numeric("webots_sensor_lut.ds").data] == [0, 0, 0, 0.3, 300, 0]
    assert float(m.sensor_cutoff[m.sensor("ds").id]) == pytest.approx(0.3)  # MuJoCo's ray sees up to D
    assert not [w for w in conv.warnings if "lookupTable" in w or "ray" in w]  # one generic ray: nothing approximate


def test_the_default_table_applies_when_the_world_gives_none() -> None:
    # Webots' default lookupTable [0 0 0, 0.1 1000 0]: 0.05 m reads 500, nothing in range 1000.
    assert _mujoco(_world(_ds(""), wall=0.05)).sensor("ds") == pytest.approx(500.0, abs=1e-6)
    assert _mujoco(_world(_ds(""))).sensor("ds") == pytest.approx(1000.0, abs=1e-6)


def test_an_empty_table_reads_zero() -> None:
    # webots-devices §1.4: an empty DistanceSensor table reads 0 (no ray), whatever is in front.
    assert _mujoco(_world(_ds("lookupTable [ ]"), wall=0.05)).sensor("ds") == 0.0


def test_control_an_identity_table_reads_the_distance() -> None:
    # Control: a table mapping metres to metres (within its 10 m) reads the raw distance, as before this change.
    assert _mujoco(_world(_ds("lookupTable [ 0 0 0, 10 10 0 ]"), wall=0.05)).sensor("ds") == pytest.approx(
        0.05, abs=1e-9)


def test_the_resolution_rounds_the_table_output() -> None:
    # lookup 50, then int(50/30 + 0.5)·30 = 60 (the resolution of the output, not of the metres).
    twin = _mujoco(_world(_ds(f"lookupTable [ {RISING} ] resolution 30"), wall=0.05))
    assert twin.sensor("ds") == pytest.approx(60.0, abs=1e-9)


@pytest.mark.parametrize("seed", [0, 7])
def test_table_noise_is_multiplicative_from_the_twin_generator(seed: int) -> None:
    # Noise 0.1 at every row: reading = 50·(1 + 0.1·g), g the first normal draw of the twin's generator after
    # reset(seed) (the generator its other sensor noise draws from).
    twin = _mujoco(_world(_ds("lookupTable [ 0 0 0.1, 0.3 300 0.1 ]"), wall=0.05))
    twin.reset(seed)
    g = float(np.random.default_rng(seed).normal(0.0, 1.0))
    assert twin.sensor("ds") == pytest.approx(50.0 * (1.0 + 0.1 * g), abs=1e-6)


def test_only_infra_red_textures_are_reported_as_approximate() -> None:
    # Every type's rays are cast as Webots does (tests/convert/test_distance_rays.py); an infra-red sensor's
    # reflection reads each Shape's colour, not a texture at the hit point (§1.4), which is reported.
    warnings = convert_world_text(_world(
        'DistanceSensor { name "a" numberOfRays 3 aperture 0.5 } DistanceSensor { name "b" type "sonar" } '
        'DistanceSensor { name "c" type "infra-red" numberOfRays 3 aperture 0.5 } '
        'DistanceSensor { name "d" type "laser" numberOfRays 3 }'), "t.wbt").warnings
    assert not any("'a'" in w or "'b'" in w or "'d'" in w for w in warnings), warnings
    assert any("'c'" in w and "textures" in w for w in warnings), warnings


@pytest.mark.parametrize(("fields", "wall", "reading"), [
    (f"lookupTable [ {FALLING} ]", 0.05, 750.0),
    (f"lookupTable [ {FALLING} ]", None, 0.0),
    (f'type "sonar" lookupTable [ {RISING} ] resolution 30', 0.05, 60.0),  # a wall facing the ray echoes
    (f'type "laser" lookupTable [ {RISING} ]', 0.5, 300.0),
])
def test_the_webots_twin_reads_the_same_distance(tmp_path: Path, fields: str, wall: float | None,
                                                  reading: float) -> None:
    # Both twins cast one ray along +x against the same box (ODE's and MuJoCo's ray-box distances agree to
    # rounding, ~1e-15 m, times the table's slope of at most 5000 per metre): 1e-6 is far below any table step.
    with converted_twins(_world(_ds(fields), wall=wall), tmp_path, PERIOD) as (_, webots, mujoco_twin):
        for twin in (webots, mujoco_twin):
            twin.step()
            assert twin.sensor("ds") == pytest.approx(reading, abs=1e-6), twin.name
