"""Issue 27 from outside: never hang, never trace back, never accept the impossible.

What the bad-input sweep (tests/test_cli_sweep.py) cannot do in-process lives here: Ctrl-C at random moments of
real command runs (a process group, as a terminal sends it), a full disk under ``--out``, unreachable
addresses, physically impossible states on both twins and recordings holding values no sensor produces. Every
case has a wall-clock bound, so a hang fails instead of blocking the suite.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from dualtwin.artifacts import verify_logs
from dualtwin.cli import main
from dualtwin.robots.binding import BUNDLED

ROOT = Path(__file__).resolve().parents[1]
SMALL_SUITE = '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.5, "initial_angle": 0.1}]}'
#: Ctrl-C delays are drawn afresh every run (the seed is printed with a failure, to replay it).
SEED = int(os.environ.get("DUALTWIN_INTERRUPT_SEED", time.time_ns() % 1_000_000))
#: Before this, the interpreter itself is starting (site, the virtual environment's paths): Python's own
#: SIGINT behaviour, before any dualtwin code exists to handle it.
EARLIEST_S = 0.3


#: Every test's wall-clock bound: an in-process hang (an endless loop in the physics) fails instead of blocking.
CASE_SECONDS = 240


class CaseTimeout(Exception):
    pass


@pytest.fixture(autouse=True)
def wall_clock_bound() -> Iterator[None]:
    def fire(signum: int, frame: object) -> None:
        raise CaseTimeout(f"still running after {CASE_SECONDS} s")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.alarm(CASE_SECONDS)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
            "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}


def cli(*argv: str, timeout: float = 60, extra_env: dict[str, str] | None = None,
        cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", "from dualtwin.cli import main; main()", *argv],
                          capture_output=True, text=True, timeout=timeout, env={**env(), **(extra_env or {})},
                          cwd=cwd, check=False)


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("error:")]


def assert_whole(folder: Path) -> None:
    """Nothing half-written: no temporary file left, every JSON file parses, a manifest's logs verify."""
    if not folder.exists():
        return
    leftovers = [p for p in folder.rglob("*") if p.name.endswith(".tmp")]
    assert not leftovers, leftovers
    for path in folder.rglob("*.json"):
        json.loads(path.read_text(encoding="utf-8"))
    for manifest in folder.rglob("manifest.json"):
        logs = json.loads(manifest.read_text(encoding="utf-8")).get("logs")
        if isinstance(logs, dict):
            verify_logs(manifest.parent, logs, manifest)


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("robust_runs")
    suite = root / "suite.json"
    suite.write_text(SMALL_SUITE)
    made = {"suite": suite}
    for name, scenarios in (("a", "cartpole"), ("b", "cartpole"), ("small", str(suite))):
        assert main(["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", scenarios,
                     "--out", str(root / name)]) == 0
        made[name] = root / name
    return made


