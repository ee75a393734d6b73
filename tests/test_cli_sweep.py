"""The CLI's promise, swept over EVERY command: bad input gets exit code 2, exactly one line on stderr that names
the input, no traceback, and no file created.

The commands come from the typer app itself (recursively), and the cases from each command's parameters, so a
new command or option joins the sweep without editing this file -- as long as its parameters are classified in
``PARAMS`` below (``test_every_parameter_is_classified`` fails, naming them, until they are).

How a case is built: the targeted parameter gets a bad value from one family; every other *required* parameter
gets the valid value of its kind (table below); optional parameters are left out, except the ones a command needs
to do anything (``NEEDS``). Where a valid value is too expensive to make here (a trained policy, a perception
model, a dataset, a live server), a placeholder path is given instead and the case accepts an error naming either
the targeted input or a placeholder ("lenient"); every other case must name the targeted option or value.

Valid value per kind (what a new command's required option gets):

    kind          valid value                                   bad-input families
    ----------    -------------------------------------------   ---------------------------------------------
    suite         a one-scenario suite file                      missing, directory, binary, invalid-json,
                                                                  deep-nesting, duplicate-keys, and every
                                                                  numeric field huge or non-finite
    json          a JSON object file (for optional inputs)       missing, directory, binary, invalid-json,
                                                                  deep-nesting, duplicate-keys
    yaml          (optional inputs only)                         missing, directory, binary, invalid-yaml,
                                                                  deep-nesting, duplicate-keys
    wbt           the bundled cartpole.wbt                       missing, directory, binary
    file          (optional inputs only)                         missing, directory, binary
    run           a finished suite run of the small suite        missing, file-for-folder, not-a-run, bad-manifest
    folder        a tiny dataset (data), perception model        missing, file-for-folder, not-a-model,
                  (model, perception), the reference exported
                  policy (serve/lockstep --policy), a 512-step
                  training run (export/transfer --policy)
                                                                  corrupt-model (every record file holds bad
                                                                  JSON, every model file garbage bytes)
    out           a new folder name                              non-empty-foreign, file-for-folder
    outfile       a new file name                                foreign-file, directory
    robot         cartpole                                       unknown-robot
    twin          mujoco                                         unknown-twin
    env           dualtwin/CartPole-MuJoCo-Continuous-v0         unknown-env
    knob          physics.substeps                               unknown-knob
    scenario      (optional: a scenario of the small suite)      unknown-scenario
    url           placeholder (nothing listens there)            unreachable
    address       (optional: a Ray address, with --executor ray)  unreachable (a loopback port nothing listens on)
    number        the option's default                          nan, negative
    numlist       "1" (a list is a repeatable option)            nan, negative
    perturb       initial_angle=0.01                             nan, negative
    choice        the option's default                           unknown-choice
    text, flag    -- (not swept)

Speed: every case runs the real ``dualtwin.cli.main`` in-process (argv in, stderr captured), under a per-case
alarm so a command that starts real work on bad input fails instead of hanging.
"""

from __future__ import annotations

import os
import signal
import socket
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import typer

from dualtwin.cli import app, main
from dualtwin.robots.binding import BUNDLED

CARTPOLE_WBT = BUNDLED / "cartpole" / "cartpole.wbt"
SMALL_SUITE = '{"suite_name": "s", "scenarios": [{"name": "a", "duration_s": 0.1, "initial_angle": 0.1}]}'
CASE_SECONDS = 30
# The files a training run, exported policy, perception model or dataset is recognised by: a "corrupt-model"
# folder holds all of them, damaged, so every loader's JSON and ONNX error paths are exercised.
CORRUPT_RECORDS = ("run.json", "policy_contract.json", "perception_contract.json", "manifest.json",
                   "training.json", "vecnormalize.json")
CORRUPT_MODELS = ("policy.onnx", "perception.onnx", "model.zip", "best_model.zip")

