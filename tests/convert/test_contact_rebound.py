"""A body dropped on the floor with ``bounce 0`` does not bounce back in the converted model (webots-on-ode §2.2:
without ``bounce`` the contact has no ``dContactBounce``, so ODE's row only removes the approach velocity and
pushes the penetration out at softERP).

Found by a dual-twin fuzz: a 7 kg box dropped 0.43 m onto a Plane with ``softCFM 0.0001`` (a stiff contact) and
basicTimeStep 1 ms came back up at 3 m/s in the MuJoCo twin, faster than it hit (2.9 m/s), and was still
bouncing 1.5 s later, while the Webots twin rested on the floor after one small hop.

Hand computations: the box falls h = 0.5407 - 0.212898/2 = 0.43425 m, so it hits at v = sqrt(2 g h) = 2.919 m/s
(h = 1 ms steps add at most g·h = 0.01 m/s). ODE with bounce 0 ends the impact step with the penetration p it
reached, at most one step's travel v·h, and pushes it out at most at softERP·p/h <= 0.2·v = 0.584 m/s: a passive,
non-bouncing contact never sends the box up faster than that. At rest it sits on its half height 0.106449 m
(the sink, CFM·m·g/softERP per ODE's spring k = ERP/(h CFM), is far below the 1 mm tolerance).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from dualtwin.convert import contact_solref, convert_world_text
from dualtwin.twins import Twin
from dualtwin.twins.mujoco import MuJoCoTwin
from tests.support.converted_twins import converted_twins, world_text

G = 9.81
TOP = 0.5407
HALF = 0.212898 / 2
IMPACT = math.sqrt(2 * G * (TOP - HALF))  # 2.919 m/s
MAX_REBOUND = 0.2 * IMPACT  # softERP × the impact speed: 0.584 m/s


def _world(friction: float) -> str:
    return world_text(
        'Solid { name "floor" boundingObject Plane { size 10 10 } }\n'
        f'DEF R Robot {{ translation 0 0 {TOP} controller "<extern>" children [ GPS {{ name "gps" }} ] '
        "boundingObject Box { size 0.173859 0.162373 0.212898 } physics Physics { density -1 mass 7 } }",
        f"basicTimeStep 1 contactProperties [ ContactProperties {{ coulombFriction [ {friction} ] bounce 0 "
        "softCFM 0.0001 } ]")


def _drop(twin: Twin) -> tuple[float, float]:
    """(fastest upward speed, height after 1.5 s) of the dropped box, stepped every 1 ms."""
    fastest = 0.0
    for _ in range(1500):
        twin.step()
        fastest = max(fastest, float(twin.body_velocity("R")[2]))
    return fastest, float(twin.body_position("R")[2])


@pytest.mark.parametrize("friction", [0.3, 1.0])
def test_a_dropped_box_settles_without_bouncing(friction: float) -> None:
    twin = MuJoCoTwin(convert_world_text(_world(friction), "drop.wbt").spec, 0.001)
    fastest, height = _drop(twin)
    assert fastest < MAX_REBOUND
    assert height == pytest.approx(HALF, abs=1e-3)


def test_the_webots_twin_does_the_same(tmp_path: Path) -> None:
    # Control: our ODE runtime obeys the same hand bound on the same world.
    with converted_twins(_world(0.3), tmp_path, 0.001) as (_, webots, _mujoco):
        fastest, height = _drop(webots)
    assert fastest < MAX_REBOUND
    assert height == pytest.approx(HALF, abs=1e-3)


def test_the_damping_never_reverses_the_approach_in_one_step() -> None:
    # MuJoCo's reference acceleration damps a contact at b = 2/(dmax·timeconst) (its solref documentation), applied
    # through an impedance of up to 1 when several rows push one body: h·b <= 1 needs timeconst >= 2h/dmax.
    # softCFM 0.0001, 1 ms, 7 kg: dmax = 1/(1 + 1e-4·7/1e-3) = 0.5882, so timeconst >= 2·0.001/0.5882 = 3.4 ms
    # (ODE's own 2m/b = 14/8000 = 1.75 ms is shorter).
    timeconst, _, d = contact_solref(0.2, 0.0001, 0.001, 7.0, 0.001)
    assert d == pytest.approx(1 / 1.7)
    assert timeconst == pytest.approx(0.0034)
