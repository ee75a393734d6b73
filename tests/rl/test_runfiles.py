"""Run folders are data: loading one never unpickles anything unless the user says they trust it.

Each malicious file below carries a pickle whose ``__reduce__`` writes a marker file; the marker must never
appear when the tool refuses (or ignores) it, and does appear when the user trusts the file, so the tests
would notice a loader that unpickles.
"""

from __future__ import annotations

import base64
import json
import pickle
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.errors import DualtwinError
from dualtwin.rl.policy import load_policy
from dualtwin.rl.runfiles import load_normalization, serialized_entries, trusting_pickles


class _Marker:
    """Unpickling this creates ``path`` (through ``pathlib.Path.touch``): proof that code ran."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        return (Path.touch, (self.path,))


def _evil(marker: Path) -> bytes:
    return pickle.dumps(_Marker(marker))


def _copy(run: Path, tmp: Path) -> Path:
    dest = tmp / "copy"
    shutil.copytree(run, dest)
    return dest


def _rewrite_zip(path: Path, edit: dict[str, bytes]) -> None:
    """Replace entries of a zip (``data``, ``policy.pth``...) keeping the others byte for byte."""
    with zipfile.ZipFile(path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    entries.update(edit)
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in entries.items():
            archive.writestr(name, content)


def _poison_data(path: Path, marker: Path, extra: str | None = None) -> list[str]:
    """Every cloudpickled entry of the model's data replaced by the marker pickle (plus ``extra``, if given)."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    payload = base64.b64encode(_evil(marker)).decode()
    poisoned = [k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v]
    for key in poisoned:
        data[key][":serialized:"] = payload
    if extra is not None:
        data[extra] = {":type:": "<class 'object'>", ":serialized:": payload}
        poisoned.append(extra)
    _rewrite_zip(path, {"data": json.dumps(data).encode()})
    return poisoned


def test_new_runs_hold_no_pickled_statistics(discrete_run: Path) -> None:
    assert not list(discrete_run.rglob("*.pkl"))
    stats = json.loads((discrete_run / "vecnormalize.json").read_text())
    assert stats["format"] == "dualtwin-vecnormalize/1" and len(stats["obs_rms"]["mean"]) == 4
    policy = load_policy(discrete_run)
    assert policy.vec_normalize is not None
    rms: Any = policy.vec_normalize.obs_rms
    np.testing.assert_array_equal(rms.mean, np.asarray(stats["obs_rms"]["mean"]))


def test_a_pickled_normalisation_file_is_refused_unless_trusted(discrete_run: Path, tmp_path: Path) -> None:
    run = _copy(discrete_run, tmp_path)
    marker = tmp_path / "pwned"
    for stem in ("vecnormalize", "best_vecnormalize"):
        (run / f"{stem}.json").unlink()
        (run / f"{stem}.pkl").write_bytes(_evil(marker))
    with pytest.raises(DualtwinError, match="refusing to unpickle.*--trust-pickles"):
        load_policy(run)
    with pytest.raises(DualtwinError, match="refusing to unpickle"):
        load_normalization(run / "vecnormalize.pkl")
    assert not marker.exists()
    # Trusting it runs it: the marker shows the refusal above is what kept the code from running.
    with trusting_pickles(), pytest.raises(Exception):  # noqa: B017,PT011 - the touch() result is no VecNormalize
        load_policy(run)
    assert marker.exists()


def test_a_legacy_run_loads_with_trust(discrete_run: Path, tmp_path: Path) -> None:
    """A run written before the JSON statistics (SB3's own pickle) loads when the user trusts it."""
    run = _copy(discrete_run, tmp_path)
    policy = load_policy(run)
    assert policy.vec_normalize is not None
    policy.vec_normalize.save(str(run / "vecnormalize.pkl"))  # SB3's format, as old runs have it
    (run / "vecnormalize.json").unlink()
    with pytest.raises(DualtwinError, match="trust-pickles"):
        load_policy(run)
    legacy = load_policy(run, trust_pickles=True)
    assert legacy.vec_normalize is not None
    old: Any = legacy.vec_normalize.obs_rms
    new: Any = policy.vec_normalize.obs_rms
    np.testing.assert_allclose(old.var, new.var)


@pytest.mark.parametrize("which", ["final", "best"])
def test_the_model_zip_is_loaded_without_unpickling_its_data(discrete_run: Path, tmp_path: Path, which: str) -> None:
    run = _copy(discrete_run, tmp_path)
    marker = tmp_path / "pwned"
    name = "model.zip" if which == "final" else "best_model.zip"
    # What SB3 cloudpickles today; if a new SB3 adds an entry, the loader must rebuild it too (or refuse).
    assert {"policy_class", "policy_kwargs", "observation_space", "action_space", "lr_schedule",
            "clip_range"} <= set(serialized_entries(run / name))
    poisoned = _poison_data(run / name, marker)
    policy = load_policy(run, which)  # type: ignore[arg-type]
    obs, _ = policy.make_env().reset(seed=0)
    assert int(policy.predict(obs)) in (0, 1)
    assert not marker.exists(), f"unpickled one of {poisoned}"


def test_an_unknown_pickled_entry_is_refused_unless_trusted(discrete_run: Path, tmp_path: Path) -> None:
    run = _copy(discrete_run, tmp_path)
    marker = tmp_path / "pwned"
    _poison_data(run / "model.zip", marker, extra="surprise")
    with pytest.raises(DualtwinError, match="refusing to unpickle surprise"):
        load_policy(run)
    assert not marker.exists()
    load_policy(run, trust_pickles=True)
    assert marker.exists()


