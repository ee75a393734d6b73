"""A case library: prior robots retrieved by similarity to a text spec and shown to the LLM as examples.

Cases are the bundled primitive descriptions (``genai/cases/*.json``), the bundled robots (their binding's
description plus their MJCF read back as a primitive description when it is made of primitives) and user
folders of twins (``*.json`` descriptions and ``binding.yaml`` files, searched recursively). Retrieval is
TF-IDF cosine similarity over words of the name, description, part types and device names: deterministic, no
network, no models.
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from dualtwin.errors import DualtwinError
from dualtwin.genai.primitive import RobotDescription, mjcf_to_description, parse_description

BUNDLED_CASES = Path(__file__).parent / "cases"
_STOP = frozenset(["a", "an", "and", "the", "of", "on", "in", "with", "to", "for", "by", "is", "are", "at", "as", "its", "it", "from", "this", "that", "be", "or"])


def tokenize(text: str) -> list[str]:
    """Lower-case word tokens (digits split off, stop words dropped, simple plural folding)."""
    words = re.findall(r"[a-z]+", text.lower())
    out = []
    for w in words:
        if w in _STOP or len(w) < 2:
            continue
        if len(w) > 3 and w.endswith("s") and not w.endswith("ss"):
            w = w[:-1]
        out.append(w)
    return out


@dataclass
class Case:
    """One prior robot."""

    name: str
    description: str
    source: str
    part_types: list[str] = field(default_factory=list)
    example: RobotDescription | None = None

    def text(self) -> str:
        devices: list[str] = []
        if self.example is not None:
            for p in self.example.parts:
                devices.append(p.name)
                if p.motor is not None:
                    devices.append(p.motor.name)
                if p.joint is not None:
                    devices.append(p.joint.type)
        return " ".join([self.name, self.description, *self.part_types, *devices])

    def example_json(self) -> str | None:
        if self.example is None:
            return None
        return self.example.model_dump_json(exclude_none=True)


def case_from_description(desc: RobotDescription, source: str) -> Case:
    return Case(desc.robot_name, desc.description, source, sorted({str(p.type) for p in desc.parts}), desc)


class CaseLibrary:
    """Cases and a TF-IDF index over them."""

    def __init__(self, cases: Iterable[Case] = ()) -> None:
        self.cases: list[Case] = []
        for case in cases:
            self.add(case)

    def add(self, case: Case) -> None:
        # A primitive description replaces a binding-only entry of the same robot (it is the better example).
        for i, existing in enumerate(self.cases):
            if existing.name == case.name:
                if existing.example is None and case.example is not None:
                    self.cases[i] = case
                return
        self.cases.append(case)

    @classmethod
    def bundled(cls) -> CaseLibrary:
        lib = cls()
        lib.add_folder(BUNDLED_CASES)
        from dualtwin.robots.binding import BUNDLED

        lib.add_folder(BUNDLED)
        return lib

    @classmethod
    def default(cls, user_dirs: Sequence[Path] = ()) -> CaseLibrary:
        lib = cls.bundled()
        for folder in user_dirs:
            lib.add_folder(Path(folder))
        return lib

    def add_folder(self, folder: Path) -> None:
        """Index ``*.json`` descriptions and ``binding.yaml`` twins under ``folder`` (recursively)."""
        folder = Path(folder)
        if not folder.is_dir():
            raise DualtwinError(f"{folder}: case folder not found")
        for path in sorted(folder.rglob("*.json")):
            if path.stat().st_size > 1_000_000:
                continue
            try:
                desc = parse_description(path.read_text(encoding="utf-8"), str(path))
            except (DualtwinError, UnicodeDecodeError):
                continue  # suites and other JSON files
            self.add(case_from_description(desc, str(path)))
        for path in sorted(folder.rglob("binding.yaml")):
            case = _case_from_binding(path)
            if case is not None:
                self.add(case)

    def retrieve(self, query: str, k: int = 2) -> list[tuple[Case, float]]:
        """The ``k`` most similar cases (cosine over TF-IDF vectors), best first; ties by name."""
        if not self.cases or k <= 0:
            return []
        docs = [Counter(tokenize(c.text())) for c in self.cases]
        n = len(docs)
        df: Counter[str] = Counter()
        for d in docs:
            df.update(d.keys())
        idf = {t: math.log((n + 1) / (df[t] + 1)) + 1.0 for t in df}

        def vector(counts: Counter[str]) -> dict[str, float]:
            return {t: c * idf.get(t, math.log(n + 1) + 1.0) for t, c in counts.items()}

        q = vector(Counter(tokenize(query)))
        qn = math.sqrt(sum(v * v for v in q.values())) or 1.0
        scored = []
        for case, d in zip(self.cases, docs, strict=True):
            v = vector(d)
            vn = math.sqrt(sum(x * x for x in v.values())) or 1.0
            score = sum(q[t] * v.get(t, 0.0) for t in q) / (qn * vn)
            scored.append((case, score))
        scored.sort(key=lambda cs: (-cs[1], cs[0].name))
        return [cs for cs in scored[:k] if cs[1] > 0]


def _case_from_binding(path: Path) -> Case | None:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (yaml.YAMLError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict) or "name" not in data:
        return None
    name = str(data["name"])
    description = str(data.get("description", ""))
    example = None
    model = ((data.get("twins") or {}).get("mujoco") or {}).get("model")
    if model:
        xml = (path.parent / str(model)).resolve()
        if xml.is_file():
            try:
                example = mjcf_to_description(xml, robot_name=re.sub(r"[^A-Za-z0-9_]", "_", name) or "robot")
            except DualtwinError:
                example = None
    if example is not None:
        example = example.model_copy(update={"description": description or example.description})
    types = sorted({str(p.type) for p in example.parts}) if example is not None else []
    return Case(name, description, str(path), types, example)


def examples_text(cases: list[tuple[Case, float]], template: str) -> str:
    """Prompt text for retrieved cases (only those with a primitive description)."""
    from string import Template

    blocks = []
    for case, _score in cases:
        example = case.example_json()
        if example is None:
            continue
        blocks.append(Template(template).safe_substitute(name=case.name, description=json.dumps(case.description),
                                                         json=example))
    return "\n".join(blocks)
