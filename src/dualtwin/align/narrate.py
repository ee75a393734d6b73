"""Optional LLM narrative (issue 4, item 7): the findings explained in words, knob changes proposed as data.

The deterministic analysis stays the default and the source of truth. With ``--llm``, the configured LLM
(`dualtwin.genai.llm`) is shown the findings, the dominant scenario × channel pairs, the measured
sensitivities and the knobs it may change, and answers with one JSON object: an explanation and proposals.
The reply is untrusted data, never code: it is parsed as JSON, its shape is checked, and each proposal is
validated against a JSON schema generated from the selected knobs (known names only, finite numbers within
the bounds). Valid proposals go through `dualtwin.align.propose.try_proposals`, which re-simulates them and
keeps only those that lower the divergence. A reply that is not JSON of that shape, or a provider that
cannot be reached, is recorded with the reason and leaves the deterministic results untouched.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from string import Template
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

from dualtwin.align.knobs import KnobSpec
from dualtwin.errors import DualtwinError
from dualtwin.models import StrictModel

if TYPE_CHECKING:
    from dualtwin.align.analyze import Analysis
    from dualtwin.align.propose import ProposalOutcome
    from dualtwin.genai.llm import LLMClient

NARRATIVE_SCHEMA = "dualtwin.llm_narrative/1"
LABEL = ("LLM output, not verified: read it against the deterministic findings. Only proposals marked "
         "'kept' were checked, by re-simulation.")
MAX_PROPOSALS = 4
# Bounds on what goes into the prompt, however large the analysis.
MAX_FINDINGS = 12
MAX_SENSITIVITIES = 15
MAX_KNOBS = 60


class _StrictReply(StrictModel):
    """An LLM reply is refused, not coerced: ``"0.3"`` for a number is a mistake to report."""

    model_config = ConfigDict(strict=True)


class _Proposal(_StrictReply):
    knobs: dict[str, Any]
    rationale: str = Field(default="", max_length=2000)


class _Reply(_StrictReply):
    explanation: str = Field(min_length=1, max_length=10_000)
    proposals: list[_Proposal] = Field(default_factory=list, max_length=MAX_PROPOSALS)


def knob_model(specs: Sequence[KnobSpec]) -> type[BaseModel]:
    """The model of one proposal's ``knobs`` object: only these knobs, finite numbers within their bounds."""
    fields: dict[str, Any] = {
        f"k{i}": (float | None, Field(default=None, alias=s.name, ge=s.lower, le=s.upper,
                                      description=f"{s.description} [{s.unit or '-'}], nominal {s.nominal:g}"))
        for i, s in enumerate(specs)
    }
    model: type[BaseModel] = create_model("KnobProposal", __base__=_StrictReply, **fields)
    return model


def reply_schema(specs: Sequence[KnobSpec]) -> dict[str, Any]:
    """JSON schema of the whole reply, sent to providers that support structured output."""
    knobs = knob_model(specs).model_json_schema(by_alias=True)
    knobs["minProperties"] = 1
    return {
        "type": "object", "additionalProperties": False, "required": ["explanation", "proposals"],
        "properties": {
            "explanation": {"type": "string"},
            "proposals": {"type": "array", "maxItems": MAX_PROPOSALS, "items": {
                "type": "object", "additionalProperties": False, "required": ["knobs"],
                "properties": {"knobs": knobs, "rationale": {"type": "string"}}}},
        },
    }


