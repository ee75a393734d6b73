"""Ctrl-C (SIGINT) for the ``dualtwin`` command line: from its first import on, one line and exit 130.

``import dualtwin`` calls :func:`hold_while_loading` first thing in the command line (and ``dualtwin.cli`` once
more, for programs that call its ``main``): a Ctrl-C while the command line is still loading is *held*
(recorded, not raised) until the command itself starts (:func:`command_starts`, after its options are parsed):
then at once for a command that says nothing about what stopping keeps, or once it has said so (:func:`ready`,
called by ``on_interrupt``), at most :data:`HELD_GRACE_S` later. Raising it earlier would stop before the command
could name what is on disk ("3 scenarios kept, resume with --resume"), on a slow machine even after loading.
Only the standard library here: this module must load in microseconds.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from typing import Any

__all__ = ["Interrupted", "came", "command_starts", "enter_native_callbacks", "hold_while_loading", "leave_native_callbacks",
           "ready", "stop_on_interrupt", "take_held"]


class Interrupted(BaseException):
    """Ctrl-C (SIGINT) while a command runs. Not a KeyboardInterrupt: typer would turn that into a silent exit
    130, and library code that handles KeyboardInterrupt its own way must not swallow the user's stop."""


#: [a Ctrl-C is held, it is raised at once (the command has said what stopping keeps), one was raised,
#: the command has started and will say what stopping keeps]
_state = [False, True, False, False]
#: The SIGINT handler found before loading held it (restored when a command ends).
_before_loading: list[Any] = []


#: Seconds a Ctrl-C held while loading waits for the command to say what stopping keeps; then it stops it anyway
#: (a command that never says, or a user who pressed Ctrl-C early, must not wait for the whole command).
HELD_GRACE_S = 2.0


#: How deep the program is in native code that calls back into Python (ODE's collision pass): an exception a
#: ctypes callback raises is printed as "Exception ignored" and lost, and Python runs a signal handler at the
#: first instruction of the next callback, before any ``try`` in it. A Ctrl-C there is held until the native
#: call returns (:func:`leave_native_callbacks`).
_in_native = [0]


def _on_sigint(signum: int, frame: Any) -> None:
    if _state[1] and not _in_native[0]:
        if _within(frame, _on_unraisable):
            # the handler runs inside the hook that re-sends a lost Ctrl-C (a loaded machine ran the re-sent signal
            # before the hook had returned): raised here it would be ignored once more and the stop lost
            _send_again_later()
            return
        _state[0] = False
        _state[2] = True
        raise Interrupted()
    _state[0] = True
    if _state[3] and not _state[1]:  # the command's code runs: it gets its grace to say what stopping keeps
        _release_held_later(HELD_GRACE_S)


def _on_unraisable(unraisable: Any) -> None:
    # Python ignores an exception raised in a weakref callback, a __del__ or a ctypes callback: it prints
    # "Exception ignored ... Traceback" and goes on. A Ctrl-C whose handler ran there was lost that way (a full
    # test run caught compare finishing with exit 0 after one, in a WeakKeyDictionary callback of the plots). It is
    # sent again a moment later, from another thread, so that the handler runs outside the callback (raising it
    # here would raise it inside this hook, ignored again); should that land in a callback too, it comes back here.
    if isinstance(unraisable.exc_value, Interrupted):
        _send_again_later()
        return
    _previous_unraisable[0](unraisable)


def _send_again_later() -> None:
    """SIGINT again in a moment, from another thread, so that the handler runs wherever the main thread is then."""
    timer = threading.Timer(0.001, os.kill, (os.getpid(), signal.SIGINT))
    timer.daemon = True
    timer.start()


def _within(frame: Any, function: Any) -> bool:
    """Whether ``frame`` or a frame that called it runs ``function``."""
    while frame is not None:
        if frame.f_code is function.__code__:
            return True
        frame = frame.f_back
    return False


_previous_unraisable: list[Any] = [sys.unraisablehook]


def _catch_lost_interrupts() -> None:
    if sys.unraisablehook is not _on_unraisable:
        _previous_unraisable[0] = sys.unraisablehook
        sys.unraisablehook = _on_unraisable


