"""``dualtwin generate``: a robot description becomes both twins, a binding and a suite.

Three sources:

* ``from_text`` (a spec in prose): the LLM proposes a primitive description (JSON, constrained by its schema;
  JSON mode where the provider has it, else the JSON block is extracted), a deterministic compiler builds the
  ``.wbt`` and the MJCF, MuJoCo compiles it, the lint pass and the smoke test run, and any error goes back
  to the LLM verbatim (repair prompt) - up to ``max_iterations`` LLM calls;
* ``from_json`` (a primitive description) and ``from_wbt`` (a Webots world, through the converter): no LLM.

LLM output is untrusted data: it is only ever parsed as JSON and validated (never executed or unpickled);
the description schema has no file references and names are restricted to ``[A-Za-z0-9_]``, so every file
written stays in the output folder (:func:`confined` rejects absolute paths and ``..`` anyway); replies and
models are size-limited (``MAX_RESPONSE_CHARS``, ``MAX_PARTS``, dimension/mass ranges). A loop that does not
converge stops at ``max_iterations``, keeps its best attempt and the (redacted) transcript, and raises
:class:`GenerationFailed` (a DualtwinError: CLI exit code 2).
"""

from __future__ import annotations

import copy
import json
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from string import Template
from typing import Any, Literal

import mujoco
import numpy as np

from dualtwin.artifacts import write_json, write_text
from dualtwin.convert.checks import Finding, SmokeResult, smoke_test
from dualtwin.errors import DualtwinError
from dualtwin.genai.agreement import MotionDisagreement, motion_disagreements
from dualtwin.genai.cases import CaseLibrary, examples_text
from dualtwin.genai.llm import MAX_RESPONSE_CHARS, LLMClient, Message
from dualtwin.genai.paper_dialect import Dialect, detect, load_any_description, read_description
from dualtwin.genai.primitive import (
    CompiledRobot,
    RobotDescription,
    compile_description,
    json_schema,
    mjcf_to_description,
)

PROMPTS = Path(__file__).parent / "prompts"
DEFAULT_MAX_ITERATIONS = 5
MAX_SPEC_CHARS = 50_000
#: Stages an attempt can reach; the best attempt is the one that got furthest.
STAGES = ("no JSON found", "JSON parsed", "valid description", "model compiles", "lint clean", "smoke test passed")


def prompt(name: str) -> str:
    """A prompt template from ``genai/prompts`` (``$name`` placeholders)."""
    return (PROMPTS / f"{name}.txt").read_text(encoding="utf-8")


def confined(out_dir: Path, relative: str) -> Path:
    """``out_dir / relative``, refusing absolute paths and anything that leaves ``out_dir``."""
    rel = Path(relative)
    if rel.is_absolute() or relative.startswith(("/", "\\")) or ".." in rel.parts or not relative:
        raise DualtwinError(f"refusing file reference {relative!r}: only plain relative paths inside the output "
                            "folder are allowed")
    target = (out_dir / rel).resolve()
    if not target.is_relative_to(out_dir.resolve()):
        raise DualtwinError(f"refusing file reference {relative!r}: it leaves the output folder")
    return target


@dataclass(frozen=True)
class Source:
    """What to generate from: ``text`` (spec file), ``json`` (primitive description) or ``wbt`` (world)."""

    kind: Literal["text", "json", "wbt"]
    path: Path
    robot: str | None = None  # wbt: DEF or name of the robot

    @classmethod
    def from_text(cls, path: Path | str) -> Source:
        return cls("text", Path(path))

    @classmethod
    def from_json(cls, path: Path | str) -> Source:
        return cls("json", Path(path))

    @classmethod
    def from_wbt(cls, path: Path | str, robot: str | None = None) -> Source:
        return cls("wbt", Path(path), robot)


@dataclass
class Attempt:
    iteration: int
    stage: int
    error: str | None = None
    description: RobotDescription | None = None
    compiled: CompiledRobot | None = None
    smoke: SmokeResult | None = None
    dialect: str = "dualtwin"
    assumptions: list[str] = field(default_factory=list)


