"""Shared, low-level output helpers: HTML pages and PNGs for reports, terminal tables, progress, JSON output.

Every report (divergence, alignment, synchronisation) and every command that prints results goes through
these public names, so the look and the rules (numbers rounded but never cut, wide tables scroll, one unit per
plot axis, progress on stderr) are decided in one place. Only numpy, matplotlib and rich are imported here: any
package may use this module.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from dualtwin.reporting.pages import (
    CSS,
    esc,
    evidence_html,
    fmt,
    html_table,
    img_html,
    page_head,
    png_bytes,
    slug,
)
from dualtwin.reporting.progress import Progress, ProgressCallback, ProgressEvent, report_progress
from dualtwin.reporting.tables import Column, configure_console, emit_json, print_table

if TYPE_CHECKING:
    from dualtwin.reporting.plots import Trace, literal_legend, plot_overlay, plot_unit_groups

_PLOT_NAMES = ("Trace", "literal_legend", "plot_overlay", "plot_unit_groups")


def __getattr__(name: str) -> Any:
    # matplotlib is imported only when a plot helper is used, so the CLI starts fast.
    if name in _PLOT_NAMES:
        from dualtwin.reporting import plots

        return getattr(plots, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "CSS",
    "Column",
    "Progress",
    "ProgressCallback",
    "ProgressEvent",
    "Trace",
    "configure_console",
    "emit_json",
    "esc",
    "evidence_html",
    "fmt",
    "html_table",
    "img_html",
    "literal_legend",
    "page_head",
    "plot_overlay",
    "plot_unit_groups",
    "png_bytes",
    "print_table",
    "report_progress",
    "slug",
]
