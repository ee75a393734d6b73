"""Webots' ``Motion``: plays a ``.motion`` file (key poses of named motors) on the robot's motors.

File format (Webots'): a header ``#WEBOTS_MOTION,V1.0,motor1,motor2,...`` then one line per pose,
``MM:SS:mmm,PoseName,value1,value2,...``, where ``*`` leaves a motor out of that pose. While playing, each motor's
target position is interpolated linearly between the poses that set it and sent with every step; ``setLoop`` and
``setReverse`` change how the time runs; a motion that is over keeps its last targets. Motors that the robot does
not have are ignored, as Webots ignores them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from dualtwin.webots.api_args import as_int, warn
from dualtwin.webots.device_base import current_host

__all__ = ["Motion"]


def _parse(path: Path) -> tuple[list[str], list[tuple[int, list[float | None]]]] | None:
    try:
        lines = [ln.strip() for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip()]
    except (OSError, UnicodeDecodeError):
        return None
    if not lines or not lines[0].startswith("#WEBOTS_MOTION"):
        return None
    header = lines[0].split(",")
    motors = [m.strip() for m in header[2:]]
    poses: list[tuple[int, list[float | None]]] = []
    for line in lines[1:]:
        parts = [p.strip() for p in line.split(",")]
        try:
            minutes, seconds, millis = (int(x) for x in parts[0].split(":"))
            values = [None if p == "*" else float(p) for p in parts[2:2 + len(motors)]]
        except ValueError:
            return None
        poses.append(((minutes * 60 + seconds) * 1000 + millis, values))
    return motors, poses


class Motion:
    """Webots ``Motion``: ``Motion(filename)``, then ``play()``; the robot's step drives it."""

    def __init__(self, filename: str) -> None:
        host = current_host()
        self._robot = host
        parsed = _parse(Path(str(filename)))
        if parsed is None:
            warn(f"Motion(): could not read motion file {filename!r}")
        self._motors, self._poses = parsed if parsed is not None else ([], [])
        self._time = 0
        self._playing = False
        self._loop = False
        self._reverse = False
        host.inputs.append(self)

    def isValid(self) -> bool:
        return bool(self._poses)

    def getDuration(self) -> int:
        return self._poses[-1][0] if self._poses else 0

    def getTime(self) -> int:
        return int(self._time)

    def setTime(self, time: Any) -> None:
        self._time = min(max(as_int(time, "Motion.setTime"), 0), self.getDuration())

    def play(self) -> None:
        self._playing = self.isValid()
        self._apply()

    def stop(self) -> None:
        self._playing = False

    def setLoop(self, loop: Any) -> None:
        self._loop = bool(loop)

    def setReverse(self, reverse: Any) -> None:
        self._reverse = bool(reverse)

    def isOver(self) -> bool:
        end = 0 if self._reverse else self.getDuration()
        return not self._loop and self._time == end

    duration = property(lambda self: self.getDuration())

    @property
    def time(self) -> int:
        return self.getTime()

    @time.setter
    def time(self, time: Any) -> None:
        self.setTime(time)

    # -- driven by the robot's step

    def _target(self, column: int) -> float | None:
        keyed = [(t, values[column]) for t, values in self._poses if column < len(values) and values[column] is not None]
        if not keyed:
            return None
        before = [(t, v) for t, v in keyed if t <= self._time]
        after = [(t, v) for t, v in keyed if t > self._time]
        if not before:
            return after[0][1]
        if not after:
            return before[-1][1]
        (t0, v0), (t1, v1) = before[-1], after[0]
        assert v0 is not None and v1 is not None
        return v0 + (v1 - v0) * (self._time - t0) / (t1 - t0)

    def _apply(self) -> None:
        for column, name in enumerate(self._motors):
            rec = self._robot._rec.devices.get(name)
            target = self._target(column)
            if rec is None or target is None or not math.isfinite(target):
                continue
            motor = self._robot._device_for(rec)
            if hasattr(motor, "setPosition"):
                motor.setPosition(target)

    def _after_step(self, now: float, clock: float) -> None:
        if not self._playing:
            return
        dt = int(round(self._robot._sim.basic_time_step))
        duration = self.getDuration()
        t = self._time + (-dt if self._reverse else dt)
        if self._loop and duration > 0:
            t %= duration
        self._time = min(max(t, 0), duration)
        self._apply()

    def _after_reset(self) -> None:
        pass
