"""Solid-state sensors read in their own frame and in the world's conventions (issue 26 item 1).

Expected values are derived by hand: a free sphere spinning at ω about the vertical in zero gravity keeps ω
(symmetric inertia, no damping), so a point at lever arm r from its centre accelerates by −ω²r (centripetal);
an accelerometer reads that (minus gravity) in its own axes, a gyro reads ω in its own axes. Controls: the old
sensors read the body's centre-of-mass acceleration for every mounting (all zero here), ignored lookup tables,
and read an InertialUnit in a NUE world as if it were ENU.
"""

from __future__ import annotations

import math
import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

W = 2.0  # rad/s


def _supervisor(text: str) -> Supervisor:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text("#VRML_SIM R2023b utf8\n" + text))
    return Supervisor(simulation=sim, robot_node=sim.robots[0].node)


SPINNER = f"""
WorldInfo {{ basicTimeStep 4 gravity 0 }}
Robot {{
  supervisor TRUE
  angularVelocity 0 0 {W}
  physics Physics {{ density -1 mass 1 }}
  boundingObject Sphere {{ radius 0.1 }}
  children [
    Accelerometer {{ name "centre" }}
    Accelerometer {{ name "east" translation 0.5 0 0 }}
    Accelerometer {{ name "north" translation 0 0.3 0 }}
    Accelerometer {{ name "east turned" translation 0.5 0 0 rotation 0 0 1 1.5707963267948966 }}
    Pose {{ translation 0 -0.2 0 rotation 0 0 1 3.141592653589793 children [
      Accelerometer {{ name "nested" translation 0.1 0 0 }}
    ] }}
    Accelerometer {{ name "high" translation 0 0 0.4 }}
    Accelerometer {{ name "no y" translation 0.5 0 0 yAxis FALSE }}
    Accelerometer {{ name "table" translation 0.5 0 0 lookupTable [ -10 -100 0, 10 100 0 ] }}
    Gyro {{ name "gyro" }}
    Gyro {{ name "gyro on its side" rotation 1 0 0 1.5707963267948966 }}
    Gyro {{ name "gyro table" lookupTable [ -10 -1000 0, 0 0 0, 10 500 0 ] resolution 1 }}
  ]
}}
"""


def _spin(names: list[str], steps: int = 10) -> dict[str, list[float]]:
    sup = _supervisor(SPINNER)
    devices = {n: sup.getDevice(n) for n in names}
    for d in devices.values():
        d.enable(4)
    for _ in range(steps):
        sup.step(4)
    return {n: d.getValues() for n, d in devices.items()}


