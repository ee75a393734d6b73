"""Ctrl-C before a command's own code runs.

Pressed while the command line is still loading, it stops a command that never says what stopping keeps (here
`webots run`) within seconds, not after the whole command (it was held until the command returned). Pressed
after the command line has loaded but before the command's code runs (Python finishing the import, typer
building the command, the options being parsed), it is held until the command has said what stopping keeps: a
resumed suite run still says how many scenarios its folder holds (it printed a bare "error: interrupted" when
the signal fell in that window, as it did on a loaded CI machine).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from dualtwin.cli import main

WORLD = Path(__file__).resolve().parents[1] / "src" / "dualtwin" / "robots" / "cartpole" / "cartpole.wbt"


def interrupt_once_loaded(argv: list[str], loaded: str) -> tuple[int, str, float]:
    """Run ``dualtwin ARGV`` and send SIGINT right after module ``loaded`` has been imported: (exit code, stderr,
    seconds from the signal to the exit).

    Signalled then (``-X importtime`` reports each import as it completes), not after a fixed delay: on a loaded
    machine 0.1 s can still be inside Python's own start-up, before any dualtwin code runs, where no program can
    catch a Ctrl-C.
    """
    process = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "dualtwin.cli", *argv],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
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
        raise AssertionError(f"Ctrl-C after {loaded} loaded did not stop `dualtwin {argv[0]}` within 30 s") from None
    return process.returncode, "".join(seen) + rest, time.monotonic() - sent


def test_an_early_ctrl_c_stops_a_long_webots_run_within_seconds() -> None:
    # The first module is the one imported right after the hook that makes an early Ctrl-C one line is in place.
    for loaded in ("dualtwin.interrupts", "dualtwin.headless", "dualtwin.cli.webots"):
        code, err, took = interrupt_once_loaded(["webots", "run", str(WORLD), "--duration", "86400"], loaded)
        assert took < 30
        assert code == 130, (loaded, err[-2000:])
        assert "Traceback" not in err and "interrupted" in err, (loaded, err[-2000:])


def test_ctrl_c_right_after_loading_still_names_what_a_resumed_run_keeps(tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = ["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", "cartpole", "--out", str(out)]
    assert main(argv) == 0
    kept = len(json.loads((out / "manifest.json").read_text())["scenarios"])
    # The last modules of the command line, the package itself last: then the command is built and parsed.
    for loaded in ("dualtwin.cli.policy", "dualtwin.cli"):
        code, err, _ = interrupt_once_loaded([*argv, "--resume"], loaded)
        assert "Traceback" not in err, (loaded, err[-2000:])
        assert code == 130, (loaded, err[-2000:])
        assert err.rstrip().endswith(f"error: interrupted; {kept} scenarios kept, resume with --resume"), \
            (loaded, err[-2000:])