# ------------------------------------------------------------------ classification of every parameter
# "name" applies to every command; "command path:name" overrides it for one command.
PARAMS: dict[str, str] = {
    "reference_run": "run", "target_run": "run",
    "out": "out", "convert:out": "outfile", "convert:binding": "outfile",
    "webots fetch:out": "text",  # a PROTO cache to fill (adds to what is there, by design)
    "scenarios": "suite",
    "config": "yaml", "dr": "json", "aligned": "json", "from_json": "json", "from_text": "file", "mapping": "file",
    "world": "wbt", "worlds": "wbt", "from_wbt": "wbt", "controller": "choice", "webots run:controller": "file",
    "policy": "folder", "policy_aligned": "folder", "policy_dr": "folder", "init_from": "folder",
    "perception": "folder", "model": "folder", "data": "folder", "log_dir": "folder", "data_dir": "folder",
    "robot": "robot", "convert:robot": "text",
    "twin": "twin", "target": "twin", "reference": "twin",
    "env": "env", "target_env": "env", "knobs": "knob", "server": "url",
    "seed": "number", "budget": "number", "steps": "number", "episodes": "number", "width": "number",
    "height": "number", "epochs": "number", "port": "number", "stride": "number", "max_iterations": "number",
    "workers": "number", "ensemble": "number", "shadow_fraction": "number", "duration": "number",
    "colour_jitter": "number", "step_timeout": "number",
    "horizons": "numlist", "perturb": "perturb",
    "optimizer": "choice", "executor": "choice", "objective": "choice", "which": "choice", "resync": "choice",
    "json_dialect": "choice", "invalid": "choice",
    "host": "text", "api_key_env": "text", "address": "text", "holdout": "text",
    "resume": "flag", "llm": "flag", "randomize": "flag", "trust_pickles": "flag", "json_out": "flag",
    "as_json": "flag", "policy_control": "folder", "keys": "file", "camera_only": "flag",
    # align's options derived from AlignConfig (KEY=VALUE mappings are checked by the model, not swept here)
    "popsize": "number", "sigma0": "number", "tolfun": "number", "tolx": "number", "patience": "number",
    "fd_step": "number", "lsq_max_iter": "number", "lsq_restarts": "number", "regularization": "number",
    "dr_top_fraction": "number", "dr_generations": "number", "dr_min_rel_width": "number",
    "reference_knobs": "text", "bounds": "text", "thresholds": "text", "weights": "text", "scales": "text",
    "channels": "text", "ray_address": "address", "global_search": "choice", "starts": "number", "tie": "text",
    "sysid_params": "yaml", "batch": "choice", "exclude": "scenario", "intervals": "choice",
}

# Issue 27's families: structure no reader should trust (deep nesting, the same key twice) and, for suites,
# every numeric field holding a huge or non-finite number (NUMERIC_FIELDS below).
HOSTILE = ("deep-nesting", "duplicate-keys")
FAMILIES: dict[str, tuple[str, ...]] = {
    "suite": ("missing", "directory", "binary", "invalid-json", *HOSTILE),
    "json": ("missing", "directory", "binary", "invalid-json", *HOSTILE),
    "yaml": ("missing", "directory", "binary", "invalid-yaml", *HOSTILE),
    "wbt": ("missing", "directory", "binary"),
    "file": ("missing", "directory", "binary"),
    "run": ("missing", "file-for-folder", "not-a-run", "bad-manifest"),
    "folder": ("missing", "file-for-folder", "not-a-model", "corrupt-model"),
    "out": ("non-empty-foreign", "file-for-folder"),
    "outfile": ("foreign-file", "directory"),
    "robot": ("unknown-robot",), "twin": ("unknown-twin",), "env": ("unknown-env",), "knob": ("unknown-knob",),
    "scenario": ("unknown-scenario",),
    "url": ("unreachable",), "address": ("unreachable",), "number": ("nan", "negative"), "numlist": ("nan", "negative"),
    "perturb": ("nan", "negative"), "choice": ("unknown-choice",), "text": (), "flag": (),
}

