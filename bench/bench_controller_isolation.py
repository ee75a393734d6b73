"""What one process per controller costs: steps/s of controllers run as processes against the former threads.

Run: ``python bench/bench_controller_isolation.py``. Three worlds, each run headless through
:func:`dualtwin.webots.runner.run_world` with ``isolation="process"`` (the default, as Webots) and
``isolation="threads"`` (the former runtime, every controller a thread of one process):

* the bundled CartPole (``robots/cartpole/cartpole.wbt``) with a controller written on the plain Webots API:
  four wheel velocities set and the pole angle and the clock read every basic step (goal: process >= 0.9 x
  threads in steps/s);
* a 4-robot world (a motor and a position sensor each), one such controller per robot;
* a supervisor reading a field ten times per step (``10 reads``): each read is a round trip to the simulation's
  process (a field can change within a step), so this row shows what one API call costs a process.

Each world also runs with ``DUALTWIN_CONTROLLER_SPIN_US=0`` (``process, no polling``): the channel's two sides
then sleep in ``read`` until woken, as before the channel polled (the control for what polling buys).

Each controller times its own loop (``steps/s`` below; the slowest controller's). CPU is counted for the
whole run (this process's threads and the controller processes together) and given per ``STEPS`` steps:
the CPU of a run of ``STEPS`` steps minus that of a run of ``SHORT`` steps, scaled, so the start-up of the
controller processes (an interpreter each) is left out; ``start`` is the CPU of the short run. On a loaded
machine wall time mostly measures waiting for a core (a controller process waits for one twice per step, a
thread never), CPU time what isolation really costs: the load average is printed with the results. Best of
``REPEATS`` interleaved runs, so load on the machine hits both modes alike.
"""

from __future__ import annotations

import contextlib
import io
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

from dualtwin.robots.binding import BUNDLED
from dualtwin.webots.runner import run_world

SPIN_VARIABLE = "DUALTWIN_CONTROLLER_SPIN_US"
SLEEPING = "process, no polling"
MODES = ("threads", "process", SLEEPING)
STEPS = 3000
SHORT = 300
REPEATS = 3
GOAL = 0.9

CARTPOLE_CONTROLLER = """
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
steps = {steps}
for k in range(steps):
    for wheel in wheels:
        wheel.setVelocity(20.0 * math.sin(0.01 * k))
    robot.step(step)
    pole.getValue()
    robot.getTime()
print("rate", steps / (time.perf_counter() - start))
"""

ARM_CONTROLLER = """
import math, time
from controller import Robot
robot = Robot()
motor = robot.getDevice("m")
sensor = robot.getDevice("s")
sensor.enable(8)
start = time.perf_counter()
steps = {steps}
for k in range(steps):
    motor.setPosition(math.sin(0.01 * k))
    robot.step(8)
    sensor.getValue()
print("rate", steps / (time.perf_counter() - start))
"""


SUPERVISOR_CONTROLLER = """
import time
from controller import Supervisor
robot = Supervisor()
field = robot.getSelf().getField("translation")
start = time.perf_counter()
steps = {steps}
for k in range(steps):
    robot.step(8)
    for _ in range(10):
        field.getSFVec3f()
print("rate", steps / (time.perf_counter() - start))
"""

SUPERVISOR_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot {
  translation 0 0 1
  boundingObject Sphere { radius 0.05 }
  physics Physics { density -1 mass 1 }
  controller "reads"
  supervisor TRUE
}
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


def _projects(root: Path, steps: int) -> tuple[Path, Path, Path, Path]:
    """(CartPole world, its controller, 4-robot world, supervisor world), controllers looping ``steps`` times."""
    (root / "worlds").mkdir(parents=True)
    (root / "controllers" / "arm").mkdir(parents=True)
    (root / "controllers" / "reads").mkdir(parents=True)
    (root / "controllers" / "reads" / "reads.py").write_text(SUPERVISOR_CONTROLLER.format(steps=steps))
    supervisor = root / "worlds" / "reads.wbt"
    supervisor.write_text(SUPERVISOR_WORLD)
    cartpole = root / "worlds" / "cartpole.wbt"
    shutil.copy(BUNDLED / "cartpole" / "cartpole.wbt", cartpole)
    controller = root / "controllers" / "cartpole_api" / "cartpole_api.py"
    controller.parent.mkdir(parents=True)
    controller.write_text(CARTPOLE_CONTROLLER.format(steps=steps))
    (root / "controllers" / "arm" / "arm.py").write_text(ARM_CONTROLLER.format(steps=steps))
    arms = root / "worlds" / "arms.wbt"
    arms.write_text("#VRML_SIM R2023b utf8\nWorldInfo { basicTimeStep 8 }\n" + "".join(_arm(i) for i in range(4)))
    return cartpole, controller, arms, supervisor


