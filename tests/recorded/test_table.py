"""CSV/TSV logs with a YAML mapping: units, scales, sources, globs, and bad inputs."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from dualtwin.divergence.runs import load_run
from dualtwin.errors import DualtwinError
from dualtwin.recorded import import_table


def _write_csvs(folder: Path, suite: Path, period: float = 0.032) -> list[Path]:
    """One CSV per scenario in a user's own units: ms, degrees (sign flipped), millimetres."""
    scenarios = json.loads(suite.read_text())["scenarios"]
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, sc in enumerate(scenarios):
        t = np.arange(0.0, sc["duration_s"] + 1e-9, 0.01)  # 100 Hz, from the initial state
        angle = sc.get("initial_angle", 0.0) * np.cos(2 * t)
        cart = 0.1 * t * (i + 1)
        lines = ["stamp_ms,theta_deg,x_mm,enc_rad"]
        lines += [f"{a * 1000:.3f},{-math.degrees(b)!r},{c * 1000!r},{b!r}"
                  for a, b, c in zip(t.tolist(), angle.tolist(), cart.tolist(), strict=True)]
        path = folder / f"log_{i}.csv"  # names sort wrongly as text past 9 (natural sort needed)
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
    return paths


MAPPING = {
    "files": "logs/log_*.csv",
    "time": {"column": "stamp_ms", "unit": "ms"},
    "channels": [
        {"name": "pole_angle_rad", "column": "theta_deg", "unit": "deg", "scale": -1},
        {"name": "cart_pos_m", "column": "x_mm", "unit": "mm"},
        {"name": "pole_angle_rad", "source": "onboard", "column": "enc_rad", "unit": "rad"},
    ],
}


def _mapping(folder: Path, **changes: object) -> Path:
    data = {**MAPPING, **changes}
    path = folder / "mapping.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_csv_in_other_units_and_signs_becomes_a_run(tmp_path: Path, cartpole_suite: Path) -> None:
    _write_csvs(tmp_path / "logs", cartpole_suite)
    run = import_table(_mapping(tmp_path), cartpole_suite, "cartpole", tmp_path / "run")
    loaded = load_run(run)
    assert loaded.kind == "recorded"
    assert set(loaded.channels) == {"pole_angle_rad", "cart_pos_m", "onboard/pole_angle_rad"}
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["units"]["pole_angle_rad"] == {"recorded": "deg", "binding": "rad", "scale": -1.0,
                                                   "factor": pytest.approx(math.pi / 180)}
    assert manifest["units"]["cart_pos_m"]["factor"] == pytest.approx(1e-3)
    assert manifest["inputs"]["mapping"]["path"].endswith("mapping.yaml")
    assert (run / "config" / "mapping.yaml").is_file()
    series = loaded.series("01_Step_Response_2")
    t = series["pole_angle_rad"].t
    assert t[0] == pytest.approx(0.032) and np.allclose(np.diff(t), 0.032)
    # -1 * degrees → radians gives back the angle; both sources agree; mm → m.
    np.testing.assert_allclose(series["pole_angle_rad"].y, np.cos(2 * t), atol=2e-4)
    np.testing.assert_allclose(series["onboard/pole_angle_rad"].y, np.cos(2 * t), atol=2e-4)
    np.testing.assert_allclose(series["cart_pos_m"].y, 0.2 * t, atol=1e-9)
    assert [s["sources"] for s in manifest["scenarios"]] == [[f"logs/log_{i}.csv"] for i in range(6)]
    assert manifest["scenarios"][0]["timing"]["origin"] == "simulation"


