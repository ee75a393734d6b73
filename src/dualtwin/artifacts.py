"""Atomic, reproducible artifact writing and careful reading.

Every file appears whole or not at all, with the permissions the user's umask gives a new file. Every output
folder goes through one policy (:func:`prepare_output_dir`), every user file is read through helpers whose
errors name the file, line and column (:func:`read_json`, :func:`read_text_file`), and every log a run writes is
recorded with its row count and SHA-256 so readers can verify it (:func:`log_record`, :func:`verify_logs`).
"""

from __future__ import annotations

import functools
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


class WriteFailed(OSError):
    """Writing a file failed in the operating system (a full disk, an I/O error, a read-only folder...).

    Raised with the path of the file that was being written (``filename``) and the system's reason, so the CLI
    says which file could not be written in one line; the file itself was left as it was (or absent).
    """


def write_failed(exc: OSError, path: Path) -> WriteFailed:
    """``exc`` (errno and reason kept) as a :class:`WriteFailed` naming ``path``."""
    return WriteFailed(exc.errno or 0, exc.strerror or str(exc), str(path))


@contextmanager
def atomic_open(path: Path, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary sibling of ``path`` and rename it over ``path`` only if the block succeeds.

    An OS error on the way (ENOSPC, EIO...) removes the temporary file and becomes a :class:`WriteFailed`
    naming ``path``: a write on a full disk leaves the previous file (or none), never half a file.
    """
    path = Path(path)
    tmp: str | None = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        # mkstemp creates 0600; the renamed file must have the mode any new file gets (0666 & ~umask), so a
        # teammate or a web server can read reports when the user's umask allows it.
        os.fchmod(fd, 0o666 & ~current_umask())
        with os.fdopen(fd, mode, encoding=None if "b" in mode else "utf-8") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and not isinstance(exc, WriteFailed | FileNotFoundError):
            raise write_failed(exc, path) from None
        raise


def copy_file(source: Path, target: Path) -> None:
    """Copy ``source`` to ``target`` atomically (whole or not at all, like every other write)."""
    with atomic_open(Path(target), "wb") as handle, open(source, "rb") as src:
        for chunk in iter(lambda: src.read(1 << 20), b""):
            handle.write(chunk)


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
    """The interpreter, platform and tracked packages' versions (a fresh dict each call)."""
    return dict(_package_versions())


@functools.cache
def _package_versions() -> tuple[tuple[str, str], ...]:
    # Read once per process: every run folder and record a command writes names them (an alignment writes
    # four), and each lookup scans the installed distributions; they do not change while a command runs.
    versions = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in TRACKED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return tuple(versions.items())


# ------------------------------------------------------------------ reading user files
#: Limits on structured input files (JSON, YAML): far beyond any real suite, config or manifest, and far below
#: what would exhaust memory or the interpreter's stack. A file past either is refused with one line.
MAX_INPUT_BYTES = 64 * 1024 * 1024
MAX_JSON_DEPTH = 64
#: Values a YAML document may hold once its aliases are expanded ("billion laughs" stays a one-line error).
MAX_YAML_VALUES = 10_000_000


def check_size(path: Path, what: str = "file", max_bytes: int = MAX_INPUT_BYTES) -> None:
    """Refuse a regular file larger than ``max_bytes`` before reading it."""
    try:
        size = Path(path).stat().st_size
    except OSError:
        return  # the reader says what is wrong with it
    if size > max_bytes:
        raise DualtwinError(f"{path}: {what} is {size} bytes; at most {max_bytes} are read")


class _DuplicateKey(ValueError):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def _unique_key_loader() -> Any:
    """PyYAML's safe loader, refusing a mapping with the same key twice (naming both lines)."""
    import yaml

    class UniqueKeyLoader(yaml.SafeLoader):
        pass

    def construct_mapping(loader: Any, node: Any, deep: bool = False) -> Any:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = loader.construct_object(key_node, deep=deep)
            line = key_node.start_mark.line + 1
            try:
                if key in seen:
                    raise _DuplicateKey(f"duplicate key {key!r} at lines {seen[key]} and {line} (the same mapping)")
                seen[key] = line
            except TypeError:  # an unhashable key: the base constructor says what is wrong with it
                break
        return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)

    UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, construct_mapping)
    return UniqueKeyLoader


def nesting_depth(data: Any) -> int:
    """How many containers deep ``data`` goes (a scalar is 0), without recursion.

    Shared containers (YAML anchors) are measured once, so an "exponential" document costs linear time; a
    container holding itself (a YAML alias cycle) counts as infinitely deep.
    """
    return _shape(data)[0]


def expanded_size(data: Any) -> int:
    """How many values ``data`` holds once every shared container (YAML alias) is expanded."""
    return _shape(data)[1]


def _shape(data: Any) -> tuple[int, int]:
    def children(item: Any) -> list[Any]:
        values = item.values() if isinstance(item, dict) else item
        return [c for c in values if isinstance(c, dict | list)]

    if not isinstance(data, dict | list):
        return 0, 1
    done: dict[int, tuple[int, int]] = {}
    open_: set[int] = set()
    stack: list[tuple[Any, bool]] = [(data, False)]
    while stack:
        item, closing = stack.pop()
        key = id(item)
        if closing:
            open_.discard(key)
            inner = [done[id(c)] for c in children(item)]
            scalars = len(item) - len(inner)
            done[key] = (1 + max((d for d, _ in inner), default=0), 1 + scalars + sum(n for _, n in inner))
            continue
        if key in done:
            continue
        if key in open_:
            return 10**9, 10**18  # a cycle
        open_.add(key)
        stack.append((item, True))
        stack.extend((c, False) for c in children(item) if id(c) not in done)
    return done[id(data)]


