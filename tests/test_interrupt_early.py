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
    for delay in (0.1, 0.4):
        process = subprocess.Popen([sys.executable, "-m", "dualtwin.cli", "webots", "run", str(WORLD),
                                    "--duration", "86400"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True)
        time.sleep(delay)
        sent = time.monotonic()
        process.send_signal(signal.SIGINT)
        try:
            _, err = process.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            raise AssertionError(f"Ctrl-C at {delay} s did not stop `webots run` within 30 s") from None
        assert time.monotonic() - sent < 30
        assert process.returncode == 130, err
        assert "Traceback" not in err and "interrupted" in err
