"""Ensembles: run every scenario N times with its initial conditions moved slightly, and store the members.

A pole released near its unstable equilibrium that lands on a hard stop is chaotic: a 1 µrad change of the
initial angle changes the bounces that follow. An ensemble measures that, so a divergence between two twins
can be judged against the divergence of each twin against itself (the reproducibility floor, see
`dualtwin.divergence.floor`).

Members (decisions):

* Member 0 is the unperturbed run, written exactly as `SuiteRun` writes any run, so an ensemble run is
  also an ordinary run that every command accepts.
* Member 1 moves every perturbed key by ``+eps``, member 2 by ``-eps``; members 3 and up draw each key's
  shift uniformly from ``[-eps, +eps]`` with ``numpy.random.default_rng(seed)``. The same spec gives the same
  shifts, so the same inputs give byte-identical runs.
* A key is any initial condition the binding knows. A scenario that does not set the key is shifted from
  the twin's reset value. Shifts apply where a scenario starts fresh; a scenario that continues from the
  previous one inherits its predecessor's (shifted) end state.
* Members run through `dualtwin.parallel.ParallelMap` (the executor alignment uses), one job per member,
  each simulating the suite in memory in a worker that builds its twin once.

Layout (added to the ordinary run folder)::

    RUN/manifest.json                                  "ensemble": the spec and every member's shifts;
                                                       per scenario "members": [{member, status, logs}]
    RUN/scenarios/<id>/members/<k>/onboard.tsv         member k >= 1, same columns as the main logs
    RUN/scenarios/<id>/members/<k>/ground_truth.tsv

Member logs are listed in the manifest's ``logs`` (row count, bytes, SHA-256) like the main ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, field_validator

from dualtwin.artifacts import log_record, verify_logs, write_json, write_text
from dualtwin.errors import DualtwinError
from dualtwin.models import FrozenModel
from dualtwin.parallel import DEFAULT_WORKERS, ExecutorKind, ParallelMap, check_executor
from dualtwin.robots.binding import RobotBinding, load_binding
from dualtwin.suite.loader import load_suite
from dualtwin.suite.manifest import read_run_manifest
from dualtwin.suite.runner import SuiteRun, check_against_binding, format_rows, run_scenario
from dualtwin.suite.schema import Suite
from dualtwin.twins import make_twin
from dualtwin.twins.io import RobotIO

ENSEMBLE_SCHEMA = "dualtwin.ensemble/1"


class EnsembleSpec(FrozenModel):
    """How many members and which initial conditions move by how much (saved in the manifest)."""

    members: int = Field(ge=2, le=1000, description="members per scenario, the unperturbed one included")
    perturb: dict[str, float] = Field(min_length=1, description="initial-condition key -> largest shift eps")
    seed: int = Field(default=0, ge=0, description="seed of the shifts drawn for members 3 and up")

    @field_validator("perturb")
    @classmethod
    def _positive(cls, value: dict[str, float]) -> dict[str, float]:
        for key, eps in value.items():
            if not eps > 0:
                raise ValueError(f"the shift of {key!r} must be positive, got {eps!r}")
        return dict(sorted(value.items()))

    def offsets(self) -> list[dict[str, float]]:
        """Each member's shift per key (member 0: none; 1: +eps; 2: -eps; then seeded uniform draws)."""
        keys = list(self.perturb)
        rng = np.random.default_rng(self.seed)
        out: list[dict[str, float]] = []
        for k in range(self.members):
            if k == 0:
                out.append(dict.fromkeys(keys, 0.0))
            elif k in (1, 2):
                sign = 1.0 if k == 1 else -1.0
                out.append({key: sign * self.perturb[key] for key in keys})
            else:
                draws = rng.uniform(-1.0, 1.0, size=len(keys))
                out.append({key: float(u) * self.perturb[key] for key, u in zip(keys, draws, strict=True)})
        return out

    def to_manifest(self) -> dict[str, Any]:
        return {"schema": ENSEMBLE_SCHEMA, **self.model_dump(mode="json"),
                "offsets": [{"member": k, "shift": o} for k, o in enumerate(self.offsets())]}


