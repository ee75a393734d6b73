"""Webots' DistanceSensor ray layout and weights (``docs/reference/webots-devices.md`` §1.2), shared by the Webots
twin's DistanceSensor (:mod:`.ranging`) and the MuJoCo twin's converted one (:mod:`dualtwin.twins.mujoco_rays`).

``numberOfRays`` rays in the sensor frame (axis +x): Webots' predefined polar patterns ``(α, k)`` for 2–10 rays
and concentric cones beyond, k the fraction of the half ``aperture``; Gaussian weights
``exp(-(θ/(aperture·gaussianWidth))²)`` normalised to sum 1 (used by generic and infra-red sensors). Kept apart
from :mod:`.ranging` so that the MuJoCo twin computes the same rays without importing the ODE runtime.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["distance_ray_directions", "distance_ray_layout", "distance_ray_weights"]

_H, _T, _Q, _F, _S, _E = math.pi, 2 * math.pi / 3, math.pi / 2, 2 * math.pi / 5, math.pi / 3, 2 * math.pi / 7
_PATTERNS: dict[int, list[tuple[float, float]]] = {
    2: [(_Q, 1), (-_Q, 1)],
    3: [(0, 1), (_T, 1), (-_T, 1)],
    4: [(0, 0), (0, 1), (_T, 1), (-_T, 1)],
    5: [(0, 0), (0, 1), (_Q, 1), (_H, 1), (-_Q, 1)],
    6: [(0, 0), (0, 1)] + [(i * _F, 1) for i in range(1, 5)],
    7: [(0, 0), (0, 1)] + [(i * _S, 1) for i in range(1, 6)],
    8: [(0, 0), (0, 1)] + [(i * _E, 1) for i in range(1, 7)],
    9: [(0, 0.3), (_T, 0.3), (-_T, 0.3), (0, 1)] + [(i * _S, 1) for i in range(1, 6)],
    10: [(0, 0), (0, 0.5), (_T, 0.5), (-_T, 0.5), (0, 1)] + [(i * _S, 1) for i in range(1, 6)],
}


def distance_ray_layout(n: int) -> list[tuple[float, float]]:
    """Webots' polar ray layout ``(α, k)`` for ``n`` rays: k is the fraction of the half aperture."""
    if n <= 1:
        return [(0.0, 0.0)]
    if n in _PATTERNS:
        return [(float(a), float(k)) for a, k in _PATTERNS[n]]
    sizes: list[int] = []
    left, c = n, 0
    while left > 0:
        take = min(3 * c + 1, left)
        sizes.append(take)
        left -= take
        c += 1
    out: list[tuple[float, float]] = []
    s = 0
    for cone, m in enumerate(sizes):
        k = cone / (len(sizes) - 1)
        for _ in range(m):
            out.append((s * 2 * math.pi / m, k))  # Webots uses the global ray index here (a quirk kept)
            s += 1
    return out


def distance_ray_directions(n: int, aperture: float) -> np.ndarray:
    """Unit ray directions in the sensor frame (axis +x), shape (n, 3)."""
    dirs = []
    for alpha, k in distance_ray_layout(n):
        a = alpha + math.pi / 2
        theta = k * aperture / 2
        dirs.append((math.cos(theta), -math.sin(theta) * math.cos(a), math.sin(theta) * math.sin(a)))
    return np.array(dirs, dtype=float)


def distance_ray_weights(directions: np.ndarray, aperture: float, gaussian_width: float) -> np.ndarray:
    """Gaussian weights of generic/infra-red rays, normalised to sum 1."""
    if len(directions) == 1:
        return np.ones(1)
    t = np.arccos(np.clip(directions[:, 0] / np.linalg.norm(directions, axis=1), -1.0, 1.0))
    w = np.exp(-((t / (aperture * gaussian_width)) ** 2))
    return w / w.sum()
