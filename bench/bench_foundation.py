"""Foundation benchmark: MuJoCo twin stepping overhead vs a raw mj_step loop, and the bundled suite's wall time.

Run: ``python bench/bench_foundation.py`` (or ``make bench``). Goals: overhead <= 10 % (issue 25; the twin runs
Webots' motor law in the compiled plugin, ``twins/native``), bundled suite < 1 s. The stepping loops are timed in
CPU seconds (single-threaded: CPU time leaves out waiting for a core on a shared machine), the suite in wall time.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import mujoco

from _common import best_of, cpu_time
from dualtwin.robots.binding import BUNDLED, resolve_robot
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins.mujoco import MuJoCoTwin

CONTROL_PERIODS = 3000


def main() -> dict[str, float]:
    path = BUNDLED / "cartpole" / "cartpole.xml"
    twin = MuJoCoTwin(path, 0.032)
    substeps = round(0.032 / twin.model.opt.timestep)
    # The baseline: a plain model where MuJoCo computes the same servo torque kv (6 - qdot) itself, with the
    # servo's armature dt kv: the physics without Webots' law (the twin runs it in the plugin, or in Python).
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    for w in ("wheel1", "wheel2", "wheel3", "wheel4"):
        motor = twin._motor_by_name[w]
        model.actuator_gainprm[motor.index, 0] = motor.kv
        model.actuator_biastype[motor.index] = mujoco.mjtBias.mjBIAS_AFFINE
        model.actuator_biasprm[motor.index, :3] = (0.0, 0.0, -motor.kv)
        model.actuator_forcelimited[motor.index] = 0
        model.dof_armature[motor.dof] += motor.kv * model.opt.timestep

    def raw_loop() -> None:
        mujoco.mj_resetData(model, data)
        data.ctrl[:] = 6.0
        for _ in range(CONTROL_PERIODS * substeps):
            mujoco.mj_step(model, data)

    def twin_loop(mode: str) -> None:
        twin.reset()
        for w in ("wheel1", "wheel2", "wheel3", "wheel4"):
            twin.command(w, mode, 6.0 if mode == "velocity" else 0.01)
        for _ in range(CONTROL_PERIODS):
            twin.step()

    # Interleaved best-of-N in CPU time (the loops are single-threaded; wall time on a shared machine measures
    # the wait for a core, which moved this ratio by tens of points), so load hits baseline and twin alike.
    raw = velocity = torque = float("inf")
    for _ in range(7):
        raw = min(raw, cpu_time(raw_loop))
        velocity = min(velocity, cpu_time(lambda: twin_loop("velocity")))
        torque = min(torque, cpu_time(lambda: twin_loop("torque")))

    suite = BUNDLED / "cartpole" / "suite.json"
    robot = resolve_robot("cartpole")
    tmp = Path(tempfile.mkdtemp())

    def run_suite() -> None:
        shutil.rmtree(tmp / "run", ignore_errors=True)
        SuiteRun(suite, "mujoco", robot, tmp / "run").run()

    suite_wall = best_of(run_suite, repeats=3)
    shutil.rmtree(tmp, ignore_errors=True)
    steps = CONTROL_PERIODS * substeps
    print("== foundation: MuJoCo twin ==")
    print(f"raw mj_step loop          {steps / raw:12,.0f} physics steps per CPU second (baseline)")
    print(f"twin, velocity servos     {steps / velocity:12,.0f} physics steps/s  overhead {velocity / raw - 1:+.1%}"
          f"  (goal <= +10%; law: {'plugin' if twin.native_law else 'Python'})")
    print(f"twin, torque mode         {steps / torque:12,.0f} physics steps/s  overhead {torque / raw - 1:+.1%}")
    print(f"bundled suite, 6 scenarios  {suite_wall:.3f} s wall  (goal < 1 s)")
    return {"raw_steps_per_s": steps / raw, "velocity_overhead": velocity / raw - 1,
            "torque_overhead": torque / raw - 1, "suite_wall_s": suite_wall}


if __name__ == "__main__":
    main()