# ------------------------------------------------------------------ Ctrl-C at random moments
def interrupt(argv: list[str], delay: float, cwd: Path) -> tuple[int, str]:
    """Run the command in its own process group and send SIGINT to the group after ``delay`` s (a terminal's
    Ctrl-C reaches every process of the job: pool workers and controller processes too)."""
    proc = subprocess.Popen([sys.executable, "-c", "from dualtwin.cli import main; main()", *argv], cwd=cwd,
                            env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    time.sleep(delay)
    with contextlib.suppress(ProcessLookupError):  # it finished first: exit 0, the folder whole all the same
        os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise AssertionError(f"still running 30 s after Ctrl-C at {delay:.2f} s: {argv}") from None
    return proc.returncode, err


def long_commands(runs: dict[str, Path], here: Path) -> Iterator[tuple[str, list[str], float]]:
    """(name, argv, seconds worth interrupting within) for each long command."""
    wbt = str(BUNDLED / "cartpole" / "cartpole.wbt")
    yield "suite run webots", ["suite", "run", "--twin", "webots", "--robot", "cartpole", "--scenarios",
                               "cartpole", "--out", str(here / "out")], 6.0
    yield "suite run ensemble", ["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios",
                                 str(runs["suite"]), "--ensemble", "3", "--perturb", "initial_angle=0.01",
                                 "--out", str(here / "out")], 6.0
    yield "compare", ["compare", "--reference-run", str(runs["a"]), "--target-run", str(runs["b"]),
                      "--out", str(here / "out")], 6.0
    yield "align", ["align", "--reference", "webots", "--target", "mujoco", "--robot", "cartpole",
                    "--scenarios", str(runs["suite"]), "--knobs", "joint.pole_hinge.damping", "--budget", "4",
                    "--out", str(here / "out")], 8.0
    yield "webots run", ["webots", "run", wbt, "--duration", "3"], 4.0


@pytest.mark.parametrize("name", ["suite run webots", "suite run ensemble", "compare", "align", "webots run"])
def test_ctrl_c_at_a_random_moment_is_one_line_and_exit_130(name: str, runs: dict[str, Path],
                                                            tmp_path: Path) -> None:
    rng = random.Random(f"{SEED}:{name}")
    argv, within = next((a, w) for n, a, w in long_commands(runs, tmp_path) if n == name)
    delay = rng.uniform(EARLIEST_S, within)
    code, err = interrupt(argv, delay, tmp_path)
    shown = f"{name}, Ctrl-C at {delay:.2f} s (DUALTWIN_INTERRUPT_SEED={SEED}), exit {code}:\n{err[-3000:]}"
    assert "Traceback" not in err, shown
    if code == 0:  # it finished before the signal came
        assert not error_lines(err), shown
    else:
        assert code == 130, shown
        lines = error_lines(err)
        assert len(lines) == 1 and lines[0].startswith("error: interrupted"), shown
        assert err.rstrip().endswith(lines[0]), shown
    assert_whole(tmp_path / "out")


def test_ctrl_c_during_a_suite_run_keeps_the_finished_scenarios_and_resume_completes(tmp_path: Path) -> None:
    """Two random moments in one suite run: the line counts what the manifest holds, and --resume finishes
    the same run an uninterrupted one gives (logs byte for byte)."""
    rng = random.Random(f"{SEED}:resume")
    out = tmp_path / "out"
    argv = ["suite", "run", "--twin", "webots", "--robot", "cartpole", "--scenarios", "cartpole", "--out",
            str(out)]
    for attempt in range(2):
        delay = rng.uniform(EARLIEST_S, 5.0)
        code, err = interrupt([*argv, *(["--resume"] if attempt else [])], delay, tmp_path)
        shown = f"Ctrl-C at {delay:.2f} s (DUALTWIN_INTERRUPT_SEED={SEED}):\n{err[-2000:]}"
        assert "Traceback" not in err and code in (0, 130), shown
        assert_whole(out)
        if code == 130 and (out / "manifest.json").is_file():
            kept = len(json.loads((out / "manifest.json").read_text())["scenarios"])
            assert f"interrupted; {kept} scenarios kept, resume with --resume" in err, shown
    finished = cli(*argv, "--resume", timeout=120)
    assert finished.returncode == 0, finished.stderr[-2000:]
    reference = tmp_path / "reference"
    assert main(["suite", "run", "--twin", "webots", "--robot", "cartpole", "--scenarios", "cartpole", "--out",
                 str(reference)]) == 0
    for tsv in sorted(reference.rglob("*.tsv")):
        assert (out / tsv.relative_to(reference)).read_bytes() == tsv.read_bytes(), tsv


# ------------------------------------------------------------------ a full disk under --out
@pytest.fixture
def full_disk(tmp_path: Path) -> Iterator[tuple[Path, dict[str, str]]]:
    """A 64 KiB file system (tmpfs, as root) or, where mounting is not allowed, a process file-size limit
    (RLIMIT_FSIZE: every write past 64 KiB fails with EFBIG, as a full disk fails with ENOSPC)."""
    mount = tmp_path / "full"
    mount.mkdir()
    mounted = os.geteuid() == 0 and subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)], capture_output=True, check=False,
    ).returncode == 0
    try:
        yield mount, ({} if mounted else {"DUALTWIN_TEST_FSIZE": str(64 * 1024)})
    finally:
        if mounted:
            subprocess.run(["umount", str(mount)], check=False)


def cli_limited(argv: list[str], limit: dict[str, str]) -> subprocess.CompletedProcess[str]:
    code = "from dualtwin.cli import main; main()"
    if limit:
        size = int(limit["DUALTWIN_TEST_FSIZE"])
        code = ("import resource, signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
                f"resource.setrlimit(resource.RLIMIT_FSIZE, ({size}, {size})); " + code)
    return subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120,
                          env=env(), check=False)


@pytest.mark.parametrize("command", ["suite run", "compare", "analyze", "import paper"])
def test_a_full_disk_is_one_line_naming_the_file_and_never_exit_0(command: str, runs: dict[str, Path],
                                                                  full_disk: tuple[Path, dict[str, str]],
                                                                  tmp_path: Path) -> None:
    disk, limit = full_disk
    out = disk / "out"
    argv = {
        "suite run": ["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", "cartpole"],
        "compare": ["compare", "--reference-run", str(runs["a"]), "--target-run", str(runs["b"])],
        "analyze": ["analyze", "--reference-run", str(runs["a"]), "--target-run", str(runs["b"])],
        "import paper": ["import", "paper", str(paper_logs(tmp_path / "logs", 3000)), "--scenarios",
                         str(paper_suite(tmp_path, 3000)), "--robot", "cartpole"],
    }[command]
    done = cli_limited([*argv, "--out", str(out)], limit)
    shown = f"{command}: exit {done.returncode}\n{done.stderr[-3000:]}"
    assert done.returncode != 0 and "Traceback" not in done.stderr, shown
    lines = error_lines(done.stderr)
    assert len(lines) == 1 and str(disk) in lines[0], shown
    assert "No space left on device" in lines[0] or "File too large" in lines[0], shown
    assert_whole(out)


