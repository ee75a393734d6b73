"""Worlds for the sensor specification tests: a static supervisor robot 0.1 m above ground carrying the devices
under test, a wall the test writes, and a noise generator whose every Gaussian draw is +1 (so a noisy value is
exactly ``v·(1 + noise)``)."""

from __future__ import annotations

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor


class UnitGauss:
    """A noise generator whose every Gaussian draw is +1; counts its draws."""

    def __init__(self) -> None:
        self.draws = 0

    def gauss(self, mu: float, sigma: float) -> float:
        self.draws += 1
        return mu + sigma

    def getrandbits(self, k: int) -> int:
        return 1


def sensor_world(devices: str, wall: str, *, head: str = "", robot_extra: str = "", step: int = 8) -> Supervisor:
    """The world (built quietly) and its supervisor: ``devices`` are the robot's children."""
    text = (
        f"#VRML_SIM R2023b utf8\nWorldInfo {{ basicTimeStep {step} }}\n{head}\n{wall}\n"
        f"Robot {{ translation 0 0 0.1 supervisor TRUE {robot_extra} children [ {devices} ] }}\n"
    )
    return quiet_supervisor(text)


def unit_noise(sup: Supervisor) -> UnitGauss:
    """Replace the simulation's noise generator (not what the tests check: the noise formula) by a UnitGauss."""
    stub = UnitGauss()
    sup.simulation._rng = stub  # type: ignore[assignment]
    return stub
