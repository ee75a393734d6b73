"""Webots' Keyboard, headless: no key is ever pressed, unless a key script replays presses at given times.

Key script format (``dualtwin webots run --keys FILE``), one press per line, ``#`` starts a comment::

    # time_s  key          [hold_s]     ('#' after a blank or at the start of a line: a comment)
    0.50      UP                       # pressed for one keyboard sample
    1.00      SHIFT+LEFT   0.25        # held from 1.00 s to 1.25 s: read at every sample in between
    2.0       a                        # letters are reported upper-case, as Webots reports them
    3.0       65                       # a raw key code

Times are simulated seconds since the run started, counted across ``simulationReset`` (the run's clock, the
one ``--duration`` bounds). A press without a hold time is delivered once, at the first keyboard sample at or
after its time; a held key at every sample in ``[time, time + hold)``. Each sample holds at most 7 keys (as in
Webots), in file order; ``getKey()`` returns them one by one, then -1; the list is cleared at the next step.
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualtwin.artifacts import check_input_file
from dualtwin.errors import DualtwinError
from dualtwin.webots.api_args import as_int
from dualtwin.webots.device_base import current_host

__all__ = ["KEY_NAMES", "KeyEvent", "KeyScript", "Keyboard", "key_code", "load_key_script"]

#: Special keys (codes from Webots' keyboard.h).
KEY_NAMES = {
    "END": 312, "HOME": 313, "LEFT": 314, "UP": 315, "RIGHT": 316, "DOWN": 317, "PAGEUP": 366, "PAGEDOWN": 367,
    "NUMPAD_HOME": 375, "NUMPAD_LEFT": 376, "NUMPAD_UP": 377, "NUMPAD_RIGHT": 378, "NUMPAD_DOWN": 379,
    "NUMPAD_END": 382, "SPACE": 32,
}
MODIFIERS = {"SHIFT": 0x10000, "CONTROL": 0x20000, "CTRL": 0x20000, "ALT": 0x40000}
MAX_KEYS = 7  # simultaneous keys per sample
_COMMENT = re.compile(r"(^|\s)#.*$")


def key_code(token: str) -> int:
    """Code of a key written as ``[MODIFIER+]...KEY``: a name, one printable character or a number.

    Raises:
        ValueError: an unknown name or modifier.
    """
    *mods, key = token.split("+") if token != "+" else ["+"]
    if key == "" and token.endswith("+"):  # "SHIFT++" means SHIFT and the '+' key
        mods, key = mods[:-1], "+"
    code = 0
    for mod in mods:
        if mod.upper() not in MODIFIERS:
            raise ValueError(f"unknown modifier {mod!r} (SHIFT, CONTROL, ALT)")
        code |= MODIFIERS[mod.upper()]
    if key.upper() in KEY_NAMES:
        return code | KEY_NAMES[key.upper()]
    if len(key) == 1 and key.isprintable():
        return code | ord(key.upper())
    if key.isdigit():
        value = int(key)
        if value > 0xFFFF:
            raise ValueError(f"key code {value} is larger than 65535 (use SHIFT+, CONTROL+, ALT+ for modifiers)")
        return code | value
    raise ValueError(f"unknown key {key!r} (a character, a code or one of {', '.join(KEY_NAMES)})")


@dataclass(frozen=True)
class KeyEvent:
    time: float
    code: int
    hold: float | None  # None: one sample


class KeyScript:
    """Scripted key presses; ``keys_at`` is called at each keyboard sample with the run's clock."""

    def __init__(self, events: list[KeyEvent]) -> None:
        self.events = sorted(events, key=lambda e: e.time)  # stable: file order among equal times
        self._delivered: set[int] = set()

    def keys_at(self, now: float) -> list[int]:
        out: list[int] = []
        for index, event in enumerate(self.events):
            if event.time > now + 1e-9:
                break
            if event.hold is None:
                if index in self._delivered:
                    continue
                self._delivered.add(index)
            elif now >= event.time + event.hold - 1e-9:
                continue
            if len(out) < MAX_KEYS:
                out.append(event.code)
        return out


