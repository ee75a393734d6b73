"""``dualtwin demo``: the whole loop on the bundled CartPole.

Run the bundled suite on both twins, compare them, analyse the divergence, align the MuJoCo twin to the
Webots twin, re-run, and report before and after.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console

from dualtwin.artifacts import package_versions, prepare_output_dir, write_json
from dualtwin.robots.binding import BUNDLED, resolve_robot
from dualtwin.suite.runner import SuiteRun

# The CartPole alignment the README and bench/bench_align.py report: the knobs that explain the pole's fall
# and its impacts, fitted on the pole angle (the cart channels follow from it), one scenario held out.
KNOBS = ["physics.substeps", "joint.pole_hinge.damping", "joint.pole_hinge.friction",
         "joint.pole_hinge.limit_timeconst", "geom.floor.friction", "geom.floor.solref_timeconst",
         "geom.floor.restitution"]
CHANNELS = ["pole_angle_rad"]
HOLDOUT = ["05_Sine_Drive"]
#: Simulations the demo's least-squares fit may spend.
BUDGET = 300
#: Wall-clock seconds without a printed line after which a long step says it is still working.
HEARTBEAT_S = 5.0


class _Heartbeat:
    """What a long step last said; a background thread repeats it, with the elapsed time, when nothing else
    was printed for ``HEARTBEAT_S`` (terminal only: logs hold simulation time alone)."""

    def __init__(self, console: Console, label: str) -> None:
        self.console, self.label = console, label
        self.status = "starting"
        self.started = self.last = time.monotonic()
        self.lock = threading.Lock()

    def say(self, line: str, status: str | None = None) -> None:
        with self.lock:
            self.console.print(line, markup=False)
            self.last = time.monotonic()
            if status is not None:
                self.status = status

    def beat(self) -> None:
        with self.lock:
            now = time.monotonic()
            if now - self.last >= HEARTBEAT_S:
                self.console.print(f"  ... {self.label}: {self.status} ({now - self.started:.0f} s)", markup=False)
                self.last = now


@contextmanager
def _heartbeat(console: Console, label: str) -> Iterator[_Heartbeat]:
    beat = _Heartbeat(console, label)
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(0.5):
            beat.beat()

    thread = threading.Thread(target=loop, name="demo-heartbeat", daemon=True)
    thread.start()
    try:
        yield beat
    finally:
        stop.set()
        thread.join()


KIND = "demo"


def run_demo(out: Path, console: Console, resume: bool = False) -> None:
    """Run the whole loop into ``out``: a new or empty folder, or (with ``resume``) an earlier demo's folder.

    The folder is never deleted: a folder holding anything but an earlier demo is refused (``--out .`` cannot
    wipe a working directory), and an earlier demo is continued only when asked, its finished runs kept.
    """
    from dualtwin.align import (
        AlignConfig,
        GenerationInfo,
        analyze_runs,
        print_analysis,
        print_result,
        run_align,
        write_analysis,
    )
    from dualtwin.divergence import compare_runs, print_summary, write_report

    robot = resolve_robot("cartpole")
    suite = BUNDLED / "cartpole" / "suite.json"
    prepare_output_dir(out, KIND, resume=resume, resumable=True)
    write_json(out / "manifest.json", {"kind": KIND, "demo": {"robot": "cartpole", "knobs": KNOBS,
                                                              "channels": CHANNELS, "holdout": HOLDOUT},
                                       "versions": package_versions()})
    runs = {}
    for twin in ("webots", "mujoco"):
        console.print(f"[bold]1. running[/bold] {suite.name} on the {twin} twin")
        run_dir = out / f"run_{twin}"
        with _heartbeat(console, f"running on the {twin} twin") as beat:
            def on_scenario(sid: str, status: str, beat: _Heartbeat = beat) -> None:
                beat.say(f"  {sid:<28} {status}", status=f"{sid} {status}")

            SuiteRun(suite, twin, robot, run_dir).run(resume=resume, on_scenario=on_scenario)
        runs[twin] = run_dir
    console.print("[bold]2. comparing[/bold] the twins")
    comparison = compare_runs(runs["webots"], runs["mujoco"])
    write_report(comparison, out / "report", label_a="webots", label_b="mujoco")
    print_summary(comparison, console)
    console.print("[bold]3. analysing[/bold] the divergence (knob sensitivities by re-simulation)")
    with _heartbeat(console, "analysing"):
        analysis = analyze_runs(runs["webots"], runs["mujoco"], robot=robot, twin_b="mujoco", knobs=KNOBS)
    write_analysis(analysis, out / "analysis")
    print_analysis(analysis, console)
    console.print(f"[bold]4. aligning[/bold] the MuJoCo twin to the Webots twin ({', '.join(KNOBS)}; fitted on "
                  f"{', '.join(CHANNELS)}; {', '.join(HOLDOUT)} held out; up to {BUDGET} simulations)")
    config = AlignConfig(reference=str(runs["webots"]), target="mujoco", robot=str(robot.path), suite=str(suite),
                         knobs=list(KNOBS), optimizer="lsq", budget=BUDGET, holdout=list(HOLDOUT),
                         channels=list(CHANNELS))
    with _heartbeat(console, "aligning") as beat:
        def on_iteration(info: GenerationInfo) -> None:
            held = f", held out {info.holdout_value:.4g}" if info.holdout_value is not None else ""
            line = (f"  iteration {info.iteration}: objective {info.best_value:.4g}{held} "
                    f"({info.evaluations}/{BUDGET} simulations)")
            beat.say(line, status=line.strip())

        result = run_align(config, out / "align", resume=resume, callback=on_iteration)
    print_result(result, console)
    console.print(f"comparison report: {out / 'report' / 'report.html'}")
    console.print(f"analysis:          {out / 'analysis' / 'analysis.html'}")
    console.print(f"before/after:      {out / 'align' / 'report.html'}")
