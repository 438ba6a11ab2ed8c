"""The quiet-window threshold of the static detector by its false-alarm rate and power.

For white noise of variance ``s^2`` a window's variance is ``s^2 chi2(n - 1) / (n - 1)``; a
window is quiet when every axis stays below the ``1 - p_false`` quantile of that law. On a
recording of pure noise the disjoint windows (independent) called moving must then number
``1 - (1 - p_false)^3`` of them; on a stretch whose noise is ``f`` times larger, those called
moving ``1 - P(chi2(n - 1) < q / f^2)^3``. Both counts must lie in the Binomial band that
holds them with probability 1 - 1e-4 (``binomial_band``).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from imucal.segments.detector import find_quiet_windows

WINDOW = 50


def _called_moving(quiet: np.ndarray, rows: slice) -> tuple[int, int]:
    """Disjoint windows starting in ``rows`` called moving, and how many there are."""
    starts = np.arange(rows.start, rows.stop - WINDOW + 1, WINDOW)
    return int(np.sum(~quiet[starts])), starts.size


def test_quiet_windows_false_alarm_and_power(binomial_band):
    rng = np.random.default_rng(11)
    p_false, n, loud = 0.01, 400_000, 1.4
    noise = np.array([0.003, 0.004, 0.006])
    x = noise * rng.standard_normal((n, 3))
    rows = slice(n - 20_000, n)  # 5 % of the recording, its noise 1.4 times larger
    x[rows] *= loud
    quiet, found = find_quiet_windows(x, WINDOW, p_false)
    # the noise is estimated from the quiet windows (the loud ones that pass add < 1 %)
    np.testing.assert_allclose(found, noise**2, rtol=0.02)
    dof = WINDOW - 1
    moving, total = _called_moving(quiet, slice(0, rows.start))
    low, high = binomial_band(total, 1 - (1 - p_false) ** 3)
    assert low <= moving <= high, (moving, low, high, total)
    q = stats.chi2.isf(p_false, dof)
    p_loud = 1 - np.prod([stats.chi2.cdf(q / loud**2, dof)] * 3)
    moving, total = _called_moving(quiet, rows)
    low, high = binomial_band(total, p_loud)
    assert low <= moving <= high, (moving, low, high, total, p_loud)
