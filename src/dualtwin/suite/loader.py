"""Loading suites with errors that name the file, the JSON path and what was expected."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import ValidationError

from dualtwin.artifacts import read_json as _read_json_file
from dualtwin.errors import DualtwinError
from dualtwin.models import validation_message
from dualtwin.suite.schema import Suite

#: Bundled robots live next to their suites: ``<robot>/suite.json``.
BUNDLED_SUITES = Path(__file__).resolve().parent.parent / "robots"


def read_json(path: Path, what: str = "file") -> Any:
    """Strict JSON: no NaN/Infinity tokens, errors with line and column (:func:`dualtwin.artifacts.read_json`)."""
    return _read_json_file(Path(path), what)


def bundled_suites() -> list[str]:
    return sorted(p.parent.name for p in BUNDLED_SUITES.glob("*/suite.json"))


def resolve_suite(name_or_path: str | Path) -> Path:
    """A bundled robot's name (``cartpole``) means its bundled suite, from any folder; anything else is a path.

    Decision: a bare word (no folder separator, no suffix) is always a bundled name, even when a file of that
    name exists in the working folder, as ``--robot cartpole`` is; write ``./cartpole`` to mean such a file.
    A bare word that names no bundled suite is an error listing the bundled names.
    """
    text = str(name_or_path)
    if "/" in text or "\\" in text or Path(text).suffix or text in ("", ".", ".."):
        return Path(name_or_path)
    candidate = BUNDLED_SUITES / text / "suite.json"
    if candidate.is_file():
        return candidate
    raise DualtwinError(f"unknown suite {text!r}: not a bundled suite ({', '.join(bundled_suites())}); "
                        f"to use a file of that name, write ./{text}")


def load_suite(path: Path) -> Suite:
    data = read_json(Path(path), "suite file")
    try:
        return Suite.model_validate(data)
    except ValidationError as exc:
        raise DualtwinError(validation_message(Path(path), exc)) from None
