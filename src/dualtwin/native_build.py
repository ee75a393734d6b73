"""Compile a C source of the package into a shared library once, with the system C compiler, into a cache.

Used by the MuJoCo motor plugin (``twins/native/webots_motor.c``) and the guarded ODE step
(``webots/native/ode_guard.c``). The library is compiled on first use, not when the package installs, so an
editable install and a wheel behave the same; a machine without a compiler (``cc``; Debian: ``gcc`` and
``libc6-dev``) gets a :class:`~dualtwin.errors.DualtwinError` saying so, and each caller falls back to what it
did before. Libraries go to ``$DUALTWIN_CACHE/native`` (default ``~/.cache/dualtwin/native``), named after a
digest of the source (and whatever else the caller says the build depends on).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from dualtwin.errors import DualtwinError

__all__ = ["cache_dir", "compile_library", "library_path"]


def cache_dir() -> Path:
    """Where compiled libraries are kept."""
    root = os.environ.get("DUALTWIN_CACHE") or Path.home() / ".cache" / "dualtwin"
    return Path(root) / "native"


def library_path(source: Path, stem: str, depends_on: str = "") -> Path:
    """The cached library of ``source``: ``<stem>-<digest of the source and depends_on>.so``."""
    digest = hashlib.sha256(source.read_bytes() + depends_on.encode()).hexdigest()[:16]
    return cache_dir() / f"{stem}-{digest}.so"


def compile_library(source: Path, target: Path, flags: Sequence[str] = (), what: str = "a native library") -> Path:
    """Compile ``source`` into the shared library ``target`` (nothing to do when it exists); returns it.

    Raises:
        DualtwinError: no C compiler, or the compilation failed (its first lines of errors)."""
    if target.exists():
        return target
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise DualtwinError("no C compiler (cc) on PATH: install gcc (Debian: apt-get install gcc libc6-dev)")
    target.parent.mkdir(parents=True, exist_ok=True)
    # Compile to a private name and rename: concurrent first uses never load a half-written library.
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        out = Path(tmp) / target.name
        command = [compiler, "-O2", "-shared", "-fPIC", "-std=c11", "-o", str(out), str(source), *flags]
        result = subprocess.run(command, capture_output=True, text=True, check=False)
        if result.returncode != 0:
            raise DualtwinError(f"building {what} failed: {result.stderr.strip()[:400]}")
        os.replace(out, target)
    return target
