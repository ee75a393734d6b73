"""HTML reports generated for real (divergence, analysis, alignment, synchronisation) are readable (issue 14):
every table scrolls instead of running off the page, no ``nan`` anywhere, evidence as tables rather than JSON,
and sides labelled by their twin names rather than the folder name the runs share."""

from __future__ import annotations

import math
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from dualtwin.divergence.channels import channel_unit
from dualtwin.reporting import plot_unit_groups


class Page(HTMLParser):
    """Cells, headers and whether each table sits in a scrolling div."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.stack: list[tuple[str, dict[str, str | None]]] = []
        self.tables = 0
        self.unscrolled = 0
        self.cells: list[str] = []
        self.headers: list[str] = []
        self._cell: list[str] | None = None
        self._kind = ""
        self.feed(text)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "table":
            self.tables += 1
            parents = [a for t, a in self.stack if t == "div"]
            nested = any(t == "table" for t, _ in self.stack)
            if not nested and not any("scroll" in (a.get("class") or "") for a in parents):
                self.unscrolled += 1
        if tag in ("td", "th"):
            self._cell, self._kind = [], tag
        self.stack.append((tag, dict(attrs)))

    def handle_endtag(self, tag: str) -> None:
        while self.stack:
            t, _ = self.stack.pop()
            if t == tag:
                break
        if tag in ("td", "th") and self._cell is not None:
            text = " ".join("".join(self._cell).split())
            (self.cells if self._kind == "td" else self.headers).append(text)
            self._cell = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


def check_page(path: Path) -> Page:
    text = path.read_text(encoding="utf-8")
    page = Page(text)
    assert page.tables > 0, path
    assert page.unscrolled == 0, f"{path}: {page.unscrolled} table(s) outside a scrolling box"
    assert "overflow-x:auto" in text
    words = set(re.findall(r"[A-Za-z]+", " ".join(page.cells + page.headers)))
    assert not words & {"nan", "NaN", "inf", "Infinity"}, (path, words & {"nan", "NaN", "inf", "Infinity"})
    # Evidence and settings are tables, not JSON blobs.
    assert not any(cell.startswith(("{", "[{")) for cell in page.cells), path
    return page


def test_divergence_report(twin_runs: tuple[Path, Path], tmp_path: Path) -> None:
    from dualtwin.divergence import compare_runs, write_report

    webots, mujoco = twin_runs
    assert webots.name == mujoco.name == "run"
    page = check_page(write_report(compare_runs(webots, mujoco), tmp_path / "cmp"))
    assert "A: webots" in page.cells and "B: mujoco" in page.cells
    assert {"webots", "mujoco"} <= set(page.headers)
    assert "run" not in page.headers
    # Numbers are rounded for reading (4 significant digits), not printed at full precision.
    numbers = [c for c in page.cells if re.fullmatch(r"-?\d+\.\d+(e-?\d+)?", c)]
    assert numbers and all(len(re.sub(r"[^0-9]", "", c.split("e")[0]).lstrip("0")) <= 4 for c in numbers)


def test_analysis_report_says_no_effect_instead_of_nan(twin_runs: tuple[Path, Path], tmp_path: Path) -> None:
    from dualtwin.align import analyze_runs, write_analysis

    webots, mujoco = twin_runs
    # The pole's damping is nominally zero: it cannot be lowered, so one direction has no number.
    analysis = analyze_runs(webots, mujoco, robot="cartpole", twin_b="mujoco", knobs=["joint.pole_hinge.damping"],
                            executor="serial")
    page = check_page(write_analysis(analysis, tmp_path / "an"))
    assert any(c in ("no effect", "not computed", "not tried (at bound)") for c in page.cells)
    assert check_page(tmp_path / "an" / "report.html")
    text = (tmp_path / "an" / "analysis.html").read_text()
    assert "Why mujoco (B) diverges" not in text and "Why mujoco diverges from webots" in text


def test_alignment_report(suite_file: Path, tmp_path: Path) -> None:
    from dualtwin.align import AlignConfig, run_align

    result = run_align(AlignConfig(reference="webots", target="mujoco", robot="cartpole",
                                   suite=str(suite_file), knobs=["joint.pole_hinge.damping"], optimizer="lsq",
                                   budget=6, workers=1), tmp_path / "al")
    page = check_page(result.out_dir / "report.html")
    assert "joint.pole_hinge.damping" in page.cells
    assert "Alignment: mujoco to the reference (webots)" in (result.out_dir / "report.html").read_text()


def test_sync_report(suite_file: Path, tmp_path: Path) -> None:
    from dualtwin.divergence.prediction import prediction_error
    from dualtwin.sync import run_lockstep, write_sync_report

    lockstep = run_lockstep("webots", "mujoco", "cartpole", suite=suite_file, out_dir=tmp_path / "ls",
                            resync="every:5")
    prediction = prediction_error("webots", "mujoco", "cartpole", suite=suite_file, out_dir=tmp_path / "pe",
                                  horizons=[1, 5], stride=10)
    events = [{"seq": 0, "t": 0.5, "episode": "e", "event": "alarm_raised", "value": 0.123456789,
               "alarm": {"threshold": 0.1, "window": [1, 2, 3]}}]
    page = check_page(write_sync_report(tmp_path / "rep", lockstep=lockstep, prediction=prediction, events=events))
    assert "0.1235" in page.cells[-1] or any("0.1235" in c for c in page.cells)
    assert any(c.endswith("[rad/s]") or "[m/s]" in c for c in page.cells)  # channel units in the table


def test_plots_put_each_unit_on_its_own_axis() -> None:
    channels = ["body/cart/x", "body/cart/vx", "joint/pole_hinge/q", "joint/pole_hinge/qd", "body/cart/z"]
    fig = Figure()
    FigureCanvasAgg(fig)
    h = np.array([1, 5, 25])
    axes = plot_unit_groups(fig, {c: (h, h * 0.1 + i) for i, c in enumerate(channels)}, channel_unit,
                            quantity="RMS error", xlabel="horizon [control periods]", log=True)
    by_label = {ax.get_ylabel(): [line.get_label() for line in ax.get_lines()] for ax in axes}
    assert by_label == {"RMS error [m]": ["body/cart/x", "body/cart/z"], "RMS error [m/s]": ["body/cart/vx"],
                        "RMS error [rad or m]": ["joint/pole_hinge/q"],
                        "RMS error [rad/s or m/s]": ["joint/pole_hinge/qd"]}
    assert all(math.isfinite(v) for ax in axes for v in ax.get_ylim())


@pytest.mark.parametrize("value", [float("nan"), float("inf"), None])
def test_non_numbers_never_print_as_nan(value: float | None) -> None:
    from dualtwin.reporting import evidence_html, fmt, html_table

    assert fmt(value) == "–"
    assert "nan" not in html_table(["a"], [[value]]).lower() and "inf" not in evidence_html({"x": value}).lower()
