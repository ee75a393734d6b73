"""Coverage of alignment's 95 % intervals (issue 24): how often they contain the truth, per knob family and method.

Run: ``python bench/bench_align_coverage.py`` (100 fits, 2 processes) or ``--fits 20 --processes 1``.
Set ``DUALTWIN_BENCH_ALIGN_COVERAGE_OUT=DIR`` to keep the runs and ``coverage.json``.

Each fit is a known-truth recording of the fake twin (tests/support/fake_twin.py: damped springs driven by
motors, milliseconds per suite run): random true values of three physics knobs (a damping, a mass, a
stiffness, each 0.6-1.6 × nominal), a random initial kick of the first released spring (a nuisance knob,
±0.3 rad/s) and a random logging delay (the shared time offset, ±10 ms). The reference run's logs are then
degraded like a real logger's: Gaussian noise (1 % of each channel's range), rounding to 3 decimals and ±2 ms
jitter on every time stamp. The fake twin at nominal is aligned to it by least squares (basin search, the
default) with the physics and both nuisance knobs, and every knob's 95 % interval is checked against its
truth. The control column is the textbook i.i.d. Jacobian interval of the same fit (what alignment reported
before the effective-sample correction), rescaled from the record.

Goal: 90-99 % coverage for every knob family.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from _common import output_folder
from dualtwin.align import AlignConfig, run_align
from dualtwin.align import run as align_run
from dualtwin.artifacts import sha256_file, write_json
from dualtwin.robots.binding import load_binding
from dualtwin.suite.runner import SuiteRun
from dualtwin.twins import make_twin

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tests.support.fake_twin import NAME, ROBOT, SUITE, registered  # noqa: E402

PHYSICS = {"joint.j1.damping": "damping", "joint.j1.mass": "mass", "joint.j2.stiffness": "stiffness"}
KICK = "scenario.00_release_1.initial_qd1"
OFFSET = "scenario.*.time_offset"
FAMILY = {**PHYSICS, KICK: "nuisance: kick", OFFSET: "nuisance: time offset"}
NOISE, JITTER_S, DECIMALS = 0.01, 0.002, 3


def degrade(run: Path, rng: np.random.Generator, offset_s: float) -> None:
    """Noise, rounding, time-stamp jitter and a logging delay on every log of ``run`` (manifest hashes updated)."""
    manifest = json.loads((run / "manifest.json").read_text())
    for rel, entry in manifest["logs"].items():
        path = run / rel
        lines = path.read_text().splitlines()
        header, rows = lines[0], np.array([[float(x) for x in line.split("\t")] for line in lines[1:]])
        t = rows[:, 0] - offset_s + rng.uniform(-JITTER_S, JITTER_S, rows.shape[0])
        values = rows[:, 1:]
        span = np.ptp(values, axis=0)
        values = values + rng.normal(0.0, 1.0, values.shape) * NOISE * np.where(span > 0, span, 1e-3)
        text = header + "\n" + "\n".join("\t".join([f"{ti:.4f}", *(f"{v:.{DECIMALS}f}" for v in row)])
                                         for ti, row in zip(t, values, strict=True)) + "\n"
        path.write_text(text)
        entry.update({"bytes": path.stat().st_size, "sha256": sha256_file(path)})
    write_json(run / "manifest.json", manifest)


def no_report(*_: object, **__: object) -> Path:
    """The HTML report is not written in this study: its plots cost more than the fit (and say nothing here)."""
    return Path("report.html")


def one_fit(args: tuple[int, str]) -> dict[str, Any]:
    index, root_text = args
    align_run.write_align_report = no_report  # type: ignore[assignment]
    root = Path(root_text) / f"fit_{index:03d}"
    rng = np.random.default_rng(1000 + index)
    with registered():
        robot = load_binding(ROBOT)
        twin = make_twin(NAME, robot, 0.02)
        nominal = {k: twin.knobs()[k].nominal for k in PHYSICS}
        truth = {k: float(v * rng.uniform(0.6, 1.6)) for k, v in nominal.items()}
        kick, offset = float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.01, 0.01))
        doc = json.loads(SUITE.read_text())
        doc["scenarios"][0]["initial_qd1"] = kick
        root.mkdir(parents=True, exist_ok=True)
        suite = root / "suite_kicked.json"
        suite.write_text(json.dumps(doc))
        twin.set_knobs(truth)
        SuiteRun(suite, NAME, robot, root / "recording", twin=twin).run()
        twin.close()
        degrade(root / "recording", rng, offset)
        start = time.perf_counter()
        config = AlignConfig(reference=str(root / "recording"), target=NAME, robot=str(ROBOT), suite=str(SUITE),
                             knobs=[*PHYSICS, KICK, OFFSET], optimizer="lsq", budget=160, executor="serial",
                             seed=index)
        result = run_align(config, root / "fit")
        wall = time.perf_counter() - start
    truths = {**truth, KICK: kick, OFFSET: offset}
    record = json.loads((root / "fit" / "align_record.json").read_text())
    noise = record["result"]["identifiability"]["after"]["noise"]
    p = len(truths)
    t_iid = float(stats.t.ppf(0.975, max(noise["samples"] - p, 1)))
    t_neff = float(stats.t.ppf(0.975, max(noise["dof"], 1)))
    rows = []
    for name, fit in {**result.knobs, **result.nuisance}.items():
        lo, hi = fit.interval_95 if fit.interval_95 is not None else (-math.inf, math.inf)
        truth_v = truths[name]
        row = {"knob": name, "family": FAMILY[name], "truth": truth_v, "fitted": fit.fitted, "method": fit.method,
               "interval": [lo, hi], "covered": bool(lo <= truth_v <= hi)}
        if fit.method and fit.method.startswith("jacobian") and fit.half_width_95 is not None:
            iid = fit.half_width_95 * t_iid / t_neff / math.sqrt(noise["inflation"])
            row["covered_iid"] = bool(abs(fit.fitted - truth_v) <= iid)
        rows.append(row)
    return {"index": index, "wall_s": wall, "stop": result.stop_reason, "rows": rows,
            "criterion": result.residual_after}


def table(fits: list[dict[str, Any]]) -> dict[str, Any]:
    groups: dict[tuple[str, str], list[bool]] = {}
    iid: dict[str, list[bool]] = {}
    family: dict[str, list[bool]] = {}
    for f in fits:
        for row in f["rows"]:
            method = (row["method"] or "none").split(" (")[0] if not row["method"].startswith("jacobian") else row["method"]
            groups.setdefault((row["family"], method), []).append(row["covered"])
            family.setdefault(row["family"], []).append(row["covered"])
            if "covered_iid" in row:
                iid.setdefault(row["family"], []).append(row["covered_iid"])
    print(f"\n{'knob family':<24}{'method':<22}{'fits':>6}{'coverage':>10}")
    out: dict[str, Any] = {"by_family_method": {}, "by_family": {}, "iid_control": {}}
    for (fam, method), hits in sorted(groups.items()):
        share = sum(hits) / len(hits)
        out["by_family_method"][f"{fam} / {method}"] = {"n": len(hits), "coverage": share}
        print(f"{fam:<24}{method:<22}{len(hits):>6}{share:>10.1%}")
    print(f"\n{'knob family':<24}{'all methods':>12}{'i.i.d. Jacobian (control)':>28}")
    for fam, hits in sorted(family.items()):
        share = sum(hits) / len(hits)
        control = iid.get(fam, [])
        ctext = f"{sum(control) / len(control):.1%} of {len(control)}" if control else "–"
        out["by_family"][fam] = {"n": len(hits), "coverage": share}
        out["iid_control"][fam] = {"n": len(control), "coverage": sum(control) / len(control) if control else None}
        print(f"{fam:<24}{share:>12.1%}{ctext:>28}   goal 90-99 %: {'yes' if 0.9 <= share <= 0.99 else 'NO'}")
    return out


def main(fits: int, processes: int) -> dict[str, Any]:
    with output_folder("DUALTWIN_BENCH_ALIGN_COVERAGE_OUT", "align-coverage") as (root, _):
        print(f"== coverage of 95 % intervals: {fits} known-truth fits of the fake twin (noise, rounding, jitter, "
              "a kick and a logging delay) ==")
        start = time.perf_counter()
        jobs = [(i, str(root)) for i in range(fits)]
        if processes > 1:
            with multiprocessing.get_context("fork").Pool(processes) as pool:
                results = pool.map(one_fit, jobs, chunksize=1)
        else:
            results = [one_fit(j) for j in jobs]
        print(f"   {fits} fits in {time.perf_counter() - start:.0f} s "
              f"(median {np.median([r['wall_s'] for r in results]):.1f} s per fit)")
        summary = table(results)
        write_json(root / "coverage.json", {"fits": results, "summary": summary})
    return summary


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--fits", type=int, default=100)
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()
    main(args.fits, args.processes)
