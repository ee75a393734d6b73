"""HTML building blocks for self-contained reports: stylesheet, tables that scroll, readable evidence, PNGs.

Decisions: numbers are rounded to 4 significant digits for reading (the JSON beside each report keeps full
precision); a value that is not a finite number is never printed as ``nan``: the caller says what it means
(``missing``), or it shows as "–"; every table sits in a ``div.scroll`` (``overflow-x:auto``) so a wide one
scrolls inside the page instead of running off it.
"""

from __future__ import annotations

import base64
import hashlib
import html
import io
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: The style of `dualtwin.reporting.svg.svg_plot`'s plots (in `CSS`; here: this module loads no numpy).
SVG_CSS = ("svg.plot{font:10px sans-serif;text-anchor:middle}svg.plot path{fill:none;stroke-width:1.4}"
           "svg.plot rect{fill:none;stroke:#999}svg.plot .g{stroke:#eee}svg.plot .d{stroke:#888;stroke-dasharray:5 3}"
           "svg.plot .c{stroke-dasharray:2 2;stroke-width:1.2}svg.plot .e{text-anchor:end}svg.plot .h{font-size:11px}")

CSS = """
body{font-family:system-ui,sans-serif;margin:2em;color:#222;max-width:1200px}
.scroll{overflow-x:auto;max-width:100%;margin:0.6em 0 1.2em}
table{border-collapse:collapse}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right;font-size:13px;white-space:nowrap}
td.wrap{white-space:normal;min-width:16em}
th{background:#f2f2f2}td.l,th.l{text-align:left}
table.evidence{margin:2px 0}table.evidence th,table.evidence td{font-size:12px;padding:1px 6px}
.completed{color:#1a7f37}.failed{color:#b35900}.unstable{color:#c62828;font-weight:bold}
.viol{color:#c62828}img{max-width:100%;margin:4px 0}code{background:#f5f5f5;padding:0 3px}
section{border-top:2px solid #ddd;margin-top:1.5em}
div.plots{display:flex;flex-wrap:wrap;gap:4px 12px}div.plots svg{max-width:100%;height:auto}
""" + SVG_CSS + """
"""


#: Colours of a report PNG's palette: a plot has a few line colours and their anti-aliased blends.
PNG_COLOURS = 64


def png_bytes(fig: Figure, *, palette: bool = True) -> bytes:
    """A figure as PNG bytes, identical for identical data (no "Software" stamp, no timestamp).

    With ``palette`` (the default) the image is stored with a palette of `PNG_COLOURS` colours (fast octree,
    no dithering) instead of 24-bit RGB: a line plot looks the same and the file is about 3 times smaller,
    which is what keeps a report with a dozen embedded figures near 1 MB. (PIL's ``optimize`` would save
    another 10 % at 0.3 s per figure: not worth it.)
    """
    import numpy as np  # imported here: this module is on the CLI's start-up path
    from PIL import Image

    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
    image = Image.fromarray(np.ascontiguousarray(rgba[..., :3]))
    if palette:
        image = image.quantize(colors=PNG_COLOURS, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    buf = io.BytesIO()
    dpi = float(fig.dpi)
    image.save(buf, format="png", dpi=(dpi, dpi))
    return buf.getvalue()


#: The longest `slug`: a plot's file name joins two (scenario and channel), and a file system allows 255 bytes.
MAX_SLUG = 100


def slug(text: str) -> str:
    """A file-name and HTML-id safe form of ``text`` (never empty, at most `MAX_SLUG` characters).

    A longer one keeps its start and ends in a hash of the whole text, so distinct names stay distinct: names
    come from run folders (data), and a 250-character scenario id and channel made a plot file name the file
    system refused, after ``metrics.json`` was already written.
    """
    out = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_") or "x"
    if len(out) <= MAX_SLUG:
        return out
    digest = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:12]
    return f"{out[:MAX_SLUG - 13]}-{digest}"


def fmt(value: Any, spec: str = ".4g", missing: str = "–") -> str:
    """A value for reading: floats rounded by ``spec``, booleans as yes/no, None and non-finite as ``missing``."""
    if value is None:
        return missing
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float | int) and not isinstance(value, bool):
        if isinstance(value, float) and not math.isfinite(value):
            return missing
        return format(value, spec) if isinstance(value, float) else str(value)
    return str(value)


def esc(value: Any, spec: str = ".4g", missing: str = "–") -> str:
    """`fmt`, HTML-escaped."""
    return html.escape(fmt(value, spec, missing))


def page_head(title: str) -> str:
    """The opening of a self-contained report page (doctype, title, stylesheet, ``<body>``)."""
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{CSS}</style></head><body>")


def html_table(headers: Sequence[str], rows: Iterable[Sequence[Any]], *, left: Iterable[int] = (0,),
               raw: Iterable[int] = (), cls: str = "") -> str:
    """A table in a horizontal scroll box.

    Args:
        headers: Column titles (plain text).
        rows: Cell values; formatted with `fmt` and escaped, except in ``raw`` columns (HTML, already safe).
        left: Indices of left-aligned (text) columns.
        raw: Indices of columns whose cells are trusted HTML.
        cls: CSS class of the table.
    """
    lefts, raws = set(left), set(raw)
    klass = f" class='{cls}'" if cls else ""
    head = "".join(f"<th{' class=l' if i in lefts else ''}>{html.escape(h)}</th>" for i, h in enumerate(headers))
    body = []
    for row in rows:
        cells = "".join(
            f"<td{' class=l' if i in lefts else ''}>{v if i in raws else esc(v)}</td>" for i, v in enumerate(row))
        body.append(f"<tr>{cells}</tr>")
    return f"<div class='scroll'><table{klass}><tr>{head}</tr>{''.join(body)}</table></div>"


def evidence_html(evidence: Any, depth: int = 0) -> str:
    """Evidence (nested dicts and lists of numbers) as small readable tables with rounded numbers, not JSON."""
    if isinstance(evidence, Mapping):
        if not evidence:
            return "–"
        rows = "".join(f"<tr><th class=l>{html.escape(str(k).replace('_', ' '))}</th>"
                       f"<td class=l>{evidence_html(v, depth + 1)}</td></tr>" for k, v in evidence.items())
        table = f"<table class='evidence'>{rows}</table>"
        return f"<div class='scroll'>{table}</div>" if depth == 0 else table
    if isinstance(evidence, list | tuple):
        if not evidence:
            return "–"
        if all(not isinstance(v, Mapping | list | tuple) for v in evidence):
            shown = ", ".join(esc(v) for v in evidence[:12])
            return shown + (f", … ({len(evidence)} values)" if len(evidence) > 12 else "")
        return "<br>".join(evidence_html(v, depth + 1) for v in evidence[:12])
    return esc(evidence)


def img_html(png: bytes, alt: str) -> str:
    """An embedded PNG."""
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'
