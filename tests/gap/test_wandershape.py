"""The shape test a wandering bias must pass: its false-alarm rate on real wanders and its power
on a bias step and on an offset that follows the pose; the Allan shape of a white-noise level
that is off."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from imucal.gap.wandershape import (
    SHAPE_P,
    WanderColumn,
    allan_shape_z,
    gauss_markov_avar,
    wander_shape,
)

TAU_S = 100.0
#: A session's resting means: 29 rests over 800 s, white noise of each mean 3e-5 rad/s.
T_S = np.sort(np.random.default_rng(0).uniform(0, 800, 29))
WHITE = 3e-5


def _columns(rng, gm=1e-4, rw=0.0, step=0.0, pose=0.0):
    """Three axes of resting means: white noise, a Gauss-Markov wander of std ``gm`` (and a
    random walk of ``rw`` per sqrt(s)), a step of ``step`` at 400 s, an offset of ``pose``
    that repeats with the pose (6 poses visited in turn)."""
    out = []
    n = len(T_S)
    kernel = np.exp(-np.abs(T_S[:, None] - T_S[None, :]) / TAU_S)
    walk = np.minimum(T_S[:, None], T_S[None, :])
    cov = gm**2 * kernel + rw**2 * walk + 1e-30 * np.eye(n)
    poses = rng.normal(0, 1, 6)
    for _ in range(3):
        y = np.linalg.cholesky(cov) @ rng.standard_normal(n) + rng.normal(0, WHITE, n)
        y += step * (T_S > 400) + pose * poses[np.arange(n) % 6]
        out.append(WanderColumn(T_S, y, np.full(n, WHITE**2), np.ones((n, 1))))
    return out


def _band(n: int, p: float, budget: float = 1e-3) -> tuple[int, int]:
    """Counts of ``n`` draws at rate ``p`` outside which the test fails with ``budget``."""
    return int(sps.binom.ppf(budget / 2, n, p)), int(sps.binom.isf(budget / 2, n, p))


@pytest.mark.slow
@pytest.mark.parametrize("gm, rw", [(1e-4, 0.0), (3e-4, 0.0), (0.0, 1e-5)])
def test_a_real_wander_is_refused_at_the_tests_level(gm, rw):
    rng = np.random.default_rng(int(gm * 1e7 + rw * 1e9))
    n = 40
    refused = sum(
        wander_shape(_columns(rng, gm, rw), TAU_S, rng, n_boot=200)["p"] < SHAPE_P for _ in range(n)
    )
    assert refused <= _band(n, SHAPE_P)[1], refused


@pytest.mark.parametrize("kind", ["step", "pose"])
def test_a_step_or_a_pose_offset_is_not_a_wander(kind):
    rng = np.random.default_rng(7)
    n = 20
    found = 0
    for _ in range(n):
        columns = _columns(rng, gm=0.0, **{kind: 20 * WHITE})
        found += wander_shape(columns, TAU_S, rng, n_boot=200)["p"] < SHAPE_P
    assert found >= 0.9 * n, found


def test_the_gauss_markov_allan_variance_is_the_simulated_one():
    rng = np.random.default_rng(3)
    dt, n = 0.05, 400_000
    a = np.exp(-dt / TAU_S)
    x = np.zeros(n)
    e = rng.standard_normal(n) * np.sqrt(1 - a * a)
    for i in range(1, n):
        x[i] = a * x[i - 1] + e[i]
    for tau in (1.0, 10.0):
        m = int(tau / dt)
        c = np.concatenate([[0.0], np.cumsum(x)])
        d = c[2 * m :] - 2 * c[m : n + 1 - m] + c[: n + 1 - 2 * m]
        avar = np.mean(d**2) / (2 * m * m)
        # the overlapping estimate's own scatter over 20000 s is a few percent at these taus
        assert avar == pytest.approx(gauss_markov_avar(np.array([tau]), 1.0, TAU_S)[0], rel=0.1)


def test_a_white_level_that_is_off_has_an_excess_at_short_times():
    """At ten samples a wander adds nothing measurable; a white level above the twin's does."""
    rate_hz, m, n = 100.0, 10, 30_000
    rng = np.random.default_rng(4)
    white = np.full(3, 1e-6)  # SI^2 s: 1e-4 per sample at 100 Hz
    sigma = np.sqrt(white[0] * rate_hz)
    edf = n / m - 1
    scores = []
    for _ in range(200):
        x = rng.normal(0, sigma, (n, 3))
        x += np.cumsum(rng.normal(0, 2e-4 / np.sqrt(rate_hz), (n, 3)), axis=0)  # a walk
        c = np.vstack([np.zeros((1, 3)), np.cumsum(x, axis=0)])
        d = c[2 * m :] - 2 * c[m : n + 1 - m] + c[: n + 1 - 2 * m]
        avar = np.mean(d**2, axis=0) / (2 * m * m)
        scores.append(allan_shape_z(avar, white, m / rate_hz, edf))
    scores = np.concatenate(scores)
    # the walk leaves the score a standard normal draw (at most as wide: edf is conservative)
    assert abs(np.mean(scores)) < 4 / np.sqrt(len(scores))
    assert np.std(scores) < 1.1
    # the white noise 30 % above the twin's, as a filtered output's first differences show it
    z = allan_shape_z(1.3 * white / (m / rate_hz), white, m / rate_hz, edf)
    assert np.all(z > 4)
