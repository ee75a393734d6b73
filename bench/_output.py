"""Where a benchmark writes: the folder an environment variable names (kept), else a temporary one (removed)."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def output_folder(variable: str, name: str) -> Iterator[tuple[Path, bool]]:
    """(folder, kept): ``$variable`` if set, kept afterwards; otherwise a temporary folder removed at the end."""
    keep = os.environ.get(variable)
    root = Path(keep) if keep else Path(tempfile.mkdtemp(prefix=f"dualtwin-bench-{name}-"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        yield root, bool(keep)
    finally:
        if not keep:
            shutil.rmtree(root, ignore_errors=True)
