"""Atomic, reproducible artifact writing and careful reading.

Every file appears whole or not at all, with the permissions the user's umask gives a new file. Every output
folder goes through one policy (:func:`prepare_output_dir`), every user file is read through helpers whose
errors name the file, line and column (:func:`read_json`, :func:`read_text_file`), and every log a run writes is
recorded with its row count and SHA-256 so readers can verify it (:func:`log_record`, :func:`verify_logs`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import stat
import sys
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import IO, Any

from dualtwin.errors import DualtwinError

TRACKED_PACKAGES = (
    "dualtwin", "mujoco", "numpy", "scipy", "dtaidistance", "cma", "pydantic",
    "gymnasium", "stable-baselines3", "torch", "onnxruntime",
)


@contextmanager
def atomic_open(path: Path, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary sibling of ``path`` and rename it over ``path`` only if the block succeeds."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        # mkstemp creates 0600; the renamed file must have the mode any new file gets (0666 & ~umask), so a
        # teammate or a web server can read reports when the user's umask allows it.
        os.fchmod(fd, 0o666 & ~current_umask())
        with os.fdopen(fd, mode, encoding=None if "b" in mode else "utf-8") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def current_umask() -> int:
    """The process umask, read without changing it where the platform allows (Linux ``/proc``)."""
    try:
        with open("/proc/self/status", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)  # no read-only query elsewhere: set and restore at once
    os.umask(mask)
    return mask


def write_text(path: Path, text: str) -> None:
    with atomic_open(path) as handle:
        handle.write(text)


def write_bytes(path: Path, data: bytes) -> None:
    with atomic_open(path, "wb") as handle:
        handle.write(data)


def write_json(path: Path, data: Any) -> None:
    write_text(path, json.dumps(data, indent=2, sort_keys=False, allow_nan=False) + "\n")


def json_safe(value: Any) -> Any:
    """``value`` with non-finite floats as ``None`` and tuples as lists, so strict JSON can hold it."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


def sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 16), b""):
            digest.update(chunk)
    return digest.hexdigest()


def sha256_files(paths: Iterable[Path]) -> str:
    """One hash over several files (a model and the meshes it includes, say), in the given order."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(path.name.encode())
        digest.update(sha256_file(path).encode())
    return digest.hexdigest()


def package_versions() -> dict[str, str]:
    versions = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in TRACKED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


# ------------------------------------------------------------------ reading user files
def check_input_file(path: Path, what: str = "file") -> Path:
    """``path`` if it is a regular file; otherwise a :class:`DualtwinError` saying what it is instead.

    Checked before opening: a pipe would block the reader forever and a directory raises an OS error.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise DualtwinError(f"{path}: {what} not found") from None
    except OSError as exc:
        raise DualtwinError(f"{path}: cannot read {what}: {exc.strerror}") from None
    if stat.S_ISDIR(mode):
        raise DualtwinError(f"{path}: is a directory, expected a {what}")
    if not stat.S_ISREG(mode):
        raise DualtwinError(f"{path}: is not a regular file (a pipe or device?), expected a {what}")
    return path


def read_text_file(path: Path, what: str = "file") -> str:
    """UTF-8 text of a user file; a binary file, a directory or a pipe is one clear error."""
    path = check_input_file(path, what)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DualtwinError(f"{path}: not a UTF-8 text {what} (binary data at byte {exc.start})") from None
    except OSError as exc:
        raise DualtwinError(f"{path}: cannot read {what}: {exc.strerror}") from None


def read_yaml(path: Path, what: str = "YAML file") -> Any:
    """YAML (safe loader) from a user file; errors name the file, line and column."""
    import yaml

    path = Path(path)
    text = read_text_file(path, what)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f":{mark.line + 1}:{mark.column + 1}" if mark else ""
        raise DualtwinError(f"{path}{where}: invalid YAML: {getattr(exc, 'problem', exc)}") from None


def _reject_constant(token: str) -> float:
    raise ValueError(f"{token} is not a valid JSON number (NaN and infinities are not allowed)")


