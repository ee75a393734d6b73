"""The CLI's promise on option values, applied to every parameter of every command."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from dualtwin.errors import DualtwinError
from dualtwin.interrupts import command_starts

# Ranges for numeric options, by option name, the same in every command (a new command's --seed is checked like
# every other). (low, high): None means unbounded; high may be a float for float options. Numeric options not
# named here must be >= 0. Every float option must be finite. Violations are usage errors naming the option.
MAX_SEED = 2**32 - 1
OPTION_RANGES: dict[str, tuple[float | None, float | None]] = {
    "seed": (0, MAX_SEED), "port": (1, 65535), "episodes": (1, 1_000_000), "budget": (1, 10_000_000),
    "epochs": (1, 100_000), "steps": (1, 10**10), "stride": (1, 1_000_000), "width": (8, 4096),
    "height": (8, 4096), "max_iterations": (1, 100), "workers": (1, 1024), "shadow_fraction": (0, 1),
    "duration": (0, 86_400), "ensemble": (0, 10_000), "horizons": (1, 1_000_000),
}


def _check_number(name: str, value: float) -> str | None:
    """Why ``value`` is not acceptable for the option ``name`` (see OPTION_RANGES), or None."""
    import math

    low, high = OPTION_RANGES.get(name, (0, None))
    if isinstance(value, float) and not math.isfinite(value):
        return f"{value!r} is not a finite number"
    if (low is not None and value < low) or (high is not None and value > high):
        def text(bound: float) -> str:
            return str(int(bound)) if float(bound).is_integer() else f"{bound:g}"

        return f"{value!r} is out of range (must be " + (
            f"from {text(low or 0)} to {text(high)})" if high is not None else f">= {text(low or 0)})")
    return None


def _policy_callback(original: Any) -> Any:
    """A parameter callback applying the option policies to the converted value, then ``original``'s."""

    def callback(ctx: Any, param: Any, value: Any) -> Any:
        option = (param.opts or [param.name or "?"])[0]
        values = value if isinstance(value, list | tuple) else [value]
        for item in values:
            if isinstance(item, int | float) and not isinstance(item, bool):
                problem = _check_number(param.name or "", item)
                if problem:
                    raise DualtwinError(f"{option}: {problem}")
        if param.name == "scenarios" and isinstance(value, Path):
            # A bundled robot's name means its bundled suite, from any folder (suite.loader.resolve_suite).
            from dualtwin.suite.loader import resolve_suite

            try:
                value = resolve_suite(value)
            except DualtwinError as exc:
                raise DualtwinError(f"{option}: {exc}") from None
        return original(ctx, param, value) if original is not None else value

    return callback


#: Every ``--scenarios`` takes a bundled robot's name as well as a file (see _policy_callback); said in its help.
SCENARIOS_HELP = "suite JSON file, or a bundled robot's name (cartpole ...) for its suite"


def _help_text(param: Any) -> None:
    """Help that says what the option takes: flags show no value type (typer prints ``<bool>``), and every
    ``--scenarios`` says it takes a bundled name as well as a file."""
    if getattr(param, "is_flag", False) and getattr(param, "metavar", None) is None:
        param.metavar = ""
    if param.name == "scenarios" and "bundled" not in (param.help or ""):
        extra = (param.help or "").replace("suite JSON file", "").strip(" ,;")
        param.help = SCENARIOS_HELP + (f"; {extra}" if extra else "")


def _flag_help_option(original: Any) -> Any:
    def get_help_option(ctx: Any) -> Any:
        option = original(ctx)
        if option is not None:
            option.metavar = ""
        return option

    return get_help_option


def _starting(callback: Any) -> Any:
    """A command's code, told to the Ctrl-C handling first: a Ctrl-C held until its options were parsed stops it
    now, or (a :func:`dualtwin.cli.common.resumable` command) once it has said what stopping keeps."""
    says = bool(getattr(callback, "says_what_stopping_keeps", False))

    @functools.wraps(callback)
    def run(*args: Any, **kwargs: Any) -> Any:
        command_starts(says)
        return callback(*args, **kwargs)

    run._dualtwin_starting = True  # type: ignore[attr-defined]
    return run


def harden(command: Any) -> Any:
    """Apply the option policies above to every parameter of every command, recursively (new commands too), and
    tell the Ctrl-C handling when each command's own code starts."""
    if (not hasattr(command, "commands") and command.callback is not None
            and not getattr(command.callback, "_dualtwin_starting", False)):
        command.callback = _starting(command.callback)
    for param in command.params:
        if not getattr(param, "_dualtwin_policy", False):
            param.callback = _policy_callback(param.callback)
            param._dualtwin_policy = True
            _help_text(param)
    if not getattr(command, "_dualtwin_help", False):
        command.get_help_option = _flag_help_option(command.get_help_option)
        command._dualtwin_help = True
    for sub in getattr(command, "commands", {}).values():
        harden(sub)
    return command
