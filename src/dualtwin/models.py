"""The project's one strict pydantic base: every typed config and every validated document derives from it.

Decisions:

* ``extra="forbid"``: a misspelt field in a config, a suite or a request is an error naming it, never
  silently ignored.
* ``allow_inf_nan=False``: a NaN or an infinity in a config is a mistake (JSON cannot even hold them; pydantic
  would write ``null``), so it is refused where it is read. Models whose values are *measured* (an analysis'
  sensitivities, which may be infinite when a perturbed run is unstable) opt back in with
  ``model_config = ConfigDict(allow_inf_nan=True)``; pydantic merges a subclass's config with its base's.
* Not ``strict=True``: JSON has no integer/float distinction worth enforcing (``1`` is a fine ``float``), and
  YAML documents arrive through the same models. Models that must refuse coercion (an LLM's reply, where
  ``"0.3"`` for a number is a mistake to report) add ``strict=True`` themselves.
* :class:`FrozenModel` for configs saved next to artifacts: a config is hashed (resume checks it), so it
  must not change after validation.
* :data:`Name` for a name a document gives (a scenario id, a channel, a unit, a twin or robot name): reports,
  plot titles, file names and the terminal show it, so it is one printable line of at most `MAX_NAME_LENGTH`
  characters. A control character (an ANSI escape sequence clearing the user's terminal, a newline splitting a
  table row or a one-line error in two, a NUL) or a bidi override (U+202E, which makes ``gnp.exe`` read as
  ``exe.png``) is refused where the document is read, rather than escaped by each of the many places that
  show names; a 1 MB name hung matplotlib's layout.
* :func:`validation_message` turns a :class:`pydantic.ValidationError` into the one line a user sees (file,
  JSON path, what was expected); bindings, suites and mappings all report through it, so it sits here,
  below every package that validates documents.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, StringConstraints, ValidationError

#: The longest `Name`: far above any real scenario, channel or robot name.
MAX_NAME_LENGTH = 256
MAX_NOTE_LENGTH = 4000


class StrictModel(BaseModel):
    """Unknown fields and non-finite numbers are validation errors."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class FrozenModel(StrictModel):
    """A :class:`StrictModel` that cannot be changed once validated (configs, specs, documents)."""

    model_config = ConfigDict(frozen=True)


def _printable(value: str) -> str:
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise ValueError(f"names are one line of printable text; this one holds {bad!r} at {value.index(bad)}")
    return value


#: A name from a document, shown by reports and the terminal: printable (no control, format or bidi
#: characters; spaces and any script are fine) and at most `MAX_NAME_LENGTH` characters.
Name = Annotated[str, StringConstraints(max_length=MAX_NAME_LENGTH), AfterValidator(_printable)]
#: A note from a document that the terminal prints (a sentence a writer of ours composed): printable like a
#: name, at most `MAX_NOTE_LENGTH` characters.
Note = Annotated[str, StringConstraints(max_length=MAX_NOTE_LENGTH), AfterValidator(_printable)]


def _key(part: str) -> str:
    # A dict key comes from the document: one with odd characters or of any length is shown quoted and cut, so
    # the error stays one printable line.
    if part.isprintable() and len(part) <= 80 and "'" not in part:
        return part
    return repr(part[:80]) + ("…" if len(part) > 80 else "")


def json_path(loc: tuple[Any, ...]) -> str:
    """``('scenarios', 2, 'duration_s')`` → ``$.scenarios[2].duration_s``."""
    out = "$"
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else f".{_key(str(part))}"
    return out


#: How pydantic labels the location part a model's or field's own validator adds (e.g.
#: ``function-after[_inputs_are_values_or_signals(), Scenario]``); it names no field of the document.
_VALIDATOR_LOC_PREFIXES = ("function-after[", "function-before[", "function-wrap[", "function-plain[")


def validation_message(path: Path, exc: ValidationError) -> str:
    """``<path>: <JSON path>: <message>`` of the first error, plus how many more there are."""
    first = exc.errors()[0]
    loc = tuple(p for p in first["loc"] if not (isinstance(p, str) and p.startswith(_VALIDATOR_LOC_PREFIXES)))
    msg = first["msg"].removeprefix("Value error, ")
    extra = f" ({exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
    return f"{path}: {json_path(loc)}: {msg}{extra}"


__all__ = ["MAX_NAME_LENGTH", "MAX_NOTE_LENGTH", "FrozenModel", "Name", "Note", "StrictModel", "json_path",
           "validation_message"]
