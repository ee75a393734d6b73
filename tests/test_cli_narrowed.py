"""The command line builds only the command it runs (``dualtwin.cli.narrowed_to``, issue 25's fixed cost).

typer turns every registered command into a click command, reading its signature and type hints, before it
parses anything: about 50 ms that a ``dualtwin align`` paid for the other commands. A command line that starts
with a command's name now builds that command alone under the same group. What it builds must be what the whole
app builds for that name (options, help, the group's own options), and anything that is not a command's name
must still get the whole app.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import click
import pytest
import typer

from dualtwin.cli import app, main, narrowed_to
from dualtwin.cli.policy import harden

NAMES = [info.name or typer.main.get_command_name(info.callback.__name__)
         for info in app.registered_commands if info.callback is not None]
NAMES += [info.name for info in app.registered_groups if info.name]


def described(command: click.Command, parent: click.Context | None, name: str) -> Iterator[tuple[str, Any]]:
    """Everything a user meets of ``command`` and its subcommands: help text, and each parameter's names,
    defaults and flags."""
    ctx = click.Context(command, info_name=name, parent=parent)
    path = ctx.command_path
    yield path, command.get_help(ctx)
    for param in command.params:
        yield path, (param.name, tuple(param.opts), tuple(param.secondary_opts), repr(param.default),
                     param.required, getattr(param, "hidden", False), str(getattr(param, "type", None)))
    for sub_name, sub in sorted(getattr(command, "commands", {}).items()):
        yield from described(sub, ctx, sub_name)


@pytest.fixture(scope="module")
def whole() -> click.Group:
    return harden(typer.main.get_command(app))


def test_every_command_has_a_name_to_narrow_to() -> None:
    assert len(NAMES) == len(set(NAMES)) >= 15
    assert "align" in NAMES and "suite" in NAMES


@pytest.mark.parametrize("name", NAMES)
def test_a_narrowed_command_is_the_whole_apps(whole: click.Group, name: str) -> None:
    narrowed = harden(typer.main.get_command(narrowed_to(name)))
    assert list(narrowed.commands) == [name]
    root = click.Context(whole, info_name="dualtwin")
    narrowed_root = click.Context(narrowed, info_name="dualtwin")
    assert list(described(narrowed.commands[name], narrowed_root, name)) == list(
        described(whole.commands[name], root, name))
    # The group's own options (--verbose, --version) and callback are kept.
    assert [p.opts for p in narrowed.params] == [p.opts for p in whole.params]
    assert narrowed.callback is not None


@pytest.mark.parametrize("first", ["--help", "--verbose", "alig", "no-such-command", "ALIGN"])
def test_anything_else_gets_the_whole_app(first: str) -> None:
    assert narrowed_to(first) is app


def test_running_a_command_builds_that_command_only(monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Counted where typer builds each command (wrapped, not replaced). Control: ``--help`` at the top level
    builds them all."""
    built: list[str] = []
    original = typer.main.get_command_from_info

    def counting(command_info: Any, **kwargs: Any) -> click.Command:
        command = original(command_info, **kwargs)
        built.append(str(command.name))
        return command

    monkeypatch.setattr(typer.main, "get_command_from_info", counting)
    main(["align", "--help"])
    assert "--reference" in capsys.readouterr().out
    assert built == ["align"]
    built.clear()
    main(["--help"])
    assert "align" in capsys.readouterr().out
    assert len(built) >= 15