def _cpu() -> float:
    """CPU seconds of this process (all threads) and of its reaped children (the controller processes)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _run(world: Path, controller: Path | None, mode: str) -> tuple[float, float, float]:
    """(slowest controller's loop steps/s, wall seconds of the whole run, CPU seconds of the whole run)."""
    isolation = "threads" if mode == "threads" else "process"
    out = io.StringIO()
    saved = os.environ.get(SPIN_VARIABLE)
    if mode == SLEEPING:  # the channel as it was before polling: each side sleeps in read() until woken
        os.environ[SPIN_VARIABLE] = "0"
    start, cpu = time.perf_counter(), _cpu()
    try:
        with contextlib.redirect_stdout(out):
            code = run_world(world, controller, None, isolation=isolation)
    finally:
        if saved is None:
            os.environ.pop(SPIN_VARIABLE, None)
        else:
            os.environ[SPIN_VARIABLE] = saved
    wall, cpu = time.perf_counter() - start, _cpu() - cpu
    if code != 0:
        raise SystemExit(f"run failed ({isolation}): exit {code}")
    rates = [float(line.split()[1]) for line in out.getvalue().splitlines() if line.startswith("rate ")]
    return min(rates), wall, cpu


def main() -> dict[str, float]:
    root = Path(tempfile.mkdtemp(prefix="dualtwin-bench-isolation-"))
    try:
        long, short = _projects(root / "long", STEPS), _projects(root / "short", SHORT)
        results: dict[str, float] = {}
        load = os.getloadavg()[0]
        print(f"== Controller isolation: process per controller vs threads ({STEPS} steps, best of {REPEATS}; "
              f"load average {load:.1f} on {os.cpu_count()} CPUs) ==")
        worlds = (("CartPole", long[0], long[1], short[0], short[1]), ("4 robots", long[2], None, short[2], None),
                  ("10 reads", long[3], None, short[3], None))
        for label, world, script, short_world, short_script in worlds:
            inf = float("inf")
            best = {mode: {"rate": 0.0, "wall": inf, "cpu": inf, "start": inf} for mode in MODES}
            for _ in range(REPEATS):
                for mode in MODES:
                    rate, wall, cpu = _run(world, script, mode)
                    start_cpu = _run(short_world, short_script, mode)[2]
                    b = best[mode]
                    b["rate"], b["wall"] = max(b["rate"], rate), min(b["wall"], wall)
                    b["cpu"] = min(b["cpu"], (cpu - start_cpu) * STEPS / (STEPS - SHORT))
                    b["start"] = min(b["start"], start_cpu)
            p, t, s = best["process"], best["threads"], best[SLEEPING]
            ratio, cpu_ratio = p["rate"] / t["rate"], p["cpu"] / t["cpu"]
            goal = f"  (goal >= {GOAL:.2f})" if label == "CartPole" else ""
            for mode in MODES:
                b = best[mode]
                print(f"  {label:9s} {mode + ':':20s} {b['rate']:8.0f} steps/s  run {b['wall']:5.2f} s  "
                      f"CPU {b['cpu']:5.2f} s per {STEPS} steps (+{b['start']:4.2f} s start)")
            print(f"  {label:9s} ratio process/threads: steps/s {ratio:4.2f}{goal}, CPU {cpu_ratio:4.2f}; "
                  f"without polling: steps/s {s['rate'] / t['rate']:4.2f}, CPU {s['cpu'] / t['cpu']:4.2f}")
            key = label.replace(" ", "_").lower()
            results.update({
                f"{key}_process_steps_per_s": p["rate"], f"{key}_threads_steps_per_s": t["rate"],
                f"{key}_ratio": ratio, f"{key}_cpu_ratio": cpu_ratio,
                f"{key}_process_run_s": p["wall"], f"{key}_threads_run_s": t["wall"],
                f"{key}_process_cpu_s": p["cpu"], f"{key}_threads_cpu_s": t["cpu"],
                f"{key}_no_polling_ratio": s["rate"] / t["rate"], f"{key}_no_polling_cpu_ratio": s["cpu"] / t["cpu"],
            })
        results["load_average"] = load
        return results
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
