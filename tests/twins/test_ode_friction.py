"""Webots' friction pyramid (ODE dContactApprox1) in the MuJoCo twin, against the Webots twin on ODE."""

from __future__ import annotations

import ctypes
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import BUNDLED
from dualtwin.twins.mujoco import MuJoCoTwin
from dualtwin.twins.ode_friction import plane_space, rebuild_constraints
from dualtwin.webots import load_world_text, ode
from dualtwin.webots.physics import Simulation

MU, G = 0.2, 9.81
SPEED = 0.2  # m/s
FLAG = '<text name="webots_contact" data="approx1"/>'
# A 1 kg slab (low, so it slides without tipping) on a floor: the same in both twins.
SLAB_WBT = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 2 contactProperties [ ContactProperties { coulombFriction [ MU ] bounce 0 } ] }
Solid { name "floor" boundingObject Plane { size 100 100 } }
Solid { translation 0 0 0.02 rotation 0 0 1 YAW
  boundingObject Box { size 0.2 0.2 0.04 } physics Physics { density -1 mass 1 } linearVelocity VX VY 0 }
"""
# A sliding slab hops in MuJoCo (either cone; not in ODE): softer contacts than MuJoCo's default (solref 0.02)
# keep the hops small.
SLAB_MJCF = """<mujoco><option timestep="0.002"/><default><geom solref="0.04 1"/></default><custom>FLAG</custom>
<worldbody><geom name="floor" type="plane" size="0 0 1" friction="MU"/>
<body name="slab" pos="0 0 0.02"><freejoint/><geom type="box" size="0.1 0.1 0.02" mass="1" friction="MU"/></body>
</worldbody></mujoco>"""


def fill(template: str, **values: object) -> str:
    for key, value in values.items():
        template = template.replace(key.upper(), str(value))
    return template


def webots_deceleration(degrees: float, yaw: float = 0.0) -> np.ndarray:
    """Per-axis deceleration of the slab sliding at SPEED in ``degrees`` from x, in units of mu g (ODE)."""
    angle = math.radians(degrees)
    world = fill(SLAB_WBT, mu=MU, yaw=yaw, vx=SPEED * math.cos(angle), vy=SPEED * math.sin(angle))
    sim = Simulation(load_world_text(world, "slab.wbt"))
    body = sim.bodies[0]
    sim.step(2)
    before = np.array([body.lvel[0], body.lvel[1]])
    sim.step(16)
    return (before - np.array([body.lvel[0], body.lvel[1]])) / (16 * sim.dt * MU * G)


def slab_twin(flag: str = FLAG) -> MuJoCoTwin:
    """The slab in the MuJoCo twin (2 ms control periods), resting on the floor."""
    twin = MuJoCoTwin(mujoco.MjSpec.from_string(fill(SLAB_MJCF, flag=flag, mu=MU)), 0.002)
    for _ in range(50):
        twin.step()
    return twin


def mujoco_deceleration(twin: MuJoCoTwin, degrees: float) -> np.ndarray:
    angle = math.radians(degrees)
    twin.data.qvel[:2] = SPEED * math.cos(angle), SPEED * math.sin(angle)
    for _ in range(2):
        twin.step()
    before = twin.data.qvel[:2].copy()
    for _ in range(16):
        twin.step()
    return (before - twin.data.qvel[:2]) / (0.032 * MU * G)


@pytest.mark.parametrize(("degrees", "expected"), [(0, (1, 0)), (30, (1, 1)), (45, (1, 1)), (135, (-1, 1))])
def test_sliding_slab_feels_the_square_limit_in_both_twins(degrees: float, expected: tuple[float, float]) -> None:
    # ODE bounds each world axis by mu N: diagonally the slab decelerates by sqrt(2) mu g, along an axis by mu g,
    # whatever its own yaw.
    ode_result = webots_deceleration(degrees)
    assert ode_result == pytest.approx(expected, abs=0.01)
    assert webots_deceleration(degrees, yaw=0.4) == pytest.approx(ode_result, abs=0.01)
    twin = slab_twin()
    assert twin.contact_semantics == "approx1"
    assert mujoco_deceleration(twin, degrees) == pytest.approx(ode_result, abs=0.05)


def test_without_the_flag_mujoco_keeps_its_diamond() -> None:
    twin = slab_twin(flag="")
    assert twin.contact_semantics is None
    # MuJoCo's own pyramid, |f1| + |f2| <= mu N on axes x and y: half of ODE's diagonal deceleration.
    assert mujoco_deceleration(twin, 45) == pytest.approx((0.5, 0.5), abs=0.05)


def test_contact_forces_obey_the_square() -> None:
    twin = slab_twin()
    twin.data.qvel[:2] = 0.18, 0.08
    m, d = twin.model, twin.data
    force = np.zeros(6)
    checked = 0
    for _ in range(10):
        twin.step()
        for i in range(d.ncon):
            mujoco.mj_contactForce(m, d, i, force)
            world = d.contact.frame[i].reshape(3, 3).T @ force[:3]
            if world[2] > 1e-3:
                # Sliding in +x and +y: each corner's friction saturates on both world axes.
                assert world[:2] == pytest.approx([-MU * world[2], -MU * world[2]], rel=1e-6)
                checked += 1
    assert checked >= 20


def test_plane_space_matches_ode() -> None:
    lib = ode.load()
    lib.dPlaneSpace.argtypes = [ctypes.c_void_p] * 3
    lib.dPlaneSpace.restype = None
    rng = np.random.default_rng(1)
    normals = rng.normal(size=(50, 3))
    normals[:4] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, math.sqrt(0.5), math.sqrt(0.5) + 1e-9]]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    p, q = plane_space(normals)
    for i, n in enumerate(normals):
        p_ode, q_ode = ode.dVector3(), ode.dVector3()
        lib.dPlaneSpace(ode.dVector3(*n), p_ode, q_ode)
        assert list(p_ode)[:3] == pytest.approx(p[i], abs=1e-12)
        assert list(q_ode)[:3] == pytest.approx(q[i], abs=1e-12)


def test_rebuild_without_edits_is_mj_step() -> None:
    # The split step redoes everything that reads the contacts: left unedited, it is mj_step bit for bit.
    m = mujoco.MjModel.from_xml_path(str(BUNDLED / "pioneer3at" / "pioneer3at.xml"))
    a, b = mujoco.MjData(m), mujoco.MjData(m)
    a.ctrl[:] = b.ctrl[:] = [0.5, -0.5, 0.5, -0.5]
    for _ in range(100):
        mujoco.mj_step(m, a)
        mujoco.mj_step1(m, b)
        rebuild_constraints(m, b)
        mujoco.mj_step2(m, b)
    assert a.ncon > 0
    assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.qvel, b.qvel)


def test_without_contacts_the_twin_steps_as_mj_step(tmp_path: Path) -> None:
    plain = BUNDLED / "pioneer3at" / "pioneer3at.xml"
    flagged = tmp_path / "pioneer3at.xml"
    flagged.write_text(plain.read_text().replace("<custom>", f"<custom>{FLAG}"))
    twins = [MuJoCoTwin(flagged, 0.032), MuJoCoTwin(plain, 0.032)]
    assert [t.contact_semantics for t in twins] == ["approx1", None]
    for twin in twins:  # a second up in the air, wheels commanded (servo and saturation paths)
        twin.set_body_position("pioneer", 2, 6.0)
        for k in range(30):
            for wheel, sign in (("front left wheel", 1), ("front right wheel", -1), ("back left wheel", 1),
                                ("back right wheel", -1)):
                twin.command(wheel, "velocity", sign * (6.0 if k < 15 else -6.0))
            twin.step()
        assert twin.data.ncon == 0
    assert np.array_equal(twins[0].data.qpos, twins[1].data.qpos)
    assert np.array_equal(twins[0].data.qvel, twins[1].data.qvel)


def test_flag_values_are_checked() -> None:
    with pytest.raises(DualtwinError, match="webots_contact.*'approx2'"):
        MuJoCoTwin(mujoco.MjSpec.from_string(fill(SLAB_MJCF, flag=FLAG.replace("approx1", "approx2"), mu=MU)), 0.002)
    elliptic = fill(SLAB_MJCF, flag=FLAG, mu=MU).replace("<option ", '<option cone="elliptic" ')
    with pytest.raises(DualtwinError, match="pyramidal"):
        MuJoCoTwin(mujoco.MjSpec.from_string(elliptic), 0.002)
    assert MuJoCoTwin(BUNDLED / "cartpole" / "cartpole.xml", 0.032).contact_semantics is None
