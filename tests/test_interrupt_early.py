"""A Ctrl-C pressed while the command line is still loading stops a command that never says what stopping keeps
(here `webots run`) within seconds, not after the whole command (it was held until the command returned)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

WORLD = Path(__file__).resolve().parents[1] / "src" / "dualtwin" / "robots" / "cartpole" / "cartpole.wbt"


def test_an_early_ctrl_c_stops_a_long_webots_run_within_seconds() -> None:
    # Signalled right after a given module of the package has loaded (``-X importtime`` reports each import as
    # it completes; the first is the one imported right after the hook that makes an early Ctrl-C one line is in
    # place), not after a fixed delay: on a loaded machine 0.1 s can still be inside Python's own start-up,
    # before any dualtwin code runs, where no program can catch a Ctrl-C.
    for loaded in ("dualtwin.interrupts", "dualtwin.headless", "dualtwin.cli.webots"):
        process = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "dualtwin.cli", "webots", "run",
                                    str(WORLD), "--duration", "86400"], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
        assert process.stderr is not None
        seen = []
        for line in process.stderr:
            seen.append(line)
            if line.strip().split("|")[-1].strip() == loaded:
                break
        sent = time.monotonic()
        process.send_signal(signal.SIGINT)
        try:
            _, rest = process.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            raise AssertionError(f"Ctrl-C after {loaded} loaded did not stop `webots run` within 30 s") from None
        err = "".join(seen) + rest
        assert time.monotonic() - sent < 30
        assert process.returncode == 130, (loaded, err[-2000:])
        assert "Traceback" not in err and "interrupted" in err, (loaded, err[-2000:])
