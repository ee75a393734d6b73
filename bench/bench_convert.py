"""Converter benchmark: conversion time, and faithfulness of converted models before any alignment.

Run: ``python bench/bench_convert.py``. Goal: the converted CartPole's pole-fall crossing time (0.99 rad) within
0.1 s of the Webots twin. Also reported: converted CartPole vs the hand-written cartpole.xml (MuJoCo vs MuJoCo),
and the fixture worlds (four_wheels skid robot, inverted_pendulum) vs the Webots twin. Webots parts are skipped
with a message while ``dualtwin.twins.webots`` is not importable; fixture parts need ``../shared``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from dualtwin.convert import convert_world
from dualtwin.convert.faithfulness import (
    FaithfulnessReport,
    converted_vs_mjcf,
    converted_vs_webots,
    webots_twin_available,
)
from dualtwin.robots.binding import BUNDLED

CARTPOLE = BUNDLED / "cartpole"
FIXTURES = Path(__file__).resolve().parents[2] / "shared" / "fixtures" / "webots"
GOAL_S = 0.1


def _print(title: str, report: FaithfulnessReport) -> None:
    print(f"  {title}: summary score {report.comparison.summary_score:.4f}")
    for c in report.crossings:
        if c.channel.startswith("onboard/"):
            continue
        a = "none" if c.a_s is None else f"{c.a_s:.4f}"
        b = "none" if c.b_s is None else f"{c.b_s:.4f}"
        diff = "one-sided" if c.diff_s is None else f"{c.diff_s * 1000:+.1f} ms"
        print(f"    {c.scenario:22s} {c.channel:28s} {report.label_a} {a} s  {report.label_b} {b} s  ({diff})")


def main() -> None:
    print("bench_convert: Webots -> MuJoCo conversion and faithfulness (before alignment)")
    worlds: list[tuple[Path, str | None]] = [(CARTPOLE / "cartpole.wbt", None)]
    if FIXTURES.is_dir():
        worlds += [(FIXTURES / "four_wheels.wbt", "FOUR_WHEELS"), (FIXTURES / "inverted_pendulum.wbt", None)]
    for world, robot in worlds:
        start = time.perf_counter()
        conv = convert_world(world, robot)
        conv.compile()
        elapsed = time.perf_counter() - start
        smoke = conv.smoke()
        print(f"  convert {world.name:24s} {elapsed * 1000:7.1f} ms  smoke {'ok' if smoke.ok else smoke.message}")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        ref = converted_vs_mjcf(CARTPOLE / "cartpole.wbt", CARTPOLE / "binding.yaml", CARTPOLE / "suite.json",
                                out / "mjcf", report=False)
        _print("CartPole: hand-written cartpole.xml (A) vs converted (B), both MuJoCo", ref)
        if not webots_twin_available():
            print("  Webots twin not importable yet (dualtwin.twins.webots): Webots comparisons skipped")
            return
        start = time.perf_counter()
        rep = converted_vs_webots(CARTPOLE / "cartpole.wbt", out / "cartpole", suite=CARTPOLE / "suite.json",
                                  base_binding=CARTPOLE / "binding.yaml", report=False)
        _print(f"CartPole: Webots twin (A) vs converted MuJoCo (B) [{time.perf_counter() - start:.1f} s]", rep)
        free_fall = next((c for c in rep.crossings
                          if c.scenario == "00_Step_Response" and c.channel == "pole_angle_rad"), None)
        if free_fall is not None and free_fall.diff_s is not None:
            verdict = "met" if abs(free_fall.diff_s) <= GOAL_S else "NOT met"
            print(f"  goal |pole-fall crossing diff| <= {GOAL_S} s: {abs(free_fall.diff_s) * 1000:.1f} ms -> {verdict}")
        if not FIXTURES.is_dir():
            print("  ../shared/fixtures/webots not present: fixture comparisons skipped")
            return
        for stem in ("four_wheels", "inverted_pendulum"):
            start = time.perf_counter()
            rep = converted_vs_webots(FIXTURES / f"{stem}.wbt", out / stem, report=False)
            _print(f"{stem}: Webots twin (A) vs converted MuJoCo (B) [{time.perf_counter() - start:.1f} s]", rep)
            for sc in rep.comparison.scenarios:
                worst = max(sc.channels.items(), key=lambda kv: kv[1].rmse, default=None)
                if worst is not None:
                    print(f"    {sc.id:22s} {sc.status_a}/{sc.status_b} score {sc.score:.3f}  "
                          f"largest rmse {worst[0]} = {worst[1].rmse:.4g}")


if __name__ == "__main__":
    main()
