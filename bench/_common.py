"""What the benchmarks share: where they write, best-of-N timing, and the RL benches' training run."""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType


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


def cpu_time(fn: Callable[[], object]) -> float:
    """CPU seconds of one call. For single-threaded loops CPU time, unlike wall time, leaves out the time other
    work on the machine holds the core."""
    start = time.process_time()
    fn()
    return time.process_time() - start


def physics_files(robot_name: str, modules: Sequence[ModuleType]) -> dict[str, str]:
    """Short sha256 of a bundled robot's files (binding and each twin's model) and of ``modules``: what an RL
    number was measured with."""
    from dualtwin.artifacts import sha256_file
    from dualtwin.robots.binding import resolve_robot

    robot = resolve_robot(robot_name)
    paths = [Path(robot.path), *(Path(robot.root) / str(section.model) for section in robot.spec.twins.values()),
             *(Path(str(module.__file__)) for module in modules)]
    return {p.name: sha256_file(p)[:16] for p in paths}


def training_run(root: Path, reuse_variable: str, env_id: str, config: str | Path, name: str) -> tuple[Path, bool]:
    """(run, reused): the training run in ``$reuse_variable`` if set, else PPO trained now on ``env_id`` with
    ``config`` (seed 0) into ``root/name``."""
    given = os.environ.get(reuse_variable)
    if given:
        return Path(given), True
    from dualtwin.rl.train import train

    out = root / name
    if out.exists():
        shutil.rmtree(out)  # the bench's own folder from an earlier run of this bench
    train(env_id, config, out, seed=0, progress_bar=False)
    return out, False


def eval_success_rates(run: Path) -> list[float] | None:
    """The success rate of each of a training run's evaluations, or None when it logged no successes."""
    import numpy as np

    if not (run / "evaluations.npz").is_file():
        return None
    with np.load(run / "evaluations.npz") as data:
        return data["successes"].mean(axis=1).tolist() if "successes" in data else None
