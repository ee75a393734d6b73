"""Sensors × ``Robot.selfCollision``.

DistanceSensor × a supervisor's edit of the field (webots-devices.md §1.3 with webots-on-ode.md §2.3): a sensor's
rays get their hits from the ordinary near callback, where "same-robot pairs [are] ignored unless
Robot.selfCollision" (D:79-80); the callback tests the robot's field at every collision pass (O:185, rule 4), so
once a supervisor turns ``selfCollision`` on, the robot's sensors see its own parts from the next sample, and no
longer once it turns it off.

Hand computation: the sensor sits at the robot's origin looking along +x (one ray, D:72); a 0.1 m Box of the
same robot is centred 0.5 m ahead, so its near face is at 0.45 m. Lookup table ``[0 0 0, 1 1000 0]``: a hit at
0.45 m reads 450; no hit reads the last output, 1000 (D:107, "No hit ⇒ d = D ⇒ value = LUT last output").
"""

from __future__ import annotations

import warnings

import pytest

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Robot, Runtime, Supervisor
from dualtwin.webots.physics import Simulation
from tests.support.quiet_worlds import quiet_supervisor

TS = 8


def _robot(self_collision: bool) -> Supervisor:
    return quiet_supervisor(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
DEF ME Robot {{ supervisor TRUE selfCollision {'TRUE' if self_collision else 'FALSE'} children [
  DistanceSensor {{ name "ds" lookupTable [ 0 0 0, 1 1000 0 ] }}
  Solid {{ translation 0.5 0 0 boundingObject Box {{ size 0.1 0.1 0.1 }} }}
] }}
""")


def _reading_after_edit(sup: Supervisor, self_collision: bool) -> tuple[float, float]:
    sensor = sup.getDevice("ds")
    sensor.enable(TS)
    sup.step(TS)
    before = sensor.getValue()
    sup.getFromDef("ME").getField("selfCollision").setSFBool(self_collision)
    sup.step(TS)
    sup.step(TS)
    return before, sensor.getValue()


def test_turning_self_collision_on_lets_a_sensor_see_its_own_robot() -> None:
    before, after = _reading_after_edit(_robot(False), True)
    assert before == 1000.0
    assert after == pytest.approx(450.0, abs=1e-9)


def test_turning_self_collision_off_hides_the_robot_from_its_own_sensor() -> None:
    before, after = _reading_after_edit(_robot(True), False)
    assert before == pytest.approx(450.0, abs=1e-9)
    assert after == 1000.0


# ---------------------------------------------------------------- infra-red Emitter × the emitter's selfCollision
# D:242-243: "an ODE ray emitter→receiver origin is collided; any hit Solid not of the emitting robot blocks it":
# the emitting robot's own Solids never block its beam, selfCollision or not (the field decides what the robot's
# parts collide with, D:79-80, not whose beam they are). Robot A emits at the origin; robot B, 2 m along +x,
# receives (apertures -1: all directions, range -1: unlimited), so one packet sent before B's step is in B's
# queue after it (D:251-253).


def _infra_red_heard(a_fields: str, a_children: str = "", elsewhere: str = "") -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ name "a" {a_fields} children [ Emitter {{ name "tx" type "infra-red" }} {a_children} ] }}
Robot {{ name "b" translation 2 0 0 children [ Receiver {{ name "rx" type "infra-red" }} ] }}
{elsewhere}
"""))
    runtime = Runtime(sim)
    a = Robot(runtime=runtime, robot_node=sim.robots[0].node)
    a.cleanup()  # A's devices work, only B's controller waits for steps
    b = Robot(runtime=runtime, robot_node=sim.robots[1].node)
    rx = b.getDevice("rx")
    rx.enable(TS)
    a.getDevice("tx").send(b"x")
    b.step(TS)
    return int(rx.getQueueLength())


def test_the_emitting_robots_own_body_does_not_block_its_infra_red_beam_with_self_collision() -> None:
    # the emitter sits inside A's own 0.2 m body box: the beam leaves through its face at x = 0.1
    assert _infra_red_heard("selfCollision TRUE boundingObject Box { size 0.2 0.2 0.2 }") == 1


def test_a_part_of_the_emitting_robot_on_the_beam_does_not_block_it_with_self_collision() -> None:
    wall = "Solid { translation 1 0 0 boundingObject Box { size 0.1 1 1 } }"
    assert _infra_red_heard("selfCollision TRUE", wall) == 1
    # control: the same wall outside any robot blocks the beam (D:243)
    assert _infra_red_heard("selfCollision TRUE", elsewhere=wall) == 0
