"""``dualtwin lockstep --policy`` reads the exported policy's ``policy_contract.json``, an untrusted file: its env
arguments build the task on both twins, so a wrong type or name there is one line naming the file and field,
exit 2, no run folder; before, a string ``env_kwargs``, a list ``action``, a number ``task_kwargs`` or an unknown
or mistyped task argument was a traceback (found by mutating an exported policy's contract).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from dualtwin.cli import main
from tests.support.sync_helpers import sign_policy

pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

CONTRACTS: dict[str, tuple[Callable[[dict[str, Any]], None], str]] = {
    "env_kwargs is text": (lambda c: c.__setitem__("env_kwargs", "abc"), "$.env_kwargs"),
    "env_kwargs is a list": (lambda c: c.__setitem__("env_kwargs", [1]), "$.env_kwargs"),
    "action is a list": (lambda c: c.__setitem__("action", [1]), "$.action"),
    "task_kwargs is a number": (lambda c: c.__setitem__("env_kwargs", {"task_kwargs": 5}),
                                "$.env_kwargs.task_kwargs"),
    "unknown task argument": (lambda c: c.__setitem__("env_kwargs", {"task_kwargs": {"bogus": 1}}),
                              "$.env_kwargs.task_kwargs.bogus"),
    "task argument of another type": (lambda c: c.__setitem__("env_kwargs", {"task_kwargs": {"x_limit": "abc"}}),
                                      "$.env_kwargs.task_kwargs.x_limit"),
}


@pytest.mark.parametrize("name", list(CONTRACTS))
def test_a_hostile_policy_contract_is_one_line(tmp_path: Path, name: str, capfd: pytest.CaptureFixture[str]) -> None:
    change, field = CONTRACTS[name]
    folder = sign_policy(tmp_path / "policy")
    contract = json.loads((folder / "policy_contract.json").read_text())
    change(contract)
    (folder / "policy_contract.json").write_text(json.dumps(contract))
    capfd.readouterr()
    code = main(["lockstep", "--robot", "cartpole", "--policy", str(folder), "--episodes", "1",
                 "--out", str(tmp_path / "out")])
    err = capfd.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "policy_contract.json" in err and field in err, err
    assert not (tmp_path / "out").exists()
