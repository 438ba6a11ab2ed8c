"""Generalised least squares with a wandering bias: the reported standard deviation of a drift
coefficient covers the truth when the residuals share a random walk confounded with the drift
(a warm-up: temperature rising with time), where ordinary least squares does not."""

from __future__ import annotations

import numpy as np
import pytest

from imucal.fits.wander import fit_with_wander

#: 29 resting segments over 1030 s as a session lays them out: rests of a rotation phase,
#: cube positions, rate-table rests and the static recording's blocks.
T_S = np.array([6, 29, 36, 55, 62, 79, 145, 156, 166, 175, 185, 195, 205, 214, 224, 233, 242,
                253, 373, 477, 582, 715, 760, 805, 850, 895, 940, 985, 1030], dtype=float)  # fmt: skip
WALK = 9e-8  # (rad/s)^2 / s: 3e-4 rad/s/sqrt(s), the harsh end of MEMS gyroscopes
WHITE = np.full(len(T_S), 3e-9)  # (rad/s)^2: noise of a 5-s mean
DRIFT = 4.36e-3  # rad/s/K: 0.25 deg/s/K


def _warm_up(t):
    return 15 * (1 - np.exp(-t / 300)) - 7.5  # K about the mid temperature


def _draws(n):
    rng = np.random.default_rng(3)
    x = np.column_stack([np.ones(len(T_S)), _warm_up(T_S)])
    steps = np.diff(T_S, prepend=T_S[0])
    for _ in range(n):
        walk = np.cumsum(rng.normal(size=len(T_S)) * np.sqrt(WALK * steps))
        yield x, 0.1 + DRIFT * x[:, 1] + walk + rng.normal(size=len(T_S)) * np.sqrt(WHITE)


def test_drift_std_covers_the_truth_under_a_walk():
    z, z_ols = [], []
    for x, y in _draws(200):
        f = fit_with_wander(x, y, WHITE, T_S)
        z.append((f.coef[1] - DRIFT) / np.sqrt(f.cov[1, 1]))
        coef, res, *_ = np.linalg.lstsq(x, y, rcond=None)
        std = np.sqrt(res[0] / (len(y) - 2) * np.linalg.inv(x.T @ x)[1, 1])
        z_ols.append((coef[1] - DRIFT) / std)
    z = np.asarray(z)
    rms = float(np.sqrt(np.mean(z**2)))
    # 200 draws: the RMS of z is known to ~5 %; the walk's variance estimated from 29 means
    # adds ~10 % (a t-like widening), so [0.85, 1.3]
    assert 0.85 < rms < 1.3, rms
    assert np.mean(np.abs(z) < 1.96) > 0.88
    assert np.sqrt(np.mean(np.square(z_ols))) > 2.5  # least squares is optimistic here


def test_without_a_walk_it_is_weighted_least_squares():
    rng = np.random.default_rng(4)
    x = np.column_stack([np.ones(len(T_S)), _warm_up(T_S)])
    white = WHITE * rng.uniform(0.5, 2, len(T_S))
    y = 0.1 + DRIFT * x[:, 1] + rng.normal(size=len(T_S)) * np.sqrt(white)
    f = fit_with_wander(x, y, white, T_S)
    w = 1 / white
    cov = np.linalg.inv(x.T @ (w[:, None] * x))
    coef = cov @ x.T @ (w * y)
    assert f.walk_per_s < 1e-3 * WALK
    np.testing.assert_allclose(f.coef, coef, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(np.diag(f.cov), np.diag(cov), rtol=2e-3)


def test_refuses_too_few_means_and_nonpositive_noise():
    x = np.column_stack([np.ones(3), np.arange(3.0)])
    with pytest.raises(ValueError, match="3 means cannot carry 2 coefficients"):
        fit_with_wander(x, np.zeros(3), np.ones(3), np.arange(3.0))
    x = np.column_stack([np.ones(5), np.arange(5.0)])
    with pytest.raises(ValueError, match="must be positive"):
        fit_with_wander(x, np.zeros(5), np.zeros(5), np.arange(5.0))


def test_the_fit_does_not_depend_on_the_clocks_origin():
    """The walk starts at the first mean: the same means stamped 1000 s later (a clock started
    earlier) give the same coefficients and the same covariance, the intercept's too (the
    level at the first mean, whose walk variance is zero there)."""
    x, y = next(_draws(1))
    f = fit_with_wander(x, y, WHITE, T_S)
    g = fit_with_wander(x, y, WHITE, T_S + 1000.0)
    np.testing.assert_allclose(g.coef, f.coef, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(g.cov, f.cov, rtol=1e-4, atol=1e-18)
