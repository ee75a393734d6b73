"""The generate-compile-repair loop against loopback replay servers, the deterministic sources, the primitive
description and the case library."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.genai.cases import CaseLibrary, tokenize
from dualtwin.genai.generate import GenerationFailed, Source, confined, extract_json, generate
from dualtwin.genai.llm import AnthropicClient, LLMConfig, OpenAIChatClient
from dualtwin.genai.primitive import (
    SCHEMA_PATH,
    compile_description,
    json_schema,
    load_description,
    mjcf_to_description,
    parse_description,
)
from dualtwin.robots.binding import BUNDLED, load_binding
from dualtwin.suite.runner import SuiteRun
from tests.support.llm_replay import Reply, replay_server

KEY = "sk-loop-secret-9876"
CARTPOLE_JSON = Path(__file__).resolve().parents[2] / "src/dualtwin/genai/cases/cartpole.json"

PENDULUM = {
    "robot_name": "pendulum",
    "description": "a fixed post with a motorised arm",
    "physics": {"timestep_ms": 8},
    "parts": [
        {"name": "post", "type": "box", "dimensions": [0.1, 0.1, 1.0], "mass": 2.0, "position": [0, 0, 0.5],
         "parent": None, "joint": {"type": "fixed"}},
        {"name": "arm", "type": "capsule", "dimensions": [0.02, 0.4], "mass": 0.3, "position": [0, 0.1, 0.45],
         "parent": "post", "joint": {"type": "hinge", "axis": [0, 1, 0], "anchor": [0, 0.1, 0.45],
                                     "damping": 0.01, "limits": [-2.5, 2.5]},
         "motor": {"name": "shoulder", "maxVelocity": 5, "maxTorque": 2, "sensor": "shoulder sensor"}},
    ],
}


def spec_file(tmp_path: Path) -> Path:
    path = tmp_path / "SPEC.md"
    path.write_text("A fixed post with one motorised arm (a pendulum) driven by a shoulder motor.\n")
    return path


def test_schema_file_is_current() -> None:
    assert json.loads(SCHEMA_PATH.read_text()) == json_schema()


def test_description_validation_messages() -> None:
    bad = json.loads(json.dumps(PENDULUM))
    bad["parts"][1]["dimensions"] = [0.02]
    with pytest.raises(DualtwinError, match="capsule needs 2 dimensions"):
        parse_description(bad)
    bad = json.loads(json.dumps(PENDULUM))
    bad["parts"][1]["joint"]["limits"] = [-90, 90]
    with pytest.raises(DualtwinError, match="degrees"):
        parse_description(bad)
    bad = json.loads(json.dumps(PENDULUM))
    bad["parts"][1]["dimensions"] = [0.02, 500]
    with pytest.raises(DualtwinError, match="less than or equal to 50"):
        parse_description(bad)
    bad = json.loads(json.dumps(PENDULUM))
    bad["parts"][0]["mesh"] = "/etc/passwd"  # no file references in the schema
    with pytest.raises(DualtwinError, match="Extra inputs"):
        parse_description(bad)
    bad = json.loads(json.dumps(PENDULUM))
    bad["parts"][1]["parent"] = "pots"
    with pytest.raises(DualtwinError, match="unknown parent 'pots'"):
        compile_description(parse_description(bad))


def test_one_description_gives_both_twins_and_runs_one_suite(tmp_path: Path) -> None:
    result = generate(Source.from_json(CARTPOLE_JSON), tmp_path)
    assert result.converged and result.iterations == 0
    for kind in ("wbt", "xml", "json", "binding", "suite"):
        assert result.files[kind].is_file()
    model = mujoco.MjModel.from_xml_path(str(result.files["xml"]))
    assert model.body("pole").mass[0] == pytest.approx(0.2)
    binding = load_binding(result.files["binding"])
    assert {"pole_sensor_rad", "wheel1_sensor_rad"} <= set(binding.spec.onboard)
    for twin in ("mujoco", "webots"):
        manifest = SuiteRun(result.files["suite"], twin, binding, tmp_path / f"run_{twin}").run()
        assert all(s["status"] == "completed" for s in manifest["scenarios"]), (twin, manifest["scenarios"])


def test_mjcf_round_trip_of_cartpole_xml() -> None:
    desc = mjcf_to_description(BUNDLED / "cartpole" / "cartpole.xml")
    assert len(desc.parts) == 6
    pole = next(p for p in desc.parts if p.name == "pole")
    assert pole.joint is not None and pole.joint.limits == pytest.approx((-1, 1))
    assert pole.joint.sensor == "pole sensor"
    model = compile_description(desc).conversion.compile()
    original = mujoco.MjModel.from_xml_path(str(BUNDLED / "cartpole" / "cartpole.xml"))
    assert sum(model.body_mass) == pytest.approx(sum(original.body_mass))
    assert model.nu == original.nu == 4 and model.nsensor == original.nsensor


def test_from_wbt_uses_the_converter(tmp_path: Path) -> None:
    result = generate(Source.from_wbt(BUNDLED / "cartpole" / "cartpole.wbt"), tmp_path)
    assert result.converged and result.iterations == 0
    assert {"wbt", "xml", "binding", "suite", "json"} <= set(result.files)
    assert load_binding(result.files["binding"]).spec.twins["webots"].robot == "cart"


def test_llm_loop_repairs_broken_json_and_a_non_compiling_model(tmp_path: Path) -> None:
    broken = '{"robot_name": "pendulum", "parts": [ {"name": "post", '
    typo = json.loads(json.dumps(PENDULUM))
    typo["parts"][1]["parent"] = "pots"  # valid JSON and schema, but the compiler cannot resolve it
    script = [Reply(broken), Reply("Here you go:\n```json\n" + json.dumps(typo) + "\n```"), Reply(json.dumps(PENDULUM))]
    with replay_server(script) as (base, log):
        llm = OpenAIChatClient(LLMConfig(model="replay", base_url=base, api_key=KEY, timeout_s=10, max_retries=0))
        result = generate(Source.from_text(spec_file(tmp_path)), tmp_path / "out", llm=llm, max_iterations=4)
    assert result.converged and result.iterations == 3
    assert len(log.requests) == 3
    # the exact errors went back to the model
    repair_1 = log.requests[1]["messages"][-1]["content"]
    assert "invalid JSON" in repair_1 or "no JSON object" in repair_1
    assert "unknown parent 'pots'" in log.requests[2]["messages"][-1]["content"]
    assert log.requests[0]["response_format"] == {"type": "json_object"}
    model = mujoco.MjModel.from_xml_path(str(result.files["xml"]))
    assert model.actuator("shoulder").forcerange == pytest.approx([-2, 2])
    assert model.joint("arm_joint").range == pytest.approx([-2.5, 2.5])
    transcript = result.transcript_path.read_text() if result.transcript_path else ""
    assert KEY not in transcript and "unknown parent" in transcript
    record = json.loads((tmp_path / "out" / "generation.json").read_text())
    assert record["iterations"] == 3 and record["converged"]


def test_llm_that_never_converges_stops_and_keeps_the_best_attempt(tmp_path: Path) -> None:
    typo = json.loads(json.dumps(PENDULUM))
    typo["parts"][1]["parent"] = "pots"
    script = [Reply("no json here"), Reply(json.dumps(typo)), Reply("{ still broken")]
    with replay_server(script) as (base, _log):
        llm = OpenAIChatClient(LLMConfig(model="replay", base_url=base, api_key=KEY, timeout_s=10, max_retries=0))
        with pytest.raises(GenerationFailed, match="3 iteration") as err:
            generate(Source.from_text(spec_file(tmp_path)), tmp_path / "out", llm=llm, max_iterations=3)
    result = err.value.result
    assert result.iterations == 3 and not result.converged
    assert result.best_stage == "valid description"
    assert result.files["json"].is_file()  # the best attempt (the schema-valid one)
    transcript = json.loads(result.transcript_path.read_text()) if result.transcript_path else []
    assert sum(1 for t in transcript if t["role"] == "assistant") == 3
    # Wall-clock time only in timing.json: the transcript is the same for the same replies.
    assert not any("seconds" in t for t in transcript)
    timing = json.loads((tmp_path / "out" / "timing.json").read_text())
    assert [t["iteration"] for t in timing["llm_calls"]] == [1, 2, 3]


def test_llm_provider_failure_inside_the_loop(tmp_path: Path) -> None:
    with replay_server([Reply(status=500)] * 3) as (base, _log):
        llm = OpenAIChatClient(LLMConfig(model="replay", base_url=base, api_key=KEY, timeout_s=5, max_retries=0))
        with pytest.raises(GenerationFailed, match="HTTP 500"):
            generate(Source.from_text(spec_file(tmp_path)), tmp_path / "out", llm=llm, max_iterations=2)
    assert (tmp_path / "out" / "transcript.json").is_file()


def test_anthropic_loop_short_case(tmp_path: Path) -> None:
    with replay_server([Reply(json.dumps(PENDULUM))], protocol="anthropic") as (base, log):
        llm = AnthropicClient(LLMConfig(provider="anthropic", model="replay", base_url=base, api_key=KEY,
                                        timeout_s=10, max_retries=0))
        result = generate(Source.from_text(spec_file(tmp_path)), tmp_path / "out", llm=llm, max_iterations=2)
    assert result.converged and result.iterations == 1
    assert "primitive robot description" in log.requests[0]["system"]


def test_extract_json_and_confinement(tmp_path: Path) -> None:
    assert extract_json('Sure!\n```json\n{"a": 1}\n```') == {"a": 1}
    assert extract_json('prefix {"a": {"b": 2}} suffix') == {"a": {"b": 2}}
    with pytest.raises(ValueError, match="no JSON object|invalid JSON"):
        extract_json("nothing")
    with pytest.raises(ValueError, match="not an object"):
        extract_json("[1, 2]")
    # nested past Python's recursion limit: before, the RecursionError escaped the repair loop (no repair round,
    # a generic error naming no input)
    with pytest.raises(ValueError, match="invalid JSON: nested too deeply"):
        extract_json('{"robot_name": "x", "parts": ' + "[" * 5000 + "]" * 5000 + "}")
    assert confined(tmp_path, "a/b.stl") == (tmp_path / "a" / "b.stl").resolve()
    for bad in ("/etc/passwd", "../x.stl", "a/../../x", ""):
        with pytest.raises(DualtwinError, match="refusing"):
            confined(tmp_path, bad)


def test_case_library_retrieval(tmp_path: Path) -> None:
    lib = CaseLibrary.bundled()
    assert "cartpole" in [c.name for c in lib.cases]
    user = tmp_path / "twins" / "arm"
    user.mkdir(parents=True)
    (user / "robot.json").write_text(json.dumps(PENDULUM))
    (tmp_path / "twins" / "suite.json").write_text('{"suite_name": "x", "scenarios": []}')  # ignored
    lib.add_folder(tmp_path / "twins")
    hits = lib.retrieve("a motorised arm on a fixed post", k=2)
    assert hits[0][0].name == "pendulum"
    hits = lib.retrieve("balance a pole on a wheeled cart", k=1)
    assert hits[0][0].name == "cartpole"
    assert lib.retrieve("balance a pole on a wheeled cart", k=2) == lib.retrieve("balance a pole on a wheeled cart", k=2)
    assert tokenize("Wheels and Poles") == ["wheel", "pole"]
    assert load_description(CARTPOLE_JSON).robot_name == "cartpole"