def parse_perturb(texts: Sequence[str], option: str = "--perturb") -> dict[str, float]:
    """``["initial_angle=1e-6", ...]`` -> ``{"initial_angle": 1e-6}``; one clear line on bad input."""
    out: dict[str, float] = {}
    for text in texts:
        key, sep, value = text.partition("=")
        key = key.strip()
        if not sep or not key:
            raise DualtwinError(f"{option} {text!r}: expected KEY=EPS, e.g. initial_angle=1e-6")
        try:
            eps = float(value)
        except ValueError:
            raise DualtwinError(f"{option} {text!r}: {value!r} is not a number") from None
        if not math.isfinite(eps) or eps <= 0:
            raise DualtwinError(f"{option} {text!r}: the shift must be a positive finite number")
        if key in out:
            raise DualtwinError(f"{option}: {key!r} is given twice")
        out[key] = eps
    return out


def make_spec(members: int, perturb: Mapping[str, float], robot: RobotBinding, seed: int = 0) -> EnsembleSpec:
    """A validated spec whose keys are all initial conditions of ``robot`` (checked before anything runs)."""
    if members < 2:
        raise DualtwinError(f"--ensemble must be at least 2 (the unperturbed member and one more), got {members}")
    if not perturb:
        raise DualtwinError("--ensemble needs at least one --perturb KEY=EPS (e.g. initial_angle=1e-6)")
    known = robot.spec.initial_conditions
    unknown = sorted(set(perturb) - set(known))
    if unknown:
        raise DualtwinError(f"--perturb {unknown[0]!r}: not an initial condition of robot {robot.name!r}; "
                            f"it knows: {', '.join(sorted(known)) or 'none'}")
    try:
        return EnsembleSpec(members=members, perturb=dict(perturb), seed=seed)
    except ValueError as exc:
        raise DualtwinError(f"--ensemble/--perturb: {exc}") from None


# ------------------------------------------------------------------ simulating members (worker side)
@dataclass(frozen=True)
class MemberJob:
    """Plain data for one member: simulate ``scenarios`` (all if None) with ``offsets`` at fresh starts."""

    robot: str
    twin: str
    suite: str
    member: int
    offsets: tuple[tuple[str, float], ...]
    seed: int = 0
    scenarios: tuple[str, ...] | None = None


@dataclass(frozen=True)
class MemberScenario:
    """One member's scenario: how it ended and its two logs (rows of time, then channels)."""

    status: str
    failure: dict[str, Any] | None
    steps: int
    onboard: list[list[float]] = field(default_factory=list)
    ground_truth: list[list[float]] = field(default_factory=list)


class _Session:
    def __init__(self, robot: str, twin: str, suite: str) -> None:
        self.robot = load_binding(Path(robot))
        self.suite = load_suite(Path(suite))
        check_against_binding(self.suite, Path(suite), self.robot)
        self.twin = make_twin(twin, self.robot, self.suite.global_settings.control_period_s)
        self.io = RobotIO(self.robot, self.twin)


_SESSIONS: dict[tuple[str, str, str], _Session] = {}


def chain(suite: Suite, wanted: Sequence[str] | None) -> list[int]:
    """Indices to simulate for ``wanted`` ids (all if None): each plus the scenarios it continues from."""
    ids = suite.scenario_ids()
    if wanted is None:
        return list(range(len(ids)))
    unknown = sorted(set(wanted) - set(ids))
    if unknown:
        raise DualtwinError(f"unknown scenario ids {unknown}; the suite has {ids}")
    need: set[int] = set()
    for sid in wanted:
        j = ids.index(sid)
        need.add(j)
        while j > 0 and suite.scenarios[j].reset == "continue":
            j -= 1
            need.add(j)
    return sorted(need)


