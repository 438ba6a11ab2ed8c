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
