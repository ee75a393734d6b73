"""A perception model folder is untrusted input: a hostile ``perception_contract.json`` is one DualtwinError naming
it, never a traceback (in the CLI) or a 500 on every request (in the server), and the ONNX files it names must lie
inside the folder; its ``weights.npz``, read to fine-tune (``--init-from``), must be the network's very arrays
(found by mutating a real model's contract and weights).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from dualtwin.cli import main
from dualtwin.errors import DualtwinError
from dualtwin.perception.estimator import CONTRACT_FILE, StateEstimator

pytestmark = pytest.mark.usefixtures("headless")


def _edit(folder: Path, change: Callable[[dict[str, Any]], None]) -> None:
    path = folder / CONTRACT_FILE
    contract = json.loads(path.read_text())
    change(contract)
    path.write_text(json.dumps(contract))


def _one_more_quantity(c: dict[str, Any]) -> None:
    # Consistent in itself, but the ONNX model still outputs 4 values: each request would zip 5 names with them.
    c["state"].append({"index": 4, "name": "extra", "unit": "m"})
    c["normalization"]["mean"].append(0.0)
    c["normalization"]["std"].append(1.0)


CONTRACTS: dict[str, Callable[[dict[str, Any]], None]] = {
    "state entry is a number": lambda c: c["state"].__setitem__(0, 5),
    "state is a number": lambda c: c.__setitem__("state", 10**30),
    "validation is text": lambda c: c.__setitem__("validation", "x"),
    "std entry is a list": lambda c: c["normalization"]["std"].__setitem__(1, []),
    "std entry missing": lambda c: c["normalization"]["std"].pop(),
    "mean missing": lambda c: c["normalization"].pop("mean"),
    "frame period is text": lambda c: c.__setitem__("frame_period_s", "x"),
    "trained_on is a list": lambda c: c.__setitem__("trained_on", [1]),
    "one more quantity than the model outputs": _one_more_quantity,
}


@pytest.fixture
def model(tiny_model: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(tiny_model, tmp_path / "model"))


@pytest.mark.parametrize("name", list(CONTRACTS))
def test_a_hostile_contract_is_one_error_naming_it(model: Path, name: str) -> None:
    _edit(model, CONTRACTS[name])
    with pytest.raises(DualtwinError, match="perception"):
        StateEstimator.load(model).session("kalman")


@pytest.mark.parametrize("field", ["file", "parts"])
@pytest.mark.parametrize("where", ["parent", "absolute"])
def test_no_onnx_file_is_read_from_outside_the_model_folder(model: Path, tmp_path: Path, field: str,
                                                            where: str) -> None:
    contract = json.loads((model / CONTRACT_FILE).read_text())
    name = contract["onnx"]["file"] if field == "file" else contract["onnx"]["parts"]["frame"]["file"]
    outside = tmp_path / "outside.onnx"
    shutil.copy(model / name, outside)  # the very model, with the hash the contract records
    value = "../outside.onnx" if where == "parent" else str(outside)
    if field == "file":
        _edit(model, lambda c: c["onnx"].__setitem__("file", value))
    else:
        _edit(model, lambda c: c["onnx"]["parts"]["frame"].__setitem__("file", value))
    with pytest.raises(DualtwinError, match="outside"):
        StateEstimator.load(model)


def test_the_server_refuses_the_model_before_it_listens(model: Path) -> None:
    pytest.importorskip("fastapi")
    from dualtwin.perception.reference_policy import export_reference_policy
    from dualtwin.server.app import create_app

    export_reference_policy(model.parent / "policy")
    _edit(model, _one_more_quantity)
    with pytest.raises(DualtwinError, match="state quantities"):
        create_app(model.parent / "policy", model)


def test_the_cli_says_one_line(model: Path, tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _edit(model, CONTRACTS["state entry is a number"])
    capsys.readouterr()
    code = main(["perception", "eval", "--model", str(model), "--data", str(tiny_dataset)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and CONTRACT_FILE in err, err


def _edit_weights(folder: Path, change: Callable[[dict[str, Any]], None]) -> None:
    import numpy as np

    with np.load(folder / "weights.npz") as data:
        arrays = {k: data[k] for k in data.files}
    change(arrays)
    np.savez(folder / "weights.npz", **arrays)  # type: ignore[arg-type]


WEIGHTS: dict[str, Callable[[Path], None]] = {
    "a parameter missing": lambda m: _edit_weights(m, lambda a: a.pop("head.0.bias")),
    "an extra array": lambda m: _edit_weights(m, lambda a: a.__setitem__("extra", a["std"])),
    "a parameter of another shape": lambda m: _edit_weights(m, lambda a: a.__setitem__("std", a["std"][:3])),
    "zero std": lambda m: _edit_weights(m, lambda a: a.__setitem__("std", a["std"] * 0)),
    "truncated": lambda m: (m / "weights.npz").write_bytes((m / "weights.npz").read_bytes()[:500]),
}


@pytest.mark.parametrize("name", list(WEIGHTS))
def test_fine_tuning_from_hostile_weights_is_one_line(model: Path, tiny_dataset: Path, tmp_path: Path, name: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    WEIGHTS[name](model)
    capsys.readouterr()
    code = main(["perception", "train", "--data", str(tiny_dataset), "--out", str(tmp_path / "more"), "--epochs", "1",
                 "--init-from", str(model)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "weights.npz" in err, err
    assert not (tmp_path / "more").exists()
