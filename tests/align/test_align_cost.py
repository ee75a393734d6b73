"""A small alignment costs what its budget says (issue 25): the checks after the fit are proportionate, and no
simulation is run twice.

* Intervals (``AlignConfig.intervals``): with ``auto``, a budget below 6 simulations per knob plus one computes
  none, and every knob's method says so in the record, the report and the result; ``profile`` computes them at
  any budget (the control).
* The identifiability check before the fit runs only when it and the nominal run take at most half the budget.
* The nominal point is scored from the ``runs/before`` folder, and the floor check's unshifted run is the
  ``runs/after`` folder: the only simulations besides the fit's are the floor check's two shifted members, and
  the floor rows are those of a fresh simulation.

Simulations are counted at the evaluator (its ``map`` is wrapped, not replaced).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dualtwin.align import AlignResult
from dualtwin.align.floor_check import check_floors
from dualtwin.align.simulate import Evaluator, SimJob, load_traces
from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import load_binding
from tests.support.align_runs import count_batches
from tests.support.fake_twin import NAME, fit_fake, registered

TRUTH = {"joint.j1.damping": 0.9, "joint.j2.stiffness": 6.5}
KNOBS = sorted(TRUTH)


@pytest.fixture(autouse=True)
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


@pytest.fixture()
def simulated(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The size of every batch the evaluators simulate."""
    return count_batches(monkeypatch)


def fit(out: Path, **settings: Any) -> AlignResult:
    return fit_fake(out, KNOBS, TRUTH, **{"budget": 4, **settings})


def test_a_tiny_budget_computes_no_interval_and_says_so(tmp_path: Path, simulated: list[int]) -> None:
    result = fit(tmp_path / "auto")
    record = json.loads((tmp_path / "auto" / "align_record.json").read_text())
    report = (tmp_path / "auto" / "report.html").read_text()
    for name in KNOBS:
        knob = result.knobs[name]
        assert knob.interval_95 is None and knob.half_width_95 is None
        assert knob.method is not None and knob.method.startswith("not computed: budget too small (4 < 13"), knob
        assert "--intervals profile" in knob.method
        assert record["result"]["knobs"][name]["interval_method"] == knob.method
        assert record["result"]["knobs"][name]["interval_95"] is None
    assert "not computed: budget too small" in report
    after = record["result"]["identifiability"]["after"]
    assert after["not_computed"].startswith("not computed") and after["correlated"] == []
    # DR ranges without intervals span the bounds, and say why.
    dr = json.loads((tmp_path / "auto" / "dr_ranges.json").read_text())
    assert "intervals not computed" in json.dumps(dr)
    # The identifiability check (2 simulations + the nominal run) would take more than half of 4.
    before = record["result"]["identifiability"]["before"]
    assert before["not_computed"].startswith("not computed") and "--budget 6" in before["not_computed"]
    assert before["advice"] == [before["not_computed"]]
    # Besides the fit's own simulations, only the floor check's two shifted members: the nominal point comes
    # from runs/before, the floor check's unshifted run is runs/after (the fit's point is cached).
    assert sum(simulated) == result.evaluations - 1 + 2, simulated
    assert "intervals" not in record["config"]  # the default: the saved config keeps its old format


def test_intervals_profile_computes_them_at_any_budget(tmp_path: Path, simulated: list[int]) -> None:
    result = fit(tmp_path / "profile", intervals="profile")
    for name in KNOBS:
        knob = result.knobs[name]
        assert knob.method is not None and not knob.method.startswith("not computed"), knob
        assert knob.interval_95 is not None
    # The checks cost at least a central Jacobian and the roughness probes: 6 per knob, beyond the fit's.
    assert sum(simulated) >= result.evaluations - 1 + 2 + 6 * len(KNOBS) - 1, simulated
    record = json.loads((tmp_path / "profile" / "align_record.json").read_text())
    assert record["config"]["intervals"] == "profile"
    assert "not_computed" not in record["result"]["identifiability"]["after"]


