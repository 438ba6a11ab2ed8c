"""The Allan deviation of each IEEE 952 term, exact, and the smallest rest a process accepts."""

from __future__ import annotations

import numpy as np
import pytest

from imucal.noise.fit import term_adev
from imucal.noise.process import fit_noise_process

TAU = np.array([0.1, 1.0, 10.0, 100.0])


@pytest.mark.parametrize(
    ("term", "curve"),
    [
        ("Q", lambda v, t: np.sqrt(3.0) * v / t),
        ("N", lambda v, t: v / np.sqrt(t)),
        ("B", lambda v, t: np.sqrt(2.0 * np.log(2.0) / np.pi) * v * np.ones_like(t)),
        ("K", lambda v, t: v * np.sqrt(t / 3.0)),
        ("R", lambda v, t: v * t / np.sqrt(2.0)),
    ],
)
def test_each_term_has_its_ieee_952_slope_and_factor(term, curve):
    """IEEE Std 952 (Table C.2): quantisation sqrt(3) Q / tau, white N / sqrt(tau), bias
    instability's flat 0.664 B, rate random walk K sqrt(tau / 3), rate ramp R tau / sqrt(2)."""
    np.testing.assert_allclose(term_adev(term, 2e-3, TAU), curve(2e-3, TAU), rtol=1e-12)


def test_a_rest_of_two_readings_is_the_smallest_accepted():
    rest = np.array([[0.0, 0.1, 9.8], [0.01, 0.1, 9.79]])
    process = fit_noise_process(rest, 100.0, 0.0)
    assert np.all(np.isfinite(process.white)) and np.all(process.white >= 0)
    with pytest.raises(ValueError, match=r"n >= 2"):
        fit_noise_process(rest[:1], 100.0, 0.0)