def simulate_member(job: MemberJob) -> dict[str, MemberScenario]:
    """Worker entry point: one member's scenarios, reset and continued exactly as `SuiteRun` does."""
    key = (job.robot, job.twin, job.suite)
    if key not in _SESSIONS:
        _SESSIONS[key] = _Session(*key)
    session = _SESSIONS[key]
    suite, io = session.suite, session.io
    ids = suite.scenario_ids()
    keep = set(ids if job.scenarios is None else job.scenarios)
    offsets = dict(job.offsets)
    thresholds = suite.global_settings.thresholds
    out: dict[str, MemberScenario] = {}
    need_fresh, previous = True, -2
    for index in chain(suite, job.scenarios):
        scenario = suite.scenarios[index]
        fresh = need_fresh or scenario.reset == "fresh" or previous != index - 1
        seed = scenario.seed if scenario.seed is not None else job.seed
        result, onboard, truth = run_scenario(io, scenario, seed, thresholds, fresh, offsets if fresh else None)
        need_fresh, previous = result.status == "unstable", index
        if ids[index] in keep:
            out[ids[index]] = MemberScenario(result.status, result.failure, result.steps, onboard, truth)
    return out


def member_jobs(spec: EnsembleSpec, robot: RobotBinding, twin: str, suite_path: Path, seed: int = 0,
                scenarios: Sequence[str] | None = None, first: int = 1) -> list[MemberJob]:
    """Jobs for members ``first`` .. ``spec.members - 1``."""
    wanted = None if scenarios is None else tuple(scenarios)
    return [MemberJob(str(robot.path), twin, str(Path(suite_path).resolve()), k, tuple(sorted(o.items())), seed,
                      wanted)
            for k, o in enumerate(spec.offsets()) if k >= first]


def simulate_members(spec: EnsembleSpec, robot: RobotBinding, twin: str, suite_path: Path, *, seed: int = 0,
                     scenarios: Sequence[str] | None = None, executor: ExecutorKind | ParallelMap = "process",
                     workers: int = DEFAULT_WORKERS) -> list[dict[str, MemberScenario]]:
    """Every member (the unperturbed one first) in memory, through the executor; nothing is written."""
    suite = load_suite(Path(suite_path))
    check_against_binding(suite, Path(suite_path), robot)
    make_spec(spec.members, spec.perturb, robot, spec.seed)
    jobs = member_jobs(spec, robot, twin, suite_path, seed, scenarios, first=0)
    own = executor if isinstance(executor, ParallelMap) else ParallelMap(
        executor, workers, preload=["dualtwin.suite.ensemble"])
    try:
        return own.map(simulate_member, jobs)
    finally:
        if own is not executor:
            own.close()


# ------------------------------------------------------------------ writing an ensemble run
def member_dir(scenario_id: str, member: int) -> str:
    """A member's log folder, relative to the run directory."""
    return f"scenarios/{scenario_id}/members/{member}"