@dataclass
class GenerationResult:
    """Where the twins were written and how the loop went."""

    out_dir: Path
    converged: bool
    iterations: int  # LLM calls made (0 for the deterministic sources)
    files: dict[str, Path] = field(default_factory=dict)
    transcript_path: Path | None = None
    warnings: list[str] = field(default_factory=list)
    lint: list[Finding] = field(default_factory=list)
    smoke: SmokeResult | None = None
    errors: list[str] = field(default_factory=list)  # one per failed iteration
    best_stage: str = ""
    dialect: str = "dualtwin"  # the schema the (best) description was written in
    assumptions: list[str] = field(default_factory=list)  # what reading the paper's schema had to assume

    def to_dict(self) -> dict[str, Any]:
        return {
            "converged": self.converged, "iterations": self.iterations, "best_stage": self.best_stage,
            "files": {k: str(v) for k, v in self.files.items()},
            "transcript": str(self.transcript_path) if self.transcript_path else None,
            "warnings": self.warnings, "lint": [f.to_dict() for f in self.lint],
            "smoke": self.smoke.to_dict() if self.smoke else None, "errors": self.errors,
            "dialect": self.dialect, "assumptions": self.assumptions,
        }


class GenerationFailed(DualtwinError):
    """The loop did not converge; ``result`` has the best attempt's files and the transcript."""

    def __init__(self, message: str, result: GenerationResult) -> None:
        super().__init__(message)
        self.result = result


# ------------------------------------------------------------------------------------------------
# checking one description


def extract_json(text: str) -> Any:
    """The JSON object in a reply: the whole reply, a fenced ```json block, or the outermost ``{...}``."""
    if len(text) > MAX_RESPONSE_CHARS:
        raise ValueError(f"reply of {len(text)} characters exceeds the {MAX_RESPONSE_CHARS} limit")
    candidates = [text.strip()]
    fence_start = text.find("```")
    while fence_start >= 0:
        body_start = text.find("\n", fence_start)
        fence_end = text.find("```", body_start + 1) if body_start >= 0 else -1
        if body_start < 0 or fence_end < 0:
            break
        candidates.append(text[body_start + 1:fence_end].strip())
        fence_start = text.find("```", fence_end + 3)
    first, last = text.find("{"), text.rfind("}")
    if 0 <= first < last:
        candidates.append(text[first:last + 1])
    error = "no JSON object found in the reply"
    for candidate in candidates:
        if not candidate:
            continue
        try:
            value = json.loads(candidate)
        except json.JSONDecodeError as exc:
            error = f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}"
            continue
        except RecursionError:  # a reply is untrusted: thousands of nested brackets are a reply to repair too
            error = "invalid JSON: nested too deeply to read"
            continue
        if isinstance(value, dict):
            return value
        error = f"the reply is JSON but a {type(value).__name__}, not an object"
    raise ValueError(error)


def check_description(desc: RobotDescription, wbt_path: str, iteration: int = 0) -> Attempt:
    """Compile, lint and smoke-test a description; the attempt records how far it got and the exact error."""
    attempt = Attempt(iteration, 2, description=desc)
    try:
        compiled = compile_description(desc, wbt_path)
        model = compiled.conversion.compile()
    except DualtwinError as exc:
        attempt.error = f"the model does not compile: {exc}"
        return attempt
    attempt.compiled = compiled
    attempt.stage = 3
    errors = [f for f in compiled.conversion.lint if f.level == "error"]
    if errors:
        attempt.error = "lint errors:\n" + "\n".join(str(f) for f in errors)
        return attempt
    overlaps = overlapping_parts(model)
    if overlaps:
        attempt.error = "parts overlap at the initial pose (the physics would push them apart violently):\n" + \
            "\n".join(overlaps)
        return attempt
    attempt.stage = 4
    smoke = smoke_test(model)
    attempt.smoke = smoke
    if not smoke.ok:
        attempt.error = f"physics smoke test failed (0.5 s of random motor torques): {smoke.message}"
        return attempt
    disagreements = _twin_disagreements(compiled)
    if disagreements:
        shown = "; ".join(str(d) for d in disagreements[:4])
        more = f" (and {len(disagreements) - 4} more)" if len(disagreements) > 4 else ""
        attempt.error = ("smoke test failed: the two twins do not move alike on the generated suite's first "
                         f"second ({shown}{more}); a model both twins cannot share is not usable — look for a "
                         "part welded to the world or to the floor")
        return attempt
    attempt.stage = 5
    return attempt


