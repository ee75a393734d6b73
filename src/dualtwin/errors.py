"""Errors the user sees. The CLI prints their message on one line and exits with code 2."""

from __future__ import annotations


class DualtwinError(ValueError):
    """Bad input: a file, a name or a value the user can fix. The message says where and what."""


class SimulationUnstable(RuntimeError):
    """The physics produced non-finite values. The scenario is marked unstable; a reset recovers."""
