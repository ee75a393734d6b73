"""What one process per controller costs: steps/s of controllers run as processes against the former threads.

Run: ``python bench/bench_controller_isolation.py``. Two worlds, each run headless through
:func:`dualtwin.webots.runner.run_world` with ``isolation="process"`` (the default, as Webots) and
``isolation="threads"`` (the former runtime, every controller a thread of one process):

* the bundled CartPole (``robots/cartpole/cartpole.wbt``) with a controller written on the plain Webots API:
  four wheel velocities set and the pole angle read every basic step (goal: process >= 0.9 x threads);
* a 4-robot world (a motor and a position sensor each), one such controller per robot.

Each controller times its own loop (``steps/s`` below; the slowest controller's) and the whole run is timed too
(``run s``: start-up of the controllers included), with the CPU time it used (this process's threads and the
controller processes together: on a loaded machine, wall time mostly measures waiting for a core, CPU time what
isolation really costs). Best of ``REPEATS`` interleaved runs, so load on the machine hits both alike.
"""

from __future__ import annotations

import contextlib
import io
import resource
import shutil
import tempfile
import time
from pathlib import Path

from dualtwin.robots.binding import BUNDLED
from dualtwin.webots.runner import run_world

STEPS = 3000
REPEATS = 3
GOAL = 0.9

CARTPOLE_CONTROLLER = f"""
import math, time
from controller import Robot
robot = Robot()
wheels = [robot.getDevice(f"wheel{{i}}") for i in range(1, 5)]
pole = robot.getDevice("pole sensor")
pole.enable(int(robot.getBasicTimeStep()))
for wheel in wheels:
    wheel.setPosition(math.inf)
step = int(robot.getBasicTimeStep())
start = time.perf_counter()
for k in range({STEPS}):
    for wheel in wheels:
        wheel.setVelocity(20.0 * math.sin(0.01 * k))
    robot.step(step)
    pole.getValue()
print("rate", {STEPS} / (time.perf_counter() - start))
"""

ARM_CONTROLLER = f"""
import math, time
from controller import Robot
robot = Robot()
motor = robot.getDevice("m")
sensor = robot.getDevice("s")
sensor.enable(8)
start = time.perf_counter()
for k in range({STEPS}):
    motor.setPosition(math.sin(0.01 * k))
    robot.step(8)
    sensor.getValue()
print("rate", {STEPS} / (time.perf_counter() - start))
"""


def _arm(i: int) -> str:
    return f"""
Robot {{
  translation {i} 0 1
  name "arm{i}"
  children [
    HingeJoint {{
      jointParameters HingeJointParameters {{ axis 0 1 0 }}
      device [ RotationalMotor {{ name "m" maxTorque 50 }} PositionSensor {{ name "s" }} ]
      endPoint Solid {{
        translation 0.3 0 0
        boundingObject Sphere {{ radius 0.05 }}
        physics Physics {{ density -1 mass 1 }}
      }}
    }}
  ]
  controller "arm"
}}"""


def _projects(root: Path) -> tuple[Path, Path, Path]:
    """(CartPole world, its controller, 4-robot world)."""
    (root / "worlds").mkdir(parents=True)
    (root / "controllers" / "arm").mkdir(parents=True)
    cartpole = root / "worlds" / "cartpole.wbt"
    shutil.copy(BUNDLED / "cartpole" / "cartpole.wbt", cartpole)
    controller = root / "controllers" / "cartpole_api" / "cartpole_api.py"
    controller.parent.mkdir(parents=True)
    controller.write_text(CARTPOLE_CONTROLLER)
    (root / "controllers" / "arm" / "arm.py").write_text(ARM_CONTROLLER)
    arms = root / "worlds" / "arms.wbt"
    arms.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n" + "".join(_arm(i) for i in range(4)))
    return cartpole, controller, arms


def _cpu() -> float:
    """CPU seconds of this process (all threads) and of its reaped children (the controller processes)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _run(world: Path, controller: Path | None, isolation: str) -> tuple[float, float, float]:
    """(slowest controller's loop steps/s, wall seconds of the whole run, CPU seconds of the whole run)."""
    out = io.StringIO()
    start, cpu = time.perf_counter(), _cpu()
    with contextlib.redirect_stdout(out):
        code = run_world(world, controller, None, isolation=isolation)
    wall, cpu = time.perf_counter() - start, _cpu() - cpu
    if code != 0:
        raise SystemExit(f"run failed ({isolation}): exit {code}")
    rates = [float(line.split()[1]) for line in out.getvalue().splitlines() if line.startswith("rate ")]
    return min(rates), wall, cpu


def main() -> dict[str, float]:
    root = Path(tempfile.mkdtemp(prefix="dualtwin-bench-isolation-"))
    try:
        cartpole, controller, arms = _projects(root)
        results: dict[str, float] = {}
        print(f"== Controller isolation: process per controller vs threads ({STEPS} steps, best of {REPEATS}) ==")
        for label, world, script in (("CartPole", cartpole, controller), ("4 robots", arms, None)):
            inf = float("inf")
            best = {"process": (0.0, inf, inf), "threads": (0.0, inf, inf)}
            for _ in range(REPEATS):
                for isolation in ("threads", "process"):
                    rate, wall, cpu = _run(world, script, isolation)
                    old = best[isolation]
                    best[isolation] = (max(old[0], rate), min(old[1], wall), min(old[2], cpu))
            (p_rate, p_wall, p_cpu), (t_rate, t_wall, t_cpu) = best["process"], best["threads"]
            ratio = p_rate / t_rate
            goal = f"  (goal >= {GOAL:.2f})" if label == "CartPole" else ""
            print(f"  {label:9s} threads: {t_rate:8.0f} steps/s  run {t_wall:5.2f} s  CPU {t_cpu:5.2f} s")
            print(f"  {label:9s} process: {p_rate:8.0f} steps/s  run {p_wall:5.2f} s  CPU {p_cpu:5.2f} s"
                  f"   ratio {ratio:5.2f}{goal}")
            key = label.replace(" ", "_").lower()
            results.update({f"{key}_process_steps_per_s": p_rate, f"{key}_threads_steps_per_s": t_rate,
                            f"{key}_ratio": ratio, f"{key}_process_run_s": p_wall, f"{key}_threads_run_s": t_wall,
                            f"{key}_process_cpu_s": p_cpu, f"{key}_threads_cpu_s": t_cpu})
        return results
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
