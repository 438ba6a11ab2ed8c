"""The held-out decision rules of the temperature terms across poses: the block standard error,
the order choice (admissible orders, then the one-standard-error rule) and the intervals of an
RMS ratio, each against an independent form and by its coverage or rates over draws.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from imucal.terms.blockspread import _interval, _part, cluster_mean, verdict_of
from imucal.terms.heldout import _achieved
from imucal.terms.poseholdout import choose_order


def test_cluster_mean_is_the_ratio_estimator_with_its_cluster_robust_error():
    """``m = sum s / N``; ``se^2 = B / (B - 1) sum (s_b - m n_b)^2 / N^2``, here from the
    linearised ratio estimator written out block by block."""
    rng = np.random.default_rng(0)
    for b in (2, 3, 7, 40):
        counts = rng.integers(5, 60, b).astype(float)
        sums = counts * rng.normal(2.0, 0.5, b)
        m, se = cluster_mean(sums, counts)
        total = counts.sum()
        assert m == pytest.approx(sums.sum() / total, rel=1e-14)
        z = [(s - m * n) / total for s, n in zip(sums, counts)]
        assert se == pytest.approx(np.sqrt(b / (b - 1) * sum(v * v for v in z)), rel=1e-12)
    assert np.isnan(cluster_mean(np.array([3.0]), np.array([2.0]))[1])
    assert all(np.isnan(cluster_mean(np.zeros(0), np.zeros(0))))


def test_cluster_mean_interval_covers_the_mean_at_its_level(binomial_band):
    """Equal blocks of Gaussian samples: ``m +- t(B - 1) se`` is the t interval of the block
    means, so it holds the true mean in exactly 95 % of the draws (an error without its
    sqrt, or its B / (B - 1), moves the coverage far off)."""
    rng = np.random.default_rng(1)
    draws, b, n = 4000, 8, 25
    t = stats.t.ppf(0.975, b - 1)
    held = 0
    for _ in range(draws):
        x = rng.normal(1.0, 0.3, (b, n))
        m, se = cluster_mean(x.sum(axis=1), np.full(b, float(n)))
        held += abs(m - 1.0) <= t * se
    low, high = binomial_band(draws, 0.95)
    assert low <= held <= high, (held, low, high)


def _choose_reference(squares: dict) -> int:
    """Admissible: every held-out pose that has two blocks or more gains by more than one
    standard error of the paired difference, at least two such poses. Then the smallest
    admissible order within one standard error of the best pooled mean square."""

    def mean_se(sums, counts):
        n, b = counts.sum(), len(counts)
        m = sums.sum() / n
        se = np.sqrt(b / (b - 1) * np.sum((sums - m * counts) ** 2)) / n if b > 1 else np.nan
        return m, se

    pooled = {k: mean_se(*(np.concatenate([p[i] for p in v]) for i in (0, 1)))
              for k, v in squares.items()}  # fmt: skip
    admissible = []
    for k in squares:
        gains = [mean_se(p[0] - q[0], p[1]) for p, q in zip(squares[k], squares[0])]
        judged = [(m, se) for m, se in gains if np.isfinite(se)]
        if k > 0 and len(judged) >= 2 and all(m + se < 0 for m, se in judged):
            admissible.append(k)
    if not admissible:
        return 0
    best = min(pooled[k][0] for k in admissible)
    se_best = next(pooled[k][1] for k in admissible if pooled[k][0] == best)
    return min(k for k in admissible if pooled[k][0] <= best + se_best)


def _squares(rng, drift: float, poses: int = 3, blocks: int = 6) -> dict:
    """Order -> per held-out pose (sums of squares per block, samples per block): order 0 has
    the drift left in it, orders 1-3 remove it and add their own small scatter."""
    counts = [rng.integers(40, 80, blocks).astype(float) for _ in range(poses)]
    base = [c * rng.gamma(20, 1 / 20, blocks) for c in counts]
    out = {0: [(b + drift * c * rng.gamma(8, 1 / 8, blocks), c) for b, c in zip(base, counts)]}
    for k in (1, 2, 3):
        out[k] = [(b * rng.gamma(200, 1 / (200 - 3 * k), blocks), c) for b, c in zip(base, counts)]
    return out


def test_choose_order_is_the_admissible_then_one_standard_error_rule():
    """500 random draws, with and without a drift: the choice of the rule as documented, on
    every one; both outcomes occur often."""
    rng = np.random.default_rng(2)
    chosen = []
    for i in range(500):
        squares = _squares(rng, drift=0.15 * (i % 2))
        order, rms = choose_order(squares)
        assert order == _choose_reference(squares), i
        chosen.append(order)
        total = {k: sum(p[0].sum() for p in v) / sum(p[1].sum() for p in v)
                 for k, v in squares.items()}  # fmt: skip
        assert rms == pytest.approx({k: np.sqrt(v) for k, v in total.items()})
    assert 100 < sum(o == 0 for o in chosen) < 400 and len(set(chosen)) >= 3


def test_ratio_interval_is_students_t_with_satterthwaite_dof():
    """Each source's variance is ``B / (B - 1) sum phi^2`` over its B blocks with ``B - 1``
    dof; two sources combine with Satterthwaite's dof."""
    phi = np.array([0.1, -0.2, 0.05, 0.3])
    assert _part(phi, 4) == (pytest.approx(4 / 3 * np.sum(phi**2)), 3)
    assert _part(phi[:1], 1) == (0.0, 0)
    log_ratio = np.log(0.64)
    lo, hi = _interval(log_ratio, [(0.01, 5)])
    half = stats.t.ppf(0.975, 5) * 0.1
    assert (lo, hi) == pytest.approx((np.exp(0.5 * (log_ratio - half)),
                                      np.exp(0.5 * (log_ratio + half))))  # fmt: skip
    parts = [(0.01, 5), (0.03, 12)]
    dof = 0.04**2 / (0.01**2 / 5 + 0.03**2 / 12)
    half = stats.t.ppf(0.975, dof) * 0.2
    assert _interval(log_ratio, parts) == pytest.approx(
        [np.exp(0.5 * (log_ratio - half)), np.exp(0.5 * (log_ratio + half))]
    )
    assert verdict_of([0.5, 0.99]) == "better" and verdict_of([1.01, 2]) == "worse"
    assert verdict_of([0.9, 1.0]) == "within noise" == verdict_of([1.0, 1.1])


def test_achieved_shrink_and_its_std_over_n_held_out_values():
    """``1 - rho`` and ``rho sqrt(2 / n + 2 / n)``, rho the ratio of mean squares."""
    shrink, std = _achieved(2.0, 1.0, 50)
    assert shrink == 0.75 and std == pytest.approx(0.25 * np.sqrt(4 / 50), rel=1e-14)
    assert np.isnan(_achieved(0.0, 1.0, 5)[0])