def _twin_disagreements(compiled: CompiledRobot) -> list[MotionDisagreement]:
    """Both twins run the robot's generated suite briefly (:mod:`dualtwin.genai.agreement`); [] without one."""
    with tempfile.TemporaryDirectory(prefix="dualtwin-generate-") as tmp:
        files = _write_compiled(compiled, Path(tmp))
        if "binding" not in files or "suite" not in files:
            return []
        return motion_disagreements(files["binding"], files["suite"])


#: Penetration at the initial pose beyond which two parts (or a part and the floor) count as overlapping.
OVERLAP_TOLERANCE_M = 0.002


def overlapping_parts(model: mujoco.MjModel) -> list[str]:
    """One line per pair of bodies that interpenetrate at the initial pose, naming both and the fix.

    A robot's parts do not collide with each other in either twin (Webots' ``selfCollision`` is off by default,
    and the converter mirrors that), so an overlap is not a physics failure but a description that cannot be
    what its author meant: it is checked on a copy in which every collision geom collides with every other.
    A body and its parent are left out (parts on a joint may interpenetrate around their axle, and a fixed base
    may stand in the floor). MuJoCo's own parent filter does not do this for a parent welded to the world, so
    the kinematic tree decides here.
    """
    model = copy.copy(model)
    solid = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    model.geom_contype[solid] = 1
    model.geom_conaffinity[solid] = 1
    model.body_contype[:] = 1  # the broad phase filters on the bodies' union of their geoms' bits
    model.body_conaffinity[:] = 1
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    worst: dict[tuple[str, str], tuple[float, np.ndarray]] = {}
    for contact in data.contact[: data.ncon]:
        depth = -float(contact.dist)
        if depth <= OVERLAP_TOLERANCE_M:
            continue
        b1, b2 = (int(model.geom_bodyid[g]) for g in (contact.geom1, contact.geom2))
        if b1 != b2 and (int(model.body_parentid[b1]) == b2 or int(model.body_parentid[b2]) == b1):
            continue
        names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "floor" if b else "floor"
                      for b in (b1, b2))
        key = (names[0], names[1])
        if key not in worst or depth > worst[key][0]:
            worst[key] = (depth, np.asarray(contact.frame[:3], float).copy())
    lines = []
    for (first, second), (depth, normal) in sorted(worst.items()):
        if first == "floor":
            lines.append(f"part {second!r} starts {1000 * depth:.1f} mm inside the floor: raise the robot (the root "
                         f"part's position z) by at least {1000 * depth:.1f} mm")
            continue
        lines.append(f"parts {first!r} and {second!r} overlap by {1000 * depth:.1f} mm: move {second!r} by "
                     f"{1000 * depth:.1f} mm along {np.round(normal, 3).tolist()} (world frame), or shrink one of them")
    return lines


def check_reply(reply: str, wbt_path: str, iteration: int, dialect: Dialect = "auto") -> Attempt:
    """Parse, translate (either dialect), compile and check one LLM reply."""
    try:
        data = extract_json(reply)
    except ValueError as exc:
        return Attempt(iteration, 0, error=str(exc))
    chosen = detect(data) if dialect == "auto" else dialect
    try:
        read = read_description(data, "the JSON", chosen)
    except DualtwinError as exc:
        return Attempt(iteration, 1, error=str(exc), dialect=chosen)
    attempt = check_description(read.description, wbt_path, iteration)
    attempt.dialect, attempt.assumptions = read.dialect, read.assumptions
    return attempt