class EnsembleRun:
    """A suite run on one twin (member 0, by `SuiteRun`) plus ``spec.members - 1`` perturbed members."""

    def __init__(self, suite_path: Path, twin_name: str, robot: RobotBinding, out_dir: Path,
                 spec: EnsembleSpec, seed: int = 0, executor: ExecutorKind = "process",
                 workers: int = DEFAULT_WORKERS, ray_address: str | None = None) -> None:
        check_executor(executor)
        self.base = SuiteRun(suite_path, twin_name, robot, out_dir, seed=seed)
        self.suite = self.base.suite
        self.spec = make_spec(spec.members, spec.perturb, robot, spec.seed)
        self.executor, self.workers, self.ray_address = executor, workers, ray_address

    def run(self, resume: bool = False, on_scenario: Callable[[str, str], None] | None = None,
            on_member: Callable[[int, int], None] | None = None) -> dict[str, Any]:
        """Run member 0 (resumable like any run), then the missing members; returns the manifest."""
        base = self.base
        out = base.out_dir
        manifest_path = out / "manifest.json"
        previous: dict[str, Any] = {}
        if resume and manifest_path.is_file():
            # The folder is data: its manifest must have the shape read below (as the base run checks too).
            previous, _ = read_run_manifest(manifest_path, "cannot resume: ")
            old = previous.get("ensemble")
            if old is not None and old != self.spec.to_manifest():
                raise DualtwinError(f"{manifest_path}: cannot resume: the ensemble (--ensemble, --perturb) "
                                    "differs from the interrupted run")
        manifest = base.run(resume=resume, on_scenario=on_scenario)
        ids = [s["id"] for s in manifest["scenarios"]]
        old_logs: dict[str, Any] = previous["logs"] if isinstance(previous.get("logs"), dict) else {}
        shifts = self.spec.offsets()
        old_members = {s["id"]: s.get("members") or [] for s in previous.get("scenarios", [])}
        # A member already on disk with verified logs (from the interrupted run) is kept.
        done: dict[int, dict[str, dict[str, Any]]] = {}
        logs: dict[str, Any] = {}
        for sid in ids:
            for rec in old_members.get(sid, []):
                k = rec.get("member")
                if not isinstance(k, int) or not 0 < k < len(shifts) or rec.get("shift") != shifts[k]:
                    continue
                # Only the layout's own paths are trusted (a manifest is data, its paths stay in the run).
                names = [f"{member_dir(sid, k)}/onboard.tsv", f"{member_dir(sid, k)}/ground_truth.tsv"]
                if [rec.get("onboard"), rec.get("ground_truth")] != names or not all(
                        n in old_logs and (out / n).is_file() for n in names):
                    continue
                try:
                    verify_logs(out, {n: old_logs[n] for n in names}, manifest_path)
                except DualtwinError:
                    continue
                done.setdefault(k, {})[sid] = rec
                logs.update({n: old_logs[n] for n in names})
        todo = [job for job in member_jobs(self.spec, base.robot, base.twin_name, base.suite_path, base.seed)
                if set(done.get(job.member, {})) != set(ids)]
        pool = ParallelMap(self.executor, self.workers, self.ray_address, preload=["dualtwin.suite.ensemble"])
        results: dict[int, dict[str, Any]] = {k: dict(v) for k, v in done.items()}
        try:
            # Batches of one job per worker keep progress visible, and the manifest is rewritten after each,
            # so an interrupted ensemble keeps the members it finished.
            batch = max(1, self.workers)
            for start in range(0, len(todo), batch):
                jobs = todo[start:start + batch]
                for job, result in zip(jobs, pool.map(simulate_member, jobs), strict=True):
                    results[job.member] = self._write_member(job.member, result, logs)
                    if on_member:
                        on_member(job.member, self.spec.members - 1)
                self._record(manifest, results, logs, final=False)
        finally:
            pool.close()
        self._record(manifest, results, logs, final=True)
        return manifest

    def _record(self, manifest: dict[str, Any], results: Mapping[int, Mapping[str, Any]],
                logs: Mapping[str, Any], final: bool) -> None:
        for record in manifest["scenarios"]:
            record["members"] = [results[k][record["id"]] for k in sorted(results) if record["id"] in results[k]]
        # The "ensemble" key marks a complete ensemble; until then only the members written so far are listed.
        if final:
            manifest["ensemble"] = self.spec.to_manifest()
        manifest["logs"] = dict(sorted({**manifest.get("logs", {}), **logs}.items()))
        write_json(self.base.out_dir / "manifest.json", manifest)

    def _names(self) -> tuple[list[str], list[str]]:
        spec = self.base.robot.spec
        return list(spec.onboard), list(spec.ground_truth)

    def _write_member(self, member: int, result: Mapping[str, MemberScenario],
                      logs: dict[str, Any]) -> dict[str, dict[str, Any]]:
        """Write one member's logs; returns its manifest record per scenario."""
        onboard_names, truth_names = self._names()
        out = self.base.out_dir
        shift = self.spec.offsets()[member]
        records: dict[str, dict[str, Any]] = {}
        for sid, r in result.items():
            rel = member_dir(sid, member)
            write_text(out / rel / "onboard.tsv", format_rows(onboard_names, r.onboard))
            write_text(out / rel / "ground_truth.tsv", format_rows(truth_names, r.ground_truth))
            for name in (f"{rel}/onboard.tsv", f"{rel}/ground_truth.tsv"):
                logs[name] = log_record(out / name)
            records[sid] = {"member": member, "shift": shift, "status": r.status, "failure": r.failure,
                            "steps": r.steps, "onboard": f"{rel}/onboard.tsv", "ground_truth": f"{rel}/ground_truth.tsv"}
        return records