def enter_native_callbacks() -> None:
    """A native call that calls back into Python starts: a Ctrl-C is held until :func:`leave_native_callbacks`.

    Only in the main thread, the one signal handlers run in: a native call in another thread (a controller
    process's serving thread steps the physics) is never interrupted by the handler, and a Ctrl-C held for it
    would be raised in that thread, where it kills the thread instead of stopping the command."""
    if threading.current_thread() is threading.main_thread():
        _in_native[0] += 1


def leave_native_callbacks() -> None:
    """The native call returned: a Ctrl-C held meanwhile (with the command ready to stop) is raised now."""
    if threading.current_thread() is not threading.main_thread():
        return
    _in_native[0] -= 1
    if not _in_native[0] and _state[0] and _state[1]:
        take_held()


def _release_held_later(seconds: float) -> None:
    def release() -> None:
        if _state[0] and not _state[1]:
            _state[1] = True
            os.kill(os.getpid(), signal.SIGINT)  # delivered to the main thread, where the handler raises

    timer = threading.Timer(seconds, release)
    timer.daemon = True
    timer.start()


def came() -> bool:
    """A Ctrl-C was raised in this command: whatever it turned into (code that wraps exceptions, such as
    ctypes' ArgumentError mid-import or an ImportError, loses the Interrupted), the command was interrupted."""
    return _state[2]


def _in_charge() -> bool:
    """Only where Python lets us (the main thread) and where SIGINT is not ignored (a job started in the
    background by a shell ignores it on purpose)."""
    if threading.current_thread() is not threading.main_thread():
        return False
    current = signal.getsignal(signal.SIGINT)
    return current is not signal.SIG_IGN and current is not None


def is_command_line() -> bool:
    """This program is the ``dualtwin`` command: its script, ``python -m dualtwin.cli`` or ``python -c`` code
    that imports ``dualtwin.cli`` (as the tests start it)."""
    argv = list(getattr(sys, "orig_argv", sys.argv))
    if sys.argv and os.path.basename(sys.argv[0]) == "dualtwin":
        return True
    return any(flag in argv[:-1] and "dualtwin.cli" in argv[argv.index(flag) + 1] for flag in ("-m", "-c"))


def hold_while_loading(only_command_line: bool = False) -> None:
    """Hold a Ctrl-C that comes while the command line loads (``only_command_line``: only in the command)."""
    if not _in_charge() or signal.getsignal(signal.SIGINT) is _on_sigint:
        return
    if only_command_line and not is_command_line():
        return
    _before_loading.append(signal.getsignal(signal.SIGINT))
    _state[1] = False
    signal.signal(signal.SIGINT, _on_sigint)
    _catch_lost_interrupts()


def loaded() -> None:
    """The command line has loaded. In the ``dualtwin`` command a Ctrl-C stays held (one that comes between here
    and :func:`stop_on_interrupt` too); in a program that imports ``dualtwin.cli`` of its own, if nothing is
    held, the previous handler comes back (nothing changes for it)."""
    if is_command_line():
        return
    if not _state[0] and _before_loading and signal.getsignal(signal.SIGINT) is _on_sigint:
        signal.signal(signal.SIGINT, _before_loading.pop())
        _state[1] = True


def stop_on_interrupt() -> Any:
    """Route SIGINT to :class:`Interrupted` for a command's duration; the handler to restore (None: unchanged).

    A Ctrl-C (held while loading, or coming while the options are parsed) is held until :func:`command_starts`.
    """
    if not _in_charge():
        return None
    previous = signal.getsignal(signal.SIGINT)
    if previous is _on_sigint:
        previous = _before_loading.pop() if _before_loading else signal.default_int_handler
    _state[1] = False
    _state[2] = False
    _state[3] = False
    signal.signal(signal.SIGINT, _on_sigint)
    _catch_lost_interrupts()
    return previous


def command_starts(says_what_stopping_keeps: bool) -> None:
    """The command's own code starts (its options parsed). One that will say what stopping keeps (by
    :func:`ready`) has :data:`HELD_GRACE_S` to say it; any other is stopped now by a Ctrl-C held until here."""
    if not says_what_stopping_keeps:
        ready()
        return
    _state[3] = True
    if _state[0]:
        _release_held_later(HELD_GRACE_S)


def ready() -> None:
    """The command has said what an interruption keeps: from now on Ctrl-C stops it at once, a held one now."""
    _state[1] = True
    take_held()


def take_held() -> None:
    """Raise :class:`Interrupted` for a Ctrl-C held until now."""
    if _state[0]:
        _state[0] = False
        _state[2] = True
        raise Interrupted()