# ------------------------------------------------------------------------------------------------
# outputs


def default_suite(binding: dict[str, Any]) -> dict[str, Any]:
    """A small suite for a generated robot: hold still, then drive each motor group (or motor)."""
    actions = binding.get("actions", {})
    velocity_keys = [k for k, a in actions.items() if a["mode"] == "velocity"]
    grouped = [k for k in velocity_keys if len(actions[k]["actuators"]) > 1]
    keys = grouped or velocity_keys
    scenarios: list[dict[str, Any]] = [{"name": "Hold", "duration_s": 1.0}]
    for k in keys[:4]:
        scenarios.append({"name": f"Drive_{k}", "duration_s": 2.0,
                          k: {"kind": "step", "at_s": 0.2, "after": 1.0, "before": 0.0}})
    return {"suite_name": f"{binding.get('name', 'robot')}_smoke",
            "global_settings": {"TIME_STEP": binding.get("control_period_ms", 32)}, "scenarios": scenarios}


def _write_compiled(compiled: CompiledRobot, out_dir: Path) -> dict[str, Path]:
    files = compiled.write(out_dir)
    if "binding" in files:
        binding = compiled.conversion.binding_dict(files["xml"].name, files["wbt"].name)
        suite_path = confined(out_dir, "suite.json")
        write_json(suite_path, default_suite(binding))
        files["suite"] = suite_path
    return files


def _finish(result: GenerationResult, out_dir: Path) -> GenerationResult:
    write_json(confined(out_dir, "generation.json"), result.to_dict())
    return result


# ------------------------------------------------------------------------------------------------
# the sources


def _from_json(path: Path, out_dir: Path, dialect: Dialect) -> GenerationResult:
    read = load_any_description(path, dialect)
    desc = read.description
    attempt = check_description(desc, str(confined(out_dir, f"{desc.robot_name}.wbt")))
    result = GenerationResult(out_dir, attempt.stage == 5, 0, best_stage=STAGES[attempt.stage],
                              dialect=read.dialect, assumptions=read.assumptions)
    if read.dialect != "dualtwin":
        # the same record an LLM reply gets: which schema was read and every assumption made reading it
        result.transcript_path = confined(out_dir, "transcript.json")
        write_json(result.transcript_path, [{"role": "input", "content": str(path), "dialect": read.dialect,
                                             "assumptions": read.assumptions}])
        result.files["transcript"] = result.transcript_path
    if attempt.compiled is not None:
        result.files.update(_write_compiled(attempt.compiled, out_dir))
        result.warnings = list(attempt.compiled.conversion.warnings)
        result.lint = list(attempt.compiled.conversion.lint)
    result.smoke = attempt.smoke
    if attempt.stage < 5:
        result.errors.append(attempt.error or "")
        _finish(result, out_dir)
        raise GenerationFailed(f"{path}: {attempt.error}", result)
    return _finish(result, out_dir)


