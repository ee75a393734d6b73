"""The proposal hook: every proposal is checked and re-simulated; only improvements are kept."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from dualtwin.align.knobs import KnobSpec
from dualtwin.align.propose import try_proposals

SPECS = [KnobSpec("joint.pole_hinge.damping", 0.0, 0.0, 1.0), KnobSpec("body.pole.mass", 0.2, 0.02, 2.0, scale="log")]


def fake_objective(values: Sequence[Mapping[str, float]]) -> list[float]:
    """A stand-in simulation: the divergence is smallest at damping 0.05."""
    return [abs(v.get("joint.pole_hinge.damping", 0.0) - 0.05) for v in values]


def test_only_valid_proposals_that_lower_the_objective_are_kept() -> None:
    seen: list[Any] = []

    def propose(analysis: Any) -> list[dict[str, float]]:
        seen.append(analysis)
        return [{"joint.pole_hinge.damping": 0.045}, {"joint.pole_hinge.damping": 0.9},
                {"joint.pole_hinge.dampng": 0.05}, {"body.pole.mass": 50.0}, {}]

    outcomes = try_proposals(propose, "the analysis", SPECS, baseline=0.05, evaluate=fake_objective)  # type: ignore[arg-type]
    assert seen == ["the analysis"]
    assert [o.accepted for o in outcomes] == [True, False, False, False, False]
    assert outcomes[0].objective is not None and outcomes[0].objective < 0.05
    assert "rejected" in outcomes[1].reason
    assert "not being fitted" in outcomes[2].reason and "joint.pole_hinge.damping" in outcomes[2].reason
    assert "outside its bounds" in outcomes[3].reason
    assert outcomes[4].reason == "empty proposal"
    assert outcomes[0].to_dict()["accepted"] is True
