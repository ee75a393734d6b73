"""A Ctrl-C that comes after the command line has loaded but before the command's own code runs (while Python
finishes the import, typer builds the command, the options are parsed) is held until the command has said what
stopping keeps: a resumed suite run still says how many scenarios its folder holds (it printed a bare "error:
interrupted" when the signal fell in that window, as it did on a loaded CI machine)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

from dualtwin.cli import main


def test_ctrl_c_right_after_loading_still_names_what_a_resumed_run_keeps(tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = ["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", "cartpole", "--out", str(out)]
    assert main(argv) == 0
    kept = len(json.loads((out / "manifest.json").read_text())["scenarios"])
    # Signalled as each module finishes importing (``-X importtime`` prints it then): the last ones of the
    # command line, the package itself last, after which the command is built and its options parsed.
    for loaded in ("dualtwin.cli.policy", "dualtwin.cli"):
        process = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "dualtwin.cli", *argv, "--resume"],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert process.stderr is not None
        seen = []
        for line in process.stderr:
            seen.append(line)
            if line.strip().split("|")[-1].strip() == loaded:
                break
        process.send_signal(signal.SIGINT)
        _, rest = process.communicate(timeout=60)
        err = "".join(seen) + rest
        assert "Traceback" not in err, (loaded, err[-2000:])
        assert process.returncode == 130, (loaded, err[-2000:])
        assert err.rstrip().endswith(f"error: interrupted; {kept} scenarios kept, resume with --resume"), \
            (loaded, err[-2000:])
