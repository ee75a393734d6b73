"""Generation from text on the six-joint arm (issue 19): a datasheet, the compile-repair loop against a scripted
LLM on loopback (a real HTTP server speaking the OpenAI protocol, used through the real ``openai`` client), and
a model that runs its generated suite in both twins.

The scripted replies make the mistakes LLMs make on an arm, one per round, and the test asserts which check
caught each one and that its message went back to the model:

1. the paper's schema with the 5 kg payload folded into the flange's mass (masses do not add up);
2. our schema with the elbow limits in degrees;
3. a part whose parent is misspelt (no such part);
4. the shoulder height written without the base plate, so the upper arm starts inside the base (overlap);
5. the corrected description: compiles, no overlaps, passes the physics smoke test.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import mujoco
import pytest

from dualtwin.genai.generate import Source, generate
from dualtwin.genai.llm import LLMConfig, OpenAIChatClient
from dualtwin.robots.binding import load_binding
from dualtwin.suite.runner import SuiteRun
from tests.support.llm_replay import Reply, replay_server

DATASHEET = Path(__file__).parent / "arm" / "ur5e_class_datasheet.md"
PI = math.pi


def _motor(name: str, torque: float) -> dict[str, Any]:
    return {"name": name, "maxVelocity": PI, "maxTorque": torque, "sensor": f"{name} sensor"}


def arm_description() -> dict[str, Any]:
    """The datasheet read correctly, in our schema (positions in the parent part's frame, parts centred)."""
    hinge_y = {"type": "hinge", "axis": [0, 1, 0]}
    parts = [
        {"name": "base", "type": "box", "dimensions": [0.2, 0.3, 0.1], "mass": 2.9, "position": [0, 0, 0.05],
         "parent": None, "joint": {"type": "fixed"}},
        {"name": "shoulder", "type": "cylinder", "dimensions": [0.06, 0.12], "mass": 3.761,
         "position": [0, 0, 0.1125], "parent": "base",
         "joint": {"type": "hinge", "name": "shoulder_pan", "axis": [0, 0, 1]}, "motor": _motor("shoulder_pan", 150)},
        {"name": "upper_arm", "type": "box", "dimensions": [0.425, 0.08, 0.08], "mass": 8.058,
         "position": [0.2125, 0.138, 0], "parent": "shoulder",
         "joint": {**hinge_y, "name": "shoulder_lift", "anchor": [0, 0.138, 0]}, "motor": _motor("shoulder_lift", 150)},
        {"name": "forearm", "type": "box", "dimensions": [0.3922, 0.06, 0.06], "mass": 2.846,
         "position": [0.4086, -0.131, 0], "parent": "upper_arm",
         "joint": {**hinge_y, "name": "elbow", "anchor": [0.2125, -0.131, 0], "limits": [-PI, PI]},
         "motor": _motor("elbow", 150)},
        {"name": "wrist_1", "type": "box", "dimensions": [0.08, 0.08, 0.08], "mass": 1.37,
         "position": [0.1961, 0.1333, 0], "parent": "forearm",
         "joint": {**hinge_y, "name": "wrist_1_joint", "anchor": [0.1961, 0.1333, 0]}, "motor": _motor("wrist_1", 28)},
        {"name": "wrist_2", "type": "box", "dimensions": [0.07, 0.07, 0.07], "mass": 1.3,
         "position": [0, 0, -0.0997], "parent": "wrist_1",
         "joint": {"type": "hinge", "name": "wrist_2_joint", "axis": [0, 0, 1]}, "motor": _motor("wrist_2", 28)},
        {"name": "wrist_3", "type": "box", "dimensions": [0.075, 0.03, 0.075], "mass": 0.365,
         "position": [0, 0.0996, 0], "parent": "wrist_2",
         "joint": {**hinge_y, "name": "wrist_3_joint"}, "motor": _motor("wrist_3", 28)},
    ]
    return {"robot_name": "gen_arm", "description": "six-joint arm, UR5e size class",
            "physics": {"timestep_ms": 2, "floor": False}, "parts": parts}


def _part(desc: dict[str, Any], name: str) -> dict[str, Any]:
    return next(p for p in desc["parts"] if p["name"] == name)


def paper_schema_with_payload_in_the_flange() -> dict[str, Any]:
    """Round 1: the paper's schema (size objects, materials, a total mass, assembly instructions, degrees)."""
    ours = arm_description()
    parts = []
    for p in ours["parts"]:
        dims = {"size": p["dimensions"]} if p["type"] == "box" else \
            {"radius": p["dimensions"][0], "height": p["dimensions"][1]}
        joint = dict(p["joint"])
        if joint.get("limits"):
            joint["limits"] = [-180, 180]
        elif joint["type"] == "hinge":
            joint["limits"] = [-360, 360]
        part = {"name": p["name"], "type": p["type"], "dimensions": dims, "mass": p["mass"],
                "position": p["position"], "material": "aluminium, blue anodised", "parent": p["parent"],
                "joint": joint}
        if "motor" in p:
            part["motor"] = p["motor"]
        parts.append(part)
    parts[-1]["mass"] = 0.365 + 5.0  # "the flange carries the rated payload"
    return {"robot_name": "gen_arm", "physics": {"mass": 20.6, "center_of_mass": [0, 0, 0], "inertia": [0] * 6,
                                                 "friction": 0.8, "restitution": 0.0, "damping": 0.0},
            "parts": parts, "assembly_instructions": ["Bolt the base plate down.", "Mount the links in order."]}


def script() -> list[str]:
    degrees = arm_description()
    _part(degrees, "forearm")["joint"]["limits"] = [-180, 180]
    misspelt = arm_description()
    _part(misspelt, "wrist_2")["parent"] = "wrist1"
    overlap = arm_description()
    _part(overlap, "shoulder")["position"] = [0, 0, 0.0625]  # d1 measured from the top of the base plate
    return [
        "Here is the arm in the primitive schema:\n```json\n" + json.dumps(paper_schema_with_payload_in_the_flange())
        + "\n```",
        json.dumps(degrees),
        "Corrected:\n" + json.dumps(misspelt),
        json.dumps(overlap),
        "```json\n" + json.dumps(arm_description(), indent=1) + "\n```",
    ]


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Any, Path]:
    out = tmp_path_factory.mktemp("gen_arm")
    with replay_server([Reply(text) for text in script()]) as (base, log):
        llm = OpenAIChatClient(LLMConfig(model="replay", base_url=base, api_key="sk-loop", timeout_s=10,
                                         max_retries=0))
        result = generate(Source.from_text(DATASHEET), out / "model", llm=llm, max_iterations=6)
    return result, log, out