def load_key_script(path: str | Path) -> KeyScript:
    """Read and check a key script (format in the module docstring).

    Raises:
        DualtwinError: naming the file and line (and the ``--keys`` option).
    """
    path = Path(path)
    try:
        check_input_file(path, "key script")  # a pipe would block the read forever
        text = path.read_bytes().decode("utf-8")
    except DualtwinError as exc:
        raise DualtwinError(f"--keys {exc}") from None
    except UnicodeDecodeError:
        raise DualtwinError(f"--keys {path}: not UTF-8 text") from None
    except OSError as exc:
        raise DualtwinError(f"--keys {path}: cannot read: {exc.strerror or exc}") from None
    events: list[KeyEvent] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = _COMMENT.sub("", raw).strip()  # '#' after a blank starts a comment; "SHIFT+#" is a key
        if not line:
            continue
        parts = line.split()
        where = f"--keys {path}:{number}"
        if len(parts) not in (2, 3):
            raise DualtwinError(f"{where}: expected 'TIME KEY [HOLD]', found {raw.strip()!r}")
        try:
            time = float(parts[0])
        except ValueError:
            raise DualtwinError(f"{where}: time {parts[0]!r} is not a number of seconds") from None
        if not math.isfinite(time) or time < 0:
            raise DualtwinError(f"{where}: time must be finite and >= 0, got {parts[0]}")
        try:
            code = key_code(parts[1])
        except ValueError as exc:
            raise DualtwinError(f"{where}: {exc}") from None
        hold: float | None = None
        if len(parts) == 3:
            try:
                hold = float(parts[2])
            except ValueError:
                raise DualtwinError(f"{where}: hold {parts[2]!r} is not a number of seconds") from None
            if not math.isfinite(hold) or hold <= 0:
                raise DualtwinError(f"{where}: hold must be finite and > 0, got {parts[2]}")
        events.append(KeyEvent(time, code, hold))
    return KeyScript(events)


class Keyboard:
    """Webots ``Keyboard`` (``robot.keyboard`` / ``robot.getKeyboard()``): the robot's own is created disabled
    (``Keyboard(0)``); ``Keyboard()`` enables at the basic time step. Headless, ``getKey()`` is -1 unless the run
    replays a key script."""

    END, HOME, LEFT, UP, RIGHT, DOWN = 312, 313, 314, 315, 316, 317
    PAGEUP, PAGEDOWN = 366, 367
    NUMPAD_HOME, NUMPAD_LEFT, NUMPAD_UP, NUMPAD_RIGHT, NUMPAD_DOWN, NUMPAD_END = 375, 376, 377, 378, 379, 382
    KEY, SHIFT, CONTROL, ALT = 0xFFFF, 0x10000, 0x20000, 0x40000

    def __init__(self, sampling_period: Any = None) -> None:
        host = current_host()
        self._robot = host
        self._script: KeyScript | None = getattr(getattr(host, "_runtime", None), "keys", None)
        self._period = 0
        self._since: float | None = None
        self._keys: list[int] = []
        host.inputs.append(self)
        if sampling_period is None:
            self.enable(int(host.getBasicTimeStep()))
        elif sampling_period:
            self.enable(sampling_period)

    def enable(self, p: Any) -> None:
        period = as_int(p, "Keyboard.enable")
        if period <= 0:
            self.disable()
            return
        self._period = period
        self._since = self._robot.getTime()

    def disable(self) -> None:
        self._period = 0
        self._keys = []

    def getSamplingPeriod(self) -> int:
        return self._period

    @property
    def sampling_period(self) -> int:
        return self._period

    @sampling_period.setter
    def sampling_period(self, p: Any) -> None:
        self.enable(0 if p is None else p)

    def getKey(self) -> int:
        if self._period == 0:  # an error at every read, as for any disabled device
            print("Error: Keyboard.getKey() called on a disabled keyboard; call Keyboard.enable() first",
                  file=sys.stderr)
            return -1
        return self._keys.pop(0) if self._keys else -1

    def getKeyCode(self) -> int:
        return self.getKey()

    def get_key(self) -> str:
        """The next key as text, e.g. ``'shift-a'``, ``'alt-x'`` or ``'up'``; '' when none. (Webots' helper spells
        the Alt modifier ``'atl-'``, a typo in its code; we write what it means, see docs/webots-coverage.md.)"""
        code = self.getKey()
        if code == -1:
            return ""
        text = "".join(prefix for bit, prefix in ((self.SHIFT, "shift-"), (self.CONTROL, "control-"),
                                                  (self.ALT, "alt-")) if code & bit)
        key = code & self.KEY
        special = next((name.lower() for name, value in KEY_NAMES.items() if value == key and name != "SPACE"), None)
        return text + (special if special is not None else chr(key).lower())

    # -- called by Robot.step

    def _after_step(self, now: float, clock: float) -> None:
        """Clear last step's keys; at a sampling instant, read the keys pressed at the run's ``clock``."""
        self._keys = []
        if self._period == 0 or self._since is None:
            return
        if (now - self._since) * 1000.0 >= self._period - 1e-6:
            self._since = now
            if self._script is not None:
                self._keys = self._script.keys_at(clock)

    def _after_reset(self) -> None:
        if self._period:
            self._since = 0.0
        self._keys = []