# Optional parameters a command needs to do anything (exactly-one-of groups): given unless the target is in
# the same group.
NEEDS: dict[str, dict[str, str]] = {
    "align": {"reference": "webots", "scenarios": "@suite"},
    "lockstep": {"scenarios": "@suite"},
    "generate": {"from_wbt": "@wbt"},
}
GROUPS = ({"reference", "reference_run"}, {"scenarios", "policy"}, {"from_text", "from_json", "from_wbt"})


def commands() -> list[tuple[tuple[str, ...], Any]]:
    """Every leaf command of the app, with its path (``("suite", "run")``)."""
    out: list[tuple[tuple[str, ...], Any]] = []

    def walk(command: Any, path: tuple[str, ...]) -> None:
        subs = getattr(command, "commands", None)
        if subs:
            for name, sub in sorted(subs.items()):
                walk(sub, (*path, name))
        else:
            out.append((path, command))

    walk(typer.main.get_command(app), ())
    return out


def kind_of(path: tuple[str, ...], name: str) -> str | None:
    return PARAMS.get(f"{' '.join(path)}:{name}", PARAMS.get(name))


@dataclass(frozen=True)
class Case:
    path: tuple[str, ...]
    param: str
    kind: str
    family: str

    @property
    def id(self) -> str:
        return f"{' '.join(self.path)}--{self.param}--{self.family}"


# Every numeric field of a suite, and the values each must refuse: an absurd magnitude where no legitimate value
# is that large, a non-finite number (JSON's NaN/Infinity tokens, 1e999 which reads as infinity) everywhere.
# A threshold or a tolerance of 1e308 is legitimate ("never"), so those get the non-finite values only.
NON_FINITE = ("NaN", "Infinity", "1e999")
HUGE = ("1e308", "-1e308")
NUMERIC_FIELDS: dict[str, tuple[str, ...]] = {
    "duration_s": (*NON_FINITE, *HUGE), "seed": (*NON_FINITE, *HUGE), "TIME_STEP": (*NON_FINITE, *HUGE),
    "initial_angle": (*NON_FINITE, *HUGE), "wheel_velocity": (*NON_FINITE, *HUGE),
    "failure_pole_angle_rad": NON_FINITE, "tolerance_rmse": NON_FINITE,
}


def suite_with(field: str, number: str) -> str:
    """The small suite with ``field`` set to the literal ``number`` (JSON text, so NaN/1e999 stay as written)."""
    scenario = '"name": "a", "duration_s": 0.1, "initial_angle": 0.1'
    settings = '"TIME_STEP": 32'
    if field in ("duration_s", "initial_angle"):
        scenario = scenario.replace(f'"{field}": 0.1', f'"{field}": {number}')
    elif field == "TIME_STEP":
        settings = f'"TIME_STEP": {number}'
    elif field == "failure_pole_angle_rad":
        settings += f', "failure_pole_angle_rad": {number}'
    elif field == "tolerance_rmse":
        scenario += f', "tolerances": {{"pole_angle_rad": {{"rmse": {number}}}}}'
    else:
        scenario += f', "{field}": {number}'
    return f'{{"suite_name": "s", "global_settings": {{{settings}}},\n "scenarios": [{{{scenario}}}]}}'


def cases() -> list[Case]:
    out = []
    for path, command in commands():
        for param in command.params:
            kind = kind_of(path, param.name)
            for family in FAMILIES.get(kind or "", ()):
                out.append(Case(path, param.name, kind or "", family))
            if kind == "suite":
                out += [Case(path, param.name, kind, f"number:{field}={number}")
                        for field, numbers in NUMERIC_FIELDS.items() for number in numbers]
    return out


def test_every_parameter_is_classified() -> None:
    missing = [f"{' '.join(path)}:{p.name}" for path, command in commands() for p in command.params
               if kind_of(path, p.name) is None]
    assert not missing, f"classify these parameters in PARAMS (tests/test_cli_sweep.py): {missing}"


