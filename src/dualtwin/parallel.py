"""One parallel map for every package that simulates many times: serially, in a process pool, or on Ray.

Alignment (`dualtwin.align.simulate`) and suite ensembles (`dualtwin.suite.ensemble`) both run many
independent simulations. They share this executor so a campaign that outgrows one machine moves to a Ray
cluster with one option (``--executor ray``), whichever command started it. This module sits below every
other package (it imports only `dualtwin.errors`), so the suite layer can use it without importing align.

Decisions:

* The process pool uses the ``forkserver`` start method (no fork of a threaded parent) and keeps its
  workers for the executor's lifetime, so a worker that caches a twin builds it once. Modules named in
  ``preload`` are imported by the fork server before it forks workers.
* As with any non-fork start method, a script that maps in a process pool must guard its entry point with
  ``if __name__ == "__main__":`` because workers import the main module.
* Results come back in input order for every kind, so the same inputs give the same outputs whatever runs
  them.
* Ray workers must see the same paths (a shared file system) and have dualtwin installed.
"""

from __future__ import annotations

import importlib.util
import math
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, Literal, TypeVar

from dualtwin.errors import DualtwinError

ExecutorKind = Literal["serial", "process", "ray"]
EXECUTORS: tuple[str, ...] = ("serial", "process", "ray")
#: Default worker count: the project machines have 2 cores shared with other work.
DEFAULT_WORKERS = 2

T = TypeVar("T")
R = TypeVar("R")

_NO_RAY = "executor 'ray' needs Ray, which is not installed: pip install 'dualtwin[ray]'"


def check_executor(kind: str) -> None:
    """Fail early, before anything is simulated, on an unknown executor or a missing optional dependency."""
    if kind not in EXECUTORS:
        raise DualtwinError(f"unknown executor {kind!r}; use one of {', '.join(EXECUTORS)}")
    if kind == "ray" and importlib.util.find_spec("ray") is None:
        raise DualtwinError(_NO_RAY)