def test_a_weights_entry_that_is_not_plain_tensors_is_refused(discrete_run: Path, tmp_path: Path) -> None:
    run = _copy(discrete_run, tmp_path)
    marker = tmp_path / "pwned"
    _rewrite_zip(run / "model.zip", {"policy.pth": _evil(marker)})
    for trust in (False, True):  # weights are never unpickled, whatever the user trusts
        with pytest.raises(DualtwinError, match="not plain tensors"):
            load_policy(run, trust_pickles=trust)
    assert not marker.exists()


def test_a_run_whose_record_does_not_describe_the_model_is_refused(discrete_run: Path, tmp_path: Path) -> None:
    run = _copy(discrete_run, tmp_path)
    record = json.loads((run / "run.json").read_text())
    del record["config"]
    (run / "run.json").write_text(json.dumps(record))
    with pytest.raises(DualtwinError, match="refusing to unpickle .*policy_class"):
        load_policy(run)


@pytest.mark.parametrize("entry, value", [("clip_range_vf", 0), ("clip_range", {}), ("n_steps", "many")])
def test_plain_values_sb3_rejects_in_the_model_data_are_one_error(discrete_run: Path, tmp_path: Path, entry: str,
                                                                  value: object) -> None:
    """The zip's ``data`` entry is JSON anyone can edit; SB3 checks some values with assertions. Before, such a
    value escaped ``export`` and ``transfer`` as an AssertionError (or TypeError) traceback."""
    run = _copy(discrete_run, tmp_path)
    with zipfile.ZipFile(run / "model.zip") as archive:
        data = json.loads(archive.read("data"))
    data[entry] = value
    _rewrite_zip(run / "model.zip", {"data": json.dumps(data).encode()})
    with pytest.raises(DualtwinError, match=r"model.zip: cannot load the model: \w+Error"):
        load_policy(run)


def test_a_run_record_with_nan_is_refused_before_anything_is_exported(discrete_run: Path, tmp_path: Path) -> None:
    """Python's json reads NaN; the run record's reader now refuses it (our writer never writes one). Before, a
    NaN in the I/O contract reached the contract's writer: a traceback, after policy.onnx was written."""
    run = _copy(discrete_run, tmp_path)
    text = (run / "run.json").read_text()
    record = json.loads(text)
    record["io"]["observation"]["terms"][1]["index"] = float("nan")
    (run / "run.json").write_text(json.dumps(record))
    result = subprocess.run([sys.executable, "-m", "dualtwin.cli", "export", "--policy", str(run), "--out",
                             str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert result.stderr.count("\n") == 1 and "run.json" in result.stderr and "NaN" in result.stderr
    assert not (tmp_path / "out").exists()


def test_cli_refuses_a_legacy_run_in_one_line_and_trusts_it_on_request(discrete_run: Path, tmp_path: Path) -> None:
    run = _copy(discrete_run, tmp_path)
    load_policy(run).vec_normalize.save(str(run / "vecnormalize.pkl"))  # type: ignore[union-attr]
    (run / "vecnormalize.json").unlink()
    command = [sys.executable, "-m", "dualtwin.cli", "export", "--policy", str(run)]
    result = subprocess.run([*command, "--out", str(tmp_path / "refused")], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.startswith("error: ") and "--trust-pickles" in result.stderr
    assert not (tmp_path / "refused").exists()
    result = subprocess.run([*command, "--out", str(tmp_path / "trusted"), "--trust-pickles"], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "trusted" / "policy.onnx").is_file()


def test_statistics_without_observation_normalisation(tmp_path: Path) -> None:
    """The published-controller config scales observations itself (norm_obs false): only reward statistics."""
    from tests.support.rl_runs import train_tiny

    run = train_tiny(tmp_path / "run", "dualtwin/CartPole-MuJoCo-v0", 512,
                 {"normalize": {"norm_obs": False, "norm_reward": True}, "checkpoint_freq": 256})
    stats = json.loads((run / "vecnormalize.json").read_text())
    assert stats["obs_rms"] is None and stats["ret_rms"]["count"] > 0
    policy = load_policy(run)
    obs, _ = policy.make_env().reset(seed=0)
    np.testing.assert_array_equal(policy.normalize(obs), obs)
    assert int(policy.predict(obs)) in (0, 1)


def test_loaders_of_other_commands_follow_the_trust_setting(discrete_run: Path, tmp_path: Path) -> None:
    """lockstep --policy and collect --policy load runs through dualtwin.sync; --trust-pickles reaches them."""
    from dualtwin.sync.policy import load_policy as load_for_lockstep

    run = _copy(discrete_run, tmp_path)
    load_policy(run).vec_normalize.save(str(run / "vecnormalize.pkl"))  # type: ignore[union-attr]
    (run / "vecnormalize.json").unlink()
    with pytest.raises(DualtwinError, match="trust-pickles"):
        load_for_lockstep(run)
    with trusting_pickles():
        assert load_for_lockstep(run).env_id == "dualtwin/CartPole-MuJoCo-v0"
    with pytest.raises(DualtwinError, match="trust-pickles"):  # the setting ends with its block
        load_for_lockstep(run)
