"""Loading suites with errors that name the file, the JSON path and what was expected."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from dualtwin.errors import DualtwinError
from dualtwin.suite.schema import Suite


def json_path(loc: tuple[Any, ...]) -> str:
    """``('scenarios', 2, 'duration_s')`` → ``$.scenarios[2].duration_s``."""
    out = "$"
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else f".{part}"
    return out


def _reject_constant(token: str) -> float:
    raise ValueError(f"{token} is not a valid JSON number (NaN and infinities are not allowed)")


def read_json(path: Path) -> Any:
    """Strict JSON: no NaN/Infinity tokens, errors with line and column."""
    if not path.is_file():
        raise DualtwinError(f"{path}: file not found")
    text = path.read_text(encoding="utf-8")
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise DualtwinError(f"{path}:{exc.lineno}:{exc.colno}: invalid JSON: {exc.msg}") from None
    except ValueError as exc:
        raise DualtwinError(f"{path}: invalid JSON: {exc}") from None


def validation_message(path: Path, exc: ValidationError) -> str:
    first = exc.errors()[0]
    loc = tuple(p for p in first["loc"] if p not in ("function-after[_inputs_are_values_or_signals(), Scenario]",))
    msg = first["msg"].removeprefix("Value error, ")
    extra = f" ({exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
    return f"{path}: {json_path(loc)}: {msg}{extra}"


def load_suite(path: Path) -> Suite:
    data = read_json(Path(path))
    try:
        return Suite.model_validate(data)
    except ValidationError as exc:
        raise DualtwinError(validation_message(Path(path), exc)) from None
