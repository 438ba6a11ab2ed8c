"""imucal.validation.timing.SmoothingSplines against scipy's make_smoothing_spline."""

import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline

from imucal.validation.timing import SmoothingSplines


@pytest.mark.parametrize("lam", [0.0, 1e-7, 1e-3, 10.0])
def test_the_same_spline_as_scipy(lam):
    rng = np.random.default_rng(4)
    x = np.cumsum(rng.uniform(0.002, 0.02, 700))
    y = np.sin(3 * x) + rng.normal(0, 0.1, x.size)
    ours, theirs = SmoothingSplines(x).fit(y, lam), make_smoothing_spline(x, y, lam=lam)
    # the same arithmetic in the same order: equal coefficients, not just close ones
    np.testing.assert_array_equal(ours.t, theirs.t)
    np.testing.assert_allclose(ours.c, theirs.c, rtol=1e-12, atol=1e-12)
    assert ours(x) == pytest.approx(theirs(x), rel=1e-12, abs=1e-12)


def test_abscissae_must_increase():
    with pytest.raises(ValueError, match="strictly increasing"):
        SmoothingSplines(np.array([0.0, 1.0, 1.0, 2.0, 3.0]))
