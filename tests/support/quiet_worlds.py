"""A world given as text, built with its build warnings silenced (the tests that use it check something else),
and a Supervisor on its first robot."""

from __future__ import annotations

import warnings
from pathlib import Path

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

__all__ = ["quiet_supervisor"]


def quiet_supervisor(text: str, path: Path | None = None) -> Supervisor:
    """The Supervisor of the first robot of the world ``text`` (a whole ``.wbt``), built quietly (the Supervisor
    too: a robot's Tracks and Propellers are built with it). ``path``: where the world is taken to be, for the
    PROTOs it declares with relative URLs."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(text) if path is None else load_world_text(text, path))
        return Supervisor(simulation=sim, robot_node=sim.robots[0].node)
