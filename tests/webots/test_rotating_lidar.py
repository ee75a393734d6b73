"""A rotating Lidar turns its head and fills its range image column by column (webots-devices.md §3, D below).

D §3.2: "Rotating: ``rotatingHead`` turned by −2π·f·dt per step about its z-axis, sampling period forced to
basicTimeStep, image filled column-wise"; §3.1: its image spans 2π (the layer check's fov); §3.3:
``setFrequency(f)`` outside [min, max] is an error. The column angles are the fixed lidar's
``θ_j = fov/2 − (j+½)·fov/W`` with fov = 2π, the head starts along +x and turns clockwise seen from +z
(:mod:`dualtwin.webots.lidar_head`).

World (hand geometry): basicTimeStep 10 ms, a static supervisor robot at the origin with a rotating lidar of
W = 40 columns and one layer (f = 10 Hz: 0.1 turn, 4 columns per step), in a square room whose walls' inner faces
are at x = ±2 and y = ±2, with a box of 0.4 m whose face toward the lidar is at y = −0.8 (centre (0, −1)).

The head reaches column j when its sweep (in turns) crosses c_j = ((j+½)/40 − ½) mod 1 = (j − 19.5)/40 mod 1, so
step k (sweep 0.1·k) casts the columns with c_j in (0.1·(k−1), 0.1·k]: step 1 → 20..23, step 2 → 24..27, step 3 →
28..31, ..., step 5 → 36..39, step 6 → 0..3, ..., step 10 → 16..19 (c_j is never a multiple of 0.1: no tie).
The box at y = −0.8 spans |x| ≤ 0.2, i.e. the columns with 0.8·|cot θ_j| ≤ 0.2: θ_j = π − (j+½)·π/20 in
[−0.578π, −0.422π] ⇒ j = 28..31, read at 0.8/|sin θ_j|. Moved to y = +1 (face at +0.8) it is met by j = 8..11.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

W = 40
STEP = 10  # ms


def _wall(x: float, y: float, sx: float, sy: float) -> str:
    return f"Solid {{ translation {x} {y} 0 children [ Shape {{ geometry Box {{ size {sx} {sy} 2 }} }} ] }}"


ROOM = " ".join([_wall(2.05, 0, 0.1, 4.2), _wall(-2.05, 0, 0.1, 4.2), _wall(0, 2.05, 4.2, 0.1),
                 _wall(0, -2.05, 4.2, 0.1)])
BOX = 'DEF BOX Solid { name "box" translation 0 -1 0 children [ Shape { geometry Box { size 0.4 0.4 2 } } ] }'
FULL_CIRCLE = f'Lidar {{ name "fixed" horizontalResolution {W} fieldOfView {2 * math.pi!r} numberOfLayers 1 maxRange 5 }}'


def _world(lidar_fields: str = "", head: str = "", extra: str = "") -> Supervisor:
    # the rotating lidar keeps the default fieldOfView (1.5708): a rotating one ignores it (its image spans 2π)
    rotating = (f'Lidar {{ name "lidar" type "rotating" horizontalResolution {W} numberOfLayers 1 maxRange 5 '
                f"{lidar_fields} {head} }}")
    return quiet_supervisor(f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {STEP} }}\n{ROOM}\n{BOX}\n"
                            f"Robot {{ supervisor TRUE children [ {rotating} {extra} ] }}\n")


def theta(j: int) -> float:
    return math.pi - (j + 0.5) * 2 * math.pi / W


def room_range(j: int, box_y: float | None = -1.0) -> float:
    """Hand geometry: the distance along column j to the room's walls, or to the box's near face."""
    c, s = math.cos(theta(j)), math.sin(theta(j))
    r = min(2 / abs(c) if c else math.inf, 2 / abs(s) if s else math.inf)
    if box_y is not None and s and math.copysign(1.0, s) == math.copysign(1.0, box_y):
        face = abs(box_y) - 0.2
        if abs(face * c / s) <= 0.2:
            r = min(r, face / abs(s))
    return r


def _image(lidar: object) -> np.ndarray:
    return np.array(lidar.getRangeImage())  # type: ignore[attr-defined]


def test_after_three_steps_only_the_swept_columns_are_cast() -> None:
    sup = _world()
    lidar = sup.getDevice("lidar")
    lidar.enable(STEP)
    sup.step(3 * STEP)
    image = _image(lidar)
    swept = list(range(20, 32))  # steps 1-3 (module docstring)
    assert image[swept] == pytest.approx([room_range(j) for j in swept], rel=1e-9)
    assert image[28:32] == pytest.approx([0.8 / abs(math.sin(theta(j))) for j in range(28, 32)], rel=1e-9)  # box
    rest = [j for j in range(W) if j not in swept]
    assert image[rest].tolist() == [0.0] * len(rest)  # not swept yet: the zero-filled buffer (D §3.2)


def test_after_a_full_turn_the_image_is_the_full_circle_cast() -> None:
    sup = _world(extra=FULL_CIRCLE)
    lidar, fixed = sup.getDevice("lidar"), sup.getDevice("fixed")
    assert lidar.getFov() == pytest.approx(2 * math.pi)  # D §3.1: 2π for a rotating lidar
    lidar.enable(STEP)
    fixed.enable(STEP)
    sup.step(9 * STEP)
    assert _image(lidar)[16:20].tolist() == [0.0] * 4  # the last four columns come at step 10
    sup.step(STEP)
    image = _image(lidar)
    assert image == pytest.approx(_image(fixed), rel=1e-9)
    assert image == pytest.approx([room_range(j) for j in range(W)], rel=1e-9)


def test_a_box_moved_mid_turn_appears_only_in_columns_swept_after_the_move() -> None:
    sup = _world(extra=FULL_CIRCLE)
    lidar, fixed = sup.getDevice("lidar"), sup.getDevice("fixed")
    lidar.enable(STEP)
    fixed.enable(STEP)
    sup.step(5 * STEP)  # columns 20..39 cast, the box seen at 28..31
    sup.getFromDef("BOX").getField("translation").setSFVec3f([0.0, 1.0, 0.0])  # applied at the next step
    sup.step(5 * STEP)  # columns 0..19 cast with the box at y = +1
    image = _image(lidar)
    assert image[8:12] == pytest.approx([room_range(j, 1.0) for j in range(8, 12)], rel=1e-9)  # swept after
    # swept before the move: they keep the box where it was, which the instant full-circle cast no longer sees
    assert image[28:32] == pytest.approx([room_range(j, -1.0) for j in range(28, 32)], rel=1e-9)
    assert _image(fixed)[28:32] == pytest.approx([room_range(j, None) for j in range(28, 32)], rel=1e-9)
    assert image[8:12] == pytest.approx(_image(fixed)[8:12], rel=1e-9)


def test_frequency_starts_at_default_and_set_frequency_outside_the_bounds_changes_nothing(capfd) -> None:
    # defaultFrequency 5 Hz: 0.05 turn per step, c_j in (0, 0.05] ⇒ j − 19.5 in (0, 2] ⇒ columns 20, 21
    sup = _world("defaultFrequency 5 minFrequency 2 maxFrequency 15")
    lidar = sup.getDevice("lidar")
    assert (lidar.getFrequency(), lidar.getMinFrequency(), lidar.getMaxFrequency()) == (5.0, 2.0, 15.0)
    lidar.enable(STEP)
    sup.step(STEP)
    assert np.flatnonzero(_image(lidar)).tolist() == [20, 21]
    lidar.setFrequency(20)  # above maxFrequency: an error line, nothing changes (D §3.3)
    assert "Error:" in capfd.readouterr().err
    assert lidar.getFrequency() == 5.0
    sup.step(STEP)  # sweep 0.1: c_j in (0.05, 0.1] ⇒ columns 22, 23
    assert np.flatnonzero(_image(lidar)).tolist() == [20, 21, 22, 23]
    lidar.setFrequency(15)  # sweep 0.1 + 0.15 = 0.25: c_j in (0.1, 0.25] ⇒ j − 19.5 in (4, 10] ⇒ 24..29
    sup.step(STEP)
    assert np.flatnonzero(_image(lidar)).tolist() == list(range(20, 30))


def test_sampling_period_is_forced_to_the_basic_step() -> None:
    # enable(50): sampled at every 10 ms step all the same, so one step already casts the first 4 columns;
    # getSamplingPeriod echoes the request (D §0.2: the controller library echoes the last requested value)
    sup = _world()
    lidar = sup.getDevice("lidar")
    lidar.enable(50)
    sup.step(STEP)
    assert np.flatnonzero(_image(lidar)).tolist() == [20, 21, 22, 23]
    assert lidar.getSamplingPeriod() == 50


HEAD = "rotatingHead DEF HEAD Solid { translation 0 0 0.05 }"


def test_rotating_head_turns_by_minus_two_pi_f_dt_per_step_and_reset_puts_it_back() -> None:
    sup = _world(head=HEAD)
    lidar, head = sup.getDevice("lidar"), sup.getFromDef("HEAD")
    rotation = head.getField("rotation")
    sup.step(2 * STEP)  # a disabled lidar's head stands still
    assert rotation.getSFRotation() == pytest.approx([0, 0, 1, 0], abs=1e-12)
    lidar.enable(STEP)
    sup.step(3 * STEP)
    # −2π·f·n·dt = −2π·10·3·0.01 = −0.6π about z, i.e. 0.6π about −z
    assert rotation.getSFRotation() == pytest.approx([0, 0, -1, 0.6 * math.pi], abs=1e-9)
    a = -0.6 * math.pi
    assert head.getOrientation() == pytest.approx([math.cos(a), -math.sin(a), 0, math.sin(a), math.cos(a), 0,
                                                   0, 0, 1], abs=1e-9)
    assert head.getPosition() == pytest.approx([0, 0, 0.05], abs=1e-12)  # only its rotation changes
    sup.step(4 * STEP)  # −1.4π ≡ +0.6π (mod 2π)
    assert rotation.getSFRotation() == pytest.approx([0, 0, 1, 0.6 * math.pi], abs=1e-9)
    sup.simulationReset()
    sup.step(STEP)  # the reset applies at the end of this step: the head is back at its load rotation
    assert rotation.getSFRotation() == pytest.approx([0, 0, 1, 0], abs=1e-9)
    sup.step(STEP)  # and turns again from there: −0.2π
    assert rotation.getSFRotation() == pytest.approx([0, 0, -1, 0.2 * math.pi], abs=1e-9)


def test_another_ray_sensor_sees_the_head_turn() -> None:
    # the head carries an arm (a 0.1 m cube centred 0.6 m along its x axis, near face at 0.55); the full-circle
    # fixed lidar at the same origin sees it in front (columns 19, 20 at θ = ±π/40: 0.55/cos(π/40)) before the
    # head turns, and behind after half a turn (5 steps: columns 0 and 39 at θ = ±(π − π/40))
    arm = ("rotatingHead Solid { children [ Pose { translation 0.6 0 0 children [ Shape { geometry Box "
           "{ size 0.1 0.1 0.1 } } ] } ] }")
    sup = _world(head=arm, extra=FULL_CIRCLE)
    lidar, fixed = sup.getDevice("lidar"), sup.getDevice("fixed")
    fixed.enable(STEP)
    sup.step(STEP)
    arm_range = 0.55 / math.cos(math.pi / 40)
    assert _image(fixed)[[19, 20]] == pytest.approx([arm_range] * 2, rel=1e-9)
    lidar.enable(STEP)
    sup.step(5 * STEP)
    image = _image(fixed)
    assert image[[0, 39]] == pytest.approx([arm_range] * 2, rel=1e-9)
    assert image[[19, 20]] == pytest.approx([room_range(19), room_range(20)], rel=1e-9)


def test_point_cloud_times_are_the_times_the_columns_were_cast() -> None:
    sup = _world()
    lidar = sup.getDevice("lidar")
    lidar.enable(STEP)
    lidar.enablePointCloud()
    sup.step(3 * STEP)
    points = lidar.getPointCloud()
    times = [p.time for p in points]
    # columns 20..23 at step 1 (t = 0.01 s), 24..27 at 0.02, 28..31 at 0.03; the others never cast
    for j in range(W):
        expected = 0.01 * ((j - 16) // 4) if 20 <= j < 32 else 0.0
        assert times[j] == pytest.approx(expected, abs=1e-12), j
    # a point of the front wall (x = 2) in the lidar frame: x = r·cos θ (D §3.2)
    assert [p.x for p in points[20:24]] == pytest.approx([2.0] * 4, rel=1e-9)
    assert [p.y for p in points[28:32]] == pytest.approx([-0.8] * 4, rel=1e-9)  # the box's face


def test_after_a_reset_the_point_cloud_has_no_times_from_before_it() -> None:
    # webots-devices.md §11.3: simulationReset puts the Lidar head back and time back to 0; the reset's own sample
    # sweeps nothing (the head has not turned since), so every column reads 0.0 at time 0, as before the first
    # sweep (module docstring of dualtwin.webots.lidar_head), not the times of the casts before the reset
    sup = _world()
    lidar = sup.getDevice("lidar")
    lidar.enable(STEP)
    lidar.enablePointCloud()
    sup.step(3 * STEP)  # columns 20..31 cast at 0.01..0.03 s (test above)
    sup.simulationReset()
    sup.step(STEP)  # the reset applies at the end of this step
    assert sup.getTime() == 0.0
    assert _image(lidar).tolist() == [0.0] * W
    assert [p.time for p in lidar.getPointCloud()] == [0.0] * W
    sup.step(STEP)  # the head turns again from its load rotation: step 1's columns 20..23 at t = 0.01 s
    times = [p.time for p in lidar.getPointCloud()]
    assert times[20:24] == pytest.approx([0.01] * 4, abs=1e-12)
    assert times[:20] + times[24:] == [0.0] * (W - 4)


def test_a_camera_sees_the_head_turn() -> None:
    # A camera 2 m above the lidar looks down (rotation 0 1 0 π/2: its x axis along −z, its image up along +x,
    # left along +y), 64×64 pixels, fov 1. The head's red arm (top face at z = 0.05, depth 1.95, centre 0.6 m
    # along the head's x) is seen at row 32 ∓ (0.6/1.95)/tan(0.5)·32 = 32 ∓ 18.0 (pixel centres), column 32:
    # ahead (+x) before the head turns, behind (−x) after half a turn (5 steps at 10 Hz, 10 ms).
    arm = ("rotatingHead Solid { children [ Pose { translation 0.6 0 0 children [ Shape { appearance "
           "PBRAppearance { baseColor 1 0 0 roughness 1 metalness 0 } geometry Box { size 0.2 0.2 0.1 } } ] } ] }")
    camera = 'Camera { name "camera" translation 0 0 2 rotation 0 1 0 1.5707963267948966 width 64 height 64 fieldOfView 1 }'
    sup = quiet_supervisor(f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {STEP} }}\n"
                           "DirectionalLight { direction 0 0 -1 }\n"
                           f'Robot {{ supervisor TRUE children [ Lidar {{ name "lidar" type "rotating" {arm} }} '
                           f"{camera} ] }}\n")
    cam, lidar = sup.getDevice("camera"), sup.getDevice("lidar")

    def red_centre() -> tuple[float, float]:  # (row, column) of the centre of the lit top face
        image = np.array(cam.getImageArray())  # indexed [column][row] (Webots' getImageArray)
        columns, rows = np.nonzero(image[..., 0] > 100)  # the red arm on black
        return float(rows.mean() + 0.5), float(columns.mean() + 0.5)

    offset = (0.6 / 1.95) / math.tan(0.5) * 32
    cam.enable(STEP)
    sup.step(STEP)
    assert red_centre() == pytest.approx((32 - offset, 32), abs=1.0)
    lidar.enable(STEP)
    sup.step(5 * STEP)
    assert red_centre() == pytest.approx((32 + offset, 32), abs=1.0)


def test_default_frequency_outside_the_bounds_is_clamped_and_a_huge_frequency_casts_every_column(capfd) -> None:
    # Our decision where the reference is silent (lidar_head.frequencies): a defaultFrequency above maxFrequency
    # starts at maxFrequency, with a warning
    sup = _world('defaultFrequency 100 maxFrequency 1e308 minFrequency 1e-300', head=HEAD)
    lidar = sup.getDevice("lidar")
    assert lidar.getFrequency() == 100.0  # within [1e-300, 1e308]: kept
    clamped = _world("defaultFrequency 100").getDevice("lidar")
    assert clamped.getFrequency() == 25.0 and "defaultFrequency" in capfd.readouterr().err
    # 1e308 Hz turns the head 1e306 turns per step (an infinite sweep after 180 steps, had it been summed):
    # every column is cast at every step and the head stays finite
    lidar.setFrequency(1e308)
    lidar.enable(STEP)
    sup.step(200 * STEP)
    assert _image(lidar) == pytest.approx([room_range(j) for j in range(W)], rel=1e-9)
    sup.getFromDef("BOX").getField("translation").setSFVec3f([0.0, 1.0, 0.0])
    sup.step(STEP)  # the next step casts the whole turn again: the box is seen where it went
    assert _image(lidar) == pytest.approx([room_range(j, 1.0) for j in range(W)], rel=1e-9)
    assert all(math.isfinite(v) for v in sup.getFromDef("HEAD").getField("rotation").getSFRotation())
