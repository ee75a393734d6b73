"""Webots-twin physics throughput: basic steps per second on the bundled CartPole-on-wheels world.

Run: ``python bench/bench_webots_physics.py`` (or ``make bench``). Goal: >= 5,000 steps/s on one core
while the wheels drive and the pole swings (auto-disable never kicks in), both for the raw
``Simulation.step`` loop and through the controller API (``Supervisor.step`` with motor commands).
"""

from __future__ import annotations

import math
import time

from dualtwin.robots.binding import BUNDLED
from dualtwin.webots import load_world
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

STEPS = 5000
GOAL = 5000.0


def best_of(fn, repeats: int = 3) -> float:  # type: ignore[no-untyped-def]
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> dict[str, float]:
    world = load_world(BUNDLED / "cartpole" / "cartpole.wbt")
    sim = Simulation(world)
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    wheels = [sup.getDevice(f"wheel{i}") for i in range(1, 5)]
    pole = sup.getDevice("pole sensor")
    pole.enable(int(sim.basic_time_step))

    def drive(k: int) -> None:
        for wheel in wheels:
            wheel.setPosition(math.inf)
            wheel.setVelocity(20.0 * math.sin(0.01 * k))

    def raw() -> None:
        sim.reset()
        drive(1)
        for k in range(STEPS):
            if k % 50 == 0:
                drive(k)
            sim.step()

    def api() -> None:
        sim.reset()
        step_ms = sim.basic_time_step
        for k in range(STEPS):
            drive(k)
            sup.step(step_ms)
            pole.getValue()

    raw_rate = STEPS / best_of(raw)
    api_rate = STEPS / best_of(api)
    print("Webots twin physics (bundled cartpole.wbt, driving, one core)")
    print(f"  Simulation.step          : {raw_rate:9.0f} steps/s (goal >= {GOAL:.0f})")
    print(f"  Supervisor.step + motors : {api_rate:9.0f} steps/s (goal >= {GOAL:.0f})")
    sim.close()
    return {"raw_steps_per_s": raw_rate, "api_steps_per_s": api_rate}


if __name__ == "__main__":
    main()
