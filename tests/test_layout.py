"""The layout rules of issue 18, checked on the source tree (the layer order itself is import-linter's, in
``.importlinter``; these are the rules it cannot express):

* no module imports another package's private (``_name``) names, by ``from`` import, by a private module
  path, or by an attribute of an imported module;
* no source file is longer than ``MAX_LINES`` unless :data:`LONG_FILES` names it with a reason;
* no test module (conftest.py included) imports another: shared helpers live in ``tests/support``;
* no docstring or comment in ``src`` cites ``shared/reference`` (a folder outside the repository): the
  specification the code cites is ``docs/reference/webots-on-ode.md``.

The allow-lists only shrink: an entry that no longer applies fails too, so the list stays true.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support.names import dotted_names, resolves

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "dualtwin"
TESTS = ROOT / "tests"
MAX_LINES = 800

#: Source files allowed over MAX_LINES, with the reason (relative to src/dualtwin).
LONG_FILES: dict[str, str] = {
    "webots/schema.py": "one data table (the fields of every Webots base node); the code around it is <100 lines",
    "webots/controller_process.py": "a controller process's whole side of the channel: run by path, it imports only "
                                    "the standard library (a child starts in tens of milliseconds), so it cannot "
                                    "import a sibling dualtwin module without importing the package",
}


def _python_files(root: Path) -> Iterator[Path]:
    yield from sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute module of a (possibly relative) ``from`` import in ``module``."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, *([node.module] if node.module else [])])


def _package(module: str) -> str:
    """``dualtwin.align.fit`` -> ``align``; a top-level module is its own package (``dualtwin.cli`` -> ``cli``)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _is_module(dotted: str, src: Path = SRC) -> bool:
    parts = dotted.split(".")[1:]
    path = src.joinpath(*parts) if parts else src
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def private_imports(src: Path = SRC) -> list[str]:
    """Every use of another package's private name under ``src`` (a ``dualtwin`` folder), as ``file:line what``."""
    found = []
    for path in _python_files(src):
        module = _module_name(path, src.parent)
        own = _package(module)
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        where = path.relative_to(src)
        foreign_modules: dict[str, str] = {}  # local name -> module of another package
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(node, module, path.name == "__init__.py")
                if not target.startswith("dualtwin") or _package(target) == own:
                    continue
                for alias in node.names:
                    dotted = f"{target}.{alias.name}"
                    if any(_private(p) for p in target.split(".")[1:]) or _private(alias.name):
                        found.append(f"{where}:{node.lineno} from {target} import {alias.name}")
                    elif _is_module(dotted, src):
                        foreign_modules[alias.asname or alias.name] = dotted
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if not alias.name.startswith("dualtwin.") or _package(alias.name) == own:
                        continue
                    if any(_private(p) for p in alias.name.split(".")[1:]):
                        found.append(f"{where}:{node.lineno} import {alias.name}")
                    if alias.asname:
                        foreign_modules[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in foreign_modules and _private(node.attr)):
                found.append(f"{where}:{node.lineno} {foreign_modules[node.value.id]}.{node.attr}")
    return found


def test_no_module_imports_another_packages_private_names() -> None:
    found = private_imports()
    assert not found, ("private names used across packages (give them a public name in a low, shared "
                       "module):\n" + "\n".join(found))


def test_the_private_name_check_sees_each_form(tmp_path: Path) -> None:
    """The control: on a small tree laid out like src, every form is flagged and same-package use is not."""
    src = tmp_path / "dualtwin"
    files = {
        "__init__.py": "",
        "divergence/__init__.py": "",
        "divergence/report.py": "_CSS = ''\ndef _slug(): ...\n",
        "divergence/runs.py": "from dualtwin.divergence.report import _CSS\nfrom .report import _slug\n",
        "webots/__init__.py": "",
        "webots/_math3.py": "def rot(): ...\n",
        "align/__init__.py": "",
        "align/fit.py": ("from dualtwin.divergence.report import _CSS\nfrom dualtwin.webots._math3 import rot\n"
                         "from dualtwin.divergence import report\nimport dualtwin.divergence.report as rep\n"
                         "x = report._slug, rep._slug, report.__name__\n"),
        "align/relative.py": "from ..divergence.report import _CSS\n",
    }
    for name, text in files.items():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / name).write_text(text)
    found = private_imports(src)
    assert sorted(f.split(" ", 1)[0] for f in found) == [
        "align/fit.py:1", "align/fit.py:2", "align/fit.py:5", "align/fit.py:5", "align/relative.py:1"], found


def long_files() -> dict[str, int]:
    out = {}
    for path in _python_files(SRC):
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_LINES:
            out[path.relative_to(SRC).as_posix()] = n
    return out


def test_no_source_file_is_long_without_a_reason() -> None:
    long = long_files()
    unlisted = {f: n for f, n in long.items() if f not in LONG_FILES}
    assert not unlisted, (f"source files over {MAX_LINES} lines: {unlisted}; split them along their seams, or "
                          "add them to LONG_FILES in tests/test_layout.py with the reason")
    stale = sorted(set(LONG_FILES) - set(long))
    assert not stale, f"LONG_FILES lists files that are no longer over {MAX_LINES} lines (remove them): {stale}"
    assert all(reason.strip() for reason in LONG_FILES.values())


def imports_of_test_modules() -> list[tuple[str, str]]:
    """(importer, imported) for every import of a ``tests`` module other than ``tests.support``."""
    found = []
    for path in _python_files(TESTS):
        module = _module_name(path, ROOT)
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                targets = [_resolve(node, module, path.name == "__init__.py")]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            found.extend((path.relative_to(ROOT).as_posix(), t) for t in targets
                         if t.startswith("tests.") and not re.match(r"tests\.support(\.|$)", t))
    return sorted(set(found))


def test_no_test_module_imports_another() -> None:
    """conftest.py files included: pytest advises against importing them; their shared code is in tests/support."""
    found = [f"{a} imports {b}" for a, b in imports_of_test_modules()]
    assert not found, "test modules import other test modules (move the shared code to tests/support):\n" \
        + "\n".join(found)


def test_the_test_import_check_sees_relative_imports() -> None:
    node = ast.parse("from .test_app import frame").body[0]
    assert isinstance(node, ast.ImportFrom)
    assert _resolve(node, "tests.server.test_sessions", False) == "tests.server.test_app"
    assert _resolve(node, "tests.server", True) == "tests.server.test_app"


SHARED_REFERENCE = re.compile(r"shared/reference")


def test_no_source_cites_the_reference_folder_outside_the_repository() -> None:
    """Facts are restated in docs/reference/webots-on-ode.md, which the code cites instead."""
    cites = [f"{p.relative_to(SRC)}:{i}" for p in _python_files(SRC)
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if SHARED_REFERENCE.search(line)]
    assert not cites, f"src cites shared/reference (not in the repository): {cites}"


@pytest.mark.parametrize("text", ["see ../shared/reference/webots-on-ode.md", "shared/reference/arm-ur5e-facts.md"])
def test_the_citation_check_matches(text: str) -> None:
    assert SHARED_REFERENCE.search(text)


def test_every_dualtwin_name_in_a_docstring_or_comment_exists() -> None:
    """A module moved or a function renamed must not leave a docstring pointing at the old name (docs pages
    are checked the same way in test_docs.py); schema ids such as ``dualtwin.knobs/1`` are not names."""
    stale = [f"{p.relative_to(SRC)}:{i}: {name}" for p in _python_files(SRC)
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             for name in sorted(dotted_names(line)) if not resolves(name)]
    assert not stale, "src names modules or attributes that do not exist:\n" + "\n".join(stale)