def read_json(path: Path, what: str = "JSON file") -> Any:
    """Strict JSON (no NaN/Infinity tokens) from a user file; errors name the file, line and column."""
    path = Path(path)
    text = read_text_file(path, what)
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise DualtwinError(f"{path}:{exc.lineno}:{exc.colno}: invalid JSON: {exc.msg}") from None
    except ValueError as exc:
        raise DualtwinError(f"{path}: invalid JSON: {exc}") from None


def require_keys(data: Any, keys: Iterable[str], path: Path, what: str = "file") -> Mapping[str, Any]:
    """``data`` as a mapping holding every key in ``keys``; otherwise an error naming the missing ones."""
    if not isinstance(data, Mapping):
        raise DualtwinError(f"{path}: {what} must be a JSON object, not {type(data).__name__}")
    missing = [k for k in keys if k not in data]
    if missing:
        raise DualtwinError(f"{path}: {what} lacks {', '.join(repr(k) for k in missing)}")
    return data


def read_json_object(path: Path, keys: Iterable[str] = (), what: str = "JSON file") -> dict[str, Any]:
    """:func:`read_json` of a file that must hold an object with ``keys``."""
    return dict(require_keys(read_json(path, what), keys, Path(path), what))


# ------------------------------------------------------------------ output folders
#: The files that mark each command's output folder, for folders whose manifest does not name a ``kind``
#: (every writer older than this policy, and writers without a manifest). A pair ``(file, key)`` matches
#: when ``file`` exists and, if ``key`` is given, is a JSON object holding ``key``.
OUTPUT_SIGNATURES: dict[str, tuple[tuple[str, str | None], ...]] = {
    "suite-run": (("config/suite.json", None),),
    "align": (("align_config.json", None),),
    "train": (("run.json", "env_id"),),
    "collect": (("manifest.json", "shards"),),
    "perception-train": (("training.json", None),),
    "export": (("policy_contract.json", None),),
    "transfer": (("transfer.json", None),),
    "compare": (("metrics.json", None),),
    "analyze": (("analysis.json", None),),
    "lockstep": (("primary/manifest.json", None),),
    "predict-error": (("prediction.json", None),),
    "generate": (("generation.json", None),),
    "demo": (("manifest.json", "demo"),),
}


def output_kind(path: Path) -> str | None:
    """The kind of dualtwin output ``path`` holds (``manifest.json``'s ``kind``, else a signature), or None."""
    path = Path(path)
    manifest = path / "manifest.json"
    if manifest.is_file():
        try:
            kind = json.loads(manifest.read_text(encoding="utf-8")).get("kind")
        except (ValueError, AttributeError, OSError):
            kind = None
        if isinstance(kind, str):
            return kind
    for kind, signature in OUTPUT_SIGNATURES.items():
        if all(_signature_matches(path / rel, key) for rel, key in signature):
            return kind
    return None


def _signature_matches(file: Path, key: str | None) -> bool:
    if not file.is_file():
        return False
    if key is None:
        return True
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (ValueError, OSError):
        return False
    return isinstance(data, dict) and key in data


def check_output_dir(path: Path, kind: str, resume: bool = False, resumable: bool = False,
                     option: str = "--out") -> bool:
    """Decide, without touching anything, whether ``kind`` may write into ``path``; True means resume.

    One policy for every writer: an absent or empty folder is used; a folder holding this command's own
    earlier output is resumed when ``resume`` is given (and refused otherwise, saying ``--resume`` continues it
    when the command is ``resumable``); anything else is refused, because nothing a writer did not write is ever
    overwritten or deleted.
    """
    path = Path(path)
    if path.is_symlink() and not path.exists():
        raise DualtwinError(f"{option} {path}: is a broken symbolic link")
    if path.exists() and not path.is_dir():
        raise DualtwinError(f"{option} {path}: exists and is not a folder; choose a folder path")
    if not path.exists() or not any(path.iterdir()):
        return False  # with --resume too: nothing to resume is a fresh start, as the writers' own logic does
    found = output_kind(path)
    if found == kind:
        if resume and resumable:
            return True
        hint = "use --resume to continue it, or choose an empty folder" if resumable else "choose an empty folder"
        raise DualtwinError(f"{option} {path}: holds an earlier {kind} output; {hint} "
                            "(nothing is overwritten)")
    what = f"holds {found} output" if found else "is not empty"
    raise DualtwinError(f"{option} {path}: {what}, not {kind} output that this command wrote; choose an empty "
                        "or new folder (nothing is overwritten or deleted)")


