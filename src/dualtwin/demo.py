"""``dualtwin demo``: the bundled CartPole suite on both twins, then the divergence report."""

from __future__ import annotations

import shutil
from pathlib import Path

from rich.console import Console

from dualtwin.robots.binding import BUNDLED, resolve_robot
from dualtwin.suite.runner import SuiteRun


def run_demo(out: Path, console: Console) -> None:
    from dualtwin.divergence import compare_runs, print_summary, write_report

    robot = resolve_robot("cartpole")
    suite = BUNDLED / "cartpole" / "suite.json"
    if out.exists():
        shutil.rmtree(out)
    runs = {}
    for twin in ("webots", "mujoco"):
        console.print(f"[bold]running[/bold] {suite.name} on the {twin} twin")
        run_dir = out / f"run_{twin}"
        manifest = SuiteRun(suite, twin, robot, run_dir).run()
        for record in manifest["scenarios"]:
            console.print(f"  {record['id']:<28} {record['status']}")
        runs[twin] = run_dir
    comparison = compare_runs(runs["webots"], runs["mujoco"])
    report_dir = out / "report"
    write_report(comparison, report_dir, label_a="webots", label_b="mujoco")
    print_summary(comparison, console)
    console.print(f"report: {report_dir / 'report.html'}")
