"""Rate series of known IEEE 952 terms (white N, flicker B, random walk K), for the noise tests.

The flicker part is white noise shaped in frequency to the two-sided PSD ``B^2 / (2 pi f)``
(IEEE Std 952, Table C.1), on a record ``OVERSAMPLE`` times longer than asked and cut to length:
an FFT-shaped series holds no frequency below one over its length, so shaping exactly the
asked length would lack the slow part of the flicker that the longest clusters see.
"""

from __future__ import annotations

import numpy as np

OVERSAMPLE = 8


def synthetic_rate(
    n: int, rate_hz: float, *, white: float, flicker: float, random_walk: float, seed: int
) -> np.ndarray:
    """Rate samples, shape (n,), with white noise N, bias instability B and rate random walk K."""
    rng = np.random.default_rng(seed)
    y = white * np.sqrt(rate_hz) * rng.standard_normal(n)
    if random_walk:
        y += random_walk * np.sqrt(1.0 / rate_hz) * np.cumsum(rng.standard_normal(n))
    if flicker:
        long = OVERSAMPLE * n
        spectrum = np.fft.rfft(rng.standard_normal(long))
        f = np.fft.rfftfreq(long, 1.0 / rate_hz)
        gain = np.zeros_like(f)
        # unit white noise has the two-sided PSD 1 / rate_hz
        gain[1:] = np.sqrt(flicker**2 / (2.0 * np.pi * f[1:]) * rate_hz)
        y += np.fft.irfft(spectrum * gain, long)[:n]
    return y
