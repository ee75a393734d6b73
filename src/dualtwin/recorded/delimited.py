"""A fast, strict reader for users' CSV/TSV logs: numbers in C, errors that name the file and line.

The common case (a well-formed file) is parsed by ``numpy.loadtxt`` in one call. Only when that fails does a
slow pass walk the lines to name the first bad one, so a 1,000-file import costs about what reading the
numbers costs.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from dualtwin.artifacts import read_text_file
from dualtwin.errors import DualtwinError

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Table:
    """A parsed log: header names, an ``(rows, columns)`` array and each row's line number in the file."""

    path: Path
    header: list[str]
    data: FloatArray
    first_line: int
    notes: tuple[str, ...] = ()

    def line(self, row: int) -> int:
        """The file line (1-based) of data row ``row``; blank lines are not allowed inside the body."""
        return self.first_line + row

    def column(self, name: str, option: str) -> FloatArray:
        """The named column; a missing one is an error listing the header."""
        try:
            return self.data[:, self.header.index(name)]
        except ValueError:
            raise DualtwinError(f"{self.path}:1: no column {name!r} ({option}); the header has: "
                                f"{', '.join(self.header)}") from None


def pick_delimiter(path: Path, header_line: str, delimiter: str) -> str:
    if delimiter != "auto":
        return delimiter
    suffix = path.suffix.lower()
    if suffix == ".tsv":
        return "\t"
    if suffix == ".csv":
        return ","
    for candidate in ("\t", ",", ";"):
        if candidate in header_line:
            return candidate
    return "\t"


def read_table(path: Path, delimiter: str = "auto") -> Table:
    """Read a delimited log with a header line.

    A short last line without a final newline (a logger killed mid-write) is dropped and noted, as the run
    reader does with our own logs.

    Raises:
        DualtwinError: a directory, a missing, empty, binary or header-only file, a row with the wrong
            number of cells or a cell that is not a number (file and line named).
    """
    path = Path(path)
    text = read_text_file(path, "log file").removeprefix("\ufeff")  # spreadsheet exports start with a BOM
    if "\x00" in text:
        raise DualtwinError(f"{path}: not a text log (binary data at character {text.index(chr(0))})")
    if not text.strip():
        raise DualtwinError(f"{path}: empty file, expected a header line and data rows")
    first_newline = text.find("\n")
    header_line = text if first_newline < 0 else text[:first_newline]
    header_line = header_line.rstrip("\r")
    sep = pick_delimiter(path, header_line, delimiter)
    header = [cell.strip().strip('"').strip("'") for cell in header_line.split(sep)]
    if len(header) < 2 or not all(header):
        raise DualtwinError(f"{path}:1: expected a header of column names separated by {sep!r}, "
                            f"got {header_line[:80]!r}")
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise DualtwinError(f"{path}:1: duplicate columns {dupes}")
    body = "" if first_newline < 0 else text[first_newline + 1:]
    notes: list[str] = []
    if body and not body.endswith("\n"):
        last_start = body.rfind("\n") + 1
        if body[last_start:].count(sep) != len(header) - 1:
            notes.append(f"dropped a truncated last line (line {body.count(chr(10)) + 2})")
            body = body[:last_start]
    if not body.strip():
        raise DualtwinError(f"{path}: no data rows after the header")
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=sep, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        _diagnose(path, body, sep, len(header))
        raise DualtwinError(f"{path}: cannot read the rows as numbers") from None
    if data.shape[1] != len(header) or _has_blank_line(body):
        _diagnose(path, body, sep, len(header))
        raise DualtwinError(f"{path}: expected {len(header)} columns, read {data.shape[1]}")
    return Table(path=path, header=header, data=data, first_line=2, notes=tuple(notes))


def _has_blank_line(body: str) -> bool:
    return "\n\n" in body.rstrip("\n") or body.startswith("\n")


def _diagnose(path: Path, body: str, sep: str, columns: int) -> None:
    """Raise for the first malformed line of ``body`` (line 2 of the file is the first body line)."""
    lines = body.split("\n")
    last = max((i for i, line in enumerate(lines) if line.strip()), default=-1)
    for lineno, line in enumerate(lines[:last + 1], start=2):
        line = line.rstrip("\r")
        if not line.strip():
            raise DualtwinError(f"{path}:{lineno}: blank line inside the data")
        cells = line.split(sep)
        if len(cells) != columns:
            raise DualtwinError(f"{path}:{lineno}: expected {columns} cells separated by {sep!r}, got {len(cells)}")
        for i, cell in enumerate(cells, start=1):
            try:
                float(cell)
            except ValueError:
                raise DualtwinError(f"{path}:{lineno}:{i}: {cell.strip()[:40]!r} is not a number") from None
