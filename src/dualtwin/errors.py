"""Errors the user sees. The CLI prints their message on one line and exits with code 2."""

from __future__ import annotations


class DualtwinError(ValueError):
    """Bad input: a file, a name or a value the user can fix. The message says where and what."""


class SimulationUnstable(RuntimeError):
    """The physics produced non-finite values. The scenario is marked unstable; a reset recovers."""


def quiet_interrupts_in_cli(argv0: str, orig_argv: list[str] | None = None) -> None:
    """In the ``dualtwin`` command (``argv0``, or ``python -m dualtwin[.cli]`` in ``orig_argv``), Ctrl-C while
    Python is still importing is one line and exit 130.

    ``import dualtwin`` calls this first thing: the command line's own handler (``dualtwin.cli.main``) is not
    in place until the package has loaded, and an uncaught KeyboardInterrupt would print an import traceback.
    In any other program (a script, a notebook) nothing changes.
    """
    import os
    import sys

    args = list(orig_argv or [])
    as_module = any(a == "-m" and args[i + 1:i + 2] in (["dualtwin"], ["dualtwin.cli"])
                    for i, a in enumerate(args))
    if os.path.basename(argv0) != "dualtwin" and not as_module:
        return
    previous = sys.excepthook

    def hook(kind: type[BaseException], value: BaseException, tb: object) -> None:
        if issubclass(kind, KeyboardInterrupt):
            sys.stderr.write("error: interrupted\n")
            sys.stderr.flush()
            os._exit(130)
        previous(kind, value, tb)  # type: ignore[arg-type]

    sys.excepthook = hook