# ------------------------------------------------------------------ addresses nothing answers at
def test_an_unreachable_ray_address_fails_in_seconds_naming_it(runs: dict[str, Path], tmp_path: Path) -> None:
    address = f"127.0.0.1:{closed_port()}"
    start = time.monotonic()
    done = cli("align", "--reference", "webots", "--target", "mujoco", "--robot", "cartpole", "--scenarios",
               str(runs["suite"]), "--knobs", "joint.pole_hinge.damping", "--budget", "4", "--executor", "ray",
               "--ray-address", address, "--out", str(tmp_path / "out"), timeout=60)
    assert time.monotonic() - start < 30
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-2000:]
    lines = error_lines(done.stderr)
    assert len(lines) == 1 and address in lines[0] and "--ray-address" in lines[0], done.stderr
    assert not (tmp_path / "out").exists()


def test_an_unreachable_llm_is_named_with_its_setting_within_the_documented_retries(
        runs: dict[str, Path], tmp_path: Path) -> None:
    url = f"http://127.0.0.1:{closed_port()}/v1"
    start = time.monotonic()
    done = cli("analyze", "--reference-run", str(runs["a"]), "--target-run", str(runs["b"]), "--out",
               str(tmp_path / "out"), "--llm", timeout=90,
               extra_env={"DUALTWIN_LLM_BASE_URL": url, "DUALTWIN_LLM_MODEL": "m", "DUALTWIN_LLM_CONFIG": ""})
    assert time.monotonic() - start < 60  # three attempts (max_retries 2) with the client's short backoff
    assert "Traceback" not in done.stderr, done.stderr[-2000:]
    said = done.stdout + done.stderr
    assert url in said and "DUALTWIN_LLM_BASE_URL" in said and "cannot connect" in said, said[-2000:]


def test_an_unreachable_proto_download_fails_in_seconds_naming_the_url(tmp_path: Path) -> None:
    url = f"http://127.0.0.1:{closed_port()}/protos/Thing.proto"
    world = tmp_path / "w.wbt"
    world.write_text(f'#VRML_SIM R2023b utf8\nEXTERNPROTO "{url}"\nWorldInfo {{}}\nThing {{}}\n')
    start = time.monotonic()
    done = cli("webots", "fetch", str(world), "--out", str(tmp_path / "cache"), timeout=60)
    assert time.monotonic() - start < 30
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = error_lines(done.stderr)
    assert len(lines) == 1 and url in lines[0], done.stderr


