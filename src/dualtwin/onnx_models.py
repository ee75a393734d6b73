"""ONNX models from folders (exported policies, perception models) opened and run as untrusted data.

A model file is a graph ONNX Runtime executes, so a downloaded one can be hostile. What ORT 1.2x already
refuses at load (checked by fuzzing: external data outside the model's folder, absolute or through a symlink;
initializers whose declared shape exceeds their data; unknown operator domains; unreleased opsets) arrives here
as an exception and leaves as one :class:`DualtwinError` naming the file. What it does not refuse is handled
here:

* ORT's own logger writes coloured multi-line records to stderr when a model fails to load or an initializer
  is unused; the sessions log fatal records only, since every failure also reaches the caller as an exception.
* A graph can run forever (a ``Loop`` with 2**62 iterations or an always-true condition) or fail while running
  (an allocation of terabytes, an input of another type): :func:`run_session` ends a run after
  :data:`RUN_LIMIT_S` seconds with ``RunOptions.terminate``, which ORT checks between nodes and between loop
  iterations, and reports either as a :class:`DualtwinError`. A single huge kernel (one enormous MatMul) is
  not interrupted by the flag; its size is bounded by the memory ORT can allocate, which fails as an error.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

from dualtwin.errors import DualtwinError

#: Seconds one inference may take. The project's models (a small MLP, a small CNN on a batch of frames) run in
#: milliseconds; the limit only ends graphs that would never finish. The server runs each request in a pool
#: thread, so a hostile model costs one thread this long and then a 422, not a hung worker.
RUN_LIMIT_S = 30.0

#: ORT's log severity for sessions: 4 is FATAL, so its ERROR and WARNING records stay off stderr.
_QUIET = 4


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return (text.splitlines()[0] if text else type(exc).__name__)[:300]


def open_session(path: Path, what: str) -> Any:
    """An ONNX Runtime CPU session for the file, or a :class:`DualtwinError` saying it is not a usable model."""
    import onnxruntime as ort

    if not path.is_file():
        raise DualtwinError(f"{path}: {what} model file not found")
    options = ort.SessionOptions()
    options.log_severity_level = _QUIET
    # Small models, many concurrent requests: one intra-op thread per run, concurrency across requests.
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    try:
        return ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
    except Exception as exc:  # noqa: BLE001 - onnxruntime raises several private exception types
        raise DualtwinError(f"{path}: not a valid ONNX {what} model ({_first_line(exc)})") from None


class _Watchdog:
    """One daemon thread for every run in flight: it sets ``terminate`` on a run past its deadline. A timer thread
    per run cost about 60 µs a run, more than a small policy's inference itself."""

    #: How often the thread looks (s): a run is stopped at most this much after its limit.
    PERIOD_S = 0.1

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._runs: dict[int, tuple[float, Any]] = {}
        self._thread: threading.Thread | None = None

    def watch(self, options: Any, limit_s: float) -> int:
        key = id(options)
        with self._lock:
            self._runs[key] = (time.monotonic() + limit_s, options)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._loop, name="dualtwin-onnx-watchdog", daemon=True)
                self._thread.start()
        return key

    def done(self, key: int) -> None:
        with self._lock:
            self._runs.pop(key, None)

    def _loop(self) -> None:
        while True:
            time.sleep(self.PERIOD_S)
            now = time.monotonic()
            with self._lock:
                for deadline, options in self._runs.values():
                    if now > deadline:
                        options.terminate = True


_WATCHDOG = _Watchdog()


def check_float_input(session: Any, path: Path, refusal: str, width: int | None = None) -> None:
    """Refuse a session that does not take one float32 ``[batch, n]`` input (``n == width`` when given).

    Callers feed one float32 row per observation to the first input; another count, type or rank would fail
    inside ORT mid-run (or as an IndexError on a rank-less input), so it is refused at load as
    ``"{path}: ONNX input [...] {refusal}"``, the refusal phrased for the caller's contract.
    """
    inputs = session.get_inputs()
    # A scalar or rank-less input has no shape to index: it is refused as not [batch, n], not an IndexError.
    shape = list(inputs[0].shape or []) if inputs else []
    if (len(inputs) != 1 or inputs[0].type != "tensor(float)" or len(shape) != 2
            or (width is not None and shape[-1] != width)):
        raise DualtwinError(f"{path}: ONNX input {[(i.name, i.type, i.shape) for i in inputs]} {refusal}")


def run_session(session: Any, feeds: dict[str, Any], what: str, limit_s: float = RUN_LIMIT_S) -> list[Any]:
    """``session.run(None, feeds)``, ended after ``limit_s`` seconds; a failure is a :class:`DualtwinError`."""
    import onnxruntime as ort

    options = ort.RunOptions()
    options.log_severity_level = _QUIET
    key = _WATCHDOG.watch(options, limit_s)
    try:
        return list(session.run(None, feeds, options))
    except Exception as exc:  # noqa: BLE001 - onnxruntime raises several private exception types
        if options.terminate:
            raise DualtwinError(f"{what}: the ONNX model ran longer than {limit_s:g} s and was stopped "
                                "(a graph that does not end)") from None
        raise DualtwinError(f"{what}: the ONNX model failed to run ({_first_line(exc)})") from None
    finally:
        _WATCHDOG.done(key)