def test_the_sweep_covers_every_command() -> None:
    swept = {c.path for c in cases()}
    everything = {path for path, _ in commands()}
    # A command without any sweepable parameter must still be listed here on purpose.
    assert everything - swept <= set(), f"commands with no bad-input case: {sorted(everything - swept)}"
    assert len(everything) >= 20


# ------------------------------------------------------------------ inputs
def closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


# Valid folders made once per module (kind ``folder``), by parameter name or "command path:name".
FOLDERS = {"data": "dataset", "model": "model", "perception": "model", "serve:policy": "exported",
           "lockstep:policy": "exported", "export:policy": "training", "transfer:policy": "training"}


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A two-episode dataset, a one-epoch perception model on it, the reference exported policy and a
    512-step training run."""
    import torch

    from dualtwin.perception.dataset import collect
    from dualtwin.perception.model import train_perception
    from dualtwin.perception.reference_policy import export_reference_policy
    from dualtwin.rl.train import train

    root = tmp_path_factory.mktemp("folders")
    env = "dualtwin/CartPole-MuJoCo-Continuous-v0"
    data = collect(env, 2, root / "data", controller="random", max_steps=8, width=16, height=16, seed=1)
    model = train_perception(data, root / "model", epochs=1, seed=0, threads=1, holdout=0.5, batch_size=8)
    exported = Path(export_reference_policy(root / "exported"))
    torch.set_num_threads(1)
    training = train(env, {"n_envs": 2, "n_steps": 256, "batch_size": 256, "n_epochs": 1, "eval_freq": 0,
                           "vec_env": "dummy"}, root / "training", seed=0, total_timesteps=512, progress_bar=False)
    return {"dataset": Path(data), "model": Path(model),
            "exported": exported.parent if exported.is_file() else exported, "training": Path(training)}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two finished runs of the small suite (the valid value of kind ``run``)."""
    root = tmp_path_factory.mktemp("runs")
    suite = root / "suite.json"
    suite.write_text(SMALL_SUITE)
    made = {}
    for name in ("a", "b"):
        code = main(["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", str(suite),
                     "--out", str(root / name)])
        assert code == 0
        made[name] = root / name
    return made


def valid_value(kind: str, name: str, here: Path, runs: dict[str, Path], url: str,
                command: str = "") -> tuple[str, bool]:
    """The valid argv value for a required parameter of ``kind`` and whether it is only a placeholder."""
    made = FOLDERS.get(f"{command}:{name}", FOLDERS.get(name)) if kind == "folder" else None
    if made is not None:
        return str(runs[made]), False
    if kind == "suite":
        path = here / "valid_suite.json"
        path.write_text(SMALL_SUITE)
        return str(path), False
    if kind == "run":
        return str(runs["b" if name == "target_run" else "a"]), False
    if kind == "wbt":
        return str(CARTPOLE_WBT), False
    if kind in ("out", "outfile"):
        return str(here / f"new_{name}"), False
    values = {"robot": "cartpole", "twin": "mujoco", "env": "dualtwin/CartPole-MuJoCo-Continuous-v0",
              "knob": "physics.substeps", "number": "1", "numlist": "1", "perturb": "initial_angle=0.01"}
    if name == "target_env":
        return "dualtwin/CartPole-Webots-Continuous-v0", False
    if kind in values:
        return values[kind], False
    if kind == "url":
        return url, True
    # folder / file / json / yaml / choice / text: nothing cheap and valid; a placeholder that does not exist.
    return str(here / f"placeholder_{name}"), True