def prepare_output_dir(path: Path, kind: str, resume: bool = False, resumable: bool = False,
                       option: str = "--out") -> bool:
    """:func:`check_output_dir`, then create the folder; call it after every other input is validated."""
    resuming = check_output_dir(path, kind, resume=resume, resumable=resumable, option=option)
    Path(path).mkdir(parents=True, exist_ok=True)
    return resuming


def remove_output_dir(path: Path, kind: str) -> None:
    """Delete ``path`` only if it holds ``kind`` output (a sub-run a command re-makes inside its own output
    folder); anything else is refused, so a wrong path can never cost the user a folder."""
    import shutil

    path = Path(path)
    if not path.exists():
        return
    if path.is_dir() and not path.is_symlink() and not any(path.iterdir()):
        path.rmdir()  # an empty folder (a run that died before writing anything)
        return
    if path.is_symlink() or not path.is_dir() or output_kind(path) != kind:
        raise DualtwinError(f"{path}: not {kind} output written by dualtwin; refusing to replace it")
    shutil.rmtree(path)


def check_output_file(path: Path, option: str = "--out", marker: str | None = None) -> None:
    """A file a command will write: its folder must not be a file, and an existing file is replaced only if
    it holds ``marker`` (text this command writes into every file it makes), so no foreign file is lost."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        if path.is_dir():
            raise DualtwinError(f"{option} {path}: is a folder, expected a file path")
        try:
            head = path.read_bytes()[:4096].decode("utf-8", "replace")
        except OSError:
            head = ""
        if marker is None or marker not in head:
            raise DualtwinError(f"{option} {path}: exists and was not written by this command; choose a new "
                                "file name (nothing is overwritten)")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise DualtwinError(f"{option} {path}: {parent} is a file, not a folder")
            break


# ------------------------------------------------------------------ log records (row counts and hashes)
def count_rows(path: Path) -> int:
    """Data rows of a TSV/CSV log: its lines after the header line."""
    with open(path, "rb") as handle:
        lines = sum(chunk.count(b"\n") for chunk in iter(lambda: handle.read(1 << 16), b""))
    return max(lines - 1, 0)


def log_record(path: Path) -> dict[str, Any]:
    """What a manifest records about a log so that any reader can verify it: data rows, bytes and SHA-256."""
    return {"rows": count_rows(path), "bytes": Path(path).stat().st_size, "sha256": sha256_file(path)}


def verify_logs(folder: Path, logs: Mapping[str, Any], where: Path | None = None) -> None:
    """Check every log named in a manifest's ``logs`` record (relative path → :func:`log_record`).

    A missing file, a different row count (a file cut short) or a different hash (an edited value, a ``nan``
    written in) is a :class:`DualtwinError` naming the file. Paths are confined to ``folder``.
    """
    folder = Path(folder)
    where = where or folder / "manifest.json"
    if not isinstance(logs, Mapping):
        raise DualtwinError(f"{where}: 'logs' must be an object of file records")
    root = folder.resolve()
    for rel, record in logs.items():
        file = (folder / rel).resolve()
        if not file.is_relative_to(root):
            raise DualtwinError(f"{where}: log path {rel!r} leaves the run folder")
        if not isinstance(record, Mapping) or "sha256" not in record:
            raise DualtwinError(f"{where}: log record for {rel!r} lacks 'sha256'")
        if not file.is_file():
            raise DualtwinError(f"{folder / rel}: log named in the manifest is missing")
        rows = record.get("rows")
        if rows is not None and count_rows(file) != rows:
            raise DualtwinError(f"{folder / rel}: has {count_rows(file)} data rows, the manifest records {rows} "
                                "(cut short or extended after the run)")
        if sha256_file(file) != record["sha256"]:
            raise DualtwinError(f"{folder / rel}: content differs from the manifest's SHA-256 "
                                "(modified after the run)")
