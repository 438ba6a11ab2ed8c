"""Overlapping Allan deviation: equal to allantools', bounded chunks, honest confidence intervals."""

from __future__ import annotations

import allantools
import numpy as np
import pytest
from scipy.special import erf

from imucal.noise import allan
from imucal.noise.allan import (
    confidence_interval,
    equivalent_dof,
    octave_cluster_sizes,
    overlapping_adev,
)


@pytest.mark.parametrize("chunk", [allan.CHUNK, 1000])
def test_deviations_equal_allantools(monkeypatch, chunk):
    """On a gravity-sized offset (precision of the integration) and across chunk boundaries.

    Both evaluate the same sums and agree to 6e-16; integrating the rate without removing its
    mean first loses digits on the offset of 9.81 and differs by 9e-11, so the tolerance is
    1e-13, not the 1e-10 that such a loss would pass."""
    monkeypatch.setattr(allan, "CHUNK", chunk)
    rng = np.random.default_rng(3)
    rate = 100.0
    y = 9.81 + 0.02 * rng.standard_normal(200_000) + 1e-4 * np.cumsum(rng.standard_normal(200_000))
    ours = overlapping_adev(y, rate)
    taus, ref, _, _ = allantools.oadev(y, rate=rate, data_type="freq", taus=ours.tau_s)
    np.testing.assert_array_equal(taus, ours.tau_s)
    np.testing.assert_allclose(ours.adev, ref, rtol=1e-13, atol=0)


def test_octave_cluster_sizes_stop_at_a_quarter_and_reject_short_records():
    m = octave_cluster_sizes(1000)
    assert m[0] == 1 and np.all(np.diff(np.log2(m)) == 1) and m[-1] <= 250 < 2 * m[-1]
    with pytest.raises(ValueError, match="at least 8"):
        octave_cluster_sizes(7)


def test_non_finite_samples_are_refused():
    y = np.ones(100)
    y[5] = np.nan
    with pytest.raises(ValueError, match="finite"):
        overlapping_adev(y, 100.0)


def test_white_noise_intervals_cover_the_truth_at_their_level():
    """Coverage of the EDF-based 68.3 % interval over 400 white-noise records, per tau.

    The truth is sigma / sqrt(m) for white noise of std sigma. The count of records whose
    interval holds it is binomial: the tolerance is 4 binomial standard deviations.
    """
    rng = np.random.default_rng(11)
    n, reps, level = 2048, 400, float(erf(1 / np.sqrt(2)))
    m = octave_cluster_sizes(n)
    edf = equivalent_dof(m, n + 1, np.zeros(len(m), dtype=int))
    hits = np.zeros(len(m))
    for _ in range(reps):
        ad = overlapping_adev(rng.standard_normal(n), 1.0)
        low, high = confidence_interval(ad.adev, edf, level)
        truth = 1.0 / np.sqrt(m)
        hits += (low <= truth) & (truth <= high)
    tol = 4 * np.sqrt(level * (1 - level) / reps)
    np.testing.assert_allclose(hits / reps, level, atol=tol)
