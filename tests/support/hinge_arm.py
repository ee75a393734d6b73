"""A one-link arm world for the joint and motor specification tests: a supervisor Robot 1 m up, whose children
the test writes (a joint with a 1 kg bob), loaded quietly at a 4 ms basic step."""

from __future__ import annotations

import warnings

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

TS = 4  # ms
DT = TS / 1000.0
G = 9.81
# a 1 kg sphere (r 0.05) 0.5 m from a hinge: I = 0.5² + 0.4·0.05² (hand computation)
INERTIA = 0.25 + 0.4 * 0.05 * 0.05
BOB = 'Solid {{ translation {t} name "bob" boundingObject Sphere {{ radius 0.05 }} physics Physics {{ density -1 mass 1 }} }}'


def load_arm(body: str, gravity: float = 0.0) -> tuple[Simulation, Supervisor]:
    """The world with ``body`` as the robot's children (no sleeping bodies), and its supervisor."""
    text = (
        "#VRML_SIM R2023b utf8\n"
        f"WorldInfo {{ basicTimeStep {TS} gravity {gravity} physicsDisableTime 0 }}\n"
        f'Robot {{ name "arm" supervisor TRUE translation 0 0 1 children [ {body} ] }}\n'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text))
    return sim, Supervisor(simulation=sim, robot_node=sim.robots[0].node)