def test_a_binary_llm_config_is_one_line(runs: dict[str, Path], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str],
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "llm.yaml"
    config.write_bytes(bytes(range(256)) * 8)
    monkeypatch.setenv("DUALTWIN_LLM_CONFIG", str(config))
    code = main(["analyze", "--reference-run", str(runs["a"]), "--target-run", str(runs["b"]), "--out",
                 str(tmp_path / "out"), "--llm"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1 and str(config) in err
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ impossible states
@pytest.mark.parametrize("value, field", [("1e300", "initial_angle"), ("2.5", "initial_angle"),
                                          ("-1e5", "initial_angular_velocity")])
@pytest.mark.parametrize("command", ["validate", "run"])
def test_impossible_initial_conditions_are_refused_naming_scenario_and_field(
        value: str, field: str, command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    suite = tmp_path / "suite.json"
    suite.write_text(f'{{"suite_name": "s", "scenarios": [{{"name": "a", "duration_s": 0.1}},\n'
                     f'  {{"name": "b", "duration_s": 0.1, "{field}": {value}}}]}}')
    argv = (["suite", "validate", "--scenarios", str(suite), "--robot", "cartpole"] if command == "validate" else
            ["suite", "run", "--twin", "webots", "--robot", "cartpole", "--scenarios", str(suite), "--out",
             str(tmp_path / "out")])
    start = time.monotonic()
    code = main(argv)
    assert time.monotonic() - start < 10
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "$.scenarios[1]" in err and field in err, err
    assert not (tmp_path / "out").exists()
    control = tmp_path / "control.json"  # the same suite at a reachable state is accepted
    control.write_text(suite.read_text().replace(value, "0.5"))
    assert main(["suite", "validate", "--scenarios", str(control), "--robot", "cartpole"]) == 0


@pytest.mark.parametrize("twin_name", ["mujoco", "webots"])
@pytest.mark.parametrize("value", [1e300, float("inf"), float("nan"), -5e4])
def test_an_absurd_state_is_an_unstable_scenario_within_one_control_period(twin_name: str, value: float) -> None:
    """Past validation (a library caller, an ensemble's perturbation): reported, never simulated forever."""
    from dualtwin.robots.binding import resolve_robot
    from dualtwin.suite.runner import run_scenario
    from dualtwin.suite.schema import Scenario
    from dualtwin.twins import make_twin
    from dualtwin.twins.io import RobotIO

    robot = resolve_robot("cartpole")
    io = RobotIO(robot, make_twin(twin_name, robot, 0.032))
    scenario = Scenario.model_construct(name="a", duration_s=1.0)
    object.__setattr__(scenario, "__pydantic_extra__", {"initial_angle": value})
    start = time.monotonic()
    result, onboard, truth = run_scenario(io, scenario, 0, {}, True)
    assert time.monotonic() - start < 5
    assert result.status == "unstable" and result.failure["time_s"] <= 0.032 and result.steps == 0
    assert "initial_angle" in result.failure["message"]


def test_angle_normalisation_ends_on_any_value() -> None:
    from dualtwin.webots._math3 import normalize_angle

    start = time.monotonic()
    assert normalize_angle(1e300) != normalize_angle(1e300)  # NaN: the physics reports it as unstable
    assert normalize_angle(float("inf")) != normalize_angle(float("inf"))
    assert normalize_angle(7.0) == pytest.approx(7.0 - 2 * 3.141592653589793)
    assert time.monotonic() - start < 1


# ------------------------------------------------------------------ recordings
def paper_suite(folder: Path, rows: int = 30) -> Path:
    path = folder / "paper_suite.json"
    path.write_text(json.dumps({"suite_name": "p", "scenarios": [
        {"name": "a", "duration_s": round(rows * 0.032, 6), "initial_angle": 0.1}]}))
    return path


def paper_logs(folder: Path, rows: int = 30, edit: dict[int, str] | None = None) -> Path:
    """One orchestrator log (time_s, pole_angle_rad, cart_pos_m), with some lines replaced."""
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["time_s\tpole_angle_rad\tcart_pos_m"]
    lines += [f"{0.032 * (k + 1):.3f}\t{0.1 + 0.001 * k:.4f}\t{0.0:.3f}" for k in range(rows)]
    for index, line in (edit or {}).items():
        lines[index] = line
    (folder / "simulation_log_SUP_0.tsv").write_text("\n".join(lines) + "\n")
    return folder


@pytest.mark.parametrize("line, where", [
    ("0.320\tinf\t0.000", ":11:2:"), ("0.320\t0.1\t1e308", ":11:3:"), ("0.320\t-inf\t0.000", ":11:2:"),
    ("0.320\t0.1\t-1e12", ":11:3:"),
])
def test_a_recording_with_values_no_sensor_produces_is_refused_at_file_line_and_column(
        line: str, where: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    logs = paper_logs(tmp_path / "logs", edit={10: line})
    code = main(["import", "paper", str(logs), "--scenarios", str(paper_suite(tmp_path)), "--robot", "cartpole",
                 "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    # The logs are read (a progress line) before their values are judged: one error line, the last one.
    assert code == 2 and len(error_lines(err)) == 1 and err.strip().splitlines()[-1].startswith("error:"), err
    assert f"simulation_log_SUP_0.tsv{where}" in err, err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("edit, expect", [
    ({1: "-0.032\t0.1\t0.0"}, "simulation_log_SUP_0.tsv:2: first time stamp -0.032 s is negative"),
    ({5: "0.064\t0.1\t0.0"}, "simulation_log_SUP_0.tsv:6: time stamps must increase"),
])
def test_negative_starts_and_time_going_backwards_are_refused(edit: dict[int, str], expect: str, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    logs = paper_logs(tmp_path / "logs", edit=edit)
    code = main(["import", "paper", str(logs), "--scenarios", str(paper_suite(tmp_path)), "--robot", "cartpole",
                 "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and expect in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize("invalid", ["mask", "unstable"])
def test_an_explicit_treatment_imports_and_the_manifest_says_what_was_done(invalid: str, tmp_path: Path) -> None:
    logs = paper_logs(tmp_path / "logs", edit={10: "0.320\tinf\t0.000"})
    assert main(["import", "paper", str(logs), "--scenarios", str(paper_suite(tmp_path)), "--robot", "cartpole",
                 "--out", str(tmp_path / "run"), "--invalid", invalid]) == 0
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert manifest["invalid_values"]["treatment"] == invalid
    scenario = manifest["scenarios"][0]
    assert any("simulation_log_SUP_0.tsv:11:2" in note for note in scenario["notes"]), scenario["notes"]
    if invalid == "mask":
        assert scenario["status"] == "completed" and any("masked 1 sample" in n for n in scenario["notes"])
    else:
        assert scenario["status"] == "unstable"