def bad_value(case: Case, here: Path, url: str) -> str:
    """Make the bad input of ``case.family`` inside ``here`` and return its argv value."""
    name = case.param
    family = case.family
    if family == "missing":
        return str(here / f"missing_{name}.json")
    if family == "directory":
        path = here / f"dir_{name}.json"
        path.mkdir()
        return str(path)
    if family == "binary":
        path = here / f"binary_{name}.json"
        path.write_bytes(bytes(range(256)) * 8)
        return str(path)
    if family == "invalid-json":
        path = here / f"invalid_{name}.json"
        path.write_text('{"suite_name": "s",\n  "scenarios": [')
        return str(path)
    if family == "deep-nesting":  # 100,000 levels: a RecursionError in any recursive reader
        path = here / f"deep_{name}.{'yaml' if case.kind == 'yaml' else 'json'}"
        path.write_text("[" * 100_000 + "]" * 100_000)
        return str(path)
    if family == "duplicate-keys":  # the later one silently wins in most parsers
        path = here / f"dupkeys_{name}.{'yaml' if case.kind == 'yaml' else 'json'}"
        path.write_text("a: 1\nb: 2\na: 3\n" if case.kind == "yaml" else
                        '{"suite_name": "s",\n "suite_name": "t",\n "scenarios": []}')
        return str(path)
    if family.startswith("number:"):
        field, number = family.removeprefix("number:").split("=")
        path = here / f"number_{name}.json"
        path.write_text(suite_with(field, number))
        return str(path)
    if family == "invalid-yaml":
        path = here / f"invalid_{name}.yaml"
        path.write_text("a: [1, 2\nb: }\n")
        return str(path)
    if family == "file-for-folder":
        path = here / f"file_{name}"
        path.write_text("not a folder\n")
        return str(path)
    if family in ("not-a-run", "not-a-model"):
        path = here / f"notone_{name}"
        path.mkdir()
        (path / "notes.txt").write_text("someone's folder\n")
        return str(path)
    if family == "corrupt-model":
        path = here / f"corrupt_{name}"
        path.mkdir()
        for record in CORRUPT_RECORDS:
            (path / record).write_text('{"env_id": "x",\n  "broken": ')
        for model in CORRUPT_MODELS:
            (path / model).write_bytes(b"\x08\x07garbage, not a model" * 20)
        return str(path)
    if family == "bad-manifest":
        path = here / f"badmanifest_{name}"
        path.mkdir()
        (path / "manifest.json").write_text('{"twin": "mujoco",')
        return str(path)
    if family == "non-empty-foreign":
        path = here / f"foreign_{name}"
        path.mkdir()
        (path / "thesis.tex").write_text("precious\n")
        return str(path)
    if family == "foreign-file":
        path = here / f"foreign_{name}.xml"
        path.write_text("precious\n")
        return str(path)
    if family == "unreachable":
        return url.removeprefix("http://") if case.kind == "address" else url
    if family == "unknown-robot":
        return "no_such_robot"
    if family == "unknown-twin":
        return "no_such_twin"
    if family == "unknown-env":
        return "dualtwin/NoSuchEnv-v0"
    if family == "unknown-knob":
        return "no.such.knob"
    if family == "unknown-scenario":
        return "no_such_scenario"
    if family == "unknown-choice":
        return "no_such_choice"
    if family in ("nan", "negative"):
        number = "nan" if family == "nan" else "-1"
        if case.kind == "perturb":
            return f"initial_angle={number}"
        return number
    raise AssertionError(f"unknown family {family}")


def snapshot(root: Path) -> dict[str, bytes | None]:
    out: dict[str, bytes | None] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            out[os.path.relpath(os.path.join(dirpath, d), root)] = None
        for f in filenames:
            full = os.path.join(dirpath, f)
            out[os.path.relpath(full, root)] = Path(full).read_bytes() if os.path.isfile(full) else None
    return out


def argv_for(case: Case, command: Any, here: Path, runs: dict[str, Path],
             url: str) -> tuple[list[str], str, list[str]]:
    """The argv of ``case``, the bad value, and the placeholders given."""
    args: list[str] = list(case.path)
    positional: list[str] = []
    placeholders: list[str] = []
    bad = bad_value(case, here, url)
    group = next((g for g in GROUPS if case.param in g), set())
    needs = {k: v for k, v in NEEDS.get(" ".join(case.path), {}).items() if k not in group}
    for param in command.params:
        kind = kind_of(case.path, param.name) or "text"
        if param.name == case.param:
            value = bad
        elif param.name in needs:
            value = needs[param.name]
            if value.startswith("@"):
                value, _ = valid_value(value[1:], param.name, here, runs, url)
        elif param.required:
            value, placeholder = valid_value(kind, param.name, here, runs, url, " ".join(case.path))
            if placeholder:
                placeholders.append(value)
        else:
            continue
        if param.param_type_name == "argument":
            positional.append(value)
        else:
            args += [param.opts[0], value]
    if case.kind == "address":  # a Ray address is only contacted for the Ray executor
        args += ["--executor", "ray"]
    return args + positional, bad, placeholders


