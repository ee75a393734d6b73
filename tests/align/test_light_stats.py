"""align's statistics without scipy.stats (its import cost a CPU-second per command): the same numbers, bit for bit."""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import special, stats

from dualtwin.align.analyze import spearman


def test_spearman_is_scipys_with_ties_and_constants() -> None:
    rng = np.random.default_rng(7)
    for trial in range(400):
        k = int(rng.integers(3, 12))
        x = rng.integers(0, 4, k).astype(float) if trial % 2 else rng.normal(size=k)
        y = rng.normal(size=k) if trial % 3 else rng.integers(0, 3, k).astype(float)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # scipy warns about a constant input, and returns NaN
            want = float(stats.spearmanr(x, y).statistic)
        got = spearman(list(x), list(y))
        assert (math.isnan(want) and math.isnan(got)) or got == want, (x, y)
    assert math.isnan(spearman([1.0, 2.0, 3.0], [4.0, 4.0, 4.0]))  # constant: undefined, as scipy says


def test_the_t_quantile_is_stats_t_ppf() -> None:
    for dof in (1, 2, 3, 7, 30, 120, 5000):
        assert float(special.stdtrit(dof, 0.975)) == float(stats.t.ppf(0.975, dof))