def test_explicit_file_list_and_tsv(tmp_path: Path, cartpole_suite: Path) -> None:
    paths = _write_csvs(tmp_path / "logs", cartpole_suite)
    for p in paths:  # tab-separated, with CRLF line ends and a byte-order mark, as spreadsheets export them
        p.with_suffix(".tsv").write_bytes(("\ufeff" + p.read_text().replace(",", "\t")).replace("\n", "\r\n")
                                          .encode())
    mapping = _mapping(tmp_path, files=[f"logs/log_{i}.tsv" for i in range(6)])
    run = import_table(mapping, cartpole_suite, "cartpole", tmp_path / "run")
    assert json.loads((run / "manifest.json").read_text())["mapping"]["files"][0] == "logs/log_0.tsv"
    cart = load_run(run).series("01_Step_Response_2")["cart_pos_m"]
    np.testing.assert_allclose(cart.y[:3], 0.2 * np.array([0.032, 0.064, 0.096]), atol=1e-12)


@pytest.mark.parametrize("change, message", [
    ({"channels": [{"name": "cart_pos_m", "column": "theta_deg", "unit": "deg"}]},
     r"channel 'cart_pos_m': unit 'deg' cannot be converted to the binding's 'm'"),
    ({"channels": [{"name": "cart_pos_m", "column": "x_mm", "unit": "furlong"}]},
     r"'furlong' is not a unit dualtwin converts"),
    ({"channels": [{"name": "cart_speed", "column": "x_mm", "unit": "mm"}]},
     r"no ground_truth channel 'cart_speed'"),
    ({"channels": [{"name": "cart_pos_m", "column": "x_cm", "unit": "cm"}]},
     r"log_0.csv:1: no column 'x_cm' \(channel 'cart_pos_m'\); the header has: stamp_ms, theta_deg"),
    ({"time": {"column": "stamp_ms", "unit": "minutes"}}, r"mapping.yaml: \$.time.unit: Input should be"),
    ({"files": "logs/nothing_*.csv"}, r"pattern 'logs/nothing_\*.csv' matches nothing"),
    ({"files": ["../outside.csv"] * 6}, r"'../outside.csv' is outside the data folder"),
    ({"files": ["logs/log_0.csv"]}, r"1 file\(s\) for 6 scenario\(s\)"),
    ({"files": [f"logs/log_{i}.csv" for i in range(5)] + ["logs"]}, r"logs: is a directory"),
    # A NUL in a file name was a ValueError traceback from the path functions (found by fuzzing the mapping).
    ({"files": "logs/log_0.csv\x00"}, r"mapping.yaml: \$.files: a file name or pattern cannot hold a NUL"),
    ({"files": [f"logs/log_{i}.csv" for i in range(5)] + ["logs/\x00"]},
     r"mapping.yaml: \$.files: a file name or pattern cannot hold a NUL"),
    # A first sample moved to 1e308 s swallowed the stamps' differences: every sample at one time, imported silently.
    ({"time": {"column": "stamp_ms", "unit": "ms", "origin": "rebase", "first_sample_s": 1e308}},
     r"log_0.csv: the mapping's time.first_sample_s 1e\+308 is too large: the stamps moved there no longer increase"),
])
def test_bad_mappings_and_files_are_one_clear_error(tmp_path: Path, cartpole_suite: Path, change: dict,
                                                    message: str) -> None:
    _write_csvs(tmp_path / "logs", cartpole_suite)
    (tmp_path / "outside.csv").write_text("a,b\n1,2\n")
    with pytest.raises(DualtwinError, match=message):
        import_table(_mapping(tmp_path, **change), cartpole_suite, "cartpole", tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_bad_table_contents(tmp_path: Path, cartpole_suite: Path) -> None:
    paths = _write_csvs(tmp_path / "logs", cartpole_suite)
    lines = paths[3].read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    paths[3].write_text("\n".join(lines) + "\n")
    with pytest.raises(DualtwinError, match=r"log_3.csv:7: time stamps must increase"):
        import_table(_mapping(tmp_path), cartpole_suite, "cartpole", tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_invalid_yaml_mapping_names_the_line(tmp_path: Path, cartpole_suite: Path) -> None:
    bad = tmp_path / "mapping.yaml"
    bad.write_text("files: [a\nchannels: {")
    with pytest.raises(DualtwinError, match=r"mapping.yaml:\d+:\d+: invalid YAML"):
        import_table(bad, cartpole_suite, "cartpole", tmp_path / "run")


def test_wrong_unit_through_the_cli_is_one_line_and_exit_2(tmp_path: Path, cartpole_suite: Path,
                                                          run_cli: Callable[..., tuple[int, str, str]]) -> None:
    _write_csvs(tmp_path / "logs", cartpole_suite)
    mapping = _mapping(tmp_path, channels=[{"name": "pole_angle_rad", "column": "x_mm", "unit": "mm"}])
    code, out, err = run_cli("import", "table", str(mapping), "--scenarios", str(cartpole_suite), "--robot",
                             "cartpole", "--out", str(tmp_path / "run"))
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: ") and "unit 'mm' cannot be converted" in err
    assert "Traceback" not in err and not (tmp_path / "run").exists()
    code, out, err = run_cli("import", "table", str(_mapping(tmp_path)), "--scenarios", str(cartpole_suite),
                             "--robot", "cartpole", "--out", str(tmp_path / "run"))
    assert code == 0, err
    assert "wrote" in out and (tmp_path / "run" / "manifest.json").is_file()


def test_coarse_rounding_raises_the_channel_resolution(tmp_path: Path, cartpole_suite: Path) -> None:
    paths = _write_csvs(tmp_path / "logs", cartpole_suite)
    for path in paths:  # degrees to one decimal: 1.7 mrad, coarser than the 1 mrad default of rad
        header, *rows = path.read_text().splitlines()
        rows = [",".join([c[0], f"{float(c[1]):.1f}", *c[2:]]) for c in (r.split(",") for r in rows)]
        path.write_text("\n".join([header, *rows]) + "\n")
    run = import_table(_mapping(tmp_path), cartpole_suite, "cartpole", tmp_path / "run")
    channels = json.loads((run / "manifest.json").read_text())["channels"]
    assert channels["pole_angle_rad"]["resolution"] == pytest.approx(math.radians(0.1))
    assert load_run(run).channels["pole_angle_rad"].resolved_resolution == pytest.approx(math.radians(0.1))
    assert "resolution" not in channels["onboard/pole_angle_rad"]  # full precision there


def _doc_block(marker: str) -> str:
    text = (Path(__file__).resolve().parents[2] / "docs" / "guides" / "recorded-runs.md").read_text()
    after = text.split(f"<!-- example: {marker} -->", 1)[1]
    return after.split("```", 2)[1].split("\n", 1)[1]


def test_the_documented_table_mapping_example_imports_as_documented(tmp_path: Path, cartpole_suite: Path) -> None:
    """The guide's complete example (its mapping and CSV, read from the page itself) imports through the CLI."""
    import subprocess
    import sys

    (tmp_path / "mapping.yaml").write_text(_doc_block("table-mapping"))
    (tmp_path / "logs").mkdir()
    for i in range(len(json.loads(cartpole_suite.read_text())["scenarios"])):
        (tmp_path / "logs" / f"log_{i}.csv").write_text(_doc_block("table-csv"))
    done = subprocess.run([sys.executable, "-m", "dualtwin.cli", "import", "table", str(tmp_path / "mapping.yaml"),
                           "--scenarios", "cartpole", "--robot", "cartpole", "--out", str(tmp_path / "run")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    run = load_run(tmp_path / "run")
    assert set(run.channels) == {"pole_angle_rad", "cart_pos_m", "onboard/pole_angle_rad"}
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert manifest["units"]["pole_angle_rad"]["scale"] == -1.0
    assert manifest["scenarios"][0]["timing"]["origin"] == "simulation"
    first = run.series(run.scenarios[0].id)
    # -(-11.459 deg) is +0.2 rad, as the encoder says; mm became m
    assert first["pole_angle_rad"].y[0] == pytest.approx(first["onboard/pole_angle_rad"].y[0], abs=1e-3)
    assert 0 < first["cart_pos_m"].y[0] < 0.01