def _from_wbt(path: Path, robot: str | None, out_dir: Path) -> GenerationResult:
    from dualtwin.convert.bindings import validate_binding
    from dualtwin.convert.webots_to_mjcf import convert_world

    conv = convert_world(path, robot)
    model = conv.compile()
    smoke = smoke_test(model)
    wbt_copy = confined(out_dir, path.name)
    if wbt_copy.resolve() != path.resolve():
        shutil.copyfile(path, wbt_copy)
    xml_path = confined(out_dir, f"{conv.model_name}.xml")
    write_text(xml_path, conv.xml)
    files = {"wbt": wbt_copy, "xml": xml_path}
    binding = conv.binding_dict(xml_path.name, wbt_copy.name)
    warnings = list(conv.warnings)
    if binding.get("onboard"):
        validate_binding(binding, out_dir / "binding.yaml")
        files["binding"] = confined(out_dir, "binding.yaml")
        write_text(files["binding"], conv.binding_yaml(xml_path.name, wbt_copy.name))
        files["suite"] = confined(out_dir, "suite.json")
        write_json(files["suite"], default_suite(binding))
    else:
        warnings.append("no binding written: the robot has no on-board sensors")
    try:
        desc = mjcf_to_description(conv.spec, robot_name=conv.model_name)
        files["json"] = confined(out_dir, "robot.json")
        write_text(files["json"], desc.model_dump_json(indent=2, exclude_none=True) + "\n")
    except DualtwinError as exc:
        warnings.append(f"no primitive description (robot.json): {exc}")
    result = GenerationResult(out_dir, smoke.ok, 0, files, warnings=warnings, lint=list(conv.lint), smoke=smoke,
                              best_stage=STAGES[5 if smoke.ok else 4])
    _finish(result, out_dir)
    if not smoke.ok:
        result.errors.append(smoke.message)
        raise GenerationFailed(f"{path}: converted model fails the smoke test: {smoke.message}", result)
    return result


def _from_text(path: Path, out_dir: Path, llm: LLMClient | None, max_iterations: int,
               cases: CaseLibrary | None, dialect: Dialect = "auto") -> GenerationResult:
    from dualtwin.genai.llm import make_llm

    if not path.is_file():
        raise DualtwinError(f"{path}: spec file not found")
    spec_text = path.read_text(encoding="utf-8")
    if len(spec_text) > MAX_SPEC_CHARS:
        raise DualtwinError(f"{path}: spec of {len(spec_text)} characters exceeds the {MAX_SPEC_CHARS} limit")
    if max_iterations < 1:
        raise DualtwinError("max_iterations must be at least 1")
    client = llm or make_llm()
    library = cases if cases is not None else CaseLibrary.bundled()
    retrieved = library.retrieve(spec_text, k=2)
    schema_text = json.dumps(json_schema(), separators=(",", ":"))
    examples = examples_text(retrieved, prompt("case_example"))
    messages: list[Message] = [
        {"role": "system", "content": prompt("system")},
        {"role": "user", "content": Template(prompt("generate_from_text")).safe_substitute(
            spec=spec_text, schema=schema_text, examples=examples)},
    ]
    transcript: list[dict[str, Any]] = [{"role": m["role"], "content": m["content"]} for m in messages]
    transcript.insert(0, {"role": "meta", "content": json.dumps({
        "llm": repr(client.config), "spec": str(path), "max_iterations": max_iterations,
        "cases": [c.name for c, _ in retrieved]})})
    result = GenerationResult(out_dir, False, 0)
    best: Attempt | None = None
    wbt_path = str(out_dir / "robot.wbt")
    # Wall-clock seconds of each LLM call: timing.json, the one file that differs between two runs with the
    # same replies (the transcript holds no time).
    timing: list[dict[str, Any]] = []
    for iteration in range(1, max_iterations + 1):
        started = time.monotonic()
        try:
            reply = client.complete(messages, json_schema=json_schema())
        except DualtwinError as exc:
            transcript.append({"role": "error", "iteration": iteration, "content": str(exc)})
            result.iterations = iteration
            result.errors.append(str(exc))
            _save_outputs(result, best, transcript, client, out_dir, timing)
            raise GenerationFailed(f"LLM call failed at iteration {iteration}: {exc}", result) from None
        result.iterations = iteration
        timing.append({"iteration": iteration, "llm_seconds": round(time.monotonic() - started, 3)})
        attempt = check_reply(reply, wbt_path, iteration, dialect)
        transcript.append({"role": "assistant", "iteration": iteration, "content": reply, "stage": STAGES[attempt.stage],
                           "error": attempt.error, "dialect": attempt.dialect, "assumptions": attempt.assumptions})
        if best is None or attempt.stage >= best.stage:
            best = attempt
        if attempt.stage == 5:
            break
        result.errors.append(attempt.error or "")
        repair = Template(prompt("repair")).safe_substitute(
            iteration=iteration, max_iterations=max_iterations, stage=STAGES[attempt.stage], error=attempt.error)
        messages = [*messages, {"role": "assistant", "content": reply}, {"role": "user", "content": repair}]
        transcript.append({"role": "user", "iteration": iteration, "content": repair})
    _save_outputs(result, best, transcript, client, out_dir, timing)
    if not result.converged:
        raise GenerationFailed(
            f"the LLM did not produce a working model in {max_iterations} iteration(s); best attempt reached "
            f"'{result.best_stage}' ({best.error if best else 'no attempt'}); files and transcript in {out_dir}",
            result)
    return result


