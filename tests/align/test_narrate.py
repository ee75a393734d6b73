"""The LLM narrative against a scripted LLM on a loopback HTTP server (real openai/anthropic clients).

The LLM's proposals are data: valid ones are re-simulated and kept only if they lower the divergence,
the others are rejected with the reason, and a malformed reply leaves the deterministic analysis as it was.
"""

from __future__ import annotations

import html
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dualtwin.align import AlignConfig, analyze_runs, run_align, write_analysis
from dualtwin.align.narrate import LABEL, LLMProposer
from dualtwin.genai.llm import LLMConfig, make_llm
from dualtwin.robots.binding import RobotBinding
from tests.support.align_runs import TRUE_DAMPING
from tests.support.llm_replay import Reply, replay_server

pytest.importorskip("openai")
pytest.importorskip("anthropic")

DAMPING = "joint.pole_hinge.damping"
GOOD = {DAMPING: TRUE_DAMPING}          # the value the reference was recorded with
WORSE = {DAMPING: 0.6}                   # valid, but further from the reference than nominal 0
OUT_OF_BOUNDS = {DAMPING: 7.0}           # the knob's range is [0, 1]
NOT_SELECTED = {"motor.wheel1.gain": -1.0}
SCRIPTED = json.dumps({
    "explanation": "The reference pole falls later in every scenario: its hinge is damped.",
    "proposals": [{"knobs": GOOD, "rationale": "add damping"}, {"knobs": WORSE, "rationale": "much more"},
                  {"knobs": OUT_OF_BOUNDS}, {"knobs": NOT_SELECTED}],
})


def proposer(base: str, provider: str = "openai") -> LLMProposer:
    llm = make_llm(LLMConfig(provider=provider, model="scripted", base_url=base, max_retries=0,  # type: ignore[arg-type]
                             timeout_s=10))
    return LLMProposer(llm, label_a="reference", label_b="nominal")


def test_good_proposal_kept_bad_ones_rejected(tmp_path: Path, robot: RobotBinding, damped_ref: Path,
                                              nominal_run: Path) -> None:
    with replay_server([Reply(f"Here you go:\n```json\n{SCRIPTED}\n```")]) as (base, log):
        analysis = analyze_runs(damped_ref, nominal_run, robot=robot, twin_b="mujoco", knobs=[DAMPING],
                                executor="serial", propose_fn=proposer(base))
    prompt = log.requests[0]["messages"][-1]["content"]
    assert DAMPING in prompt and "motor.wheel1.gain" not in prompt  # only the selected knob is offered
    assert analysis.findings and analysis.narrative is not None
    narrative = analysis.narrative
    assert narrative["label"] == LABEL and "damped" in narrative["explanation"]
    status = [p["status"] for p in narrative["proposals"]]
    assert status == ["kept", "rejected", "invalid", "invalid"]
    assert "less than or equal to 1" in narrative["proposals"][2]["reason"]
    assert "proposals[3].knobs.motor.wheel1.gain" in narrative["proposals"][3]["reason"]
    assert analysis.objective is not None
    kept, rejected = analysis.proposals  # only the schema-valid ones were simulated
    assert kept.accepted and kept.objective is not None and kept.objective < analysis.objective.total
    assert not rejected.accepted and rejected.objective is not None and rejected.objective > analysis.objective.total
    write_analysis(analysis, tmp_path / "out")
    saved = json.loads((tmp_path / "out" / "analysis.json").read_text())
    assert saved["llm_narrative"]["proposals"][0]["status"] == "kept"
    assert html.escape(LABEL) in (tmp_path / "out" / "analysis.html").read_text()


def test_malformed_reply_leaves_the_analysis_alone(robot: RobotBinding, damped_ref: Path, nominal_run: Path) -> None:
    plain = analyze_runs(damped_ref, nominal_run)
    replies = [Reply("I think the damping differs {but no JSON here"),
               Reply(json.dumps({"explanation": "x", "proposals": [{"knobs": GOOD}], "code": "import os"}))]
    with replay_server(replies, protocol="anthropic") as (base, _):
        for expected in ("invalid JSON", "code: Extra inputs are not permitted"):
            analysis = analyze_runs(damped_ref, nominal_run, propose_fn=proposer(base, "anthropic"))
            assert analysis.narrative is not None
            assert expected in analysis.narrative["error"] and analysis.narrative["explanation"] is None
            assert analysis.proposals == [] and analysis.narrative["proposals"] == []
            assert [f.message for f in analysis.findings] == [f.message for f in plain.findings]


def test_align_starts_from_the_kept_proposal(tmp_path: Path, robot: RobotBinding, suite3: Path,
                                             damped_ref: Path) -> None:
    with replay_server([Reply(SCRIPTED)]) as (base, _):
        result = run_align(AlignConfig(reference=str(damped_ref), target="mujoco", robot=str(robot.path),
                                       suite=str(suite3), knobs=[DAMPING], optimizer="cma", budget=8,
                                       popsize=4, executor="serial"), tmp_path / "out",
                           propose_fn=proposer(base))
    assert [p.accepted for p in result.proposals] == [True, False]
    assert result.narrative is not None and result.narrative["proposals"][0]["status"] == "kept"
    # The search started from the kept proposal, so even this tiny budget ends near the true damping.
    assert abs(result.fitted[DAMPING] - TRUE_DAMPING) < 0.2 * TRUE_DAMPING
    record = json.loads((tmp_path / "out" / "align_record.json").read_text())
    assert record["llm_narrative"]["label"] == LABEL
    assert "LLM narrative" in (tmp_path / "out" / "report.html").read_text()


def test_cli_analyze_llm(tmp_path: Path, damped_ref: Path, nominal_run: Path) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("DUALTWIN_LLM")}
    with replay_server([Reply(SCRIPTED)]) as (base, _):
        env.update(DUALTWIN_LLM_PROVIDER="openai", DUALTWIN_LLM_BASE_URL=base, DUALTWIN_LLM_MODEL="scripted")
        done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "analyze",
                               "--reference-run", str(damped_ref), "--target-run", str(nominal_run),
                               "--out", str(tmp_path / "out"), "--llm"], env=env, capture_output=True, text=True,
                              timeout=120)
    assert done.returncode == 0, done.stderr
    assert "LLM narrative" in done.stdout
    saved = json.loads((tmp_path / "out" / "analysis.json").read_text())
    # Without --robot/--target nothing can be re-simulated: every proposal is refused, none kept.
    assert saved["llm_narrative"]["explanation"]
    assert all(p["status"] == "invalid" for p in saved["llm_narrative"]["proposals"])
    unconfigured = {k: v for k, v in env.items() if not k.startswith("DUALTWIN_LLM")}
    failed = subprocess.run([sys.executable, "-m", "dualtwin.cli", "analyze",
                             "--reference-run", str(damped_ref), "--target-run", str(nominal_run),
                             "--out", str(tmp_path / "out2"), "--llm"], env=unconfigured, capture_output=True,
                            text=True, timeout=120)
    assert failed.returncode == 2 and "no LLM model configured" in failed.stderr + failed.stdout
    assert "Traceback" not in failed.stderr
