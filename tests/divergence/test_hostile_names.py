"""Names in a run folder (scenario ids, channels, units, twin, robot) are data that reports and the terminal show.

Found by fuzzing ``dualtwin compare`` with run folders whose manifest names were hostile: a ``$`` pair made
matplotlib parse a plot title as TeX and the command ended in a traceback; an ANSI escape sequence reached
the user's terminal as it was; a 1 MB name hung the plot layout.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

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


@pytest.mark.parametrize("value", [1e308, -1e308])
def test_values_near_the_float_limit_are_plotted(make_run: Callable[..., Path], tmp_path: Path, value: float) -> None:
    """A run that blew up logs numbers near 1e308: the overlay is still drawn (matplotlib's tick arithmetic
    overflowed on them: 'arange: cannot compute length')."""
    channels = {"pole_velocity_rad_s": {"source": "ground_truth", "unit": "rad/s"}}
    data = {"00_a": {"pole_velocity_rad_s": (T, np.full_like(T, value))}}  # both sides: the metrics are finite
    a = make_run("a", data, channels=channels)
    b = make_run("b", data, channels=channels)
    out = tmp_path / "out"
    assert main(["compare", "--reference-run", str(a), "--target-run", str(b), "-o", str(out)]) == 0
    assert len(list((out / "plots").glob("*.png"))) == 1


def test_long_scenario_and_channel_names_give_short_plot_file_names(make_run: Callable[..., Path],
                                                                   tmp_path: Path) -> None:
    """Two names of 250 characters (each allowed) made a plot file name beyond the file system's 255 bytes:
    exit 2 with metrics.json left behind."""
    sid, channel = "S" * 250, "C" * 250
    channels = {channel: {"source": "ground_truth", "unit": "rad"}}
    data = {sid: {channel: (T, np.sin(T))}}
    a = make_run("a", data, channels=channels, twin="webots")
    b = make_run("b", data, channels=channels)
    out = tmp_path / "out"
    assert main(["compare", "--reference-run", str(a), "--target-run", str(b), "-o", str(out)]) == 0
    (png,) = (out / "plots").glob("*.png")
    assert len(png.name) <= 255 and png.name.startswith("SSSS")


def _set(manifest: dict[str, Any], field: str, value: str) -> None:
    if field == "channel":
        spec = manifest["channels"].pop("pole_angle_rad")
        manifest["channels"][value] = {**spec, "column": "pole_angle_rad"}
    elif field == "unit":
        manifest["channels"]["pole_angle_rad"]["unit"] = value
    elif field == "id":
        manifest["scenarios"][0]["id"] = value
    elif field == "note":  # an importer's finding, printed by analyze (before: raw to the terminal)
        manifest["scenarios"][0]["state_continuity"] = {"carried_over": {"note": value}}
    else:
        manifest[field] = value


@pytest.mark.parametrize(("field", "value", "shown"), [
    ("id", "00_a\x1b[2J", "$.scenarios[0].id"),
    ("twin", "mujoco\u202egnp.exe", "$.twin"),
    ("robot", "cart\npole", "$.robot"),
    ("unit", "rad\x00", "$.channels.pole_angle_rad.unit"),
    ("channel", "\x1b[31mangle", "$.channels.'\\x1b[31mangle'"),
    ("suite_name", "x" * 1_000_000, "$.suite_name"),
    ("channel", "y" * 1_000_000, "$.channels.'yyyy"),
    ("note", "carried over\x1b[2J", "$.scenarios[0].state_continuity.carried_over.note"),
])
def test_name_with_control_characters_or_too_long_is_one_error_line(
    make_run: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
    field: str, value: str, shown: str,
) -> None:
    data = {"00_a": {"pole_angle_rad": (T, np.sin(T))}}
    good = make_run("good", data)
    bad = make_run("bad", data)
    manifest = json.loads((bad / "manifest.json").read_text())
    _set(manifest, field, value)
    (bad / "manifest.json").write_text(json.dumps(manifest))
    capsys.readouterr()
    code = main(["compare", "--reference-run", str(good), "--target-run", str(bad), "-o", str(tmp_path / "out")])
    captured = capsys.readouterr()
    err = captured.err.splitlines()
    assert code == 2
    assert len([line for line in err if line.startswith("error:")]) == 1, err
    assert str(bad / "manifest.json") in captured.err and shown in captured.err, captured.err
    assert len(captured.err) < 2000  # the name is cut in the message, not repeated whole
    assert not any(c in captured.err + captured.out for c in "\x1b\u202e\x00")
    assert not (tmp_path / "out").exists()
