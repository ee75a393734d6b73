"""The ``dualtwin`` command line. Thin: every command calls into a package and prints.

One module per command group; importing them registers their commands on :data:`app`, in the order
``--help`` lists them. :func:`main` is the entry point (``dualtwin.cli:main``).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import typer

# Importing a command module registers its commands; this order is the order ``--help`` lists them in.
# isort: off
from dualtwin.cli import suite, compare, align, rl, perception, serve, sync, demo, webots, convert, recorded  # noqa: F401
# isort: on
from dualtwin.cli.common import app
from dualtwin.cli.policy import harden
from dualtwin.errors import DualtwinError

__all__ = ["app", "main", "one_line"]


def one_line(message: str) -> str:
    """The error promise: one line, whatever the message's own line breaks."""
    return "; ".join(part.strip() for part in str(message).splitlines() if part.strip())


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: user errors become one line on stderr and exit code 2, never a traceback.

    Usage errors (unknown option, bad number, missing option) are printed by us, not by click/typer's boxes, so
    they keep the same one-line form; ``argv`` (default ``sys.argv[1:]``) lets tests call this in-process.
    """
    from typer.exceptions import Abort, TyperException

    code = 0
    try:
        command = harden(typer.main.get_command(app))
        result = command.main(args=list(sys.argv[1:] if argv is None else argv), prog_name="dualtwin",
                              standalone_mode=False)
        code = result if isinstance(result, int) else 0
    except Abort:
        print("error: interrupted", file=sys.stderr)
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
    except OSError as exc:
        # A file the user named cannot be read or written (permissions, a folder where a file belongs, a full
        # disk): their input, not our bug. Errors without a file name are bugs and keep their traceback.
        if exc.filename is None:
            raise
        print(f"error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        code = 2
    sys.stdout.flush()
    if argv is None:
        sys.exit(code)
    return code
