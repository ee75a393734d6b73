"""Camera frames for tests that need an image of a given size but not its content."""

from __future__ import annotations

import numpy as np


def random_frame(size: int, seed: int = 0) -> np.ndarray:
    """A seeded ``size`` x ``size`` RGB uint8 frame of uniform noise."""
    return np.random.default_rng(seed).integers(0, 255, (size, size, 3), dtype=np.uint8)