def test_off_and_auto_with_a_budget_that_affords_them(tmp_path: Path) -> None:
    off = fit(tmp_path / "off", intervals="off", budget=13)
    assert all((k.method or "").startswith("not computed (intervals off)") for k in off.knobs.values())
    auto = fit(tmp_path / "auto", budget=13)  # 6 per knob + 1: computed
    assert all(k.method and not k.method.startswith("not computed") for k in auto.knobs.values())
    record = json.loads((tmp_path / "auto" / "align_record.json").read_text())
    before = record["result"]["identifiability"]["before"]  # 2 (1 + 2 knobs) <= 13: the check ran
    assert "not_computed" not in before and before["rank"] == 2


def test_the_floor_check_reusing_the_after_run_matches_a_fresh_simulation(tmp_path: Path) -> None:
    out = tmp_path / "fit"
    fit(out, budget=13)
    record = json.loads((out / "align_record.json").read_text())
    rows = record["result"]["floor_check"]["rows"]
    assert rows
    binding = load_binding(Path(record["config"]["robot"]))
    scenarios = tuple(dict.fromkeys(r["scenario"] for r in rows))
    channels = list(dict.fromkeys(r["channel"] for r in rows))
    fitted = json.loads((out / "knobs.json").read_text())["values"]
    job = SimJob(str(binding.path), NAME, record["config"]["suite"], scenarios, (), record["simulation_seed"])
    with Evaluator("serial") as evaluator:
        fresh = check_floors(evaluator, job, fitted, load_traces(out / "reference"), scenarios, channels, binding)
    assert json.loads(json.dumps([r.to_dict() for r in fresh])) == rows


def test_the_prediction_objective_takes_no_intervals_choice(tmp_path: Path) -> None:
    with pytest.raises(DualtwinError, match="does not take intervals"):
        fit(tmp_path / "p", objective="prediction", intervals="off")
    assert not (tmp_path / "p").exists()


def test_cma_with_a_budget_below_one_generation_still_searches(tmp_path: Path) -> None:
    # CMA-ES's default population for 2 knobs is 6: a budget of 4 used to end before the first generation
    # (1 of 4 evaluations, the nominal run) and then blame the knobs. The population now shrinks to what the
    # budget affords; the control is a population the user set, which is kept (and so cannot start).
    small = fit(tmp_path / "small", optimizer="cma")
    assert small.evaluations > 1 and small.iterations == 1, (small.evaluations, small.stop_reason)
    assert all("cannot express" not in w for w in small.warnings), small.warnings
    kept = fit(tmp_path / "kept", optimizer="cma", popsize=6)
    assert kept.evaluations == 1 and kept.iterations == 0, (kept.evaluations, kept.stop_reason)
    stuck = [w for w in kept.warnings if w.startswith("the fit did not move")]
    assert stuck and "before its budget ran out" in stuck[0] and "raise --budget" in stuck[0], kept.warnings


def test_a_fit_cut_off_by_its_budget_says_its_values_may_not_be_the_minimum(tmp_path: Path) -> None:
    short = fit(tmp_path / "short")  # least squares, budget 4: cut off
    assert "evaluations used)" in short.stop_reason, short.stop_reason
    cut = [w for w in short.warnings if w.startswith("the fit ended on its budget")]
    assert cut and "may not cover" in cut[0], short.warnings
    record = json.loads((tmp_path / "short" / "align_record.json").read_text())
    assert cut[0] in record["result"]["warnings"]
    # The control: with room, least squares stops by its own rule and the warning is absent.
    roomy = fit(tmp_path / "roomy", budget=80)
    assert "evaluations used)" not in roomy.stop_reason, roomy.stop_reason
    assert not any(w.startswith("the fit ended on its budget") for w in roomy.warnings), roomy.warnings
