"""The Webots twin and the converter agree on every body's mass, centre of mass and inertia.

Both take each Solid's mass from :mod:`dualtwin.webots.mass_rules`, but they merge Solids into bodies on their
own (the twin into ODE bodies, with wheels and TouchSensors kept apart on fixed joints; the converter into
MuJoCo bodies), place them on their own, and the converter's MJCF goes through MuJoCo's XML writer (6
significant digits, inertia diagonalised). So the test compares what each side ends up with, in the world
frame at load: the twin's ODE bodies as built (``dBodyGetMass`` and the body pose), against the MJCF read
back by MuJoCo (``body_mass``, ``xipos``, ``ximat``·``body_inertia``·``ximat``ᵀ after ``mj_forward``).

Rigid clusters are compared, not single bodies: ODE bodies tied by fixed joints form one cluster, MuJoCo
bodies without joints join their parent's. Each of the twin's clusters in the converted robot must match one
MuJoCo cluster. Tolerances: the compiled spec (full precision) must agree to 1e-9 relative; the MJCF file
read back to 2e-5 relative (mass, CoM with a 1e-6 m floor, and inertia against its largest entry).

Worlds: the bundled robots, the test worlds, the Webots reference worlds in ``../shared/fixtures/webots``
(skipped when absent) and one synthetic world that walks through every mass rule.
"""

from __future__ import annotations

from ctypes import byref
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dualtwin.convert import convert_loaded
from dualtwin.errors import DualtwinError
from dualtwin.webots import load_world, ode
from dualtwin.webots.nodes import World
from dualtwin.webots.physics import BodyRec, Simulation

REPO = Path(__file__).resolve().parents[2]
BUNDLED = sorted((REPO / "src" / "dualtwin" / "robots").glob("*/*.wbt"))
TEST_WORLDS = sorted(p for p in (REPO / "tests").rglob("*.wbt"))
SHARED_WORLDS = REPO.parent / "shared" / "fixtures" / "webots"

SPEC_RTOL = 1e-9
XML_RTOL = 2e-5

# Every rule of mass_rules: density, mass overriding density, centerOfMass, a valid and an invalid
# inertiaMatrix, posed/rotated/grouped primitives, every primitive kind, an off-centre mesh (ODE's
# dMassSetTrimesh inertia), a Solid without boundingObject, a merged child Solid, and joints.
CUBE_POINTS = ", ".join(f"{x + 0.3} {y} {z + 0.1}" for x in (-0.05, 0.05) for y in (-0.05, 0.05) for z in (-0.05, 0.05))
CUBE_FACES = " ".join(f"{a} {b} {c} -1" for a, b, c in (
    (0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
    (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)))
RULES_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ }}
DEF RULES Robot {{
  translation 0.1 -0.2 0.5
  rotation 0 0 1 0.4
  children [
    Solid {{
      translation 0 0.2 0
      name "merged"
      boundingObject Sphere {{ radius 0.05 }}
      physics Physics {{ density 300 }}
    }}
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 0 0.1 }}
      endPoint DEF ARM Solid {{
        translation 0.2 0 0.1
        rotation 1 0 0 0.3
        name "arm"
        boundingObject Group {{ children [
          Pose {{ translation 0.1 0 0 rotation 0 1 0 1.2 children [ Box {{ size 0.2 0.04 0.03 }} ] }}
          Shape {{ geometry Capsule {{ radius 0.02 height 0.1 }} }}
          Pose {{ translation -0.05 0.02 0 children [ Cylinder {{ radius 0.03 height 0.05 }} ] }}
          IndexedFaceSet {{ coord Coordinate {{ point [ {CUBE_POINTS} ] }} coordIndex [ {CUBE_FACES} ] }}
        ] }}
        physics Physics {{ density -1 mass 0.7 centerOfMass [ 0.02 0.01 0 ] }}
        children [
          SliderJoint {{
            jointParameters JointParameters {{ axis 1 0 0 }}
            endPoint DEF TIP Solid {{
              translation 0.3 0 0
              name "tip"
              boundingObject Box {{ size 0.05 0.05 0.05 }}
              physics Physics {{ density -1 mass 0.2 centerOfMass [ 0.01 0 0 ]
                               inertiaMatrix [ 0.001 0.002 0.0025, 0.0001 0 0 ] }}
            }}
          }}
          HingeJoint {{
            jointParameters HingeJointParameters {{ axis 0 0 1 }}
            endPoint DEF BAD Solid {{
              translation 0 0.2 0
              name "bad inertia"
              boundingObject Sphere {{ radius 0.03 }}
              physics Physics {{ density 2000 mass 0.3 inertiaMatrix [ 1 1 1, 5 0 0 ] }}
            }}
          }}
          HingeJoint {{
            jointParameters HingeJointParameters {{ axis 1 0 0 }}
            endPoint DEF NOBO Solid {{
              translation 0 -0.2 0
              name "no bounding object"
              physics Physics {{ density -1 mass 0.4 centerOfMass [ 0 0 0.05 ] }}
            }}
          }}
        ]
      }}
    }}
  ]
  boundingObject Box {{ size 0.3 0.2 0.1 }}
  physics Physics {{ density 800 }}
}}
"""


@pytest.fixture(autouse=True)
def _offline_protos(monkeypatch: pytest.MonkeyPatch, tmp_path_factory: pytest.TempPathFactory) -> None:
    """PROTOs come from the bundled stand-ins and local folders only: no network, no user cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("xdg-cache")))
    monkeypatch.setenv("DUALTWIN_PROTO_OFFLINE", "1")
    monkeypatch.delenv("DUALTWIN_PROTO_CACHE", raising=False)
    monkeypatch.delenv("DUALTWIN_PROTO_MIRROR", raising=False)