def ignore_interrupts() -> None:
    """A pool worker's initializer: Ctrl-C reaches every process of the terminal's group, and stopping is the
    parent's job (it shuts the pool down, keeping what finished); a worker that raised KeyboardInterrupt
    would print its own traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Ctrl-C held (not lost) for the block, then delivered to this process's handler as usual.

    Blocked in this thread, so processes started meanwhile inherit the mask; and recorded, not raised, where
    another thread of ours (a pool's manager thread, a BLAS thread) receives it, since Python would raise it in
    the main thread mid-block all the same. Elsewhere than the main thread (where Python handles signals) it
    changes nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    handler = signal.signal(signal.SIGINT, lambda signum, frame: came.append(signum))
    try:
        yield
    finally:
        if signal.SIGINT in signal.sigpending() and signal.sigtimedwait({signal.SIGINT}, 0) is not None:
            came.append(signal.SIGINT)
        signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        if came:
            signal.raise_signal(signal.SIGINT)


#: Seconds allowed to open a TCP connection to a Ray cluster's address before it counts as unreachable.
RAY_CONNECT_TIMEOUT_S = 5.0


def check_ray_address(address: str, option: str = "--ray-address") -> None:
    """Refuse, within :data:`RAY_CONNECT_TIMEOUT_S`, a Ray address nothing answers at.

    ``ray.init(address=...)`` retries an unreachable cluster for minutes (a cluster job that never ends and
    never says why); one TCP connection tells the user at once, naming the address and the option that set it.
    ``auto`` and ``local`` are Ray's own words, left to Ray.
    """
    import socket
    from urllib.parse import urlsplit

    text = address.strip()
    if text in ("auto", "local", ""):
        return
    parts = urlsplit(text if "://" in text else f"ray://{text}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or port is None:
        raise DualtwinError(f"{option} {address}: not a Ray address; expected HOST:PORT (e.g. 10.0.0.5:6379) "
                            "or ray://HOST:PORT")
    try:
        socket.create_connection((host, port), timeout=RAY_CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        reason = f"no answer within {RAY_CONNECT_TIMEOUT_S:g} s" if isinstance(exc, TimeoutError) else (
            exc.strerror or str(exc))
        raise DualtwinError(f"{option} {address}: cannot reach a Ray cluster there ({reason}); start one with "
                            f"'ray start --head' or leave {option} out to use a local instance") from None


def ray_backend(address: str | None, option: str = "--ray-address") -> Any:
    """The ``ray`` module, initialised (joining ``address`` or a running instance, else starting one).

    An address nothing answers at fails within seconds, naming it and ``option`` (:func:`check_ray_address`).
    """
    try:
        import ray  # optional dependency, imported only when asked for
    except ImportError:
        raise DualtwinError(_NO_RAY) from None
    if not ray.is_initialized():
        if address is not None:
            check_ray_address(address, option)
        elif os.environ.get("RAY_ADDRESS"):
            check_ray_address(os.environ["RAY_ADDRESS"], "RAY_ADDRESS")
        if address is None and not os.environ.get("RAY_ADDRESS"):
            # A local instance of our own: its workers run at the driver's priority. Ray's default (+15
            # niceness) is for workers sharing a machine with other work; here they ARE the work, and on a
            # busy 2-core machine the default left the Ray executor slower than one process (0.86x).
            ray.init(ignore_reinit_error=True, log_to_driver=False, include_dashboard=False,
                     _system_config={"worker_niceness": 0})
        else:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    return ray


class ParallelMap:
    """Applies one picklable, module-level function to many inputs; results in input order.

    Args:
        kind: ``serial`` (in this process), ``process`` (a local pool) or ``ray``.
        workers: Pool size for ``process``.
        ray_address: Ray cluster address (None: a running instance or a new local one).
        preload: Modules the process pool's fork server imports once (e.g. the one defining the function).
    """

    def __init__(self, kind: ExecutorKind = "process", workers: int = DEFAULT_WORKERS,
                 ray_address: str | None = None, preload: Sequence[str] = ()) -> None:
        check_executor(kind)
        if workers < 1:
            raise DualtwinError(f"workers must be at least 1, got {workers}")
        self.kind = kind
        self.workers = workers
        self.preload = list(preload)
        self._pool: ProcessPoolExecutor | None = None
        self._ray: Any = ray_backend(ray_address) if kind == "ray" else None
        self._remote: dict[Callable[..., Any], Any] = {}

    @property
    def started(self) -> bool:
        """Whether the process pool's workers are running (started by the first map, kept until close)."""
        return self._pool is not None

    def map(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        """``[fn(x) for x in items]``, run by this executor."""
        items = list(items)
        if not items:
            return []
        if self.kind == "serial" or (self.kind == "process" and (self.workers == 1 or len(items) == 1)):
            return [fn(x) for x in items]
        if self.kind == "ray":
            remote = self._remote.get(fn)
            if remote is None:
                remote = self._remote[fn] = self._ray.remote(fn)
            return list(self._ray.get([remote.remote(x) for x in items]))
        if self._pool is None:
            context = multiprocessing.get_context("forkserver")
            if self.preload:
                context.set_forkserver_preload(self.preload)
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context,
                                             initializer=ignore_interrupts)
        chunk = max(1, math.ceil(len(items) / self.workers))
        # Submitting starts the fork server and the workers (on the first map): SIGINT is blocked meanwhile, so
        # they are born with it blocked (as CPython starts its resource tracker) and a Ctrl-C in their start-up
        # (interpreter start, the preload imports, before the initializer runs) cannot trace back in them. Here
        # it is held until the submissions are done: raised mid-start, it left a worker the pool did not know,
        # still starting after this process had exited (a traceback from its missing semaphore).
        with interrupts_held():
            results = self._pool.map(fn, items, chunksize=chunk)
        return list(results)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> ParallelMap:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