def test_accelerometers_read_the_centripetal_acceleration_of_where_they_are_mounted() -> None:
    values = _spin(["centre", "east", "north", "east turned", "nested", "high"])
    w2 = W * W
    tol = 0.02  # the change of velocity over one 4 ms step turns with the body by ω·dt/2 (0.004 rad)
    assert values["centre"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    # the body turned by ω·t; in the body (= device) axes the centripetal vector is fixed: −ω²·r
    assert values["east"] == pytest.approx([-w2 * 0.5, 0.0, 0.0], abs=tol)
    assert values["north"] == pytest.approx([0.0, -w2 * 0.3, 0.0], abs=tol)
    # turned +90° about z: the device's x is the body's y, its y the body's −x
    assert values["east turned"] == pytest.approx([0.0, w2 * 0.5, 0.0], abs=tol)
    # inside a Pose turned 180° at (0, −0.2): the device sits at (−0.1, −0.2) with its x along the body's −x
    assert values["nested"] == pytest.approx([-w2 * 0.1, -w2 * 0.2, 0.0], abs=tol)
    assert values["high"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)  # on the spin axis
    assert len({tuple(round(v, 3) for v in vec) for vec in values.values()}) == 5  # control: not all one vector


def test_accelerometer_axes_and_lookup_table() -> None:
    values = _spin(["no y", "table"])
    assert math.isnan(values["no y"][1]) and not math.isnan(values["no y"][0])
    assert values["table"][0] == pytest.approx(10 * -W * W * 0.5, abs=0.2)  # table maps a → 10·a


def test_gyro_reads_in_its_own_frame_through_its_table() -> None:
    values = _spin(["gyro", "gyro on its side", "gyro table"])
    assert values["gyro"] == pytest.approx([0.0, 0.0, W], abs=1e-9)
    # turned +90° about x: the world's z is the device's y
    assert values["gyro on its side"] == pytest.approx([0.0, W, 0.0], abs=1e-9)
    # the table's second segment maps W to 50·W, rounded to resolution 1
    assert values["gyro table"] == [0.0, 0.0, 50.0 * W]


def test_accelerometer_reads_plus_g_along_its_up_axis_when_mounted_tilted() -> None:
    sup = _supervisor(
        "WorldInfo { basicTimeStep 8 }\nRobot { supervisor TRUE children [ "
        'Accelerometer { name "a" rotation 0 1 0 1.5707963267948966 } ] }'
    )
    acc = sup.getDevice("a")
    acc.enable(8)
    assert all(math.isnan(v) for v in acc.getValues())  # NaN before the first sample
    sup.step(8)
    assert acc.getValues() == pytest.approx([-9.81, 0.0, 0.0], abs=1e-9)


@pytest.mark.parametrize("system", ["NUE", "EUN"])
def test_inertial_unit_in_a_y_up_world_reads_a_turn_about_the_vertical_as_yaw(system: str) -> None:
    sup = _supervisor(
        f'WorldInfo {{ basicTimeStep 8 coordinateSystem "{system}" }}\n'
        "Robot { supervisor TRUE rotation 0 1 0 0.7 children [ "
        'InertialUnit { name "imu" } InertialUnit { name "tilted" rotation 1 0 0 0.3 } ] }'
    )
    imu, tilted = sup.getDevice("imu"), sup.getDevice("tilted")
    imu.enable(8)
    tilted.enable(8)
    sup.step(8)
    assert imu.getRollPitchYaw() == pytest.approx([0.0, 0.0, 0.7], abs=1e-12)
    q = imu.getQuaternion()  # a yaw of 0.7 about the reference z axis
    assert q == pytest.approx([0.0, 0.0, math.sin(0.35), math.cos(0.35)], abs=1e-12)
    # rolled 0.3 about its own forward axis, then the body's yaw
    assert tilted.getRollPitchYaw() == pytest.approx([0.3, 0.0, 0.7], abs=1e-12)


def test_inertial_unit_in_enu_and_disabled_axes() -> None:
    sup = _supervisor(
        "WorldInfo { basicTimeStep 8 }\nRobot { supervisor TRUE rotation 0 0 1 0.7 children [ "
        'InertialUnit { name "imu" zAxis FALSE resolution 0.1 } ] }'
    )
    imu = sup.getDevice("imu")
    imu.enable(8)
    sup.step(8)
    roll, pitch, yaw = imu.getRollPitchYaw()
    assert (roll, pitch) == (0.0, 0.0) and math.isnan(yaw)


GPS_WORLD = """
WorldInfo {{ basicTimeStep 8 gravity 0 {extra} }}
Robot {{
  supervisor TRUE
  translation 1 2 3
  linearVelocity 0.5 -0.25 1
  physics Physics {{ density -1 mass 1 }}
  boundingObject Sphere {{ radius 0.1 }}
  children [ Pose {{ translation 0.1 0 0 children [ GPS {{ name "gps" translation 0 0.2 0 }} ] }} ]
}}
"""


def test_gps_position_speed_vector_and_nan_before_the_first_sample() -> None:
    sup = _supervisor(GPS_WORLD.format(extra=""))
    gps = sup.getDevice("gps")
    assert gps.getCoordinateSystem() == gps.LOCAL
    gps.enable(16)
    sup.step(8)
    assert all(math.isnan(v) for v in gps.getValues() + gps.getSpeedVector())
    assert math.isnan(gps.getSpeed())
    sup.step(8)
    t = 0.016
    assert gps.getValues() == pytest.approx([1.1 + 0.5 * t, 2.2 - 0.25 * t, 3 + t], abs=1e-12)
    assert gps.getSpeedVector() == pytest.approx([0.5, -0.25, 1.0], abs=1e-9)
    assert gps.getSpeed() == pytest.approx(math.sqrt(0.25 + 0.0625 + 1.0), abs=1e-9)


def test_gps_wgs84_goes_through_utm_grid_metres() -> None:
    # Webots projects through UTM: world east/north metres are added to the reference's easting/northing (zone 32
    # here, central meridian 9° E) and projected back. Grid metres are ground metres scaled by 1/k and turned by
    # the grid convergence γ, so by hand (Snyder's point scale and convergence, ellipsoidal terms):
    #   ground east = (dE·cos γ + dN·sin γ)/k,  ground north = (−dE·sin γ + dN·cos γ)/k,
    #   Δlatitude = ground north / M,  Δlongitude = ground east / (N·cos φ).
    # The differences are taken from the world origin's own reading (the reference, to the series' 1e-8°).
    # Control: a local tangent plane (the old reading) misses γ and k by about 3e-7° here.
    sup = _supervisor(GPS_WORLD.format(extra='gpsCoordinateSystem "WGS84" gpsReference 46.5 6.6 400'))
    gps = sup.getDevice("gps")
    assert gps.getCoordinateSystem() == gps.WGS84
    gps.enable(8)
    sup.step(8)
    d_east, d_north, up = 1.1 + 0.004, 2.2 - 0.002, 3.008
    a, e2 = 6378137.0, 6.69437999014e-3
    ep2 = e2 / (1 - e2)
    phi, dl = math.radians(46.5), math.radians(6.6 - 9.0)
    c, t, amp = ep2 * math.cos(phi) ** 2, math.tan(phi) ** 2, dl * math.cos(phi)
    gamma = dl * math.sin(phi) * (1 + dl**2 * math.cos(phi) ** 2 / 3 * (1 + 3 * c + 2 * c**2))
    k = 0.9996 * (1 + (1 + c) * amp**2 / 2 + (5 - 4 * t + 42 * c + 13 * c**2 - 28 * ep2) * amp**4 / 24)
    w = 1 - e2 * math.sin(phi) ** 2
    meridian, prime = a * (1 - e2) / w**1.5, a / math.sqrt(w)
    east = (d_east * math.cos(gamma) + d_north * math.sin(gamma)) / k
    north = (-d_east * math.sin(gamma) + d_north * math.cos(gamma)) / k
    from dualtwin.webots.world_frame import gps_position  # (not in the tangent-plane code this test replaced)

    reference = gps_position((0.0, 0.0, 0.0), (46.5, 6.6, 400.0), "ENU", wgs84=True)
    assert reference[:2] == pytest.approx([46.5, 6.6], abs=1e-8) and reference[2] == 400.0
    got = gps.getValues()
    expected = [reference[0] + math.degrees(north / meridian),
                reference[1] + math.degrees(east / (prime * math.cos(phi))), 400 + up]
    assert got == pytest.approx(expected, abs=1e-10)
    tangent_plane = [46.5 + math.degrees(d_north / (meridian + 400)),
                     6.6 + math.degrees(d_east / ((prime + 400) * math.cos(phi)))]
    assert abs(got[1] - tangent_plane[1]) > 5e-7


def test_gps_local_readings_are_offset_by_the_reference() -> None:
    # gpsReference is the world origin expressed in the GPS coordinate system: in "local" mode, an offset.
    sup = _supervisor(GPS_WORLD.format(extra="gpsReference 10 -20 30"))
    gps = sup.getDevice("gps")
    gps.enable(8)
    sup.step(8)
    assert gps.getValues() == pytest.approx([1.104 + 10, 2.198 - 20, 3.008 + 30], abs=1e-12)
    assert gps.getSpeedVector() == pytest.approx([0.5, -0.25, 1.0], abs=1e-9)  # control: speed has no offset


def _imu_samples(noise: float, n: int = 1500) -> list[list[float]]:
    sup = _supervisor(f"""WorldInfo {{ basicTimeStep 8 randomSeed 3 }}
Robot {{ supervisor TRUE rotation 0 0 1 0.7 children [ InertialUnit {{ name "imu" noise {noise} }} ] }}""")
    imu = sup.getDevice("imu")
    imu.enable(8)
    out = []
    for _ in range(n):
        sup.step(8)
        out.append(imu.getRollPitchYaw())
    return out


def test_inertial_unit_noise_is_relative_to_each_angle_range() -> None:
    # Webots' noise is a fraction of each angle's half-range: σ = noise·π on roll and yaw, noise·π/2 on pitch,
    # drawn afresh at every sample around the true (0, 0, 0.7). 1500 samples: sample σ within 8 %, means within
    # 4 standard errors. Control: the old unit reported getNoise() but read the exact angles (σ = 0).
    samples = _imu_samples(0.02)
    for axis, (truth, sigma) in enumerate(((0.0, 0.02 * math.pi), (0.0, 0.01 * math.pi), (0.7, 0.02 * math.pi))):
        values = [s[axis] for s in samples]
        mean = sum(values) / len(values)
        std = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
        assert std == pytest.approx(sigma, rel=0.08)
        assert abs(mean - truth) < 4 * sigma / math.sqrt(len(values))
    quiet = _imu_samples(0.0, 5)
    assert all(s == pytest.approx([0.0, 0.0, 0.7], abs=1e-12) for s in quiet)  # control: no noise, exact
