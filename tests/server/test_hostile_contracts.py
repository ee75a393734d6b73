"""An exported policy folder is untrusted input: a hostile ``policy_contract.json`` is refused with one
DualtwinError naming it before the server listens, never a traceback, a 500 on every request, or a /v1/info the
server changes in transit (found by mutating a real export's contract and serving it).
"""

from __future__ import annotations

import json
import shutil
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from dualtwin.cli import main
from dualtwin.errors import DualtwinError
from dualtwin.perception.onnx_policy import POLICY_CONTRACT
from dualtwin.server.app import create_app


def _repeat_first_name(c: dict[str, Any]) -> None:
    c["observation"][1]["name"] = c["observation"][0]["name"]


CONTRACTS: dict[str, tuple[Callable[[dict[str, Any]], None], str]] = {
    "action is a number": (lambda c: c.__setitem__("action", 0.5), POLICY_CONTRACT),
    "onnx is text": (lambda c: c.__setitem__("onnx", "x"), POLICY_CONTRACT),
    "control period is text": (lambda c: c.__setitem__("control_period_s", "x"), POLICY_CONTRACT),
    "control period is null": (lambda c: c.__setitem__("control_period_s", None), POLICY_CONTRACT),
    "wheel radius is text": (lambda c: c["action"].__setitem__("wheel_radius_m", "x"), POLICY_CONTRACT),
    # Each request zipped the action names with the model's command outputs: a 500 per request.
    "two action names for one command": (lambda c: c["action"].__setitem__("names", ["a", "b"]), "policy.onnx"),
    "action names is text": (lambda c: c["action"].__setitem__("names", "12"), POLICY_CONTRACT),
    # The observation is assembled by name: the policy got an input short, a 500 per request.
    "an observation name twice": (_repeat_first_name, POLICY_CONTRACT),
}


def _write(folder: Path, change: Callable[[dict[str, Any]], None]) -> None:
    path = folder / POLICY_CONTRACT
    contract = json.loads(path.read_text())
    change(contract)
    path.write_text(json.dumps(contract))


@pytest.fixture
def policy(policy_dir: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(policy_dir, tmp_path / "policy"))


@pytest.mark.parametrize("name", list(CONTRACTS))
def test_a_hostile_policy_contract_is_refused_before_serving(policy: Path, perception_dir: Path, name: str) -> None:
    change, named = CONTRACTS[name]
    _write(policy, change)
    with pytest.raises(DualtwinError, match=named.replace(".", r"\.")):
        create_app(policy, perception_dir)


def test_nan_in_a_contract_is_refused_not_served_as_null(policy: Path, perception_dir: Path) -> None:
    # json.loads reads NaN (not JSON); /v1/info, which echoes env_kwargs, silently sent it on as null.
    text = (policy / POLICY_CONTRACT).read_text()
    contract = json.loads(text)
    contract["env_kwargs"] = {"max_episode_steps": "@NAN@"}
    (policy / POLICY_CONTRACT).write_text(json.dumps(contract).replace('"@NAN@"', "NaN"))
    with pytest.raises(DualtwinError, match="NaN"):
        create_app(policy, perception_dir)


def test_serve_says_one_line(policy: Path, perception_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _write(policy, CONTRACTS["control period is text"][0])
    capsys.readouterr()
    with socket.socket() as busy:  # should the contract pass, serve stops at the busy port instead of serving
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = str(busy.getsockname()[1])
        code = main(["serve", "--policy", str(policy), "--perception", str(perception_dir), "--port", port])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and POLICY_CONTRACT in err, err
