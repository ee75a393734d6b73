"""Composite: devices that report a direction or a place on Earth, in a world whose ``coordinateSystem`` is not ENU.

webots-on-ode.md §1.1: ``coordinateSystem`` names the world axes, "ENU" x=East, y=North, z=Up, and "NUE" and "EUN"
are accepted as well: each letter names the axis at its place, so in "EUN" x is East, y is Up and z is North. One
world has one north: the Compass's north and the GPS's WGS84 latitude must both take it from those letters.
Before this test the GPS took an EUN world's north as -z (a right-handed East-North-Up read into a y-up world)
while its Compass read +z as north: walking toward the Compass's north lowered the GPS latitude.

A ``coordinateSystem`` (or ``gpsCoordinateSystem``) the devices cannot read falls back to Webots' default, as
before, but no longer silently: the build names it in one line.
"""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.quiet_worlds import quiet_supervisor


def _readings(system: str, translation: str) -> tuple[list[float], list[float]]:
    """(GPS WGS84 reading, Compass reading) of a robot standing at ``translation`` (no physics: it stays)."""
    sup = quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep 8 coordinateSystem "{system}" gpsCoordinateSystem "WGS84" gpsReference 46.5 6.6 400 }}
Robot {{ supervisor TRUE translation {translation} children [ GPS {{ name "gps" }} Compass {{ name "compass" }} ] }}
""")
    gps, compass = sup.getDevice("gps"), sup.getDevice("compass")
    gps.enable(8)
    compass.enable(8)
    sup.step(8)
    return list(gps.getValues()), list(compass.getValues())


def test_an_eun_world_has_one_north_for_its_gps_and_its_compass() -> None:
    # The same place on Earth written in both systems: 30 m East, 20 m North, 5 m Up is (30, 20, 5) in ENU and
    # (30, 5, 20) in EUN (x East, y Up, z North), so the two GPS read the same latitude, longitude and altitude.
    enu, enu_north = _readings("ENU", "30 20 5")
    eun, eun_north = _readings("EUN", "30 5 20")
    assert eun == pytest.approx(enu, abs=1e-12)
    assert enu_north == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    assert eun_north == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)  # the Compass: north is +z


def test_walking_toward_the_compass_north_raises_the_latitude_in_every_system() -> None:
    for system, north_step in (("ENU", "0 10 0"), ("NUE", "10 0 0"), ("EUN", "0 0 10")):
        origin, _ = _readings(system, "0 0 0")
        moved, _ = _readings(system, north_step)
        # 10 m north is about 10/111 km of latitude (9e-5°), and almost no change of longitude (grid convergence)
        assert moved[0] - origin[0] == pytest.approx(10.0 / 111_180.0, rel=0.01), system
        assert abs(moved[1] - origin[1]) < 1e-5, system


def _world_info_warnings(info: str) -> list[str]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(f"#VRML_SIM R2023b utf8\nWorldInfo {{ {info} }}\n"))
    return [w for w in sim.build_warnings if "WorldInfo" in w and "oordinateSystem" in w]


def test_a_coordinate_system_the_devices_cannot_read_is_named_in_one_line() -> None:
    # bad input gets one clear line: the world is read as ENU, and a GPS system other than local/WGS84 as local
    # (the GPS compares the exact text, as Webots' WorldInfo page writes it); the readings themselves are unchanged
    assert _world_info_warnings('coordinateSystem "NED"') == [
        'WorldInfo: coordinateSystem "NED" is not "ENU", "NUE" or "EUN": the world is read as ENU (gravity along -z, '
        "north +y)"]
    assert _world_info_warnings('gpsCoordinateSystem "wgs84"') == [
        'WorldInfo: gpsCoordinateSystem "wgs84" is not "local" or "WGS84": GPS devices read local coordinates']
    # controls: the values Webots names, the coordinate system in any case, say nothing
    for info in ('coordinateSystem "NUE" gpsCoordinateSystem "WGS84"', 'coordinateSystem "eun"', ""):
        assert _world_info_warnings(info) == [], info


def test_a_compass_keeps_the_north_of_the_load_when_a_supervisor_writes_the_coordinate_system() -> None:
    # The coordinateSystem is read at load only, for the gravity and every device (the coverage registry's WorldInfo
    # entry): a Compass with the world's axes reads north = +y of an ENU world, (0, 1, 0), before and after
    # "NUE" is written; it read the field at every sample, and took +x (NUE's north) while the gravity stayed ENU's
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n"
                                         'Robot { supervisor TRUE children [ Compass { name "c" } ] }\n'))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    try:
        compass = sup.getDevice("c")
        compass.enable(8)
        sup.step(8)
        assert compass.getValues() == pytest.approx([0.0, 1.0, 0.0])  # the control
        sup.getRoot().getField("children").getMFNode(0).getField("coordinateSystem").setSFString("NUE")
        sup.step(8)
        assert compass.getValues() == pytest.approx([0.0, 1.0, 0.0])
        assert sim.gravity == (0.0, 0.0, -9.81)
    finally:
        sim.close()
