"""Ranging-device cost in the Webots twin: a driving robot with 8 distance sensors and a 180-ray Lidar.

Run: ``python bench/bench_devices.py``. Goal (issue 16): >= 2,000 steps/s on one core with every sensor
sampled at every basic step (the worst case: rays are cast only when a sample is due). Speed is measured in
CPU time of this process (what one core does), and wall time is printed beside it: on a shared machine the
wall time mostly measures the other load.

Baseline, measured in the same run: the same world and robot without the sensors, driven the same way through
the controller API. The ratio is sensors / baseline steps per second. The robot drives in a walled arena with
box, cylinder and sphere obstacles on a floor plane, so rays hit every primitive kind.
"""

from __future__ import annotations

import math
import time
import warnings

from dualtwin.webots import load_world_text
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

STEPS = 2000
REPEATS = 3
GOAL = 2000.0
STEP_MS = 16

_SENSORS = "\n".join(
    f'DistanceSensor {{ name "ds{i}" translation {0.2 * math.cos(a):.4f} {0.2 * math.sin(a):.4f} 0.05 '
    f"rotation 0 0 1 {a:.4f} lookupTable [ 0 1000 0, 2 0 0 ] }}"
    for i, a in enumerate(i * math.pi / 4 for i in range(8))
)
_LIDAR = (
    'Lidar { name "lidar" translation 0 0 0.12 horizontalResolution 180 fieldOfView 3.14159 '
    "numberOfLayers 1 maxRange 5 }"
)


def world(with_sensors: bool) -> str:
    devices = f"{_SENSORS}\n{_LIDAR}" if with_sensors else ""
    wheels = "\n".join(
        f"""HingeJoint {{
  jointParameters HingeJointParameters {{ axis 0 1 0 anchor 0 {y} 0 }}
  device [ RotationalMotor {{ name "{name}" maxVelocity 20 }} ]
  endPoint Solid {{ translation 0 {y} 0 rotation 1 0 0 1.5708 name "{name}"
    boundingObject Cylinder {{ radius 0.06 height 0.03 }} physics Physics {{ mass 0.2 }} }}
}}"""
        for name, y in (("left wheel", 0.16), ("right wheel", -0.16))
    )
    obstacles = "\n".join(
        [
            "Solid { translation 1.2 0.5 0.2 boundingObject Box { size 0.4 0.4 0.4 } }",
            "Solid { translation -1 1 0.3 boundingObject Cylinder { radius 0.2 height 0.6 } }",
            "Solid { translation 0.3 -1.3 0.2 boundingObject Sphere { radius 0.2 } }",
            "Solid { translation -1.2 -0.8 0.2 rotation 0 0 1 0.5 boundingObject Box { size 0.6 0.2 0.4 } }",
        ]
        + [
            f"Solid {{ translation {x} {y} 0.25 boundingObject Box {{ size {sx} {sy} 0.5 }} }}"
            for x, y, sx, sy in ((2.5, 0, 0.1, 5), (-2.5, 0, 0.1, 5), (0, 2.5, 5, 0.1), (0, -2.5, 5, 0.1))
        ]
    )
    return f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {STEP_MS} }}
Solid {{ boundingObject Plane {{ size 5 5 }} }}
{obstacles}
Robot {{
  translation 0 0 0.06
  supervisor TRUE
  children [
    {wheels}
    {devices}
  ]
  boundingObject Pose {{ translation -0.12 0 0 children [ Sphere {{ radius 0.05 }} ] }}
  physics Physics {{ mass 2 centerOfMass [ -0.05 0 0 ] }}
}}
"""


def run(with_sensors: bool, steps: int) -> tuple[float, float, float]:
    """(CPU seconds and wall seconds for ``steps`` controller steps, a checksum of the readings)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(load_world_text(world(with_sensors)))
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    left, right = sup.getDevice("left wheel"), sup.getDevice("right wheel")
    for m in (left, right):
        m.setPosition(math.inf)
    sensors = [sup.getDevice(f"ds{i}") for i in range(8)] if with_sensors else []
    lidar = sup.getDevice("lidar") if with_sensors else None
    for s in sensors:
        s.enable(STEP_MS)
    if lidar is not None:
        lidar.enable(STEP_MS)
    check = 0.0
    cpu, wall = time.process_time(), time.perf_counter()
    for k in range(steps):
        # drive in a slow arc, turning in place now and then, so the view changes
        turn = (k // 200) % 2
        left.setVelocity(4.0 if not turn else -3.0)
        right.setVelocity(6.0)
        sup.step(STEP_MS)
        if sensors:
            check += sum(s.getValue() for s in sensors)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    if lidar is not None:
        image = lidar.getRangeImage()
        check += sum(v for v in image if math.isfinite(v))
    sim.close()
    return cpu, wall, check


def main() -> None:
    run(True, 50)  # warm-up (imports, first allocations)
    # interleaved repeats, best of each: the least disturbed by other load on a shared machine
    cpu_s, wall_s, cpu_b, wall_b = [], [], [], []
    check = 0.0
    for _ in range(REPEATS):
        c, w, check = run(True, STEPS)
        cpu_s.append(c)
        wall_s.append(w)
        c, w, _ = run(False, STEPS)
        cpu_b.append(c)
        wall_b.append(w)
    rate, base = STEPS / min(cpu_s), STEPS / min(cpu_b)
    print(f"{STEPS} controller steps of {STEP_MS} ms, every sensor sampled at every step, best of {REPEATS}")
    print(
        f"  with 8 distance sensors + 180-ray lidar: {rate:8,.0f} steps/s CPU time "
        f"({STEPS / min(wall_s):,.0f} wall)"
    )
    print(
        f"  same robot without the sensors:          {base:8,.0f} steps/s CPU time "
        f"({STEPS / min(wall_b):,.0f} wall)"
    )
    print(f"  ratio sensors/baseline (CPU): {rate / base:.2f}   readings checksum {check:.1f}")
    print(f"  goal >= {GOAL:,.0f} steps/s on one core (CPU time): {'met' if rate >= GOAL else 'NOT met'}")


if __name__ == "__main__":
    main()
