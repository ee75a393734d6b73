"""The import contract (.importlinter): declared without exceptions, kept by the package, and able to fail.

``make test`` runs ``lint-imports``; these tests pin what the contract must stay (no ``ignore_imports``, the
acyclic contract's skip list only shrinking) and show on a copy of the package that an upward import, a
cycle inside a package and a type-only (``if TYPE_CHECKING:``) cycle are all caught (the controls: the
unchanged copy passes).
"""

from __future__ import annotations

import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / ".importlinter"
LINT = Path(sys.executable).with_name("lint-imports")
#: Packages that still hold an import cycle between their modules: none (align, twins and webots left this set
#: when their cycles were cut). It may only shrink.
CYCLIC_PACKAGES: set[str] = set()


def _contracts() -> dict[str, configparser.SectionProxy]:
    parser = configparser.ConfigParser()
    parser.read(CONFIG, encoding="utf-8")
    return {name: parser[name] for name in parser.sections() if name.startswith("importlinter:contract:")}


def _lines(value: str) -> list[str]:
    return [line.strip() for line in value.splitlines() if line.strip()]


def test_the_contract_has_no_exceptions() -> None:
    contracts = _contracts()
    assert {c["type"] for c in contracts.values()} == {"layers", "acyclic_siblings"}
    for name, contract in contracts.items():
        assert "ignore_imports" not in contract, f"{name}: ignore_imports is not allowed; invert the dependency"
    acyclic = next(c for c in contracts.values() if c["type"] == "acyclic_siblings")
    assert _lines(acyclic["ancestors"]) == ["dualtwin"]
    skipped = set(_lines(acyclic.get("skip_descendants", "")))
    assert skipped <= CYCLIC_PACKAGES, f"new packages skipped by the acyclic contract: {skipped - CYCLIC_PACKAGES}"


def _lint(package_parent: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    if not LINT.is_file():
        pytest.skip("lint-imports is not installed next to this Python")
    env = {**os.environ, "PYTHONPATH": str(package_parent)}
    return subprocess.run([str(LINT), "--config", str(CONFIG), "--no-cache", "--no-logo"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def package_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Python sources of dualtwin, copied (data files are not imports)."""
    parent = tmp_path_factory.mktemp("src")
    shutil.copytree(ROOT / "src" / "dualtwin", parent / "dualtwin",
                    ignore=lambda folder, names: [n for n in names
                                                  if not n.endswith(".py") and not (Path(folder) / n).is_dir()])
    return parent


def _append(path: Path, line: str) -> str:
    original = path.read_text(encoding="utf-8")
    path.write_text(original + f"\n{line}\n", encoding="utf-8")
    return original


def test_the_package_keeps_the_contract_and_a_break_fails(package_copy: Path, tmp_path: Path) -> None:
    ok = _lint(package_copy, tmp_path)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "BROKEN" not in ok.stdout and ok.stdout.count("KEPT") == 2

    # An upward import: the twins importing the lockstep runner.
    base = package_copy / "dualtwin" / "twins" / "base.py"
    original = _append(base, "import dualtwin.sync.lockstep  # noqa")
    try:
        upward = _lint(package_copy, tmp_path)
    finally:
        base.write_text(original, encoding="utf-8")
    assert upward.returncode != 0
    assert "dualtwin.twins.base -> dualtwin.sync.lockstep" in upward.stdout

    # A cycle inside a package the acyclic contract checks: rl.env importing rl.shadow, which imports rl.env.
    env = package_copy / "dualtwin" / "rl" / "env.py"
    original = _append(env, "import dualtwin.rl.shadow  # noqa")
    try:
        cycle = _lint(package_copy, tmp_path)
    finally:
        env.write_text(original, encoding="utf-8")
    assert cycle.returncode != 0
    assert "No cycles are allowed in dualtwin.rl" in cycle.stdout


def test_a_type_only_cycle_counts(package_copy: Path, tmp_path: Path) -> None:
    """The twins' knob tables type the twin as a Protocol; importing the twin back, even only for type checking,
    is the cycle the contract forbids (import-linter counts ``if TYPE_CHECKING:`` imports)."""
    table = package_copy / "dualtwin" / "twins" / "mujoco_knobs.py"
    original = _append(table, "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import dualtwin.twins.mujoco")
    try:
        cycle = _lint(package_copy, tmp_path)
    finally:
        table.write_text(original, encoding="utf-8")
    assert cycle.returncode != 0
    assert "No cycles are allowed in dualtwin.twins" in cycle.stdout
    assert ".mujoco_knobs -> .mujoco" in cycle.stdout
