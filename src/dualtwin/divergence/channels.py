"""State-difference channels and their normalisation.

A state difference (:meth:`dualtwin.twins.base.MechanicalState.difference`) has one channel per body
coordinate (``body/<b>/x`` … ``body/<b>/wz``, orientation as a rotation vector ``rx ry rz``) and per joint
(``joint/<j>/q``, ``joint/<j>/qd``). Channels carry units, so they are divided by a *scale* before they are
combined. The default scales are natural units of a table-top robot:

=================  =========  =====================================================================
channel            scale      meaning of 1.0
=================  =========  =====================================================================
``x y z``          0.1 m      10 cm off
``rx ry rz``       0.1 rad    6 degrees off
``vx vy vz``       0.5 m/s    half a metre per second off
``wx wy wz``       1 rad/s    one radian per second off
``q``              0.1 rad    6 degrees (or 10 cm for a slider) off
``qd``             1 rad/s    one radian (or metre) per second off
=================  =========  =====================================================================

Override them per channel with fnmatch patterns (``{"joint/wheel*/q": math.inf}`` ignores wheel angles,
which drift freely on a skid-steer robot). The *normalised state error* is the root mean square of the scaled
differences over the channels with a finite scale: 0 when the twins agree, about 1 when every channel is one
scale unit off.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Iterable, Mapping

import numpy as np

from dualtwin.geometry import relative_rotation_vectors
from dualtwin.twins.base import MechanicalState, check_same_entities

DEFAULT_UNIT_SCALES: dict[str, float] = {
    "x": 0.1, "y": 0.1, "z": 0.1, "rx": 0.1, "ry": 0.1, "rz": 0.1,
    "vx": 0.5, "vy": 0.5, "vz": 0.5, "wx": 1.0, "wy": 1.0, "wz": 1.0,
    "q": 0.1, "qd": 1.0,
}


#: Unit of a state channel by its last name part. A joint's ``q``/``qd`` is an angle for a hinge and a length
#: for a slider; the state does not say which, so its unit names both.
CHANNEL_UNITS: dict[str, str] = {
    "x": "m", "y": "m", "z": "m", "rx": "rad", "ry": "rad", "rz": "rad",
    "vx": "m/s", "vy": "m/s", "vz": "m/s", "wx": "rad/s", "wy": "rad/s", "wz": "rad/s",
    "q": "rad or m", "qd": "rad/s or m/s",
}


def channel_unit(name: str) -> str:
    """Unit of a state-difference channel (``body/cart/vx`` → ``m/s``); ``hold/...`` entries are positions."""
    last = name.rsplit("/", 1)[-1]
    if name.startswith("hold/"):
        return CHANNEL_UNITS["q"]
    return CHANNEL_UNITS.get(last, "unit not recorded")


def channel_scales(channels: Iterable[str], overrides: Mapping[str, float] | None = None) -> dict[str, float]:
    """Scale of every channel: the default for its last name part, replaced by the first matching override."""
    out: dict[str, float] = {}
    patterns = dict(overrides or {})
    for name in channels:
        scale = DEFAULT_UNIT_SCALES.get(name.rsplit("/", 1)[-1], 1.0)
        for pattern, value in patterns.items():
            if pattern == name or fnmatch.fnmatchcase(name, pattern):
                scale = float(value)
                break
        if not scale > 0:
            raise ValueError(f"channel {name!r}: scale must be positive (inf ignores the channel), got {scale}")
        out[name] = scale
    return out


def normalized(diff: Mapping[str, float], scales: Mapping[str, float]) -> dict[str, float]:
    """Each channel divided by its scale (channels with an infinite scale are left out)."""
    return {k: v / scales[k] for k, v in diff.items() if math.isfinite(scales[k])}


def normalized_error(diff: Mapping[str, float], scales: Mapping[str, float]) -> float:
    """Root mean square of the scaled differences (0 for identical states)."""
    values = np.array(list(normalized(diff, scales).values()), dtype=float)
    if values.size == 0:
        return 0.0
    return float(np.sqrt(np.mean(values ** 2)))


class DiffLayout:
    """Vectorised state differences between two twins whose states name the same bodies and joints.

    Built once from a state of each twin: it maps the secondary's state vector onto the primary's order and
    computes :meth:`~dualtwin.twins.base.MechanicalState.difference` for many rows at once (the channels and
    their order are :meth:`~dualtwin.twins.base.MechanicalState.diff_channels` of the primary).
    """

    def __init__(self, primary: MechanicalState, secondary: MechanicalState) -> None:
        check_same_entities(primary, secondary, "the primary", "the secondary")
        self.bodies = list(primary.bodies)
        self.joints = list(primary.joint_positions)
        self.core = 13 * len(self.bodies) + 2 * len(self.joints)
        layout = primary.layout()[: self.core]
        where = {name: i for i, name in enumerate(secondary.layout())}
        self.permutation = np.array([where[name] for name in layout], dtype=int)
        self.channels = primary.diff_channels()

    def vectors(self, primary: MechanicalState | np.ndarray,
                secondary: MechanicalState | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The two states' core vectors (no holds), in the primary's order (states or their ``vector()``)."""
        a = primary.vector() if isinstance(primary, MechanicalState) else primary
        b = secondary.vector() if isinstance(secondary, MechanicalState) else secondary
        return a[: self.core], b[self.permutation]

    def differences(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(rows, channels) of ``b - a`` for state-vector rows ``a`` (primary) and ``b`` (secondary)."""
        a, b = np.atleast_2d(a), np.atleast_2d(b)
        n = a.shape[0]
        out = np.empty((n, len(self.channels)))
        col = 0
        for i in range(len(self.bodies)):
            s = 13 * i
            out[:, col:col + 3] = b[:, s:s + 3] - a[:, s:s + 3]
            out[:, col + 3:col + 6] = relative_rotation_vectors(a[:, s + 3:s + 7], b[:, s + 3:s + 7])
            out[:, col + 6:col + 12] = b[:, s + 7:s + 13] - a[:, s + 7:s + 13]
            col += 12
        s, nj = 13 * len(self.bodies), len(self.joints)
        out[:, col:col + 2 * nj:2] = b[:, s:s + nj] - a[:, s:s + nj]
        out[:, col + 1:col + 2 * nj:2] = b[:, s + nj:s + 2 * nj] - a[:, s + nj:s + 2 * nj]
        return out

    def errors(self, differences: np.ndarray, scales: Mapping[str, float]) -> np.ndarray:
        """Normalised state error of every row (as :func:`normalized_error`)."""
        scale = np.array([scales[c] for c in self.channels])
        keep = np.isfinite(scale)
        if not keep.any():
            return np.zeros(differences.shape[0])
        scaled = differences[:, keep] / scale[keep]
        return np.sqrt(np.mean(scaled ** 2, axis=1))