class CaseTimeout(Exception):
    pass


@pytest.fixture
def alarm() -> Iterator[None]:
    def fire(signum: int, frame: Any) -> None:
        raise CaseTimeout(f"the command was still running after {CASE_SECONDS} s on bad input")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.alarm(CASE_SECONDS)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


ALL_CASES = cases()
COMMANDS = dict(commands())


@pytest.mark.parametrize("case", ALL_CASES, ids=[c.id for c in ALL_CASES])
def test_bad_input(case: Case, tmp_path: Path, runs: dict[str, Path], folders: dict[str, Path],
                   monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], alarm: None) -> None:
    here = tmp_path / "case"
    here.mkdir()
    monkeypatch.chdir(here)
    url = f"http://127.0.0.1:{closed_port()}"
    command = COMMANDS[case.path]
    argv, bad, placeholders = argv_for(case, command, here, {**runs, **folders}, url)
    before = snapshot(here)
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:  # a command that exits by itself must still follow the promise
        code = exc.code if isinstance(exc.code, int) else 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    shown = f"dualtwin {' '.join(argv)}\nstderr:\n{err}"
    assert "Traceback" not in err, shown
    assert code == 2, f"exit code {code}; {shown}"
    assert len(lines) == 1 and lines[0].startswith("error: "), shown
    param = next(p for p in command.params if p.name == case.param)
    names = {bad, Path(bad).name, *(param.opts or []), param.name}
    if case.family in ("nan", "negative", "unknown-choice", "unknown-twin", "unknown-knob", "unknown-scenario",
                       "unknown-env", "unknown-robot", "unreachable"):
        names.add(bad.split("=")[-1].split(",")[-1])
    if placeholders and case.kind not in ("out", "outfile"):  # output folders are checked first: always strict
        names |= set(placeholders) | {Path(p).name for p in placeholders}
    assert any(n and n in lines[0] for n in names), f"the line does not name {sorted(names)}; {shown}"
    assert snapshot(here) == before, f"files were created or changed; {shown}"
    if case.family == "duplicate-keys" and bad in lines[0]:
        assert ("lines 1 and 3" if case.kind == "yaml" else "lines 1 and 2") in lines[0], shown