def _where(loc: Sequence[int | str]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _errors(exc: ValidationError, prefix: str) -> str:
    return "; ".join(f"{_where([*([prefix] if prefix else []), *e['loc']])}: {e['msg']}" for e in exc.errors()[:5])


@dataclass
class Narrative:
    """What the LLM said, and what became of each proposal (JSON-ready through `to_dict`)."""

    provider: str
    model: str
    explanation: str | None = None
    error: str | None = None
    proposals: list[dict[str, Any]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"schema": NARRATIVE_SCHEMA, "label": LABEL, "provider": self.provider, "model": self.model,
                "explanation": self.explanation, "error": self.error, "proposals": self.proposals}


def _prompt_data(analysis: Analysis, specs: Sequence[KnobSpec]) -> dict[str, str]:
    findings = [{"kind": f.kind, "message": f.message, "share": round(f.share, 4), "scenarios": f.scenarios,
                 "channel": f.channel, "knobs_to_try": f.knobs[:6], "evidence": f.evidence}
                for f in analysis.findings[:MAX_FINDINGS]]
    dominant = [{"scenario": c.scenario_id, "channel": c.channel, "share": round(c.share, 4)}
                for c in analysis.dominant[:8]]
    sensitivity = [{"knob": s.knob, "nominal": s.nominal, "sensitivity": s.sensitivity,
                    "to_move_toward_reference": s.best_direction} for s in analysis.sensitivity[:MAX_SENSITIVITIES]]
    knobs = [{"name": s.name, "unit": s.unit, "nominal": s.nominal, "range": [s.lower, s.upper],
              "meaning": s.description} for s in specs[:MAX_KNOBS]]

    def dump(value: Any) -> str:
        return json.dumps(value, indent=1, default=str)[:30_000]

    return {"findings": dump(findings), "dominant": dump(dominant), "sensitivity": dump(sensitivity),
            "knobs": dump(knobs) if knobs else "(none: no knob can be tested here; answer with an empty list)"}


class LLMProposer:
    """A proposer for `dualtwin.align.propose.try_proposals` that asks an LLM and keeps its narrative.

    ``try_proposals`` calls `select` with the knobs being fitted, then the proposer with the analysis, then
    `record` with the re-simulation outcomes; `narrative` holds the result.
    """

    def __init__(self, llm: LLMClient, *, label_a: str = "reference", label_b: str = "target") -> None:
        self.llm = llm
        self.labels = (label_a, label_b)
        self.specs: list[KnobSpec] = []
        self.narrative = Narrative(llm.config.provider, llm.config.model)
        self._valid: list[dict[str, Any]] = []

    def select(self, specs: Sequence[KnobSpec]) -> None:
        self.specs = list(specs)

    def __call__(self, analysis: Analysis) -> list[dict[str, float]]:
        from dualtwin.genai.generate import extract_json, prompt

        narrative = self.narrative = Narrative(self.llm.config.provider, self.llm.config.model)
        self._valid = []
        content = Template(prompt("align_narrative")).safe_substitute(
            label_a=self.labels[0], label_b=self.labels[1], max_proposals=MAX_PROPOSALS,
            **_prompt_data(analysis, self.specs))
        messages: list[Any] = [
            {"role": "system", "content": "You are a simulation calibration expert. You answer with JSON data only."},
            {"role": "user", "content": content}]
        try:
            text = self.llm.complete(messages, json_schema=reply_schema(self.specs))
        except DualtwinError as exc:
            narrative.error = f"no narrative: {exc}"
            return []
        try:
            reply = _Reply.model_validate(extract_json(text))
        except ValueError as exc:  # ValidationError is a ValueError
            reason = _errors(exc, "") if isinstance(exc, ValidationError) else str(exc)
            narrative.error = f"the reply is not usable and was ignored: {reason}"
            return []
        narrative.explanation = reply.explanation
        model = knob_model(self.specs)
        for i, proposal in enumerate(reply.proposals):
            record: dict[str, Any] = {"knobs": proposal.knobs, "rationale": proposal.rationale}
            narrative.proposals.append(record)
            try:
                parsed = model.model_validate(proposal.knobs)
            except ValidationError as exc:
                record.update(status="invalid", reason=f"fails the knob schema: {_errors(exc, f'proposals[{i}].knobs')}")
                continue
            values = {k: float(v) for k, v in parsed.model_dump(by_alias=True).items() if v is not None}
            if not values or not all(math.isfinite(v) for v in values.values()):
                record.update(status="invalid", reason="sets no knob")
                continue
            record.update(status="untested", reason="not re-simulated")
            self._valid.append(record)
        return [{k: float(v) for k, v in r["knobs"].items()} for r in self._valid]

    def record(self, outcomes: Sequence[ProposalOutcome]) -> None:
        """Attach the re-simulation outcomes (in proposal order) to the narrative's proposals."""
        for record, outcome in zip(self._valid, outcomes, strict=False):
            record.update(status="kept" if outcome.accepted else "rejected", reason=outcome.reason,
                          objective=outcome.objective, baseline=outcome.baseline)


def narrative_html(narrative: dict[str, Any] | None) -> str:
    """The narrative as an HTML section, clearly labelled as LLM output ("" without one)."""
    if narrative is None:
        return ""
    import html

    parts = [f"<h2>LLM narrative ({html.escape(str(narrative.get('provider')))}, "
             f"{html.escape(str(narrative.get('model')))})</h2>",
             f"<p class='viol'><b>{html.escape(LABEL)}</b></p>"]
    if narrative.get("error"):
        parts.append(f"<p>{html.escape(str(narrative['error']))}</p>")
    if narrative.get("explanation"):
        parts.append(f"<blockquote>{html.escape(str(narrative['explanation']))}</blockquote>")
    rows = [f"<li><code>{html.escape(json.dumps(p.get('knobs'), default=str))}</code> — "
            f"<b>{html.escape(str(p.get('status')))}</b>: {html.escape(str(p.get('reason', '')))}"
            f"{'<br><small>rationale (LLM): ' + html.escape(str(p['rationale'])) + '</small>' if p.get('rationale') else ''}"
            "</li>" for p in narrative.get("proposals", [])]
    if rows:
        parts.append("<h3>Proposals</h3><ul>" + "".join(rows) + "</ul>")
    return "\n".join(parts)


def print_narrative(narrative: dict[str, Any] | None, console: Any) -> None:
    """The narrative for the terminal, labelled as LLM output."""
    if narrative is None:
        return
    from rich.markup import escape

    console.print(f"[bold]LLM narrative[/] ({escape(str(narrative.get('model')))}) — {escape(LABEL)}")
    if narrative.get("error"):
        console.print(f"[yellow]{escape(str(narrative['error']))}[/]")
    if narrative.get("explanation"):
        console.print(f"    {escape(str(narrative['explanation']))}")
    for p in narrative.get("proposals", []):
        console.print(f"    proposal {escape(json.dumps(p.get('knobs'), default=str))}: "
                      f"{escape(str(p.get('status')))} ({escape(str(p.get('reason', '')))})")
