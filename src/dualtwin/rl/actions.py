"""What a task accepts as an action: one rule for every task of this package, one env or a batch.

Gymnasium leaves an action outside the space to the environment. Stable-Baselines3 clips a Box policy's
actions to the space before ``step``, so what reaches a task out of range comes from other code (a script,
another trainer, a policy served elsewhere). The rule here:

* a Box action has exactly the task's number of values (a scalar counts as one); a value beyond [-1, 1]
  (±inf included) is clipped, as every task's action contract says (``clip(action, -1, 1) * scale``);
* NaN has no nearest valid value: it raises, naming the task. Before, one task drove its motors with it (the
  CartPole's wheels took a NaN velocity and the run went on), another refused it, a third refused ±inf too;
* a discrete action is one integer: any integer type, a bool, or a float of integral value (``1.0``); ``1.5``
  or a string raises instead of being truncated by ``int()``.

The batch functions apply the same rule to one row per env, so a vector env accepts and refuses exactly what
the same envs stepped one by one do.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError

__all__ = ["batch_box_actions", "batch_discrete_actions", "box_action", "discrete_action"]


def _numbers(action: Any, task: str, expected: str) -> np.ndarray:
    try:
        return np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise DualtwinError(f"{task}: the action is {expected}, got {action!r}") from None


def box_action(action: Any, size: int, task: str) -> np.ndarray:
    """``action`` as ``size`` float64 values clipped to [-1, 1]; wrong size or NaN raise."""
    expected = f"{size} number{'s' if size != 1 else ''}, none NaN"
    values = _numbers(action, task, expected).reshape(-1)
    if values.shape != (size,) or np.isnan(values).any():
        raise DualtwinError(f"{task}: the action is {expected}, got {action!r}")
    return np.clip(values, -1.0, 1.0)


def batch_box_actions(actions: Any, n: int, size: int, task: str) -> np.ndarray:
    """:func:`box_action` for each of ``n`` rows: an (n, size) float64 array."""
    expected = f"{size} number{'s' if size != 1 else ''} per env, none NaN"
    values = _numbers(actions, task, expected)
    if values.size != n * size:
        raise DualtwinError(f"{task}: the action is {expected}, got shape {values.shape} for {n} envs")
    values = values.reshape(n, size)
    bad = np.isnan(values).any(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise DualtwinError(f"{task}: the action is {expected}, got {values[row]!r} for env {row}")
    return np.clip(values, -1.0, 1.0)


def _integral(value: np.ndarray) -> bool:
    kind = value.dtype.kind
    if kind in "biu":
        return True
    return kind == "f" and bool(np.isfinite(value).all()) and bool((value == np.floor(value)).all())


def discrete_action(action: Any, choices: int, task: str) -> int:
    """``action`` as one integer in ``range(choices)``."""
    value = np.asarray(action)
    if value.size != 1 or not _integral(value) or not 0 <= int(value.reshape(-1)[0]) < choices:
        raise DualtwinError(f"{task}: the discrete action is one integer from 0 to {choices - 1}, got {action!r}")
    return int(value.reshape(-1)[0])


def batch_discrete_actions(actions: Any, n: int, choices: int, task: str) -> np.ndarray:
    """:func:`discrete_action` for each of ``n`` envs: an (n,) int64 array."""
    value = np.asarray(actions)
    if value.size != n or not _integral(value):
        raise DualtwinError(f"{task}: the discrete action is one integer from 0 to {choices - 1} per env, "
                            f"got {actions!r}")
    index = value.reshape(n).astype(np.int64)
    bad = (index < 0) | (index >= choices)
    if bad.any():
        raise DualtwinError(f"{task}: the discrete action is one integer from 0 to {choices - 1} per env, "
                            f"got {value.reshape(n)[bad][0]!r}")
    return index
