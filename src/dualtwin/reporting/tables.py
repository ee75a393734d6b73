"""Result tables for the terminal and for pipes, and JSON output, used by every command that prints results.

Decisions: on a terminal a rich table folds a long cell onto more lines rather than cutting it (no ``…``); off
a terminal (pipes, CI logs) the table is plain text, aligned, with every cell complete and no line wrapped,
so it can be read, grepped and diffed. ``--json`` output goes to stdout through `emit_json`; everything else a
command says while it works (progress) goes to stderr.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

from dualtwin.artifacts import json_safe

#: A table row: cells as plain strings or rich Text (styled); None starts a new section.
Row = Sequence[str | Text] | None


@dataclass(frozen=True)
class Column:
    """A table column: its title, whether it holds numbers (right-aligned) or text, and whether a value equal
    to the row above is left blank on a terminal (``group``: a scenario id over its channels' rows). Off a
    terminal every row is complete, so it can be filtered on its own."""

    title: str
    numeric: bool = True
    group: bool = False


def configure_console(console: Console) -> Console:
    """Off a terminal, never wrap printed lines (a pipe has no width); returns ``console``."""
    if not console.is_terminal:
        console.soft_wrap = True
    return console


def _plain(cell: str | Text) -> str:
    return cell.plain if isinstance(cell, Text) else str(cell)


def print_table(console: Console, columns: Sequence[Column], rows: Sequence[Row], *, title: str | None = None) -> None:
    """Print a table complete: folded cells on a terminal, plain aligned text otherwise.

    Cells are plain text (never rich markup), so names with brackets print as they are.
    """
    if console.is_terminal:
        table = Table(title=title)
        for i, col in enumerate(columns):
            # A number column is never narrower than its widest number (names fold instead); if even that does
            # not fit, the table is wider than the terminal, which wraps it: nothing is cut.
            widest = max((len(_plain(r[i])) for r in rows if r is not None and i < len(r)), default=0)
            longest_word = max((len(w) for w in col.title.split()), default=0)
            # Text folds, but not into slivers: up to 16 characters of it stay on one line.
            table.add_column(Text(col.title), justify="right" if col.numeric else "left", overflow="fold",
                             min_width=max(widest if col.numeric else min(widest, 16), longest_word))
        previous: Sequence[str | Text] | None = None
        for row in rows:
            if row is None:
                table.add_section()
                previous = None
                continue
            shown = [Text("") if col.group and previous is not None and i < len(previous)
                     and _plain(previous[i]) == _plain(cell) else cell if isinstance(cell, Text) else Text(str(cell))
                     for i, (cell, col) in enumerate(zip(row, columns, strict=False))]
            table.add_row(*shown)
            previous = row
        # crop=False: a table wider than the terminal wraps there instead of losing its right-hand columns.
        console.print(table, crop=False)
        return
    body = [[_plain(c) for c in row] for row in rows if row is not None]
    header = [c.title for c in columns]
    widths = [max([len(header[i]), *(len(r[i]) for r in body if i < len(r))]) for i in range(len(columns))]

    def line(cells: Sequence[str]) -> str:
        parts = [c.rjust(w) if col.numeric else c.ljust(w) for c, w, col in zip(cells, widths, columns, strict=False)]
        return "  ".join(parts).rstrip()

    out = [title] if title else []
    out += [line(header), "  ".join("-" * w for w in widths)]
    out += [line(r) for r in body]
    # Straight to the console's file: no wrapping, no markup, no highlighting.
    console.file.write("\n".join(out) + "\n")
    console.file.flush()


def emit_json(data: Any) -> None:
    """Print ``data`` as strict JSON on stdout (non-finite numbers become null)."""
    sys.stdout.write(json.dumps(json_safe(data), indent=2, default=str) + "\n")
    sys.stdout.flush()