def duplicate_key_lines(text: str, key: str) -> str:
    """Where ``key`` appears twice in one object of the JSON ``text``: 'duplicate key ... at lines A and B'.

    Only called once the parser found the duplicate, so a plain scan suffices: strings, brackets and colons
    are tracked and the keys of every open object remembered with their line.
    """
    import re

    token = re.compile(r'"(?:[^"\\]|\\.)*"|[{}\[\]:,]|\n')
    line = 1
    stack: list[dict[str, int] | None] = []  # per open container: None for a list, else {key: line}
    last_string: tuple[str, int] | None = None
    for match in token.finditer(text):
        tok = match.group()
        if tok == "\n":
            line += 1
        elif tok in "{[":
            stack.append({} if tok == "{" else None)
        elif tok in "}]":
            if stack:
                stack.pop()
        elif tok == ":" and last_string is not None and stack and stack[-1] is not None:
            name, at = last_string
            if name == key and name in stack[-1]:
                return f"duplicate key {key!r} at lines {stack[-1][name]} and {at} (the same object)"
            stack[-1][name] = at
        if tok.startswith('"'):
            try:
                last_string = (json.loads(tok), line)
            except ValueError:
                last_string = None
        elif tok != "\n":
            last_string = None if tok != ":" else last_string
    return f"duplicate key {key!r} in one object"
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


def resolved(path: Path) -> Path:
    """``path.resolve()`` for a path a user or a document named: a symbolic link that leads back to itself (a
    loop) is one clear error naming the path. Python 3.11 and 3.12's pathlib raise ``RuntimeError`` for a loop,
    which is no user's error to read as a traceback; from 3.13 the loop is left unresolved, and whoever opens
    the file gets ``OSError`` (``ELOOP``), which names it."""
    try:
        return Path(path).resolve()
    except RuntimeError:
        raise DualtwinError(f"{path}: a symbolic link loop (the link leads back to itself)") from None


def confined_file(folder: Path, name: Any, where: str) -> Path:
    """``folder / name`` for a file name read from an untrusted document in ``folder`` (a manifest, a contract).

    The name must be a plain relative path that stays inside ``folder`` once resolved: ``..``, an absolute
    path or a symbolic link leading out of the folder would make the reader open a file the document's author
    chose anywhere on this machine. A :class:`DualtwinError` names ``where`` (file and field) otherwise.
    """
    if not isinstance(name, str) or not name or "\x00" in name:
        raise DualtwinError(f"{where}: expected a file name inside {folder}, got {name!r}")
    root = resolved(Path(folder))
    path = resolved(root / name)
    if Path(name).is_absolute() or not path.is_relative_to(root):
        raise DualtwinError(f"{where}: {name!r} points outside {folder}; refused")
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
    check_size(path, what)
    text = read_text_file(path, what)
    try:
        data = yaml.load(text, Loader=_unique_key_loader())  # noqa: S506 -- a SafeLoader subclass
    except _DuplicateKey as exc:
        raise DualtwinError(f"{path}: {exc.args[0]}") from None
    except RecursionError:
        raise DualtwinError(f"{path}: {what} is nested too deeply (at most {MAX_JSON_DEPTH} levels)") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f":{mark.line + 1}:{mark.column + 1}" if mark else ""
        raise DualtwinError(f"{path}{where}: invalid YAML: {getattr(exc, 'problem', exc)}") from None
    depth, size = _shape(data)
    if depth > MAX_JSON_DEPTH:
        raise DualtwinError(f"{path}: {what} is nested too deeply (at most {MAX_JSON_DEPTH} levels)")
    if size > MAX_YAML_VALUES:
        raise DualtwinError(f"{path}: {what} expands to more than {MAX_YAML_VALUES} values (aliases of aliases)")
    return data


def _reject_constant(token: str) -> float:
    raise ValueError(f"{token} is not a valid JSON number (NaN and infinities are not allowed)")


def read_json(path: Path, what: str = "JSON file", max_bytes: int = MAX_INPUT_BYTES) -> Any:
    """Strict JSON from a user file; errors name the file, line and column.

    Refused: NaN/Infinity tokens (a number too large for a double reads as infinity, which the schema
    validators refuse naming its JSON path), an object with the same key twice
    (JSON parsers disagree on which one wins; the error names both lines), nesting deeper than
    :data:`MAX_JSON_DEPTH` and files larger than ``max_bytes`` (no input of ours is near either limit).
    """
    path = Path(path)
    check_size(path, what, max_bytes)
    text = read_text_file(path, what)
    try:
        data = json.loads(text, parse_constant=_reject_constant, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as exc:
        raise DualtwinError(f"{path}:{exc.lineno}:{exc.colno}: invalid JSON: {exc.msg}") from None
    except _DuplicateKey as exc:
        raise DualtwinError(f"{path}: {duplicate_key_lines(text, exc.key)}") from None
    except RecursionError:
        raise DualtwinError(f"{path}: {what} is nested too deeply (at most {MAX_JSON_DEPTH} levels)") from None
    except ValueError as exc:
        raise DualtwinError(f"{path}: invalid JSON: {exc}") from None
    if nesting_depth(data) > MAX_JSON_DEPTH:
        raise DualtwinError(f"{path}: {what} is nested too deeply (at most {MAX_JSON_DEPTH} levels)")
    return data


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
    root = resolved(folder)
    for rel, record in logs.items():
        file = resolved(folder / rel)
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
