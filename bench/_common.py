"""What the benchmarks share: where they write, and best-of-N timing."""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
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


def best_of(fn: Callable[[], object], repeats: int) -> float:
    """The shortest wall time of ``repeats`` calls: the least disturbed by other load on the machine."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best