@dataclass
class Cluster:
    mass: float
    com: np.ndarray  # world
    inertia: np.ndarray  # world axes, about the CoM
    label: str


def _combine(parts: list[tuple[float, np.ndarray, np.ndarray]], label: str) -> Cluster:
    mass = sum(m for m, _, _ in parts)
    com = sum((m * c for m, c, _ in parts), np.zeros(3)) / mass
    inertia = np.zeros((3, 3))
    for m, c, i in parts:
        d = c - com
        inertia += i + m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return Cluster(mass, com, inertia, label)


def _ode_body(body: BodyRec) -> tuple[float, np.ndarray, np.ndarray]:
    """The body as ODE holds it: dBodyGetMass (about the CoM, body axes) rotated by the body's rotation."""
    lib = ode.load()
    mass = ode.dMass()
    lib.dBodyGetMass(body.ptr, byref(mass))
    I_body = np.array([[mass.I[4 * r + c] for c in range(3)] for r in range(3)])
    R = np.array([[body.R[4 * r + c] for c in range(3)] for r in range(3)])
    com = np.array([body.pos[0], body.pos[1], body.pos[2]])
    return float(mass.mass), com, R @ I_body @ R.T


def twin_clusters(sim: Simulation, robot_node: object) -> list[Cluster]:
    """The robot's ODE bodies grouped by fixed joints (a body fixed to the world stays on its own)."""
    bodies = [b for b in sim.bodies if b.root.robot is not None and b.root.robot.node is robot_node]
    parent = {b.index: b.index for b in bodies}

    def find(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for b in bodies:
        if b.fixed_joint and b.fixed_to is not None and b.fixed_to.index in parent:
            parent[find(b.index)] = find(b.fixed_to.index)
    groups: dict[int, list[BodyRec]] = {}
    for b in bodies:
        groups.setdefault(find(b.index), []).append(b)
    return [_combine([_ode_body(b) for b in g], " + ".join(b.root.name or b.root.node.type_name for b in g))
            for g in groups.values()]


def mujoco_clusters(model: mujoco.MjModel) -> list[Cluster]:
    """MuJoCo bodies grouped with their parent when they have no joint (welded)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    root = list(range(model.nbody))
    for b in range(1, model.nbody):
        p = int(model.body_parentid[b])
        if model.body_jntnum[b] == 0 and p != 0:
            root[b] = root[p]
    groups: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        if model.body_mass[b] > 0:
            groups.setdefault(root[b], []).append(b)
    out = []
    for members in groups.values():
        parts = []
        for b in members:
            R = data.ximat[b].reshape(3, 3)
            parts.append((float(model.body_mass[b]), data.xipos[b].copy(), R @ np.diag(model.body_inertia[b]) @ R.T))
        out.append(_combine(parts, " + ".join(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in members)))
    return out


def _agrees(a: Cluster, b: Cluster, rtol: float) -> bool:
    scale = float(np.abs(a.inertia).max())
    return (abs(a.mass - b.mass) <= rtol * a.mass
            and float(np.abs(a.com - b.com).max()) <= rtol * max(1.0, float(np.abs(a.com).max())) + rtol / 20
            and float(np.abs(a.inertia - b.inertia).max()) <= rtol * scale)


def check_world(world: World, rtol_spec: float = SPEC_RTOL, rtol_xml: float = XML_RTOL) -> int:
    """Compare every robot of ``world``; returns how many clusters were compared."""
    sim = Simulation(world)
    compared = 0
    try:
        for robot in sim.robots:
            conv = convert_loaded(world, robot.node.def_name or robot.name)
            for model, rtol in ((conv.spec.compile(), rtol_spec), (mujoco.MjModel.from_xml_string(conv.xml), rtol_xml)):
                mj = mujoco_clusters(model)
                for cluster in twin_clusters(sim, robot.node):
                    match = [c for c in mj if _agrees(cluster, c, rtol)]
                    assert match, (
                        f"{world.path} robot {robot.name!r}: twin body {cluster.label} (mass {cluster.mass:.9g}, "
                        f"CoM {cluster.com.round(9).tolist()}, inertia {cluster.inertia.round(9).tolist()}) has no "
                        f"MuJoCo counterpart at rtol {rtol:g}; MuJoCo: "
                        + "; ".join(f"{c.label} {c.mass:.9g} {c.com.round(9).tolist()} {c.inertia.round(9).tolist()}"
                                    for c in mj))
                    compared += 1
    finally:
        sim.close()
    return compared


@pytest.mark.parametrize("path", BUNDLED + TEST_WORLDS, ids=lambda p: str(p.relative_to(REPO)))
def test_twin_and_converter_agree_on_repository_worlds(path: Path) -> None:
    assert check_world(load_world(path)) > 0


@pytest.mark.parametrize("name", ["inverted_pendulum.wbt", "four_wheels.wbt", "pioneer3at.wbt"])
def test_twin_and_converter_agree_on_webots_reference_worlds(name: str) -> None:
    path = SHARED_WORLDS / name
    if not path.is_file():
        pytest.skip(f"{path} is not present")
    try:
        world = load_world(path)
    except DualtwinError as exc:  # a PROTO the reference world needs is not available offline
        pytest.skip(f"{name} cannot be loaded here: {exc}")
    assert check_world(world) > 0


def test_twin_and_converter_agree_on_every_mass_rule(tmp_path: Path) -> None:
    path = tmp_path / "rules.wbt"
    path.write_text(RULES_WORLD)
    with pytest.warns(UserWarning):  # the twin warns about the invalid inertiaMatrix and the missing boundingObject
        world = load_world(path)
        sim = Simulation(world)
    warnings = sim.build_warnings
    sim.close()
    assert any("'bad inertia': invalid inertiaMatrix ignored" in w for w in warnings), warnings
    assert any("'no bounding object' has Physics but no boundingObject" in w for w in warnings), warnings
    with pytest.warns(UserWarning):
        assert check_world(load_world(path)) == 5 * 2  # 5 ODE bodies, compiled spec and MJCF file


def test_the_comparison_notices_a_wrong_mass(tmp_path: Path) -> None:
    """Control: the same world with one Solid's mass changed on the converter side only fails the check."""
    path = tmp_path / "rules.wbt"
    path.write_text(RULES_WORLD)
    with pytest.warns(UserWarning):
        world = load_world(path)
        sim = Simulation(world)
    try:
        conv = convert_loaded(world, "RULES")
        conv.spec.body("TIP").mass = 0.2 * (1 + 1e-4)
        mj = mujoco_clusters(conv.spec.compile())
        twin = twin_clusters(sim, sim.robots[0].node)
        assert sum(any(_agrees(t, c, XML_RTOL) for c in mj) for t in twin) == len(twin) - 1
    finally:
        sim.close()
