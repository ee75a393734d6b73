"""Every ``dualtwin ...`` command line the docs pages show names a real command, real options and, for options
with closed choices, real values; checked against the typer app without running anything. (The README's
lines are checked by ``tests/test_docs.py``; ``docs/reference/cli.md`` is generated from the app.)"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GENERATED = DOCS / "reference" / "cli.md"


def _pages() -> list[Path]:
    return [p for p in sorted(DOCS.rglob("*.md")) if p != GENERATED]


def command_lines(text: str) -> list[tuple[str, bool]]:
    """``(line, complete)`` per ``dualtwin ...`` line of the shell blocks (continuation lines joined, comments
    dropped; complete: it must end at a command, not a group) and of inline code (which may name a group)."""
    found = []
    for block in re.findall(r"```(?:sh|bash|console|shell)?\n(.*?)```", text, re.DOTALL):
        for line in re.sub(r"\\\n\s*", " ", block).splitlines():
            line = re.split(r"\s#\s", line.strip(), maxsplit=1)[0].strip().removeprefix("$ ")
            if line.startswith("dualtwin "):
                found.append((line, True))
    found += [(m.group(1), False) for m in re.finditer(r"`(dualtwin [^`]+)`", text)]
    return found


def _is_option(word: str) -> bool:
    return re.match(r"--?[A-Za-z]", word) is not None


def _placeholder(word: str) -> bool:
    """A word standing for what the reader fills in: ``COMMAND``, ``FILE``, ``...``, ``RUN_DIR``."""
    return word in ("...", "…") or word.rstrip(".") == "" or re.fullmatch(r"[A-Z][A-Z0-9_.]*(\.\.\.)?", word) is not None


def _choices(param: Any) -> set[str]:
    """The values of an option with closed choices (click's ``Choice``, or typer's own descriptor), else empty."""
    choices = getattr(getattr(param, "type", None), "choices", None)
    if choices is None:
        choices = getattr(getattr(param, "type_descriptor", None), "choices", None)
    return {str(getattr(c, "value", c)) for c in choices or ()}


def line_problems(line: str, root: Any, complete: bool = True) -> list[str]:
    """What is wrong with one command line: an unknown command, option or closed-choice value."""
    clean = [w.strip("[]") for w in line.split()[1:]]
    command, path = root, ["dualtwin"]
    i = 0
    problems: list[str] = []
    while i < len(clean):
        word = clean[i]
        groups = getattr(command, "commands", None)
        if groups is not None and word and not _is_option(word) and word != "|":
            names = [w for w in word.split("|") if w]
            if names and all(n in groups for n in names):
                if len(names) > 1:  # `perception collect|train|eval`: the line names several commands
                    return problems
                command = groups[names[0]]
                path.append(names[0])
            elif not _placeholder(word):
                problems.append(f"{' '.join(path)} has no command {word!r}")
                return problems
        elif _is_option(word):
            params = {o: p for p in command.params for o in [*p.opts, *p.secondary_opts]}
            for option in word.split("|"):
                name = option.split("=", 1)[0]
                if not _is_option(name):
                    continue
                if name == "--help":
                    continue
                param = params.get(name)
                if param is None:
                    problems.append(f"{' '.join(path)} has no option {name}")
                    continue
                choices = _choices(param)
                value = option.split("=", 1)[1] if "=" in option else (clean[i + 1] if i + 1 < len(clean) else "")
                if choices and value and not _is_option(value) and value != "|" and not _placeholder(value):
                    wrong = [v for v in value.split("|") if v and v not in choices]
                    if wrong:
                        problems.append(f"{' '.join(path)} {name}: {wrong} not among {sorted(choices)}")
        i += 1
    if complete and getattr(command, "commands", None) is not None and not any(_placeholder(w) for w in clean):
        problems.append(f"{' '.join(path)} is a group: the line names no command")
    return problems


@pytest.fixture(scope="module")
def root() -> Any:
    import typer.main

    from dualtwin.cli import app

    return typer.main.get_command(app)


def test_every_command_line_in_the_docs_names_real_commands_options_and_choices(root: Any) -> None:
    problems, count = [], 0
    for page in _pages():
        for line, complete in command_lines(page.read_text(encoding="utf-8")):
            count += 1
            problems += [f"{page.relative_to(ROOT)}: {line!r}: {p}" for p in line_problems(line, root, complete)]
    assert count >= 60, f"found only {count} command lines: is the parser still reading the pages?"
    assert not problems, "docs pages show command lines the CLI does not have:\n" + "\n".join(problems)


def test_the_check_catches_each_kind_of_mistake(root: Any) -> None:
    """The control: lines that are right pass, and an unknown command, option or choice value is caught."""
    good = ["dualtwin suite run --twin mujoco|webots --robot cartpole --scenarios FILE --out DIR [--resume]",
            "dualtwin --verbose COMMAND ...", "dualtwin perception collect|train|eval",
            "dualtwin align ... --objective prediction [--horizons 1 --horizons 5]",
            "dualtwin align --reference webots|mujoco | --reference-run RUN_DIR --target mujoco --out o"]
    for line in good:
        assert line_problems(line, root) == [], line
    assert "has no command 'runn'" in line_problems("dualtwin suite runn --twin mujoco", root)[0]
    assert "has no option --twins" in line_problems("dualtwin suite run --twins mujoco", root)[0]
    assert "['gazebo'] not among" in line_problems("dualtwin suite run --twin mujoco|gazebo", root)[0]
    assert "not among" in line_problems("dualtwin align --ensemble median --target mujoco", root)[0]
    assert "names no command" in line_problems("dualtwin suite --help", root)[0]
    assert line_problems("dualtwin import", root, complete=False) == []
    blocks = "```sh\ndualtwin demo --out x   # a comment --bogus\n# dualtwin nothing\n```\n`dualtwin compare`"
    assert command_lines(blocks) == [("dualtwin demo --out x", True), ("dualtwin compare", False)]


def test_the_train_config_help_names_every_bundled_config() -> None:
    """``train --config`` lists the bundled configs by name; a new config must appear in the CLI reference."""
    from dualtwin.rl.ppo_config import bundled_configs

    text = GENERATED.read_text(encoding="utf-8")
    help_line = next(line for line in text.splitlines() if line.startswith("* `--config <path>`: PPO config"))
    missing = [name for name in bundled_configs() if name not in re.findall(r"\w+", help_line)]
    assert not missing, f"train --config's help does not name {missing}"
