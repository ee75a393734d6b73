"""A dataset folder is untrusted input: a hostile manifest or shard is one DualtwinError naming the file, never a
traceback, and no shard is read from outside the folder (found by mutating a real dataset's manifest and shards).

Each case edits a copy of a real collected dataset and, where the shard changes, records the new sha256 in the
manifest as its author could: the checks must not rely on the hash.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualtwin.artifacts import sha256_file
from dualtwin.cli import main
from dualtwin.errors import DualtwinError
from dualtwin.perception.dataset import load_dataset

pytestmark = pytest.mark.usefixtures("headless")


def _edit_manifest(folder: Path, change: Callable[[dict[str, Any]], None]) -> None:
    path = folder / "manifest.json"
    manifest = json.loads(path.read_text())
    change(manifest)
    path.write_text(json.dumps(manifest))


def _edit_shard(folder: Path, change: Callable[[dict[str, np.ndarray]], None] | None = None,
                raw: Callable[[bytes], bytes] | None = None) -> None:
    shard = folder / "shard-00000.npz"
    if change is not None:
        with np.load(shard) as data:
            arrays = {k: data[k] for k in data.files}
        change(arrays)
        with open(shard, "wb") as handle:
            np.savez(handle, **arrays)  # type: ignore[arg-type]
    if raw is not None:
        shard.write_bytes(raw(shard.read_bytes()))
    _edit_manifest(folder, lambda m: m["shards"][0].update(sha256=sha256_file(shard)))


def _set(key: str, value: Any) -> Callable[[dict[str, Any]], None]:
    return lambda m: m["shards"][0].__setitem__(key, value)


def _object_masks(a: dict[str, np.ndarray]) -> None:
    a["masks"] = np.array([{"x": 1}] * len(a["masks"]), dtype=object)


def _negative_steps(a: dict[str, np.ndarray]) -> None:
    a["step"] = a["step"] - 7


MANIFESTS: dict[str, Callable[[dict[str, Any]], None]] = {
    "shard is a string": lambda m: m["shards"].__setitem__(0, ""),
    "file is a number": _set("file", 10**30),
    "episode ids are a number": _set("episode_ids", 5),
    "episodes reversed": _set("episodes", [1, 0]),
    "seed is text": lambda m: m.__setitem__("seed", "x"),
}
SHARDS: dict[str, dict[str, Any]] = {
    "truncated": {"raw": lambda b: b[: len(b) // 2]},
    "object array": {"change": _object_masks},
    "missing array": {"change": lambda a: a.pop("step")},
    "frames flattened": {"change": lambda a: a.__setitem__("frames", a["frames"].reshape(len(a["frames"]), -1))},
    "scalar time": {"change": lambda a: a.__setitem__("time_s", np.zeros(()))},
    "text labels": {"change": lambda a: a.__setitem__("state", np.array(["x"] * len(a["state"])))},
    "negative steps": {"change": _negative_steps},
}


@pytest.fixture
def copy(tiny_dataset: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(tiny_dataset, tmp_path / "data"))


@pytest.mark.parametrize("name", list(MANIFESTS))
def test_a_hostile_manifest_is_one_error_naming_it(copy: Path, name: str) -> None:
    _edit_manifest(copy, MANIFESTS[name])
    with pytest.raises(DualtwinError, match="manifest.json"):
        load_dataset(copy)


@pytest.mark.parametrize("name", list(SHARDS))
def test_a_hostile_shard_is_one_error_naming_it(copy: Path, name: str) -> None:
    _edit_shard(copy, **SHARDS[name])
    with pytest.raises(DualtwinError, match="shard-00000.npz"):
        load_dataset(copy)


@pytest.mark.parametrize("where", ["parent", "absolute", "symlink"])
def test_no_shard_is_read_from_outside_the_dataset_folder(copy: Path, tmp_path: Path, where: str) -> None:
    outside = tmp_path / "outside.npz"
    shutil.copy(copy / "shard-00000.npz", outside)  # a valid shard, with the hash the manifest records
    if where == "symlink":
        (copy / "shard-00000.npz").unlink()
        (copy / "shard-00000.npz").symlink_to(outside)
    else:
        name = "../outside.npz" if where == "parent" else str(outside)
        _edit_manifest(copy, _set("file", name))
    with pytest.raises(DualtwinError, match="outside"):
        load_dataset(copy)


def test_the_cli_says_one_line_and_writes_nothing(copy: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    _edit_shard(copy, change=_object_masks)
    capsys.readouterr()
    code = main(["perception", "train", "--data", str(copy), "--out", str(tmp_path / "model"), "--epochs", "1"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "shard-00000.npz" in err, err
    assert not (tmp_path / "model").exists()
