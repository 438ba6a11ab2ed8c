"""The time alignment's formal covariance rebuilt from its residuals, and its Birge inflation
from the windows' offsets.

The multi-session check (``test_timing_std.py``) tests the reported std statistically; a
degree of freedom too many or too few moves it by less than that check resolves. Here the
formal covariance of the shift fit is ``r.r / (n - p) (J^T J)^-1`` with ``J`` by central
differences of the model, on 40 samples where one dof is 3 %.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import make_interp_spline

from imucal.validation.timing import _fit_shift


def _model(p, spline, t, t_mid):
    return p[0] + p[1] * spline(t_mid + p[2] + (1.0 + p[3] * 1e-6) * (t - t_mid))


@pytest.mark.parametrize("free", [[True] * 4, [False, False, True, False]])
def test_shift_fit_covariance_is_the_residual_variance_over_n_minus_p(free):
    rng = np.random.default_rng(0)
    knots = np.linspace(-2.0, 12.0, 200)
    spline = make_interp_spline(knots, np.sin(1.3 * knots) ** 2 + 0.3 * np.cos(0.4 * knots), k=3)
    t = np.sort(rng.uniform(0.0, 10.0, 40))
    t_mid = 5.0
    truth = np.array([0.2, 1.5, 0.13, 40.0])
    w = _model(truth, spline, t, t_mid) + 0.05 * rng.standard_normal(t.size)
    free = np.array(free)
    start = np.where(free, truth + [0.01, 0.02, 0.01, 5.0], truth)
    p, cov, _ = _fit_shift(t, w, spline, t_mid, start, free)
    r = _model(p, spline, t, t_mid) - w
    jac = []
    for k in np.flatnonzero(free):
        h = np.zeros(4)
        h[k] = 1e-6 * max(1.0, abs(p[k]))
        jac.append((_model(p + h, spline, t, t_mid) - _model(p - h, spline, t, t_mid)) / (2 * h[k]))
    jac = np.array(jac).T
    want = r @ r / (t.size - free.sum()) * np.linalg.inv(jac.T @ jac)
    np.testing.assert_allclose(cov, want, rtol=1e-4)


def test_birge_inflation_is_the_windows_reduced_chi_square_with_k_minus_2_dof(monkeypatch):
    """The windows' offsets about the fitted line (offset and drift: 2 dof) against their own
    formal std, recorded as the alignment computes them: ``inflation^2 = chi2 / (k - 2)``."""
    from scipy.spatial.transform import Rotation
    from test_validation import RATE_HZ, Motion

    from imucal.validation import timing

    calls = []

    def spy(*args):
        out = timing_fit(*args)
        calls.append((args[5].copy(), out[1]))
        return out

    timing_fit = timing._fit_shift
    monkeypatch.setattr(timing, "_fit_shift", spy)
    motion = Motion()
    t_mod = np.arange(int(motion.duration_s * RATE_HZ)) / RATE_HZ
    t_ref = np.arange(int((motion.duration_s + 1.0) * RATE_HZ)) / RATE_HZ
    inflated = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        gyr_mod = motion.truth(t_mod)["gyr"] + rng.normal(0, 0.003, (t_mod.size, 3))
        truth = motion.truth((t_ref - 0.2) / (1 + 30e-6))["gyr"]
        gyr_ref = Rotation.from_rotvec([0.02, 0.0, -0.03]).inv().apply(truth)
        gyr_ref = gyr_ref + rng.normal(0, 0.002, truth.shape)
        calls.clear()
        ta = timing.estimate_time_alignment(t_mod, gyr_mod, t_ref, gyr_ref)
        window_std = np.array([np.sqrt(cov[0, 0]) for free, cov in calls if free.sum() == 1])
        k = ta.window_offset_s.size
        assert k == window_std.size >= 3
        line = ta.offset_mid_s + ta.drift_ppm * 1e-6 * (ta.window_t_s - ta.t_mid_s)
        ratio = np.sum(((ta.window_offset_s - line) / window_std) ** 2) / (k - 2)
        assert ta.std_inflation == pytest.approx(np.sqrt(max(ratio, 1.0)), rel=1e-10)
        formal = calls[0][1]
        assert ta.offset_mid_std_s == pytest.approx(
            np.sqrt(formal[2, 2]) * ta.std_inflation, rel=1e-10
        )
        assert ta.drift_std_ppm == pytest.approx(
            np.sqrt(formal[3, 3]) * ta.std_inflation, rel=1e-10
        )
        inflated += ta.std_inflation > 1.0
    assert inflated >= 2  # the ratio decides on some of them