# ------------------------------------------------------------------ specific promises
def test_missing_ode_library_is_one_line_naming_the_package(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    import ctypes.util

    from dualtwin.webots import ode

    monkeypatch.setattr(ode, "_LIB", None)
    monkeypatch.setattr(ode, "_CANDIDATE_NAMES", ("libode-not-installed.so",))
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    suite = tmp_path / "suite.json"
    suite.write_text(SMALL_SUITE)
    code = main(["suite", "run", "--twin", "webots", "--robot", "cartpole", "--scenarios", str(suite),
                 "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and "libode8" in err


def test_a_fifo_is_refused_without_blocking(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           alarm: None) -> None:
    fifo = tmp_path / "suite.json"
    os.mkfifo(fifo)
    code = main(["suite", "validate", "--scenarios", str(fifo)])
    err = capsys.readouterr().err
    assert code == 2 and "not a regular file" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("argv", [
    ["suite", "run", "--twin", "mujoco", "--robot", "cartpole", "--scenarios", "cartpole", "--seed", "x"],
    ["suite", "run", "--twin", "mujoco"],
    ["no-such-command"],
    ["align", "--optimizer", "cma", "--no-such-option"],
])
def test_usage_errors_are_one_line(argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: ") and "Traceback" not in err
    assert not any(tmp_path.iterdir())


def test_json_reader_names_file_line_and_column(tmp_path: Path) -> None:
    from dualtwin.artifacts import read_json
    from dualtwin.errors import DualtwinError

    path = tmp_path / "x.json"
    path.write_text('{\n  "a": 1,\n  "b": }\n')
    with pytest.raises(DualtwinError, match=r"x\.json:3:8: invalid JSON"):
        read_json(path)



# ------------------------------------------------------------------ one CLI shape (issue 18)
def test_one_cli_shape() -> None:
    """Every output is --out (short -o), a suite is --scenarios, runs and twins are options named by role, and
    every closed choice is an Enum (so --help lists it)."""
    import typing
    from enum import Enum

    def is_enum(param: Any) -> bool:  # an Enum or a Literal: both become a click Choice that --help lists
        annotation = param.type_descriptor.annotation
        return typing.get_origin(annotation) is typing.Literal or any(
            (isinstance(a, type) and issubclass(a, Enum)) or typing.get_origin(a) is typing.Literal
            for a in (annotation, *typing.get_args(annotation)))

    problems = []
    for path, command in commands():
        where = " ".join(path)
        for param in command.params:
            kind = kind_of(path, param.name)
            if param.name in ("output", "suite", "file", "run_a", "run_b", "primary", "secondary"):
                problems.append(f"{where}: old parameter name {param.name}")
            if param.name == "out" and list(param.opts) + list(param.secondary_opts) != ["--out", "-o"]:
                problems.append(f"{where}: {param.opts} instead of --out/-o")
            if kind in ("run", "suite", "twin") and param.param_type_name == "argument":
                problems.append(f"{where}: {param.name} is positional")
            if kind == "suite" and param.opts != ["--scenarios"]:
                problems.append(f"{where}: a suite named {param.opts}")
            if kind == "twin" and param.name != "twin" and param.name not in ("reference", "target"):
                problems.append(f"{where}: a twin named {param.name}")
            if kind == "run" and param.name not in ("reference_run", "target_run"):
                problems.append(f"{where}: a run named {param.name}")
            if kind == "twin" and not is_enum(param):
                problems.append(f"{where}: --{param.name} is not an Enum")
            if kind == "choice" and param.name not in ("resync", "controller") and not is_enum(param):
                problems.append(f"{where}: --{param.name} is not an Enum")
            if param.name == "controller" and where == "perception collect" and not is_enum(param):
                problems.append(f"{where}: --controller is not an Enum")
    assert not problems, problems


def test_choice_enums_follow_the_registries() -> None:
    from dualtwin.cli.common import Executor, Twin
    from dualtwin.parallel import EXECUTORS
    from dualtwin.twins import TWINS

    assert sorted(t.value for t in Twin) == sorted(TWINS)
    assert sorted(e.value for e in Executor) == sorted(EXECUTORS)


@pytest.mark.parametrize("argv", [
    ["collect", "--env", "dualtwin/CartPole-MuJoCo-v0", "--episodes", "1", "--out", "x"],  # now perception collect
    ["suite", "run", "--twin", "bullet", "--robot", "cartpole", "--scenarios", "cartpole", "--out", "x"],
    ["lockstep", "--robot", "cartpole", "--scenarios", "cartpole", "--reference", "gazebo", "--out", "x"],
    ["predict-error", "--robot", "cartpole", "--scenarios", "cartpole", "--horizons", "1,5", "--out", "x"],
    ["compare", "a", "b", "--out", "x"],  # runs are --reference-run / --target-run
])
def test_old_shapes_and_bad_choices_are_one_line(argv: list[str], capsys: pytest.CaptureFixture[str],
                                                  tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: ") and "Traceback" not in err
    assert not any(tmp_path.iterdir())


def test_help_lists_the_choices(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["suite", "run", "--help"]) == 0
    shown = capsys.readouterr().out
    assert "mujoco" in shown and "webots" in shown and "serial" in shown and "ray" in shown
