"""The twins' knob tables: every knob a twin lists comes from exactly one entry, every entry's ``apply`` reaches
the model and returns to nominal, unknown names are refused, and the docs' knob table is generated from them
(``scripts/gen_knob_docs.py``; the page is stale when it differs)."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.robots.binding import resolve_robot
from dualtwin.twins import make_twin
from dualtwin.twins.knob_table import KnobKind, KnobTable
from dualtwin.twins.mujoco_knobs import MUJOCO_KNOBS
from dualtwin.twins.webots_knobs import WEBOTS_KNOBS, read_field

ROOT = Path(__file__).resolve().parents[2]
TABLES: dict[str, KnobTable[Any]] = {"mujoco": MUJOCO_KNOBS, "webots": WEBOTS_KNOBS}


def _generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("gen_knob_docs", ROOT / "scripts" / "gen_knob_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _pattern(kind: KnobKind[Any]) -> re.Pattern[str]:
    return re.compile("^" + ".+".join(re.escape(part) for part in re.split(r"<[a-z]+>", kind.pattern)) + "$")


def test_the_docs_knob_table_is_generated_from_the_tables() -> None:
    generator = _generator()
    assert generator.TARGET.read_text(encoding="utf-8") == generator.render(), (
        "docs/concepts/knobs.md's knob table is stale: run python scripts/gen_knob_docs.py")


def test_a_stale_knob_table_is_caught() -> None:
    # The control: drop one generated row (as if an entry had been added to a table) and the check fails.
    generator = _generator()
    page = generator.TARGET.read_text(encoding="utf-8")
    stale = page.replace(next(line for line in page.splitlines() if line.startswith("| `motor.<m>.kp`")) + "\n", "")
    assert stale != page
    assert generator.render(stale) != stale
    assert generator.render(stale) == page
    with pytest.raises(SystemExit, match="markers"):
        generator.render(page.replace(generator.BEGIN, ""))


def test_every_entry_is_on_the_page() -> None:
    page = _generator().render_table()
    for table in TABLES.values():
        for kind in table.kinds:
            assert f"| `{kind.pattern}` |" in page


@pytest.mark.parametrize("robot", ["cartpole", "pioneer3at", "arm"])
@pytest.mark.parametrize("twin_name", sorted(TABLES))
def test_every_knob_comes_from_exactly_one_entry(twin_name: str, robot: str) -> None:
    twin = make_twin(twin_name, resolve_robot(robot))
    patterns = [_pattern(kind) for kind in TABLES[twin_name].kinds]
    knobs = twin.knobs()
    assert knobs
    for name, knob in knobs.items():
        matches = [p.pattern for p in patterns if p.match(name)]
        assert len(matches) == 1, (name, matches)
        assert knob.lower <= knob.nominal <= knob.upper or twin_name == "mujoco", name
    twin.close()


def _mujoco_digest(twin: Any) -> bytes:
    """Everything a MuJoCo-twin knob may write: model arrays and options, motor and sensor models."""
    m = twin.model
    parts = [np.asarray(getattr(m, name)).tobytes() for name in dir(m)
             if not name.startswith("_") and isinstance(getattr(m, name, None), np.ndarray)]
    parts.append(np.array([m.opt.timestep, m.opt.impratio]).tobytes())
    for mo in twin._motors:
        p = mo.state.params
        parts.append(np.array([p.max_torque, p.max_velocity, p.kp, mo.state.gain]).tobytes())
    parts += [np.array([twin._delay, twin._substeps]).tobytes(), twin._noise.tobytes(), twin._sensor_bias.tobytes(),
              twin._sensor_quant.tobytes(), twin._sensor_delay.tobytes()]
    return b"".join(parts)


def _other_value(knob: Any) -> float:
    """A value in bounds, away from the nominal (whole for integer knobs)."""
    value = knob.nominal + 0.5 * (knob.upper - knob.nominal) if knob.upper > knob.nominal else \
        knob.nominal - 0.5 * (knob.nominal - knob.lower)
    return float(round(value)) if knob.unit in ("periods", "steps") else value


@pytest.mark.parametrize("robot", ["pioneer3at", "arm"])
def test_each_mujoco_entry_writes_the_model_and_nominal_restores_it(robot: str) -> None:
    twin = make_twin("mujoco", resolve_robot(robot))
    nominal = _mujoco_digest(twin)
    for name, knob in twin.knobs().items():
        twin.set_knobs({name: _other_value(knob)})
        assert _mujoco_digest(twin) != nominal, f"{name} changed nothing"
        twin.set_knobs({})
        assert _mujoco_digest(twin) == nominal, f"{name} did not return to nominal"
    twin.close()


@pytest.mark.parametrize("robot", ["pioneer3at", "arm"])
def test_each_webots_entry_writes_its_field_and_nominal_restores_it(robot: str) -> None:
    twin: Any = make_twin("webots", resolve_robot(robot))
    bound = WEBOTS_KNOBS.build(twin)
    for name, knob in twin.knobs().items():
        value = _other_value(knob)
        twin.set_knobs({name: value})
        if name.endswith(".gain"):
            assert twin._gains[name[len("motor."):-len(".gain")]] == value
        else:
            assert read_field(twin, bound[name].handle) == pytest.approx(value, rel=1e-12), name
        twin.set_knobs({})
        assert bound[name].kind.nominal(twin, bound[name].handle) == knob.nominal
    twin.close()


@pytest.mark.parametrize("twin_name", sorted(TABLES))
def test_unknown_knobs_are_refused_before_anything_is_written(twin_name: str) -> None:
    twin: Any = make_twin(twin_name, resolve_robot("cartpole"))
    with pytest.raises(DualtwinError, match=r"unknown knobs: joint\.nope\.damping, zzz$"):
        twin.set_knobs({"joint.pole_hinge.damping": 0.3, "zzz": 1.0, "joint.nope.damping": 1.0})
    assert twin._knob_values == {}
    twin.close()


def test_friction_coefficients_are_dimensionless() -> None:
    """Coulomb friction (contact.<p>.friction, geom.<g>.friction) is a ratio of forces; a joint's dry friction is a
    torque (the control: the unit check can tell them apart)."""
    robot = resolve_robot("pioneer3at")
    units = {**make_twin("webots", robot).knobs(), **make_twin("mujoco", robot).knobs()}
    coefficients = {n: k.unit for n, k in units.items() if re.match(r"^(contact|geom)\..+\.friction$", n)}
    assert any(n.startswith("contact.") for n in coefficients) and any(n.startswith("geom.") for n in coefficients)
    assert set(coefficients.values()) == {""}, coefficients
    torques = {k.unit for n, k in units.items() if re.match(r"^joint\..+\.friction$", n)}
    assert torques == {"N*m"}
