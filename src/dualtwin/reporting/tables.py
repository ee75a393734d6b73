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
    """A table column: its title, and whether it holds numbers (right-aligned) or text."""

    title: str
    numeric: bool = True


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
        for col in columns:
            table.add_column(col.title, justify="right" if col.numeric else "left", overflow="fold")
        for row in rows:
            if row is None:
                table.add_section()
            else:
                table.add_row(*(cell if isinstance(cell, Text) else Text(str(cell)) for cell in row))
        console.print(table)
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
