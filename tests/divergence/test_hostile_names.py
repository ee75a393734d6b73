"""Names in a run folder (scenario ids, channels, units, twin, robot) are data that reports and the terminal show.

Found by fuzzing ``dualtwin compare`` with run folders whose manifest names were hostile: a ``$`` pair made
matplotlib parse a plot title as TeX and the command ended in a traceback; an ANSI escape sequence reached
the user's terminal as it was; a 1 MB name hung the plot layout.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from dualtwin.cli import main

T = np.arange(1, 11) * 0.032


def test_names_with_dollar_signs_are_plotted_as_text(make_run: Callable[..., Path], tmp_path: Path) -> None:
    """``$x^$`` is bad mathtext: the report is still written, the name shown as it is."""
    name = "$x^$"
    channels = {name: {"source": "ground_truth", "unit": "$\\frac{"}}
    data = {f"00_{name}": {name: (T, np.sin(T))}}
    a = make_run("a", data, twin=f"{name} A", channels=channels)
    b = make_run("b", data, twin=f"{name} B", channels=channels)
    out = tmp_path / "out"
    assert main(["compare", "--reference-run", str(a), "--target-run", str(b), "-o", str(out)]) == 0
    assert (out / "report.html").is_file()
    assert len(list((out / "plots").glob("*.png"))) == 1
