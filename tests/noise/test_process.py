"""The session's noise as a process (imucal.noise.process): measured on a rest, drawn again."""

from __future__ import annotations

import numpy as np
import pytest

from imucal.noise.process import NoiseProcess, dither_std, fit_noise_process

RATE_HZ = 100.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_white_noise_and_bias_walk_are_measured_on_a_rest(seed):
    white, walk = 1e-3, 5e-5
    truth = NoiseProcess(np.full(3, white), np.zeros(3), np.ones(3), np.array([walk, walk, 0]), 0)
    rest = truth.draw(int(600 * RATE_HZ), RATE_HZ, np.random.default_rng(seed))
    found = fit_noise_process(rest, RATE_HZ, 0.0)
    # white: 60,000 first differences, a relative standard error of 1/sqrt(2 * 60000) = 0.3 %
    assert found.white == pytest.approx(np.full(3, white), rel=0.02)
    # the walk shows at the longest averaging times only (a few degrees of freedom at 150 s):
    # four seeds gave 0.86-1.07 of the truth
    assert found.walk[:2] == pytest.approx([walk, walk], rel=0.3)
    # where there is none, the fit finds at most a tenth of it
    assert found.walk[2] < 0.1 * walk


@pytest.mark.parametrize("ratio", [0.15, 0.3, 2.0])
def test_white_noise_below_one_count_is_found_under_the_rounding(ratio):
    """Rounded to a step of 1e-3, a noise of 0.15 counts flips the reading a few times in a
    hundred: its first differences' variance is far below step^2 / 12, which subtracting the
    uniform rounding variance would call no noise at all."""
    step = 1e-3
    n = 200_000
    rng = np.random.default_rng(9)
    drift = np.linspace(0.0, 7.3 * step, n)[:, None]  # the offsets within a count all occur
    rounded = np.rint((drift + ratio * step * rng.standard_normal((n, 3))) / step) * step
    variance = np.var(np.diff(rounded, axis=0), axis=0) / 2
    found = np.array([dither_std(v, step) for v in variance])
    assert found == pytest.approx(np.full(3, ratio * step), rel=0.05)
    if ratio < 0.2:  # where the uniform rounding variance would miss most of it
        assert np.sqrt(np.maximum(variance - step**2 / 12, 0)).max() < 0.5 * ratio * step


def test_a_rest_that_never_changes_has_no_noise_and_bad_input_is_refused():
    assert fit_noise_process(np.ones((2000, 3)), RATE_HZ, 1e-3).white.tolist() == [0, 0, 0]
    with pytest.raises(ValueError, match=r"shape \(n >= 2, 3\)"):
        fit_noise_process(np.ones((10, 2)), RATE_HZ, 1e-3)
