"""The ``dualtwin`` command line. Thin: every command calls into a package and prints.

One module per command group; importing them registers their commands on :data:`app`, in the order
``--help`` lists them. :func:`main` is the entry point (``dualtwin.cli:main``).
"""

from __future__ import annotations

import copy
import errno
import signal
import sys
import warnings
from collections.abc import Sequence

from dualtwin.interrupts import Interrupted, came, hold_while_loading, loaded, stop_on_interrupt, take_held

hold_while_loading()  # before typer and the command modules: a Ctrl-C from here on is ours to report

try:
    import typer

    # Importing a command module registers its commands; this order is the order ``--help`` lists them in.
    # Command modules import only typer and light dualtwin modules: each command imports what it needs when it
    # runs (``dualtwin --help`` and a bad-input error cost no NumPy, SciPy, matplotlib, MuJoCo or torch;
    # tests/test_cli_startup.py holds that).
    # isort: off
    from dualtwin.cli import suite, compare, align, rl, perception, serve, sync, demo, webots, convert, recorded  # noqa: F401
    # isort: on
    from dualtwin.cli.common import app, interrupted_note
    from dualtwin.cli.policy import harden
    from dualtwin.errors import DualtwinError
except (KeyboardInterrupt, Interrupted):  # Ctrl-C while the command line is still loading: a normal way to stop, too
    print("error: interrupted", file=sys.stderr)
    raise SystemExit(130) from None

loaded()

__all__ = ["Interrupted", "app", "main", "narrowed_to", "one_line"]

#: OS errors that are about the machine, not the program: a full disk or quota, an I/O error, a read-only
#: file system, a file over the size limit. Always one line, never a traceback (and never exit 0).
_MACHINE_ERRORS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS, errno.EFBIG}


def one_line(message: str) -> str:
    """The error promise: one line, whatever the message's own line breaks."""
    return "; ".join(part.strip() for part in str(message).splitlines() if part.strip())


def _warning_line(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  line: str | None = None) -> str:
    """A warning raised while a command runs (a world's node we do not simulate, a library's complaint), shown
    as the command line shows its own: one ``warning:`` line, not Python's ``file:line: UserWarning`` and the
    source line under it."""
    return f"warning: {one_line(str(message))}\n"


def narrowed_to(name: str) -> typer.Typer:
    """``app`` with only its command (or command group) ``name``; ``app`` itself when no command has that name.

    typer builds a click command for every registered command before it parses anything, reading each
    function's signature and type hints: about 50 ms for the ~40 commands. A command line that starts with a
    command's name runs only that command, under the same group (its callback and global options), so building
    that one gives the same parsing, help and errors; anything else (an option first, a typo that click
    suggests a command for, no command) gets the whole app."""
    commands = [info for info in app.registered_commands
                if (info.name or typer.main.get_command_name(info.callback.__name__ if info.callback else "")) == name]
    groups = [info for info in app.registered_groups if info.name == name]
    if len(commands) + len(groups) != 1:
        return app
    narrowed = copy.copy(app)
    narrowed.registered_commands, narrowed.registered_groups = commands, groups
    return narrowed


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: user errors become one line on stderr and exit code 2, never a traceback.

    Usage errors (unknown option, bad number, missing option) are printed by us, not by click/typer's boxes, so
    they keep the same one-line form; ``argv`` (default ``sys.argv[1:]``) lets tests call this in-process.
    """
    from typer.exceptions import Abort, TyperException

    code = 0
    interrupted_note(reset=True)
    previous = stop_on_interrupt()
    previous_format = warnings.formatwarning
    warnings.formatwarning = _warning_line
    try:
        args = list(sys.argv[1:] if argv is None else argv)
        command = harden(typer.main.get_command(narrowed_to(args[0]) if args else app))
        result = command.main(args=args, prog_name="dualtwin", standalone_mode=False)
        code = result if isinstance(result, int) else 0
        take_held()  # a Ctrl-C held while loading, for a command that never said what stopping keeps
    except (Interrupted, Abort, KeyboardInterrupt):
        # Ctrl-C is a normal way to stop: every file is written whole or not at all (dualtwin.artifacts), so
        # what was finished is kept; the note says how much and how to continue, where a command can.
        print(f"error: interrupted{interrupted_note()}", file=sys.stderr)
        code = 130
    except TyperException as exc:  # click's usage errors, as vendored by typer: bad value, missing option...
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
            print(ctx.get_help())  # a group without a subcommand: its help, as before
        else:
            where = f"{ctx.command_path}: " if ctx is not None else ""
            print(f"error: {where}{one_line(exc.format_message())}", file=sys.stderr)
        code = getattr(exc, "exit_code", 2) or 2
    except DualtwinError as exc:
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        code = 2
    except RecursionError:
        # A structure too deep for the interpreter (every reader of ours refuses deep files first; this is the
        # net under readers of other formats).
        print("error: an input is nested too deeply to read", file=sys.stderr)
        code = 2
    except OSError as exc:
        # A file the user named cannot be read or written (permissions, a folder where a file belongs, a full
        # disk): their input or their machine, not our bug. A full disk or an I/O error is one line even where
        # the writer could not say which file it was; other errors without a file name keep their traceback.
        if came():
            print(f"error: interrupted{interrupted_note()}", file=sys.stderr)
            code = 130
        elif exc.filename is None and exc.errno not in _MACHINE_ERRORS:
            raise
        else:
            where = f"{exc.filename}: " if exc.filename is not None else ""
            print(f"error: {where}{exc.strerror or exc}", file=sys.stderr)
            code = 2
    except Exception:  # after the errors above: a user's error stays theirs
        if not came():
            raise
        # A Ctrl-C that code on the way wrapped into another error (ctypes mid-import: ArgumentError).
        print(f"error: interrupted{interrupted_note()}", file=sys.stderr)
        code = 130
    finally:
        warnings.formatwarning = previous_format
        if previous is not None:
            # The program ends here (argv None): a late Ctrl-C has nothing left to stop, and Python restores the
            # default action while it finalises (killed by SIGINT: exit -2 after a finished run).
            signal.signal(signal.SIGINT, signal.SIG_IGN if argv is None else previous)
    sys.stdout.flush()
    if argv is None:
        sys.exit(code)
    return code