def test_four_repair_rounds_each_caught_by_its_check(generated: tuple[Any, Any, Path]) -> None:
    result, log, _ = generated
    assert result.converged and result.iterations == 5 and len(log.requests) == 5
    # The datasheet went to the model; each repair prompt carried the check's own message.
    assert "d4 = 0.1333" in log.requests[0]["messages"][-1]["content"]
    repairs = [log.requests[i]["messages"][-1]["content"] for i in range(1, 5)]
    assert "masses do not add up" in repairs[0] and "'wrist_3'" in repairs[0] and "+24 %" in repairs[0]
    assert "degrees?" in repairs[1]
    assert "unknown parent 'wrist1'" in repairs[2]
    assert "'base' and 'upper_arm' overlap" in repairs[3]
    transcript = json.loads(result.transcript_path.read_text())
    stages = [t["stage"] for t in transcript if t["role"] == "assistant"]
    assert stages[-1] == "smoke test passed" and len(set(stages[:-1])) >= 2
    first = next(t for t in transcript if t["role"] == "assistant")
    # The paper-schema reply was read as such; its degrees were converted, with a note, before the mass check.
    assert first["dialect"] == "paper"


def test_generated_arm_matches_the_datasheet(generated: tuple[Any, Any, Path]) -> None:
    result, _, _ = generated
    model = mujoco.MjModel.from_xml_path(str(result.files["xml"]))
    assert model.njnt == 6 and model.nu == 6
    # The six moving links (the fixed base plate is welded to the world, so its 2.9 kg never moves).
    assert sum(model.body_mass) == pytest.approx(20.6 - 2.9, abs=1e-6)
    assert model.actuator("elbow").forcerange == pytest.approx([-150, 150])
    assert model.actuator("wrist_3").forcerange == pytest.approx([-28, 28])
    assert model.joint("elbow").range == pytest.approx([-PI, PI])
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # Reach at zero: a2 + a3 along x, as the datasheet says.
    assert data.body("wrist_3").xpos[0] == pytest.approx(0.425 + 0.3922, abs=1e-4)


def test_generated_arm_runs_its_suite_in_both_twins(generated: tuple[Any, Any, Path]) -> None:
    result, _, out = generated
    binding = load_binding(result.files["binding"])
    suite = json.loads(result.files["suite"].read_text())
    assert len(suite["scenarios"]) >= 2
    finals = {}
    for twin in ("mujoco", "webots"):
        manifest = SuiteRun(result.files["suite"], twin, binding, out / f"run_{twin}").run()
        assert all(s["status"] == "completed" for s in manifest["scenarios"]), (twin, manifest["scenarios"])
        finals[twin] = manifest
    assert len(finals["mujoco"]["scenarios"]) == len(finals["webots"]["scenarios"]) == len(suite["scenarios"])


def test_cli_generate_from_text_runs_the_same_loop(tmp_path: Path) -> None:
    """``dualtwin generate --from-text``, configured through the environment, against the same script."""
    with replay_server([Reply(text) for text in script()]) as (base, log):
        env = {**os.environ, "DUALTWIN_LLM_BASE_URL": base, "DUALTWIN_LLM_MODEL": "replay",
               "DUALTWIN_LLM_API_KEY": "sk-loop", "DUALTWIN_LLM_PROVIDER": "openai"}
        env.pop("DUALTWIN_LLM_CONFIG", None)
        done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "generate", "--from-text", str(DATASHEET),
                               "--out", str(tmp_path / "model"), "--max-iterations", "6"],
                              capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "converged after 5 LLM iteration(s)" in done.stdout and len(log.requests) == 5
    record = json.loads((tmp_path / "model" / "generation.json").read_text())
    assert record["converged"] and record["iterations"] == 5
    # generation.json keeps what each failed round was refused for, in order.
    caught = ["masses do not add up", "degrees?", "unknown parent 'wrist1'", "overlap"]
    assert len(record["errors"]) == 4
    assert all(word in error for word, error in zip(caught, record["errors"], strict=True))
