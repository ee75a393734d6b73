"""mujoco.sysid parameter descriptions as knob definitions, and fitted knobs in its format, with mujoco.sysid's own
classes (issue 24, part 6): a ``ParameterDict`` saved by ``save_to_disk`` drives a fit from the Python API and from
the command line (without ``--knobs``), and what the fit exports loads back with ``ParameterDict.load_from_disk``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.align import AlignConfig, run_align, sysid_knobs, to_parameter_dict
from dualtwin.cli import main
from dualtwin.errors import DualtwinError
from tests.support.fake_twin import NAME, ROBOT, SUITE, registered

sysid = pytest.importorskip("mujoco.sysid")
if not hasattr(sysid, "ParameterDict"):
    pytest.skip("mujoco.sysid is installed without its optional dependencies (the sysid extra)",
                allow_module_level=True)

FREE = {"joint.j1.damping": (0.05, 1.0), "joint.j2.damping": (0.1, 2.0)}
TRUTH = {"joint.j1.damping": 0.7, "joint.j2.damping": 1.3}


@pytest.fixture
def fake() -> Iterator[str]:
    with registered() as name:
        yield name


def parameter_dict(frozen_mass: bool = True) -> Any:
    """What a mujoco.sysid user writes: parameters with modifiers (never saved), one of them frozen."""
    params = sysid.ParameterDict()
    for name, (lo, hi) in FREE.items():
        params.add(sysid.Parameter(name, nominal=0.5 * (lo + hi), min_value=lo, max_value=hi,
                                   modifier=lambda spec, p: None))
    params.add(sysid.Parameter("joint.j1.mass", nominal=1.0, min_value=0.5, max_value=2.0, frozen=frozen_mass))
    return params


def test_a_saved_parameter_dict_defines_the_knobs_and_the_fit_exports_one_it_loads(fake: str, tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    parameter_dict().save_to_disk(path)
    config = AlignConfig(reference=NAME, reference_knobs=TRUTH, target=NAME, robot=str(ROBOT), suite=str(SUITE),
                         knobs=[], sysid_params=str(path), optimizer="lsq", executor="serial", budget=60,
                         holdout=["04_kick"])
    result = run_align(config, tmp_path / "fit")
    assert list(result.knobs) == list(FREE)  # the frozen mass is not fitted
    assert {n: (k.lower, k.upper) for n, k in result.knobs.items()} == FREE  # the file's bounds
    for name, knob in result.knobs.items():
        assert knob.fitted == pytest.approx(TRUTH[name], rel=1e-3)

    loaded = sysid.ParameterDict.load_from_disk(tmp_path / "fit" / "sysid_params.yaml")
    assert loaded.keys() == list(FREE)
    np.testing.assert_array_equal(loaded.as_vector(), [result.knobs[n].fitted for n in FREE])
    lower, upper = loaded.get_bounds()
    assert list(zip(lower, upper, strict=True)) == list(FREE.values())
    # The nominal written back is the twin's (where the fit started), not the sysid user's start.
    assert [float(loaded[n].nominal[0]) for n in FREE] == [result.knobs[n].nominal for n in FREE]
    # And what we export reads back as the same knob definitions.
    assert sysid_knobs(loaded) == (list(FREE), FREE)


def test_parameter_dict_objects_in_and_out_of_the_python_api(fake: str, tmp_path: Path) -> None:
    names, bounds = sysid_knobs(parameter_dict())
    assert (names, bounds) == (list(FREE), FREE)
    names, bounds = sysid_knobs(parameter_dict(frozen_mass=False))
    assert names[-1] == "joint.j1.mass" and bounds["joint.j1.mass"] == (0.5, 2.0)

    config = AlignConfig(reference=NAME, reference_knobs=TRUTH, target=NAME, robot=str(ROBOT), suite=str(SUITE),
                         knobs=list(FREE), bounds=FREE, optimizer="lsq", executor="serial", budget=60,
                         holdout=["04_kick"])
    result = run_align(config, tmp_path / "fit")
    out = to_parameter_dict(result.knobs)
    assert isinstance(out, sysid.ParameterDict)
    np.testing.assert_array_equal(out.as_vector(), [result.knobs[n].fitted for n in FREE])
    np.testing.assert_array_equal(out.as_nominal_vector(), [result.knobs[n].nominal for n in FREE])
    assert [tuple(b) for b in zip(*out.get_bounds(), strict=True)] == list(FREE.values())
    # The object and the file the fit wrote say the same.
    written = sysid.ParameterDict.load_from_disk(tmp_path / "fit" / "sysid_params.yaml")
    np.testing.assert_array_equal(written.as_vector(), out.as_vector())


def test_what_alignment_cannot_fit_is_refused_with_the_reason() -> None:
    params = sysid.ParameterDict()
    params.add(sysid.Parameter("body.pole.inertia", nominal=[1.0, 1.0, 1.0], min_value=[0.5] * 3,
                               max_value=[2.0] * 3))
    with pytest.raises(DualtwinError, match="3-element parameter"):
        sysid_knobs(params)
    frozen = sysid.ParameterDict()
    frozen.add(sysid.Parameter("joint.j1.mass", nominal=1.0, min_value=0.5, max_value=2.0, frozen=True))
    with pytest.raises(DualtwinError, match="every parameter is frozen"):
        sysid_knobs(frozen)
    with pytest.raises(DualtwinError, match="expected a mujoco.sysid ParameterDict"):
        sysid_knobs([1.0])


SMALL = {"suite_name": "s", "scenarios": [{"name": "fall", "duration_s": 0.6, "initial_angle": 0.3}]}


def test_the_cli_fits_a_parameter_file_alone_and_without_one_or_knobs_says_what_to_give(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    suite = tmp_path / "suite.json"
    suite.write_text(json.dumps(SMALL))
    params = sysid.ParameterDict()
    params.add(sysid.Parameter("joint.pole_hinge.damping", nominal=0.0, min_value=0.0, max_value=0.2))
    params.add(sysid.Parameter("body.pole.mass", nominal=0.2, min_value=0.1, max_value=0.4, frozen=True))
    params.save_to_disk(tmp_path / "params.yaml")
    common = ["align", "--reference", "mujoco", "--reference-knobs", "joint.pole_hinge.damping=0.05", "--target",
              "mujoco", "--robot", "cartpole", "--scenarios", str(suite), "--optimizer", "lsq", "--executor", "serial",
              "--budget", "16"]

    # The control: neither --knobs nor --sysid-params is one line naming both, exit 2, nothing written.
    capsys.readouterr()
    assert main([*common, "--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "--knobs" in err and "--sysid-params" in err
    assert not (tmp_path / "none").exists()

    assert main([*common, "--sysid-params", str(tmp_path / "params.yaml"), "--out", str(tmp_path / "fit")]) == 0
    record = json.loads((tmp_path / "fit" / "align_record.json").read_text())
    assert [s["name"] for s in record["knob_specs"]] == ["joint.pole_hinge.damping"]
    loaded = sysid.ParameterDict.load_from_disk(tmp_path / "fit" / "sysid_params.yaml")
    assert loaded.keys() == ["joint.pole_hinge.damping"]
    fitted = record["result"]["knobs"]["joint.pole_hinge.damping"]
    assert float(loaded["joint.pole_hinge.damping"].value[0]) == fitted["fitted"]
    assert (fitted["lower"], fitted["upper"]) == (0.0, 0.2)  # the file's bounds, not the knob's default (0, 1)