def _save_outputs(result: GenerationResult, best: Attempt | None, transcript: list[dict[str, Any]],
                  client: LLMClient, out_dir: Path, timing: list[dict[str, Any]]) -> None:
    if best is not None:
        result.best_stage = STAGES[best.stage]
        result.converged = best.stage == 5
        result.smoke = best.smoke
        result.dialect, result.assumptions = best.dialect, best.assumptions
        if best.compiled is not None:
            result.files = _write_compiled(best.compiled, out_dir)
            result.warnings = list(best.compiled.conversion.warnings)
            result.lint = list(best.compiled.conversion.lint)
        elif best.description is not None:
            result.files["json"] = confined(out_dir, "robot.json")
            write_text(result.files["json"], best.description.model_dump_json(indent=2, exclude_none=True) + "\n")
    redacted = [{**entry, "content": client.config.redact(str(entry.get("content", "")))} for entry in transcript]
    result.transcript_path = confined(out_dir, "transcript.json")
    write_json(result.transcript_path, redacted)
    result.files["transcript"] = result.transcript_path
    write_json(confined(out_dir, "timing.json"), {"llm_calls": timing})
    _finish(result, out_dir)


def generate(source: Source, out_dir: Path | str, *, llm: LLMClient | None = None,
             max_iterations: int = DEFAULT_MAX_ITERATIONS, cases: CaseLibrary | None = None,
             dialect: Dialect = "auto") -> GenerationResult:
    """Generate both twins (``<name>.wbt``, ``<name>.xml``), ``binding.yaml``, ``suite.json`` and
    ``generation.json`` (plus ``robot.json`` and, for text or the paper's schema, ``transcript.json``) in ``out_dir``;
    the LLM loop also writes ``timing.json`` (each call's wall-clock seconds), the one file two runs with the
    same replies do not share.
    ``dialect`` names the JSON schema of a description (ours, the paper's, or ``auto`` to detect it).

    Raises:
        GenerationFailed: the loop did not converge (best attempt and transcript are kept); CLI exit 2.
        DualtwinError: bad input, unreachable/failing LLM provider.
    """
    out = Path(out_dir)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        if source.kind == "json":
            return _from_json(source.path, out, dialect)
        if source.kind == "wbt":
            if not source.path.is_file():
                raise DualtwinError(f"{source.path}: world file not found")
            return _from_wbt(source.path, source.robot, out)
        return _from_text(source.path, out, llm, max_iterations, cases, dialect)
    except DualtwinError as exc:
        # a refusal (bad input, unreachable provider) leaves nothing behind; a loop that did not converge
        # keeps its best attempt and transcript on purpose
        if created and not isinstance(exc, GenerationFailed) and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise


def explain_divergence(metrics: dict[str, Any], llm: LLMClient, *, label_a: str = "Webots",
                       label_b: str = "MuJoCo", notes: list[str] | None = None) -> str:
    """Ask the LLM which parameters likely explain a divergence report (``faithfulness.json``/``metrics.json``)."""
    text = json.dumps(metrics, indent=1)[:60_000]
    content = Template(prompt("explain_divergence")).safe_substitute(
        label_a=label_a, label_b=label_b, metrics=text, notes="\n".join(notes or []) or "(none)")
    return llm.complete([{"role": "system", "content": "You are a simulation calibration expert."},
                         {"role": "user", "content": content}])
