"""Known-truth recordings degraded like a real logger's: noise, rounding, time-stamp jitter, a logging delay.

Used by the identifiability tests: an exact fit has no noise to judge intervals by.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dualtwin.artifacts import sha256_file, write_json


def degrade(run: Path, rng: np.random.Generator, noise: float, offset_s: float = 0.0, jitter_s: float = 0.0,
            decimals: int | None = None) -> None:
    """Gaussian noise (``noise`` × each channel's range), rounding, jitter and a delay on every log of ``run``.

    The manifest's log hashes are updated, so the run still loads as a run.
    """
    manifest = json.loads((run / "manifest.json").read_text())
    for rel, entry in manifest["logs"].items():
        path = run / rel
        lines = path.read_text().splitlines()
        header, rows = lines[0], np.array([[float(x) for x in line.split("\t")] for line in lines[1:]])
        t = rows[:, 0] - offset_s + (rng.uniform(-jitter_s, jitter_s, rows.shape[0]) if jitter_s else 0.0)
        values = rows[:, 1:]
        span = np.ptp(values, axis=0)
        values = values + rng.normal(0.0, 1.0, values.shape) * noise * np.where(span > 0, span, 1e-3)
        fmt = f"{{:.{decimals}f}}" if decimals is not None else "{!r}"
        body = "\n".join("\t".join([f"{ti:.6f}", *(fmt.format(float(v)) for v in row)])
                         for ti, row in zip(t, values, strict=True))
        path.write_text(header + "\n" + body + "\n")
        entry.update({"bytes": path.stat().st_size, "sha256": sha256_file(path)})
    write_json(run / "manifest.json", manifest)


def noisy_recording(out: Path, twin_name: str, robot: Path, suite: Path, knobs: dict[str, float],
                    seed: int, noise: float) -> Path:
    """The suite run on ``twin_name`` with ``knobs`` into ``out``, then degraded with Gaussian noise."""
    from dualtwin.robots.binding import load_binding
    from dualtwin.suite.runner import SuiteRun
    from dualtwin.twins import make_twin

    binding = load_binding(robot)
    twin = make_twin(twin_name, binding, binding.spec.control_period_ms / 1000.0)
    twin.set_knobs(knobs)
    SuiteRun(suite, twin_name, binding, out, twin=twin).run()
    twin.close()
    degrade(out, np.random.default_rng(seed), noise)
    return out
