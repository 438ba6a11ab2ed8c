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


def test_phase_starts_at_zero_whatever_memory_it_is_given(monkeypatch):
    """The phase's first point is set, not left to what np.empty returns (NaN here)."""
    monkeypatch.setattr(allan.np, "empty", lambda shape, **kw: np.full(shape, np.nan, **kw))
    y = np.array([1.0, 2.0, 4.0, 8.0])
    x = allan.integrate_rate(y, 2.0)
    np.testing.assert_array_equal(x, [0.0, -1.375, -2.25, -2.125, 0.0])


def test_given_cluster_sizes_and_record_bounds():
    """Cluster sizes given explicitly are used (as allantools at the same taus); the shortest
    record and the largest cluster size it admits are accepted, one less refused."""
    rng = np.random.default_rng(4)
    y = rng.standard_normal(1000)
    ours = overlapping_adev(y, 50.0, m=[1, 3, 7, 499])
    np.testing.assert_array_equal(ours.m, [1, 3, 7, 499])
    np.testing.assert_array_equal(ours.tau_s, np.array([1, 3, 7, 499]) / 50.0)
    assert ours.n_phase == 1001
    _, ref, _, _ = allantools.oadev(y, rate=50.0, data_type="freq", taus=ours.tau_s)
    np.testing.assert_allclose(ours.adev, ref, rtol=1e-13)
    # 2 m + 1 phase points give one second difference; 2 m do not
    assert np.isfinite(overlapping_adev(y[:998], 50.0, m=[499]).adev[0])
    with pytest.raises(
        ValueError, match="cluster size 499 needs more than 998 phase points, got 998"
    ):
        overlapping_adev(y[:997], 50.0, m=[499])
    np.testing.assert_array_equal(octave_cluster_sizes(8), [1, 2])
    with pytest.raises(ValueError, match="rate_hz must be positive, got 0.0"):
        overlapping_adev(y, 0.0)


def test_interval_follows_its_level_and_refuses_levels_outside_0_1():
    adev, edf = np.array([1.0, 2.0]), np.array([10.0, 40.0])
    low68, high68 = confidence_interval(adev, edf, 0.683)
    low95, high95 = confidence_interval(adev, edf, 0.95)
    assert np.all(low95 < low68) and np.all(high68 < high95)
    # chi-square with 10 dof: the 95 % interval of the deviation is sqrt(10 / chi2 quantiles)
    from scipy import stats

    want = np.sqrt(10 / stats.chi2.ppf([0.975, 0.025], 10))
    np.testing.assert_allclose([low95[0], high95[0]], want, rtol=1e-6)
    for level in (0.0, 1.0):
        with pytest.raises(ValueError, match=r"confidence level must be in \(0, 1\)"):
            confidence_interval(adev, edf, level)
    low, high = confidence_interval(np.array([]), np.array([]), 0.683)
    assert low.shape == high.shape == (0,)
